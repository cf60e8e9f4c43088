#!/usr/bin/env python3
"""Send hilcam pose frames over a serial port with pyserial.

    python3 examples/send_serial.py --port /dev/ttyUSB0 --baud 921600 \
        --trajectory scenes/trajectories/approach.csv

Replays the trajectory CSV in real time (--speed scales it; --speed inf sends as
fast as the line takes). --hex prints the frames as hex instead of sending.
"""
import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import hilcam_proto as hp  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--port", help="serial device, e.g. /dev/ttyUSB0")
    ap.add_argument("--baud", type=int, default=115200)
    ap.add_argument("--trajectory", required=True)
    ap.add_argument("--count", type=int, default=None, help="send only the first N samples")
    ap.add_argument("--speed", type=float, default=1.0, help="replay speed; inf = unpaced")
    ap.add_argument("--hex", action="store_true", help="print frames as hex, do not send")
    a = ap.parse_args()

    rows = hp.load_trajectory(a.trajectory)[: a.count]
    frames = [hp.serial_frame(hp.pose_of(r, k)) for k, r in enumerate(rows)]
    if a.hex:
        for f in frames:
            print(f.hex())
        return
    if not a.port:
        ap.error("--port is required unless --hex")
    import serial  # pyserial

    with serial.Serial(a.port, a.baud, bytesize=8, parity="N", stopbits=1) as port:
        t0 = time.monotonic()
        for r, f in zip(rows, frames):
            if a.speed != float("inf"):
                due = t0 + (r["time_s"] - rows[0]["time_s"]) / a.speed
                time.sleep(max(0.0, due - time.monotonic()))
            port.write(f)
        port.flush()
    print(f"sent {len(frames)} poses", file=sys.stderr)


if __name__ == "__main__":
    main()
