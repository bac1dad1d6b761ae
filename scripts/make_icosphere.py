#!/usr/bin/env python3
"""Writes a unit icosphere (radius 1, centred at the origin) as OBJ: an
icosahedron whose triangles are split in four `levels` times, every new
vertex pushed onto the sphere. Closed, manifold, outward-facing.

  make_icosphere.py OUT.obj [levels=3]   (levels 3: 642 vertices, 1280 faces)

Used for scenes/meshes/sphere.obj (scenes/sphere.json)."""
import math
import sys


def icosphere(levels):
    t = (1.0 + math.sqrt(5.0)) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0),
             (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
             (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    verts = [tuple(c / math.sqrt(sum(x * x for x in v)) for c in v) for v in verts]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11),
             (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8),
             (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
             (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(levels):
        cache = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = [(verts[a][k] + verts[b][k]) / 2.0 for k in range(3)]
                n = math.sqrt(sum(x * x for x in m))
                verts.append(tuple(x / n for x in m))
                cache[key] = len(verts) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return verts, faces


def main():
    if len(sys.argv) < 2:
        sys.stderr.write(__doc__)
        return 2
    levels = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    verts, faces = icosphere(levels)
    with open(sys.argv[1], "w") as f:
        f.write("# unit icosphere, %d subdivisions (scripts/make_icosphere.py)\n" % levels)
        for v in verts:
            f.write("v %.9f %.9f %.9f\n" % v)
        for a, b, c in faces:
            f.write("f %d %d %d\n" % (a + 1, b + 1, c + 1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
