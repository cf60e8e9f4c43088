#!/usr/bin/env python3
"""The GGX satellite of make_gltf_satellite.py with a solar-cell texture on its arrays,
written as GLB and as OBJ + MTL + PNG from the same geometry, with the Python standard
library only (the cell pattern is drawn here; no downloaded asset):

    scripts/make_textured_satellite.py [OUT_DIR]   # default scenes/textured_satellite/

- cells.png: 512 × 192 sRGB (8-bit palette, stored uncompressed so that any zlib writes
  the same bytes), 16 × 6 dark-blue cells with silver gaps and bus bars and
  fine fingers, one texel ≈ 3.9 mm on the 2 m × 0.75 m panel.
- The `solar_cell` material becomes base colour 1 × the texture (glTF
  `baseColorTexture`, MTL `map_Kd`); the other materials are as in sat.glb.
- UVs: OBJ `vt` (u, v) with v = 0 at the image's bottom row; the GLB's TEXCOORD_0 is
  (u, 1 − v), glTF's origin being the image's top-left. Both put the image's top row at
  the panel's +Y edge, so the two files render the same (tests/render/texture.rs).
"""
import importlib.util
import struct
import sys
import zlib
from pathlib import Path

HERE = Path(__file__).resolve().parent
spec = importlib.util.spec_from_file_location("gltf_sat", HERE / "make_gltf_satellite.py")
base = importlib.util.module_from_spec(spec)
spec.loader.exec_module(base)

W, H = 512, 192
CELLS_X, CELLS_Y = 16, 6
TEXTURED = "solar_cell"
MATERIALS = dict(base.MATERIALS, solar_cell=(1.0, 0.0, 0.2))


PALETTE = [(190, 190, 200), (170, 170, 180), (60, 70, 110)] + [(18 + 2 * k, 28 + 2 * k, 72 + 3 * k) for k in range(5)]


def cell_texel(x, y):
    """Palette index of texel (x, y), row 0 at the top: silver gaps, a bus bar across
    each cell, thin fingers, dark-blue silicon with a slight per-cell shade."""
    cw, ch = W // CELLS_X, H // CELLS_Y
    cx, cy = x % cw, y % ch
    if cx < 2 or cy < 2:
        return 0
    if cx == cw // 2:
        return 1
    if cy % 4 == 0:
        return 2
    return 3 + ((x // cw) * 7 + (y // ch) * 3) % 5


def stored_zlib(data):
    """A zlib stream of stored (uncompressed) deflate blocks: the same bytes with any
    zlib, so the shipped files can be compared byte for byte."""
    out = bytearray(b"\x78\x01")
    for i in range(0, len(data), 65535):
        block = data[i:i + 65535]
        final = 1 if i + 65535 >= len(data) else 0
        out += struct.pack("<BHH", final, len(block), 0xFFFF ^ len(block)) + block
    return bytes(out + struct.pack(">I", zlib.adler32(data)))


def png_chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png(w, h, texel):
    """An 8-bit palette PNG (filter 0 on every row)."""
    raw = b"".join(b"\0" + bytes(texel(x, y) for x in range(w)) for y in range(h))
    return (b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 3, 0, 0, 0))
            + png_chunk(b"PLTE", bytes(c for rgb in PALETTE for c in rgb))
            + png_chunk(b"IDAT", stored_zlib(raw)) + png_chunk(b"IEND", b""))


def uv_of(p):
    """OBJ (u, v) of a panel corner: u along the 2 m span, v across, 0 at −Y."""
    return (p[0] / 2.0, (p[1] + 0.375) / 0.75)


