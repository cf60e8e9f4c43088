#!/usr/bin/env python3
"""A 1 m plate and a 1 m-radius UV sphere, Lambert under one grey, asymmetric texture:
the textured scenes `benches/vs_mitsuba.py` compares with Mitsuba 3's `bitmap` (Python
standard library only; the pattern is drawn here, no downloaded asset):

    scripts/make_textured_targets.py [OUT_DIR]   # default scenes/textured/

- checks.png: 256 × 256 8-bit greyscale sRGB (stored uncompressed, as cells.png, so any
  zlib writes the same bytes): 8-texel checks, the light ones sRGB 200, the dark ones a
  ramp from 16 at the left edge to 136 at the right; a one-texel line of 128 every 32
  texels (finer than a pixel at 128²); a 48 × 24 white marker in the top-left corner.
  Grey (r = g = b), so no colour reduction can differ between renderers; a flip of u or
  v, or a swap of the two, moves the marker or turns the ramp.
- plate.obj: the plate of scenes/meshes/plate.obj (body XY plane, face normal −Z) with
  `vt` (x + ½, y + ½): OBJ v = 0, the image's bottom row, at body −Y.
- sphere.obj: a latitude-longitude sphere (96 × 48 quads, the seam's vertices doubled,
  one triangle per pole quad), poles on ±Y, v = 0 at −Y, u = ¼ facing −Z, u growing
  toward +X: a texel is 25 mm along the equator by 12 mm, the pole quads crowd the
  image's top and bottom rows.
- checks.mtl: `Kd 1` and `map_Kd checks.png`, so ρ is the linearised texel itself.
"""
import math
import importlib.util
import struct
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
spec = importlib.util.spec_from_file_location("textured_sat", HERE / "make_textured_satellite.py")
sat = importlib.util.module_from_spec(spec)
spec.loader.exec_module(sat)

N = 256


def texel(x, y):
    """sRGB value of texel (x, y), row 0 at the top."""
    if x < 48 and y < 24:
        return 255
    if x % 32 == 16 or y % 32 == 16:
        return 128
    if (x // 8 + y // 8) % 2 == 0:
        return 200
    return 16 + x * 120 // (N - 1)


def grey_png(w, h, value):
    """An 8-bit greyscale PNG (colour type 0, filter 0 on every row)."""
    raw = b"".join(b"\0" + bytes(value(x, y) for x in range(w)) for y in range(h))
    return (b"\x89PNG\r\n\x1a\n" + sat.png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
            + sat.png_chunk(b"IDAT", sat.stored_zlib(raw)) + sat.png_chunk(b"IEND", b""))


OBJ = """\
# hilcam scripts/make_textured_targets.py: 1 m × 1 m plate in the body XY plane, face normal −Z;
# vt (x + 1/2, y + 1/2): v = 0 (the image's bottom row) at body −Y.
mtllib checks.mtl
v -0.5 -0.5 0
v 0.5 -0.5 0
v 0.5 0.5 0
v -0.5 0.5 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
usemtl checks
f 1/1 3/3 2/2
f 1/1 4/4 3/3
"""

MTL = """\
# hilcam scripts/make_textured_targets.py: Lambert, ρ = the linearised texel (Kd 1).
newmtl checks
Kd 1 1 1
map_Kd checks.png
"""


def sphere_obj(nu=96, nv=48):
    """The UV sphere as OBJ text: vertex (i, j) at v = i/nv, u = j/nu, outward winding."""
    lines = ["# hilcam scripts/make_textured_targets.py: 1 m-radius latitude-longitude sphere, poles on ±Y,",
             "# vt (u, v): v = 0 at −Y, u = 1/4 facing −Z, growing toward +X.", "mtllib checks.mtl"]
    for i in range(nv + 1):
        for j in range(nu + 1):
            th, ph = math.pi * i / nv, 2 * math.pi * (j / nu - 0.25)
            x, y, z = math.sin(th) * math.sin(ph), -math.cos(th), -math.sin(th) * math.cos(ph)
            lines.append(f"v {x:.9f} {y:.9f} {z:.9f}")
    lines += [f"vt {j / nu!r} {i / nv!r}" for i in range(nv + 1) for j in range(nu + 1)]
    lines.append("usemtl checks")

    def k(i, j):
        return i * (nu + 1) + j + 1

    for i in range(nv):
        for j in range(nu):
            a, b, c, d = k(i, j), k(i, j + 1), k(i + 1, j + 1), k(i + 1, j)
            if i > 0:
                lines.append(f"f {a}/{a} {c}/{c} {b}/{b}")
            if i < nv - 1:
                lines.append(f"f {a}/{a} {d}/{d} {c}/{c}")
    return "\n".join(lines) + "\n"


def main():
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE.parent / "scenes" / "textured"
    out.mkdir(parents=True, exist_ok=True)
    files = {"checks.png": grey_png(N, N, texel), "checks.mtl": MTL, "plate.obj": OBJ, "sphere.obj": sphere_obj()}
    for name, data in files.items():
        (out / name).write_bytes(data if isinstance(data, bytes) else data.encode())
    print("wrote " + ", ".join(str(out / n) for n in files))


if __name__ == "__main__":
    main()
