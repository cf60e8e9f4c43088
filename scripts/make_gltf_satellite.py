#!/usr/bin/env python3
"""A small GGX-material satellite written both as glTF 2.0 (GLB) and as OBJ + MTL, from the
same geometry and materials, with the Python standard library only:

    scripts/make_gltf_satellite.py [OUT_DIR]      # default scenes/gltf_satellite/

- sat.glb: a node hierarchy (a root with a bus, two solar panels — the second the first's
  mesh mirrored by a negative scale — and a dish), one mesh per part, the bus with two
  primitives (gold MLI, white radiators); glTF metallic-roughness materials.
- sat.obj + sat.mtl: the same triangles with the node transforms applied, in the order
  hilcam reads the GLB (depth-first, each node before its children, siblings in order;
  a mirrored node's triangles with two corners swapped, as hilcam does), and the same
  materials in the MTL PBR extension (Kd, Pr, Pm).

Every coordinate is a multiple of 1/8 m, so both files hold exactly the same f32
vertices and hilcam renders them to the same bytes (tests/render/gltf.rs).
"""
import json
import struct
import sys
from pathlib import Path

# name: (base colour, metallic, roughness)
MATERIALS = {
    "mli_gold": (0.81, 1.0, 0.35),
    "radiator": (0.8, 0.0, 0.6),
    "solar_cell": (0.05, 0.0, 0.2),
    "antenna": (0.91, 1.0, 0.5),
}


def quad(a, b, c, d):
    """Two triangles (a b c), (a c d): counter-clockwise seen from the front."""
    return [a, b, c, d], [(0, 1, 2), (0, 2, 3)]


def box_faces(hx, hy, hz):
    """The bus: ±X faces (radiators), and ±Y, ±Z faces (gold), outward."""
    x, y, z = hx, hy, hz
    gold = [
        quad((-x, y, -z), (-x, y, z), (x, y, z), (x, y, -z)),      # +Y
        quad((-x, -y, -z), (x, -y, -z), (x, -y, z), (-x, -y, z)),  # -Y
        quad((-x, -y, z), (x, -y, z), (x, y, z), (-x, y, z)),      # +Z
        quad((-x, -y, -z), (-x, y, -z), (x, y, -z), (x, -y, -z)),  # -Z
    ]
    radiator = [
        quad((x, -y, -z), (x, y, -z), (x, y, z), (x, -y, z)),      # +X
        quad((-x, -y, -z), (-x, -y, z), (-x, y, z), (-x, y, -z)),  # -X
    ]
    return gold, radiator


def merge(quads):
    pos, tri = [], []
    for p, t in quads:
        base = len(pos)
        pos += p
        tri += [(base + a, base + b, base + c) for a, b, c in t]
    return pos, tri


