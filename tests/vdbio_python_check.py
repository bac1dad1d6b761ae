#!/usr/bin/python3
"""Reads the known file of test_vdbio (test_vdbio write DIR) with OpenVDB's own
Python module, as another tool would, and checks it against the functions the
file was written from. Run with /usr/bin/python3 (Debian's python3-openvdb).

Known grids (the numbers repeat tests/test_vdbio.c): dims 12x10x8, voxel 0.25,
origin (-1.5, 0.75, 2.0), cell-centred; "density" (float) = 1 + 0.5x - 0.25y +
2z at voxel centres with i >= 2, inactive 0 for i < 2; "radiance" (Vec3f,
invariant) = (x, 2y, 3 + z)."""
import sys

import pyopenvdb as vdb

NX, NY, NZ, VOXEL, ORIGIN = 12, 10, 8, 0.25, (-1.5, 0.75, 2.0)
TOL = 1e-5


def density(w):
    return 1.0 + 0.5 * w[0] - 0.25 * w[1] + 2.0 * w[2]


def radiance(w):
    return (w[0], 2.0 * w[1], 3.0 + w[2])


def centre(i, j, k):
    return tuple(ORIGIN[a] + (n + 0.5) * VOXEL for a, n in enumerate((i, j, k)))


def main(path):
    failures = []

    def check(cond, msg):
        if not cond:
            failures.append(msg)
            print("FAIL", msg)

    grids, meta = vdb.readAll(path)
    print("file metadata:", meta)
    for key in ("creator", "voxel_centering"):
        check(key in meta, "file metadata lacks %s" % key)
    check(str(meta.get("creator", "")).startswith("baker "), "creator is %r" % meta.get("creator"))
    check("cell-centred" in str(meta.get("voxel_centering", "")), "voxel_centering text")
    check(meta.get("frame") == 7 and meta.get("mode") == "reference" and meta.get("scale") == 0.5,
          "custom metadata frame/mode/scale: %r" % meta)

    by_name = {g.name: g for g in grids}
    check(sorted(by_name) == ["density", "radiance"], "grid names %r" % sorted(by_name))
    if failures:
        return 1
    den, rad = by_name["density"], by_name["radiance"]
    check(isinstance(den, vdb.FloatGrid), "density is %s" % type(den).__name__)
    check(isinstance(rad, vdb.Vec3SGrid), "radiance is %s" % type(rad).__name__)
    # fog volume on scalars only: NanoVDB refuses the class on vector grids
    for g, want in ((den, "fog volume"), (rad, "unknown")):
        check(g.gridClass == want, "%s class %r" % (g.name, g.gridClass))
        check(g.background in (0.0, (0.0, 0.0, 0.0)), "%s background %r" % (g.name, g.background))
    check(rad.metadata.get("vector_type") == "invariant",
          "radiance vector_type metadata %r" % rad.metadata.get("vector_type"))
    check(den.activeVoxelCount() == (NX - 2) * NY * NZ, "density active %d" % den.activeVoxelCount())
    check(rad.activeVoxelCount() == NX * NY * NZ, "radiance active %d" % rad.activeVoxelCount())
    check(den.evalActiveVoxelBoundingBox() == ((2, 0, 0), (NX - 1, NY - 1, NZ - 1)),
          "density bbox %r" % (den.evalActiveVoxelBoundingBox(),))

    # the corner of our voxel (0,0,0) is the corner of the index cell (0,0,0):
    # index -0.5 in the transform's continuous index space (cell-centred)
    corner = den.transform.worldToIndex(ORIGIN)
    check(all(abs(c + 0.5) < 1e-6 for c in corner), "origin maps to index %r, expected -0.5" % (corner,))

    # every voxel centre, through the grid's transform, to the stored value
    worst = 0.0
    for k in range(NZ):
        for j in range(NY):
            for i in range(NX):
                w = centre(i, j, k)
                for g, fn in ((den, density), (rad, radiance)):
                    idx = g.transform.worldToIndex(w)
                    ijk = tuple(int(round(c)) for c in idx)
                    check(all(abs(c - n) < 1e-6 for c, n in zip(idx, ijk)),
                          "%s: world %r is not a voxel centre: index %r" % (g.name, w, idx))
                    got = g.getConstAccessor().getValue(ijk)
                    if g is den:
                        want, got = ((fn(w) if i >= 2 else 0.0),), (got,)
                    else:
                        want = fn(w)
                    for a, b in zip(got, want):
                        worst = max(worst, abs(a - b) / (1.0 + abs(b)))
    check(worst <= TOL, "values at voxel centres: worst relative error %g" % worst)
    print("%d voxel centres x 2 grids through worldToIndex: worst relative error %g" % (NX * NY * NZ, worst))
    print("%s: %d failure(s)" % (path, len(failures)))
    return 1 if failures else 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: vdbio_python_check.py FILE.vdb")
    sys.exit(main(sys.argv[1]))
