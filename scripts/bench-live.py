#!/usr/bin/env python3
"""What the live view costs the loop: one `hilcam serve` run (the shipped satellite at the
1024² navigation camera, the fly-around replayed in real time, `[live]` on at its
defaults: 512-pixel previews, ≤ 10 Hz, JPEG quality 80) in alternating phases of 0 and
3 browsers' worth of viewers reading /live/stream.mjpeg. Per phase: frames rendered, the
mean render time (hilcam_render_seconds), previews encoded and the mean encode time
(hilcam_live_encode_seconds), previews sent and dropped. Standard library only.

  cargo build --release --bin hilcam && python3 scripts/bench-live.py [--phase-s 20]
"""
import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request

DROPPED = 'hilcam_live_previews_dropped_total{reason="queue_full"}'
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def metrics(port):
    out = {}
    for line in urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=10).read().decode().splitlines():
        if line and not line.startswith("#"):
            k, v = line.rsplit(" ", 1)
            out[k] = float(v)
    return out


def viewer(port, stop):
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/live/stream.mjpeg", timeout=30) as r:
        while not stop.is_set() and r.read(65536):
            pass


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--phase-s", type=float, default=20.0)
    ap.add_argument("--rate-hz", type=float, default=4.0)
    ap.add_argument("--port", type=int, default=9187)
    ap.add_argument("--hilcam", default=os.path.join(ROOT, "target/release/hilcam"))
    a = ap.parse_args()
    cfg = f"""scene = "{ROOT}/scenes/satellite.toml"
[input]
kind = "trajectory"
file = "{ROOT}/scenes/trajectories/flyaround.csv"
[trigger]
mode = "rate"
rate_hz = {a.rate_hz}
[governor]
policy = "fixed-quality"
[render]
spp = 1
depth = 1
[stream]
listen = "127.0.0.1:0"
[metrics]
listen = "127.0.0.1:{a.port}"
print_interval_s = 60.0
[live]
enabled = true
"""
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "serve.toml")
        open(path, "w").write(cfg)
        server = subprocess.Popen([a.hilcam, "serve", "--config", path], stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL)
        try:
            for _ in range(300):
                try:
                    metrics(a.port)
                    break
                except OSError:
                    time.sleep(0.1)
            time.sleep(3)  # past the first frames (BVH build, warm-up)
            print("viewers  frames  render_ms  previews  encode_ms  sent  dropped")
            for n in [0, 3, 0, 3]:
                stop = threading.Event()
                threads = [threading.Thread(target=viewer, args=(a.port, stop), daemon=True) for _ in range(n)]
                for t in threads:
                    t.start()
                m0 = metrics(a.port)
                time.sleep(a.phase_s)
                m1 = metrics(a.port)
                stop.set()
                dm = lambda k: m1.get(k, 0.0) - m0.get(k, 0.0)
                frames = dm("hilcam_render_seconds_count")
                enc = dm("hilcam_live_encode_seconds_count")
                print(f"{n:7d}  {frames:6.0f}  {1e3 * dm('hilcam_render_seconds_sum') / max(frames, 1):9.1f}  "
                      f"{enc:8.0f}  {1e3 * dm('hilcam_live_encode_seconds_sum') / max(enc, 1):9.2f}  "
                      f"{dm('hilcam_live_previews_sent_total'):4.0f}  "
                      f"{dm(DROPPED):7.0f}")
                sys.stdout.flush()
                time.sleep(1)
        finally:
            server.terminate()
            server.wait()


if __name__ == "__main__":
    main()
