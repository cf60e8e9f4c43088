#!/usr/bin/env python3
"""Send hilcam poses as CAN frames with python-can (SocketCAN or slcan).

    python3 examples/send_can.py --interface socketcan --channel can0 \
        --trajectory scenes/trajectories/flyaround.csv
    python3 examples/send_can.py --interface slcan --channel /dev/ttyACM0 --bitrate 500000 ...

Each pose goes out as a group of classic 8-byte frames on ids base..base+N-1
(default base 0x300), or with --fd as one CAN FD frame on base+0x10.
"""
import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import hilcam_proto as hp  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--interface", choices=["socketcan", "slcan"], required=True)
    ap.add_argument("--channel", required=True, help="vcan0/can0, or the slcan tty")
    ap.add_argument("--bitrate", type=int, default=500000, help="slcan CAN bit rate")
    ap.add_argument("--base-id", type=lambda s: int(s, 0), default=0x300)
    ap.add_argument("--extended", action="store_true", help="29-bit ids")
    ap.add_argument("--fd", action="store_true", help="one CAN FD frame per pose")
    ap.add_argument("--trajectory", required=True)
    ap.add_argument("--count", type=int, default=None)
    ap.add_argument("--speed", type=float, default=1.0, help="replay speed; inf = unpaced")
    a = ap.parse_args()

    import can  # python-can

    if a.interface == "slcan":
        bus = can.Bus(interface="slcan", channel=a.channel, bitrate=a.bitrate, sleep_after_open=0)
    else:
        bus = can.Bus(interface="socketcan", channel=a.channel, fd=a.fd)
    rows = hp.load_trajectory(a.trajectory)[: a.count]
    try:
        t0 = time.monotonic()
        for k, r in enumerate(rows):
            if a.speed != float("inf"):
                due = t0 + (r["time_s"] - rows[0]["time_s"]) / a.speed
                time.sleep(max(0.0, due - time.monotonic()))
            pose = hp.pose_of(r, k)
            if a.fd:
                data = hp.can_fd(pose)
                data += bytes((48 if len(data) <= 48 else 64) - len(data))
                msgs = [can.Message(arbitration_id=a.base_id + 0x10, data=data, is_fd=True,
                                    bitrate_switch=True, is_extended_id=a.extended)]
            else:
                msgs = [can.Message(arbitration_id=a.base_id + i, data=d, is_extended_id=a.extended)
                        for i, d in hp.can_group(pose)]
            for m in msgs:
                for attempt in range(100):
                    try:
                        bus.send(m, timeout=1.0)
                        break
                    except can.CanOperationError:  # kernel queue full: retry shortly
                        time.sleep(0.001)
                else:
                    raise SystemExit("CAN send kept failing")
    finally:
        bus.shutdown()
    print(f"sent {len(rows)} poses", file=sys.stderr)


if __name__ == "__main__":
    main()
