#!/usr/bin/env python3
"""Minimal hilcam frame stream client, Python standard library only.

Connects to a `hilcam serve` stream, parses each 88-byte header (docs/protocol.md,
"Frame stream (TCP)"), checks the header and payload CRCs (CRC-32/ISO-HDLC, which is
what zlib.crc32 computes), and prints one line per frame and a summary.

    python3 examples/recv_frames.py --connect 127.0.0.1:5600 --count 100
"""

import argparse
import socket
import struct
import sys
import time
import zlib

MAGIC = b"HLCF"
HEADER_LEN = 88
# magic, version, header_len, frame_seq, pose_seq, flags, pose_t_ns,
# pose_arrival_unix_ns, emit_unix_ns, width, height, pixel_format, bit_depth, spp,
# depth, spp_frac_milli (thousandths beyond spp), integration_s, payload_crc32, payload_len, reserved, header_crc32
HEADER = struct.Struct("<4sHHQIIQQQIIBBHHHfIQII")
assert HEADER.size == HEADER_LEN
FORMATS = {1: ("Mono8", 1), 2: ("Mono16", 2), 3: ("Float32", 4)}
FLAGS = {1: "late", 2: "extrapolated", 4: "degraded"}


def read_exact(sock, n):
    """n bytes, or None on a clean close before the first byte."""
    buf = bytearray()
    while len(buf) < n:
        chunk = sock.recv(min(n - len(buf), 1 << 20))
        if not chunk:
            if not buf:
                return None
            raise EOFError("stream closed in the middle of a frame")
        buf += chunk
    return bytes(buf)


def parse_header(raw):
    f = HEADER.unpack(raw)
    (magic, version, header_len, frame_seq, pose_seq, flags, pose_t_ns, arrival_ns,
     emit_ns, width, height, fmt, bits, spp_whole, depth, spp_frac_milli, integration_s, payload_crc,
     payload_len, _r2, header_crc) = f
    if magic != MAGIC:
        raise ValueError("bad magic %r" % magic)
    if version != 1 or header_len != HEADER_LEN:
        raise ValueError("unsupported version %d / header_len %d" % (version, header_len))
    if zlib.crc32(raw[:84]) != header_crc:
        raise ValueError("header CRC mismatch")
    if fmt not in FORMATS:
        raise ValueError("unknown pixel format %d" % fmt)
    name, bpp = FORMATS[fmt]
    spp = spp_whole + spp_frac_milli / 1000 if spp_frac_milli else spp_whole  # 1.25 spp: whole 1, milli 250
    if payload_len != width * height * bpp:
        raise ValueError("payload_len %d does not match %dx%d %s" % (payload_len, width, height, name))
    return dict(frame_seq=frame_seq, pose_seq=pose_seq, flags=flags, pose_t_ns=pose_t_ns,
                pose_arrival_unix_ns=arrival_ns, emit_unix_ns=emit_ns, width=width,
                height=height, pixel_format=name, bit_depth=bits, spp=spp, depth=depth,
                integration_s=integration_s, payload_crc32=payload_crc,
                payload_len=payload_len)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--connect", default="127.0.0.1:5600", help="host:port")
    ap.add_argument("--count", type=int, default=0, help="stop after N frames (0: until close)")
    ap.add_argument("--quiet", action="store_true", help="summary only")
    args = ap.parse_args()
    host, port = args.connect.rsplit(":", 1)
    sock = socket.create_connection((host, int(port)))
    frames = gaps = missing = crc_errors = 0
    last_seq = None
    latencies_ms = []
    t0 = None
    while args.count == 0 or frames < args.count:
        raw = read_exact(sock, HEADER_LEN)
        if raw is None:
            break
        t0 = t0 or time.monotonic()
        h = parse_header(raw)
        payload = read_exact(sock, h["payload_len"]) if h["payload_len"] else b""
        if payload is None:
            raise EOFError("stream closed in the middle of a frame")
        now_ns = time.time_ns()
        if zlib.crc32(payload) != h["payload_crc32"]:
            crc_errors += 1
            print("frame seq=%d payload CRC mismatch" % h["frame_seq"], flush=True)
            continue
        seq = h["frame_seq"]
        if last_seq is not None and seq > last_seq + 1:
            gaps += 1
            missing += seq - last_seq - 1
        last_seq = seq
        frames += 1
        latency_ms = (now_ns - h["emit_unix_ns"]) / 1e6
        latencies_ms.append(latency_ms)
        if not args.quiet:
            flags = ",".join(n for b, n in FLAGS.items() if h["flags"] & b) or "-"
            print("frame seq=%d pose_seq=%d %dx%d %s bits=%d spp=%s depth=%d flags=%s "
                  "crc=ok emit->recv=%.3fms" % (seq, h["pose_seq"], h["width"], h["height"],
                                                h["pixel_format"], h["bit_depth"], h["spp"],
                                                h["depth"], flags, latency_ms), flush=True)
    elapsed = time.monotonic() - t0 if t0 else 0.0
    rate = (frames - 1) / elapsed if frames > 1 and elapsed > 0 else 0.0
    lat = sorted(latencies_ms)
    p50 = lat[max(0, -(-len(lat) // 2) - 1)] if lat else float("nan")
    print("summary frames=%d gaps=%d missing=%d crc_errors=%d fps=%.2f emit_recv_p50_ms=%.3f"
          % (frames, gaps, missing, crc_errors, rate, p50), flush=True)
    return 0 if crc_errors == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