def write_glb(path, meshes, nodes, image):
    names = list(MATERIALS)
    bin_ = bytearray()
    views, accessors, gmeshes = [], [], []

    def add(data, target=None):
        while len(bin_) % 4:
            bin_.append(0)
        v = {"buffer": 0, "byteOffset": len(bin_), "byteLength": len(data)}
        if target:
            v["target"] = target
        views.append(v)
        bin_.extend(data)
        return len(views) - 1

    for name, prims in meshes:
        gprims = []
        for mat, pos, tri in prims:
            pv = add(b"".join(struct.pack("<3f", *p) for p in pos), 34962)
            lo = [min(p[i] for p in pos) for i in range(3)]
            hi = [max(p[i] for p in pos) for i in range(3)]
            accessors.append({"bufferView": pv, "componentType": 5126, "count": len(pos), "type": "VEC3",
                              "min": lo, "max": hi})
            attributes = {"POSITION": len(accessors) - 1}
            if mat == TEXTURED:
                tv = add(b"".join(struct.pack("<2f", u, 1.0 - v) for u, v in map(uv_of, pos)), 34962)
                accessors.append({"bufferView": tv, "componentType": 5126, "count": len(pos), "type": "VEC2"})
                attributes["TEXCOORD_0"] = len(accessors) - 1
            iv = add(b"".join(struct.pack("<3H", *t) for t in tri), 34963)
            accessors.append({"bufferView": iv, "componentType": 5123, "count": 3 * len(tri), "type": "SCALAR"})
            gprims.append({"attributes": attributes, "indices": len(accessors) - 1,
                           "material": names.index(mat), "mode": 4})
        gmeshes.append({"name": name, "primitives": gprims})
    image_view = add(image)
    gnodes = base.glb_nodes(nodes)
    materials = []
    for n, (b, m, r) in MATERIALS.items():
        pbr = {"baseColorFactor": [b, b, b, 1.0], "metallicFactor": m, "roughnessFactor": r}
        if n == TEXTURED:
            pbr["baseColorTexture"] = {"index": 0}
        materials.append({"name": n, "doubleSided": True, "pbrMetallicRoughness": pbr})
    doc = {
        "asset": {"version": "2.0", "generator": "hilcam scripts/make_textured_satellite.py"},
        "scene": 0,
        "scenes": [{"name": "satellite", "nodes": [0]}],
        "nodes": gnodes,
        "meshes": gmeshes,
        "materials": materials,
        "textures": [{"source": 0}],
        "images": [{"name": "cells", "bufferView": image_view, "mimeType": "image/png"}],
        "buffers": [{"byteLength": len(bin_) + (-len(bin_) % 4)}],
        "bufferViews": views,
        "accessors": accessors,
    }
    path.write_bytes(base.glb_container(doc, bin_))


def write_obj(obj_path, mtl_path, meshes, nodes):
    lines = ["# hilcam scripts/make_textured_satellite.py: sat.glb with its node transforms applied",
             f"mtllib {mtl_path.name}"]
    faces = []
    count = 0
    vts = 0

    def visit(i, parent_t, parent_s):
        nonlocal count, vts
        name, mesh, t, s, children = nodes[i]
        ws = [parent_s[k] * s[k] for k in range(3)]
        wt = [parent_t[k] + parent_s[k] * t[k] for k in range(3)]
        if mesh is not None:
            mirrored = ws[0] * ws[1] * ws[2] < 0
            for mat, pos, tri in meshes[mesh][1]:
                for p in pos:
                    lines.append("v " + " ".join(repr(wt[k] + ws[k] * p[k]) for k in range(3)))
                textured = mat == TEXTURED
                if textured:
                    for p in pos:
                        lines.append("vt %r %r" % uv_of(p))
                faces.append(f"usemtl {mat}")
                for tr in tri:
                    a, b, c = tr
                    if mirrored:
                        b, c = c, b
                    if textured:
                        faces.append("f " + " ".join(f"{count + k + 1}/{vts + k + 1}" for k in (a, b, c)))
                    else:
                        faces.append(f"f {count + a + 1} {count + b + 1} {count + c + 1}")
                count += len(pos)
                if textured:
                    vts += len(pos)
        for c in children:
            visit(c, wt, ws)

    visit(0, [0.0, 0.0, 0.0], [1.0, 1.0, 1.0])
    obj_path.write_text("\n".join(lines + faces) + "\n")
    mtl = ["# hilcam scripts/make_textured_satellite.py: sat.glb's materials (MTL PBR extension)"]
    for n, (b, m, r) in MATERIALS.items():
        mtl += [f"newmtl {n}", f"Kd {b} {b} {b}", f"Pr {r}", f"Pm {m}"]
        if n == TEXTURED:
            mtl.append("map_Kd cells.png")
    mtl_path.write_text("\n".join(mtl) + "\n")


def main():
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE.parent / "scenes" / "textured_satellite"
    out.mkdir(parents=True, exist_ok=True)
    meshes, nodes = base.model()
    image = png(W, H, cell_texel)
    (out / "cells.png").write_bytes(image)
    write_glb(out / "sat.glb", meshes, nodes, image)
    write_obj(out / "sat.obj", out / "sat.mtl", meshes, nodes)
    print(f"wrote {out / 'sat.glb'}, {out / 'sat.obj'}, {out / 'sat.mtl'}, {out / 'cells.png'}")


if __name__ == "__main__":
    main()
