"""hilcam pose protocol encoders in plain Python (no dependencies).

Shared by send_serial.py and send_can.py; see docs/protocol.md. Written
independently of the Rust codecs (own CRC tables), so the test suite's
cross-checks compare two implementations of the same document.
"""
import csv
import math
import struct

SYNC = b"\xa5\x5a"
VERSION = 1
TYPE_POSE, TYPE_TRIGGER, TYPE_HEARTBEAT = 1, 2, 3


def _crc32c_table():
    table = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = (c >> 1) ^ (0x82F63B78 if c & 1 else 0)
        table.append(c)
    return table


_T32 = _crc32c_table()


def crc32c(data: bytes) -> int:
    """CRC-32C (Castagnoli): check value crc32c(b"123456789") == 0xE3069283."""
    c = 0xFFFFFFFF
    for b in data:
        c = _T32[(c ^ b) & 0xFF] ^ (c >> 8)
    return c ^ 0xFFFFFFFF


def crc16_ccitt(data: bytes) -> int:
    """CRC-16/CCITT-FALSE: check value crc16_ccitt(b"123456789") == 0x29B1."""
    c = 0xFFFF
    for b in data:
        c ^= b << 8
        for _ in range(8):
            c = ((c << 1) ^ 0x1021) & 0xFFFF if c & 0x8000 else (c << 1) & 0xFFFF
    return c


def load_trajectory(path):
    """Rows of a hilcam trajectory CSV as dicts of floats (docs/trajectory.md)."""
    with open(path, newline="") as f:
        lines = [l for l in f if l.strip() and not l.lstrip().startswith("#")]
    reader = csv.reader(lines)
    header = [h.strip() for h in next(reader)]
    return [dict(zip(header, (float(x) for x in row))) for row in reader]


def pose_of(row, seq):
    """(seq, t_ns, position, quaternion wxyz, sun, velocity|None, rate|None, planet|None)."""
    g = lambda *k: tuple(row[x] for x in k)
    vel = g("vx", "vy", "vz") if "vx" in row else None
    rate = g("wx", "wy", "wz") if "wx" in row else None
    planet = g("plx", "ply", "plz") if "plx" in row else None
    t_ns = int(round(row["time_s"] * 1e9))
    return (seq, t_ns, g("px", "py", "pz"), g("qw", "qx", "qy", "qz"), g("sx", "sy", "sz"), vel, rate, planet)


def serial_frame(pose) -> bytes:
    """One serial pose frame: sync, header, f64 payload, CRC-32C."""
    seq, t_ns, pos, q, sun, vel, rate = pose[:7]
    planet = pose[7] if len(pose) > 7 else None
    flags = (1 if vel else 0) | (2 if rate else 0) | (4 if planet else 0)
    payload = struct.pack("<B3x", flags) + struct.pack("<10d", *pos, *q, *sun)
    for opt in (vel, rate, planet):
        if opt:
            payload += struct.pack("<3d", *opt)
    body = struct.pack("<BBHIQ", VERSION, TYPE_POSE, len(payload), seq & 0xFFFFFFFF, t_ns) + payload
    return SYNC + body + struct.pack("<I", crc32c(body))


def heartbeat_frame(seq, t_ns=0, status=0) -> bytes:
    """One serial heartbeat frame (type 3): liveness, no render."""
    body = struct.pack("<BBHIQI", VERSION, 3, 4, seq & 0xFFFFFFFF, t_ns, status)
    return SYNC + body + struct.pack("<I", crc32c(body))


def _q(v, scale):
    x = v * scale
    r = math.floor(x + 0.5) if x >= 0 else -math.floor(-x + 0.5)  # half away from zero
    return max(-int(scale), min(int(scale), r))


def compact_block(pose) -> bytes:
    """The CAN compact pose block: flags, t_ns, f32 position, Q23 quaternion, Q15 sun,
    options (velocity, rate, planet centre: f32 each)."""
    _, t_ns, pos, q, sun, vel, rate = pose[:7]
    planet = pose[7] if len(pose) > 7 else None
    flags = (1 if vel else 0) | (2 if rate else 0) | (4 if planet else 0)
    b = struct.pack("<BQ3f", flags, t_ns, *pos)
    for c in q:
        b += struct.pack("<i", _q(c, 8388607.0))[:3]
    b += struct.pack("<3h", *(_q(c, 32767.0) for c in sun))
    for opt in (vel, rate, planet):
        if opt:
            b += struct.pack("<3f", *opt)
    return b


def can_group(pose):
    """[(frame index, 8 data bytes)] of a classic CAN pose group."""
    seq = pose[0] & 0xFF
    block = compact_block(pose)
    stream = block + struct.pack("<H", crc16_ccitt(bytes([seq]) + block))
    frames = []
    for k in range(0, len(stream), 7):
        chunk = stream[k:k + 7]
        frames.append((k // 7, bytes([seq]) + chunk + bytes(7 - len(chunk))))
    return frames


def can_fd(pose) -> bytes:
    """Data of the CAN FD pose frame (before padding to 48/64 bytes)."""
    data = bytes([pose[0] & 0xFF]) + compact_block(pose)
    if len(data) > 64:
        raise ValueError("a pose with both rates and the planet (76 bytes) does not fit one CAN FD frame: "
                         "send it as a classic group (docs/protocol.md)")
    return data
