#!/usr/bin/env python3
"""Close a GNC loop with Basilisk through hilcam's Python module, in one process.

    python examples/bsk_loop.py [--steps 60] [--json log.json]

Basilisk (bsk 2.12.1) propagates a chaser and a 1 m sphere target in low Earth orbit;
each step hilcam renders what the chaser's camera sees (Renderer.render, no file, no
process), Basilisk's houghCircles (bsk-opnav) finds the target's disc in it, and the
circle's centre and radius feed a PD controller that thrusts the chaser to centre the
target at 30 m (examples/bsk_common.py). Prints one line per step and the Hough circle
(and the numpy centroid) against Basilisk's truth. Needs the venv of
scripts/setup-basilisk.sh.
"""
import argparse
import json
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bsk_common as bc  # noqa: E402

import hilcam  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=60)
    ap.add_argument("--json", help="write the per-step log here")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "scene.toml")
        with open(path, "w") as f:
            f.write(bc.scene_toml(os.path.join(ROOT, "scenes/meshes/sphere.obj")))
        renderer = hilcam.Renderer(hilcam.Scene.load(path))

    def render(k, _t, pos, q, sun):
        return renderer.render([*pos, *q], sun, frame=k, sensor=False).radiance

    start = time.monotonic()
    log = bc.run(render, a.steps)
    elapsed = time.monotonic() - start
    report(log)
    print("%d steps in %.2f s (%.1f steps/s)" % (len(log), elapsed, len(log) / elapsed))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(log, f)


def report(log):
    for s in log:
        print("step %3d  range %6.2f m (est %6.2f)  hough (%6.2f, %6.2f) r %5.2f  truth (%7.2f, %7.2f) r %5.2f"
              "  centroid (%7.2f, %7.2f)  phase %4.1f°"
              % (s["step"], s["range_m"], s["range_est_m"], *s["hough"], s["hough_r_px"], *s["truth"],
                 s["truth_r_px"], *s["centroid"], s["phase_deg"]))
    worst = max(max(abs(c - t) for c, t in zip(s["hough"], s["truth"])) for s in log)
    worst_r = max(abs(s["hough_r_px"] - s["truth_r_px"]) for s in log)
    worst_c = max(max(abs(c - p) for c, p in zip(s["centroid"], s["predicted"])) for s in log)
    print("houghCircles vs Basilisk truth: centre worst %.3f px, radius worst %.3f px over %d steps"
          % (worst, worst_r, len(log)))
    print("numpy centroid vs Basilisk truth (+ 3/8·r·tan φ toward the sun): worst %.3f px" % worst_c)


if __name__ == "__main__":
    main()
