#!/usr/bin/env python3
"""Frames per second from Python vs the CLI on the same scene, pose and settings, in one
run, side by side (docs/python.md, "Speed"; issue #38 asks the binding to cost <= 2 %).

    "$(scripts/build-python.sh --release)" python/bench.py --hilcam target/release/hilcam

Both take the median of --frames renders after one warm-up render through the same warm
buffers: the CLI by `hilcam render --repeat N --warm-up 1` (its own render timer; with
--sensor plus the sensor time it prints), Python by the wall time of `Renderer.render`
(everything: argument checks, GIL release, the render, the sensor, the numpy arrays). The
binding's own cost is also shown within the Python process: wall time minus the core's
timers for the same frames, which machine noise between the two processes does not blur.
"""

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

import hilcam

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def cli_median_ms(args, hilcam_bin, frames, sensor, threads):
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "x.png" if sensor else "x.pfm")
        cmd = [hilcam_bin, "--log", "warn", "render", *args, "--repeat", str(frames), "--warm-up", "1", "--out", out]
        if sensor:
            cmd.append("--sensor")
        if threads:
            cmd += ["--threads", str(threads)]
        p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=True)
    render = float(re.search(r"renders: median ([0-9.]+) ms", p.stdout).group(1))
    extra = float(re.search(r"sensor: \w+, ([0-9.]+) ms", p.stdout).group(1)) if sensor else 0.0
    return render + extra


def python_ms(r, pose, sun, frames, sensor):
    r.render(pose, sun, sensor=sensor)  # warm-up
    wall, core = [], []
    for _ in range(frames):
        t0 = time.perf_counter()
        f = r.render(pose, sun, sensor=sensor)
        wall.append((time.perf_counter() - t0) * 1e3)
        core.append((f.render_s + f.sensor_s) * 1e3)
    return statistics.median(wall), statistics.median(core), statistics.median(w - c for w, c in zip(wall, core))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hilcam", default=os.path.join(ROOT, "target", "release", "hilcam"))
    ap.add_argument("--scene", default="scenes/satellite.toml")
    ap.add_argument("--width", type=int, default=1024)
    ap.add_argument("--spp", default="4")
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--rounds", type=int, default=3, help="CLI and Python alternate this many times (default 3)")
    ap.add_argument("--threads", type=int, help="worker threads for both (default: all cores)")
    a = ap.parse_args()
    scene = hilcam.Scene.load(os.path.join(ROOT, a.scene))
    p = scene.pose
    pose, sun = [*p["position"], *p["attitude"]], p["sun"]
    r = hilcam.Renderer(scene, scene.camera.scaled(a.width), spp=float(a.spp), threads=a.threads)
    cli_args = [a.scene, "--width", str(a.width), "--spp", a.spp]
    print(
        f"{a.scene}, {r.width}x{r.height}, spp {a.spp}, threads {a.threads or 'all'}: median of {a.frames} frames "
        f"after a warm-up, median over {a.rounds} alternating rounds"
    )
    print(f"{'':22}{'CLI':>16}{'Python':>16}{'Python/CLI':>12}{'binding (in Python)':>24}")
    for sensor in (False, True):
        rounds = []
        for _ in range(a.rounds):
            c = cli_median_ms(cli_args, a.hilcam, a.frames, sensor, a.threads)
            rounds.append((c, *python_ms(r, pose, sun, a.frames, sensor)))
        cli, wall, core, extra = (statistics.median(x[k] for x in rounds) for k in range(4))
        what = "radiance + sensor" if sensor else "radiance"
        print(
            f"{what:22}{cli:9.1f} ms {1e3 / cli:4.1f}/s{wall:9.1f} ms {1e3 / wall:4.1f}/s{wall / cli - 1:+11.1%}"
            f"{extra:12.2f} ms ({extra / core:+.2%})"
        )


if __name__ == "__main__":
    sys.exit(main())
