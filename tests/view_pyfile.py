#!/usr/bin/python3
"""Writes VDB files for the viewing-pass tests with pyopenvdb, i.e. not with
the project's own writer, so the test sees a transform and layout of another
tool's making.

  view_pyfile.py fog OUT.vdb --voxel S --translate X,Y,Z --imin I --imax J
                 [--rotate-z DEG] [--stretch-z F]
                 --radiance R,G,B --extinction S|R,G,B --scattering S|R,G,B
      a fog volume: voxels [I, J]^3 active with constant values, on a linear
      transform world = S Rz(DEG) diag(1, 1, F) index + (X, Y, Z); a
      one-component value gives a float grid, three a Vec3f grid. F != 1
      makes the voxels non-cubic, which the viewing pass must refuse.
  view_pyfile.py bool_radiance OUT.vdb
      a file whose `radiance` grid is a bool grid (the wrong type).

Run it with /usr/bin/python3 (python3-openvdb), not a pyenv python."""
import argparse
import math
import sys

import pyopenvdb as vdb


def values(text):
    v = [float(x) for x in text.split(",")]
    if len(v) not in (1, 3):
        raise argparse.ArgumentTypeError("expected S or R,G,B, got " + text)
    return v


def grid_for(name, v, xform, lo, hi):
    if len(v) == 1:
        g = vdb.FloatGrid()
        g.fill(lo, hi, v[0], True)
    else:
        g = vdb.Vec3SGrid()
        g.fill(lo, hi, tuple(v), True)
        if name == "radiance":
            g.vectorType = vdb.VectorType.INVARIANT
    g.name = name
    g.gridClass = vdb.GridClass.FOG_VOLUME
    g.transform = xform
    return g


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["fog", "bool_radiance"])
    ap.add_argument("out")
    ap.add_argument("--voxel", type=float, default=0.05)
    ap.add_argument("--translate", type=values, default=[0.0, 0.0, 0.0])
    ap.add_argument("--imin", type=int, default=0)
    ap.add_argument("--imax", type=int, default=9)
    ap.add_argument("--rotate-z", type=float, default=0.0)
    ap.add_argument("--stretch-z", type=float, default=1.0)
    ap.add_argument("--radiance", type=values, default=[1.0, 1.0, 1.0])
    ap.add_argument("--extinction", type=values, default=[1.0])
    ap.add_argument("--scattering", type=values, default=[1.0])
    a = ap.parse_args()
    s = a.voxel
    t = a.translate if len(a.translate) == 3 else a.translate * 3
    c, r = math.cos(math.radians(a.rotate_z)), math.sin(math.radians(a.rotate_z))
    # OpenVDB multiplies row vectors: world = [i j k 1] M, so row k is the
    # world image of index axis k
    xform = vdb.createLinearTransform([[s * c, s * r, 0, 0], [-s * r, s * c, 0, 0],
                                       [0, 0, s * a.stretch_z, 0], [t[0], t[1], t[2], 1]])
    lo, hi = (a.imin,) * 3, (a.imax,) * 3
    if a.mode == "fog":
        grids = [grid_for("radiance", a.radiance, xform, lo, hi),
                 grid_for("extinction", a.extinction, xform, lo, hi),
                 grid_for("scattering", a.scattering, xform, lo, hi)]
    else:
        g = vdb.BoolGrid()
        g.fill(lo, hi, True, True)
        g.name = "radiance"
        g.transform = xform
        grids = [g]
    vdb.write(a.out, grids=grids, metadata={"creator": "tests/view_pyfile.py"})
    return 0


if __name__ == "__main__":
    sys.exit(main())
