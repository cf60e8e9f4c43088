"""Render a pose list to images + labels, resumably (docs/python.md, "Datasets").

    python -m hilcam.dataset SCENE OUT --poses scenes/trajectories/approach.csv --width 256
    python -m hilcam.dataset SCENE OUT --sample 1000 --range 20,200 --seed 7

Layout of OUT:

    dataset.json     what made it: scene, camera, size, settings (a resumed run must match)
    labels.jsonl     one JSON object per frame, in frame order (the keys: docs/python.md)
    images/NNNNNN.png  the camera's output (DN, 16-bit PNG; .exr for a float camera)
    truth/NNNNNN_depth.npy, truth/NNNNNN_mask.npy  ground truth (the channels asked for)

Every frame is a pure function of its inputs: the renderer is reset before each one (the
auto-exposure starts afresh, as `hilcam render` does) and the frame index keys the random
numbers. Files are written whole (image: renamed into place by the core's writer; truth:
the same by os.replace), and a frame's label line is appended and synced last, so after a
kill a rerun with the same arguments skips the frames whose label is there and renders
the rest: the result is the same bytes as an uninterrupted run.
"""

import argparse
import csv
import json
import math
import os
import sys
import time

import numpy as np

from . import Camera, Renderer, Scene, camera_presets

LABELS = "labels.jsonl"
MANIFEST = "dataset.json"


