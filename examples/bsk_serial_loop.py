#!/usr/bin/env python3
"""Close a GNC loop with Basilisk over the serial link against `hilcam serve`.

    python examples/bsk_serial_loop.py --hilcam target/debug/hilcam [--steps 60] [--json log.json]

The same loop as examples/bsk_loop.py (examples/bsk_common.py), but the way a bench runs
it: each step's pose goes out as a serial pose frame (examples/hilcam_proto.py) on a
pseudo-terminal into `hilcam serve`, which renders it and streams the frame back over TCP
(examples/recv_frames.py parses it, checking both CRCs); Basilisk's houghCircles
measures that frame and its circle drives the controller. The server is started here with a config on the pty and a free
port, and stopped at the end. Needs the venv of scripts/setup-basilisk.sh (pyserial is
not needed: the pty is written directly).
"""
import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
import tty
import zlib

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bsk_common as bc  # noqa: E402
import hilcam_proto as hp  # noqa: E402
from bsk_loop import report  # noqa: E402
from recv_frames import HEADER_LEN, parse_header, read_exact  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """`hilcam serve` on a pty (poses in) and a TCP port (frames out)."""

    def __init__(self, hilcam, workdir):
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # no line discipline on the frames, whoever opens it first
        port, metrics = free_port(), free_port()
        with open(os.path.join(workdir, "scene.toml"), "w") as f:
            f.write(bc.scene_toml(os.path.join(ROOT, "scenes/meshes/sphere.obj")))
        cfg = os.path.join(workdir, "serve.toml")
        with open(cfg, "w") as f:
            f.write('scene = "scene.toml"\n[input]\nkind = "serial"\ndevice = "%s"\nbaud = 921600\n'
                    '[stream]\nlisten = "127.0.0.1:%d"\n[trigger]\nmode = "pose"\n[metrics]\nlisten = "127.0.0.1:%d"\n'
                    % (os.ttyname(self.slave), port, metrics))
        self.proc = subprocess.Popen([hilcam, "--log", "warn", "serve", "--config", cfg],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 60
        while True:
            try:
                self.sock = socket.create_connection(("127.0.0.1", port), timeout=60)
                break
            except OSError:
                if self.proc.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError("hilcam serve did not start: " + self.proc.communicate()[1])
                time.sleep(0.05)
        # Heartbeats until the server counts one: it has the pty open, so the poses that
        # follow each make exactly one frame (frame k is pose k).
        while self.counter(metrics, "hilcam_input_heartbeats_total") < 1:
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("hilcam serve never read the pty: " + self.proc.communicate()[1])
            os.write(self.master, hp.heartbeat_frame(0))
            time.sleep(0.05)

    @staticmethod
    def counter(port, name):
        with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
            s.sendall(b"GET /metrics HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
            text = b""
            while chunk := s.recv(1 << 16):
                text += chunk
        for line in text.decode().splitlines():
            if line.startswith(name + " "):
                return float(line.split()[1])
        return 0.0

    def frame(self, seq, t_ns, pos, q, sun):
        """Send the pose; the radiance of the frame rendered from it."""
        msg = hp.serial_frame((seq, t_ns, tuple(pos), tuple(q), tuple(sun), None, None))
        os.write(self.master, msg)
        h = parse_header(read_exact(self.sock, HEADER_LEN))
        payload = read_exact(self.sock, h["payload_len"])
        assert zlib.crc32(payload) == h["payload_crc32"], "payload CRC"
        assert h["pose_seq"] == seq and h["pixel_format"] == "Float32", h
        return np.frombuffer(payload, dtype="<f4").reshape(h["height"], h["width"]), h

    def stop(self):
        self.sock.close()
        self.proc.terminate()
        out, err = self.proc.communicate(timeout=60)
        os.close(self.master)
        os.close(self.slave)
        return self.proc.returncode, out, err


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hilcam", default=os.path.join(ROOT, "target/debug/hilcam"))
    ap.add_argument("--steps", type=int, default=60)
    ap.add_argument("--json", help="write the per-step log here")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        server = Server(a.hilcam, d)
        frames = []
        try:
            def render(k, t, pos, q, sun):
                img, h = server.frame(k, int(round(t * 1e9)), pos, q, sun)
                frames.append(h["frame_seq"])
                return img

            start = time.monotonic()
            log = bc.run(render, a.steps)
            elapsed = time.monotonic() - start
        finally:
            code, out, err = server.stop()
    for s, seq in zip(log, frames):
        s["frame_seq"] = seq
    report(log)
    print("%d steps in %.2f s (%.1f steps/s); hilcam serve exited %d" % (len(log), elapsed, len(log) / elapsed, code))
    print(out.strip())
    if a.json:
        with open(a.json, "w") as f:
            json.dump(log, f)


if __name__ == "__main__":
    main()
