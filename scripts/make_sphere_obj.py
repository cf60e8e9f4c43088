#!/usr/bin/env python3
"""Write an icosphere OBJ (radius 1 m, outward winding): scenes/meshes/sphere.obj."""
import math, sys

def icosphere(levels):
    t = (1 + 5 ** 0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
         (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    v = [tuple(c / math.sqrt(sum(x * x for x in p)) for c in p) for p in v]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(levels):
        cache, nf = {}, []
        def mid(a, b):
            k = (min(a, b), max(a, b))
            if k not in cache:
                m = [(v[a][i] + v[b][i]) / 2 for i in range(3)]
                n = math.sqrt(sum(x * x for x in m))
                v.append(tuple(x / n for x in m))
                cache[k] = len(v) - 1
            return cache[k]
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = nf
    return v, f

levels = int(sys.argv[1]) if len(sys.argv) > 1 else 5
v, f = icosphere(levels)
with open("scenes/meshes/sphere.obj", "w") as out:
    out.write(f"# icosphere, {levels} subdivisions, radius 1 m: {len(v)} vertices, {len(f)} triangles\n")
    out.write("mtllib sphere.mtl\n")
    for p in v:
        out.write("v %.7f %.7f %.7f\n" % p)
    out.write("usemtl white_paint\n")
    for a, b, c in f:
        out.write(f"f {a+1} {b+1} {c+1}\n")