def sample_poses(n, *, range_m=(20.0, 100.0), phase_deg=(0.0, 90.0), off_axis_deg=5.0, exposure_s=None, seed=0):
    """`n` poses of a sampled distribution: range uniform in `range_m` (m); the target's
    origin uniform over the cone of half-angle `off_axis_deg` around the boresight;
    attitude uniform over rotations (Shoemake); the sun at a phase angle (camera–target–sun) uniform in `phase_deg`, about
    a uniformly random axis; with `exposure_s` = (lo, hi), an integration time log-uniform in
    it (else the camera's auto-exposure chooses). Returns a list of
    {"pose": [px, py, pz, qw, qx, qy, qz], "sun": [sx, sy, sz]} (and "integration_s")."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        r = rng.uniform(*range_m)
        theta = math.radians(off_axis_deg) * math.sqrt(rng.uniform())
        phi = rng.uniform(0, 2 * math.pi)
        d = np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)])
        u1, u2, u3 = rng.uniform(size=3)
        q = [
            math.sqrt(u1) * math.cos(2 * math.pi * u3),
            math.sqrt(1 - u1) * math.sin(2 * math.pi * u2),
            math.sqrt(1 - u1) * math.cos(2 * math.pi * u2),
            math.sqrt(u1) * math.sin(2 * math.pi * u3),
        ]
        # The sun: the direction back to the camera (-d) turned by the phase angle.
        alpha = math.radians(rng.uniform(*phase_deg))
        axis = np.cross(-d, rng.normal(size=3))
        axis /= np.linalg.norm(axis)
        v = -d
        sun = v * math.cos(alpha) + np.cross(axis, v) * math.sin(alpha) + axis * np.dot(axis, v) * (1 - math.cos(alpha))
        item = {"pose": [*(r * d).tolist(), *q], "sun": sun.tolist()}
        if exposure_s is not None:
            item["integration_s"] = math.exp(rng.uniform(math.log(exposure_s[0]), math.log(exposure_s[1])))
        out.append(item)
    return out


def read_poses(path):
    """A pose CSV: hilcam's trajectory format (docs/trajectory.md; `#` comments, a header
    naming px,py,pz,qw,qx,qy,qz,sx,sy,sz, other columns ignored)."""
    with open(path, newline="") as f:
        rows = csv.DictReader(line for line in f if not line.startswith("#"))
        out = []
        for row in rows:
            pose = [float(row[k]) for k in ("px", "py", "pz", "qw", "qx", "qy", "qz")]
            sun = [float(row[k]) for k in ("sx", "sy", "sz")] if "sx" in row else None
            out.append({"pose": pose, "sun": sun})
        return out


def _done_frames(labels):
    """The frame indices whose label line is complete; a torn last line is cut off."""
    if not os.path.exists(labels):
        return set()
    done, keep = set(), 0
    with open(labels, "rb") as f:
        data = f.read()
    for line in data.split(b"\n")[:-1]:
        try:
            done.add(json.loads(line)["index"])
        except (ValueError, KeyError):
            break
        keep += len(line) + 1
    if keep != len(data):
        with open(labels, "r+b") as f:
            f.truncate(keep)
    return done


def _save_npy(path, array):
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        np.save(f, array)
    os.replace(tmp, path)


class _Progress:
    def __init__(self, total, done, enabled):
        self.total, self.start, self.t0, self.enabled = total, done, time.monotonic(), enabled
        self.show(done)

    def show(self, n):
        if not self.enabled:
            return
        rate = (n - self.start) / max(time.monotonic() - self.t0, 1e-9)
        eta = (self.total - n) / rate if rate > 0 else float("nan")
        bar = "#" * int(30 * n / max(self.total, 1))
        sys.stderr.write(f"\r[{bar:<30}] {n}/{self.total} frames, {rate:.2f} frames/s, ETA {eta:.0f} s ")
        if n == self.total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def render_dataset(renderer, poses, out, *, truth=("depth", "mask"), manifest=None, progress=True):
    """Render `poses` (a list of {"pose": [...3 or 7], "sun": [...3] or None}) with
    `renderer` into the directory `out` (layout: this module's doc); skips the frames
    already labelled there. `manifest`: a dict saved as dataset.json, which a resumed run
    must give equal. Returns the number of frames rendered by this call."""
    os.makedirs(os.path.join(out, "images"), exist_ok=True)
    os.makedirs(os.path.join(out, "truth"), exist_ok=True)
    manifest = dict(manifest or {}, frames=len(poses), truth=list(truth), settings=renderer.settings)
    mpath = os.path.join(out, MANIFEST)
    if os.path.exists(mpath):
        with open(mpath) as f:
            old = json.load(f)
        if old != json.loads(json.dumps(manifest)):
            raise ValueError(f"{mpath}: made with other inputs ({old}); use another directory")
    else:
        with open(mpath + ".tmp", "w") as f:
            json.dump(manifest, f, indent=1)
        os.replace(mpath + ".tmp", mpath)
    labels_path = os.path.join(out, LABELS)
    done = _done_frames(labels_path)
    bar = _Progress(len(poses), len(done), progress)
    rendered = 0
    with open(labels_path, "a") as labels:
        for i, p in enumerate(poses):
            if i in done:
                continue
            pose, sun = p["pose"], p.get("sun")
            renderer.reset()
            frame = renderer.render(pose, sun, frame=i, integration_s=p.get("integration_s"))
            ext = "png" if frame.bits is not None else "exr"
            image = f"images/{i:06d}.{ext}"
            frame.save(os.path.join(out, image))
            t = renderer.truth(pose, sun, channels=list(truth)) if truth else renderer.truth(pose, sun, channels=["mask"])
            paths = {}
            for ch in truth:
                paths[ch] = f"truth/{i:06d}_{ch}.npy"
                _save_npy(os.path.join(out, paths[ch]), t[ch])
            fp = t["footprint"]
            label = {
                "index": i,
                "image": image,
                "pose": [float(v) for v in pose],
                "sun": None if sun is None else [float(v) for v in sun],
                "range_m": float(np.linalg.norm(np.asarray(pose[:3], dtype=float))),
                "bbox_px": None if fp is None else list(fp["bbox_px"]),
                "centroid_px": None if fp is None else list(fp["centroid_px"]),
                "pixels": 0 if fp is None else fp["pixels"],
                "integration_s": frame.integration_s,
                "truth": paths,
            }
            labels.write(json.dumps(label) + "\n")
            labels.flush()
            os.fsync(labels.fileno())
            rendered += 1
            bar.show(len(done) + rendered)
    return rendered


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m hilcam.dataset", description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", help="scene TOML")
    ap.add_argument("out", help="output directory (resumed when it exists)")
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--poses", help="pose CSV (trajectory format: px,py,pz,qw,qx,qy,qz,sx,sy,sz)")
    src.add_argument("--sample", type=int, metavar="N", help="N poses of a sampled distribution")
    ap.add_argument("--range", default="20,100", help="sampled range, m: LO,HI (default 20,100)")
    ap.add_argument("--phase", default="0,90", help="sampled sun phase angle, degrees: LO,HI (default 0,90)")
    ap.add_argument("--exposure", help="sampled integration time, s: LO,HI, log-uniform (default: auto-exposure)")
    ap.add_argument("--camera", help="camera preset or TOML (default: the scene's)")
    ap.add_argument("--width", type=int, help="scale the camera to this many columns")
    ap.add_argument("--spp", type=float)
    ap.add_argument("--seed", type=int, default=0, help="render seed, and the sampled poses' (default 0)")
    ap.add_argument("--threads", type=int)
    ap.add_argument("--truth", default="depth,mask", help="truth channels to save (default depth,mask)")
    ap.add_argument("--no-progress", action="store_true")
    a = ap.parse_args(argv)
    scene = Scene.load(a.scene)
    if a.camera in camera_presets():
        cam = Camera.preset(a.camera)
    else:
        cam = Camera.load(a.camera) if a.camera else scene.camera
    if a.width:
        cam = cam.scaled(a.width)
    r = Renderer(scene, cam, spp=a.spp, seed=a.seed, threads=a.threads)
    if a.poses:
        poses = read_poses(a.poses)
    else:
        lo, hi = (float(v) for v in a.range.split(","))
        plo, phi = (float(v) for v in a.phase.split(","))
        exposure = tuple(float(v) for v in a.exposure.split(",")) if a.exposure else None
        poses = sample_poses(a.sample, range_m=(lo, hi), phase_deg=(plo, phi), exposure_s=exposure, seed=a.seed)
    truth = [c for c in a.truth.split(",") if c]
    manifest = {"scene": a.scene, "camera": a.camera, "width": cam.width, "height": cam.height,
                "poses": a.poses, "sample": a.sample, "range": a.range, "phase": a.phase, "exposure": a.exposure}
    n = render_dataset(r, poses, a.out, truth=truth, manifest=manifest, progress=not a.no_progress)
    print(f"{a.out}: {n} frames rendered, {len(poses) - n} already there")


if __name__ == "__main__":
    main()