def model():
    """Meshes (name, [(material, positions, triangles)]) and nodes (name, mesh or None,
    translation, scale, children)."""
    gold, radiator = box_faces(0.5, 0.625, 0.5)
    panel = quad((0.0, -0.375, 0.0), (2.0, -0.375, 0.0), (2.0, 0.375, 0.0), (0.0, 0.375, 0.0))
    apex = (0.0, 0.75, 0.0)
    rim = [(-0.375, 1.0, -0.375), (-0.375, 1.0, 0.375), (0.375, 1.0, 0.375), (0.375, 1.0, -0.375)]
    dish = ([apex] + rim, [(0, 1 + (i + 1) % 4, 1 + i) for i in range(4)])
    meshes = [
        ("bus", [("mli_gold", *merge(gold)), ("radiator", *merge(radiator))]),
        ("panel", [("solar_cell", *merge([panel]))]),
        ("dish", [("antenna", *dish)]),
    ]
    nodes = [
        ("satellite", None, [0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [1, 2, 3, 4]),
        ("bus", 0, [0.0, 0.0, 0.0], [1.0, 1.0, 1.0], []),
        ("panel+x", 1, [0.625, 0.0, 0.0], [1.0, 1.0, 1.0], []),
        ("panel-x", 1, [-0.625, 0.0, 0.0], [-1.0, 1.0, 1.0], []),
        ("dish", 2, [0.0, 0.0, 0.0], [1.0, 1.0, 1.0], []),
    ]
    return meshes, nodes


def write_glb(path, meshes, nodes):
    names = list(MATERIALS)
    bin_ = bytearray()
    views, accessors, gmeshes = [], [], []

    def add(data, target):
        while len(bin_) % 4:
            bin_.append(0)
        views.append({"buffer": 0, "byteOffset": len(bin_), "byteLength": len(data), "target": target})
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
            iv = add(b"".join(struct.pack("<3H", *t) for t in tri), 34963)
            accessors.append({"bufferView": iv, "componentType": 5123, "count": 3 * len(tri), "type": "SCALAR"})
            gprims.append({"attributes": {"POSITION": len(accessors) - 2}, "indices": len(accessors) - 1,
                           "material": names.index(mat), "mode": 4})
        gmeshes.append({"name": name, "primitives": gprims})
    gnodes = glb_nodes(nodes)
    doc = {
        "asset": {"version": "2.0", "generator": "hilcam scripts/make_gltf_satellite.py"},
        "scene": 0,
        "scenes": [{"name": "satellite", "nodes": [0]}],
        "nodes": gnodes,
        "meshes": gmeshes,
        "materials": [{"name": n, "doubleSided": True,
                       "pbrMetallicRoughness": {"baseColorFactor": [b, b, b, 1.0], "metallicFactor": m,
                                                "roughnessFactor": r}}
                      for n, (b, m, r) in MATERIALS.items()],
        "buffers": [{"byteLength": len(bin_)}],
        "bufferViews": views,
        "accessors": accessors,
    }
    path.write_bytes(glb_container(doc, bin_))


def glb_nodes(nodes):
    """glTF node objects of (name, mesh, translation, scale, children), defaults left out."""
    gnodes = []
    for name, mesh, t, s, children in nodes:
        n = {"name": name}
        if mesh is not None:
            n["mesh"] = mesh
        if t != [0.0, 0.0, 0.0]:
            n["translation"] = t
        if s != [1.0, 1.0, 1.0]:
            n["scale"] = s
        if children:
            n["children"] = children
        gnodes.append(n)
    return gnodes


def glb_container(doc, bin_):
    """The GLB file of a glTF JSON document and its binary buffer: the 12-byte header, then
    the JSON chunk (space-padded) and the BIN chunk (zero-padded) to 4-byte boundaries."""
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    bin_ = bytes(bin_) + b"\0" * (-len(bin_) % 4)
    total = 12 + 8 + len(js) + 8 + len(bin_)
    out = struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(js), b"JSON") + js
    return out + struct.pack("<I4s", len(bin_), b"BIN\0") + bin_


def write_obj(obj_path, mtl_path, meshes, nodes):
    lines = ["# hilcam scripts/make_gltf_satellite.py: sat.glb with its node transforms applied",
             f"mtllib {mtl_path.name}"]
    faces = []
    count = 0

    def visit(i, parent_t, parent_s):
        nonlocal count
        name, mesh, t, s, children = nodes[i]
        # Translation and scale only (no rotation): world = parent_t + parent_s * (t + s * p).
        ws = [parent_s[k] * s[k] for k in range(3)]
        wt = [parent_t[k] + parent_s[k] * t[k] for k in range(3)]
        if mesh is not None:
            mirrored = ws[0] * ws[1] * ws[2] < 0
            for mat, pos, tri in meshes[mesh][1]:
                for p in pos:
                    lines.append("v " + " ".join(repr(wt[k] + ws[k] * p[k]) for k in range(3)))
                faces.append(f"usemtl {mat}")
                for a, b, c in tri:
                    if mirrored:
                        b, c = c, b
                    faces.append(f"f {count + a + 1} {count + b + 1} {count + c + 1}")
                count += len(pos)
        for c in children:
            visit(c, wt, ws)

    visit(0, [0.0, 0.0, 0.0], [1.0, 1.0, 1.0])
    obj_path.write_text("\n".join(lines + faces) + "\n")
    mtl = ["# hilcam scripts/make_gltf_satellite.py: sat.glb's materials (MTL PBR extension)"]
    for n, (b, m, r) in MATERIALS.items():
        mtl += [f"newmtl {n}", f"Kd {b} {b} {b}", f"Pr {r}", f"Pm {m}"]
    mtl_path.write_text("\n".join(mtl) + "\n")


def main():
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent / "scenes" / "gltf_satellite"
    out.mkdir(parents=True, exist_ok=True)
    meshes, nodes = model()
    write_glb(out / "sat.glb", meshes, nodes)
    write_obj(out / "sat.obj", out / "sat.mtl", meshes, nodes)
    print(f"wrote {out / 'sat.glb'}, {out / 'sat.obj'}, {out / 'sat.mtl'}")


if __name__ == "__main__":
    main()
