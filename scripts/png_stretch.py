#!/usr/bin/env python3
"""Stretch a grey PNG (8- or 16-bit, e.g. the raw DN `hilcam render --sensor` writes) to an
8-bit preview: values LO..HI map to 0..255 with a gamma, so faint detail (stars) shows.

    python3 scripts/png_stretch.py IN.png OUT.png LO HI [GAMMA]

Standard library only (zlib); reads non-interlaced greyscale PNGs.
"""
import struct
import sys
import zlib


def read_grey(path):
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    pos, idat, w = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert colour == 0 and interlace == 0 and depth in (8, 16), "grey, non-interlaced, 8/16-bit only"
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw, bpp = zlib.decompress(idat), depth // 8
    stride, prev, rows = w * bpp, bytearray(w * bpp), []
    for y in range(h):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b, c = prev[i], prev[i - bpp] if i >= bpp else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append([int.from_bytes(line[i:i + bpp], "big") for i in range(0, stride, bpp)])
        prev = line
    return w, h, rows


def write_grey8(path, w, h, rows):
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    raw = b"".join(b"\x00" + bytes(r) for r in rows)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
    open(path, "wb").write(png + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def main():
    src, dst, lo, hi = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
    gamma = float(sys.argv[5]) if len(sys.argv) > 5 else 1.0
    w, h, rows = read_grey(src)
    out = [[round(255 * min(1.0, max(0.0, (v - lo) / (hi - lo))) ** (1.0 / gamma)) for v in r] for r in rows]
    write_grey8(dst, w, h, out)


if __name__ == "__main__":
    main()
