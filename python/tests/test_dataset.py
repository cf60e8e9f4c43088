"""hilcam.dataset: images + labels from a pose list, resumable after a kill (docs/python.md)."""

import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import numpy as np

import hilcam
from hilcam.dataset import read_poses, render_dataset, sample_poses
from pngpfm import read_png

ARGS = ["scenes/satellite.toml", "--sample", "10", "--range", "25,60", "--width", "128", "--spp", "2",
        "--seed", "3", "--no-progress"]


def run_dataset(root, out, *extra):
    return subprocess.Popen([sys.executable, "-m", "hilcam.dataset", ARGS[0], str(out), *ARGS[1:], *extra],
                            cwd=root, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def tree(d):
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(pathlib.Path(d).rglob("*")) if p.is_file()}


def test_a_killed_run_resumes_to_the_same_bytes(root, tmp_path):
    whole = tmp_path / "whole"
    p = run_dataset(root, whole)
    out, err = p.communicate(timeout=600)
    assert p.returncode == 0, err
    assert "10 frames rendered, 0 already there" in out
    # Kill -9 a second run once two frames are labelled, then run it again.
    cut = tmp_path / "cut"
    p = run_dataset(root, cut)
    labels = cut / "labels.jsonl"
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and p.poll() is None:
        if labels.exists() and labels.read_bytes().count(b"\n") >= 2:
            break
        time.sleep(0.005)
    p.send_signal(signal.SIGKILL)
    p.wait()
    assert p.returncode == -signal.SIGKILL, "the run ended before it could be killed"
    before = labels.read_bytes().count(b"\n")
    assert 2 <= before < 10
    p = run_dataset(root, cut)
    out, err = p.communicate(timeout=600)
    assert p.returncode == 0, err
    assert f"{10 - before} frames rendered, {before} already there" in out
    a, b = tree(whole), tree(cut)
    assert sorted(a) == sorted(b)
    assert [k for k in a if a[k] != b[k]] == []
    assert not any(k.endswith(".tmp") for k in b)


def test_labels_agree_with_the_images_and_truth(root, tmp_path):
    scene = hilcam.Scene.load(str(root / "scenes/satellite.toml"))
    r = hilcam.Renderer(scene, scene.camera.scaled(64), spp=1, seed=2)
    poses = sample_poses(4, range_m=(30, 40), seed=1)
    poses[2]["integration_s"] = 2.5e-4  # a frame's own exposure, kept in its label
    poses.append({"pose": [0.0, 0.0, 22.0], "sun": None})  # the scene's attitude and sun
    poses.append({"pose": [0.0, 500.0, 30.0], "sun": [0.0, 0.0, -1.0]})  # out of view
    assert render_dataset(r, poses, str(tmp_path), truth=("depth", "mask", "normal"), progress=False) == 6
    assert render_dataset(r, poses, str(tmp_path), truth=("depth", "mask", "normal"), progress=False) == 0
    labels = [json.loads(line) for line in (tmp_path / "labels.jsonl").read_text().splitlines()]
    assert [x["index"] for x in labels] == list(range(6))
    for x, p in zip(labels, poses):
        assert x["pose"] == p["pose"] and x["sun"] == p["sun"]
        assert abs(x["range_m"] - np.linalg.norm(p["pose"][:3])) < 1e-9
        dn = read_png(tmp_path / x["image"])
        assert dn.shape == (64, 64)
        mask = np.load(tmp_path / x["truth"]["mask"])
        depth = np.load(tmp_path / x["truth"]["depth"])
        assert np.load(tmp_path / x["truth"]["normal"]).shape == (64, 64, 3)
        assert x["pixels"] == int((mask > 0).sum())
        if x["pixels"] == 0:
            assert x["bbox_px"] is None and x["centroid_px"] is None
            continue
        rows, cols = np.nonzero(mask)
        assert x["bbox_px"] == [cols.min(), rows.min(), cols.max() + 1, rows.max() + 1]
        assert np.allclose(x["centroid_px"], [cols.mean() + 0.5, rows.mean() + 0.5])
        assert np.all(depth[mask > 0] < x["range_m"] + 10) and np.all(depth[mask > 0] > x["range_m"] - 10)
    assert labels[-1]["pixels"] == 0 and labels[0]["pixels"] > 0
    assert labels[2]["integration_s"] == 2.5e-4 and labels[1]["integration_s"] != 2.5e-4
    # The same frame rendered directly: the dataset's frame is the fresh renderer's.
    r2 = hilcam.Renderer(scene, scene.camera.scaled(64), spp=1, seed=2)
    f = r2.render(poses[1]["pose"], poses[1]["sun"], frame=1)
    assert np.array_equal(f.dn, read_png(tmp_path / labels[1]["image"]))
    # A different renderer in the same directory is refused, not mixed in.
    r3 = hilcam.Renderer(scene, scene.camera.scaled(64), spp=2, seed=2)
    try:
        render_dataset(r3, poses, str(tmp_path), progress=False)
        raise AssertionError("mixed settings were accepted")
    except ValueError as e:
        assert "made with other inputs" in str(e)


def test_sampled_poses_follow_the_distribution_and_a_trajectory_reads(root):
    poses = sample_poses(400, range_m=(20, 30), phase_deg=(10, 40), off_axis_deg=3, seed=9)
    assert poses == sample_poses(400, range_m=(20, 30), phase_deg=(10, 40), off_axis_deg=3, seed=9)
    assert "integration_s" not in poses[0]
    timed = sample_poses(400, exposure_s=(1e-5, 1e-3), seed=9)
    t = np.array([p["integration_s"] for p in timed])
    assert t.min() >= 1e-5 and t.max() <= 1e-3 and 0.3 < (t < 1e-4).mean() < 0.7  # log-uniform: half below 1e-4
    for p in poses:
        pos, q, sun = np.array(p["pose"][:3]), np.array(p["pose"][3:]), np.array(p["sun"])
        r = np.linalg.norm(pos)
        assert 20 <= r <= 30 and abs(np.linalg.norm(q) - 1) < 1e-12 and abs(np.linalg.norm(sun) - 1) < 1e-12
        assert np.degrees(np.arccos(pos[2] / r)) <= 3 + 1e-9
        phase = np.degrees(np.arccos(np.clip(np.dot(-pos / r, sun), -1, 1)))
        assert 10 - 1e-6 <= phase <= 40 + 1e-6
    traj = read_poses(root / "scenes/trajectories/approach.csv")
    assert len(traj) > 10 and len(traj[0]["pose"]) == 7 and len(traj[0]["sun"]) == 3
    assert abs(traj[0]["pose"][2] - 999.9955000303748) < 1e-12
