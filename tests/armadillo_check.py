#!/usr/bin/python3
"""Checks a baked armadillo the way users' tools read it.

1. `vdb_print` lists the grids of DESIGN.md §5.
2. OpenVDB's Python module reads `ior`, and at world points that an
   independent inside test (the generalized winding number of the mesh,
   computed here with numpy) puts deep inside the armadillo it finds the
   object's n, and at points well outside the medium's n.

Usage: armadillo_check.py OUT.vdb MESH.obj SCALE ROT_Y_DEG TX TY TZ N_IN N_OUT
"""
import subprocess
import sys

import numpy as np
import pyopenvdb as vdb

vdb_path, mesh_path = sys.argv[1], sys.argv[2]
scale, rot_y = float(sys.argv[3]), float(sys.argv[4])
translate = np.array([float(v) for v in sys.argv[5:8]])
n_in, n_out = float(sys.argv[8]), float(sys.argv[9])
failures = []

listing = subprocess.run(["vdb_print", "-l", vdb_path], capture_output=True, text=True)
print(listing.stdout)
if listing.returncode != 0:
    failures.append("vdb_print failed: " + listing.stderr)
for name in ("ior", "extinction", "scattering", "density"):
    if name not in listing.stdout:
        failures.append(f"vdb_print does not list grid '{name}'")

# the mesh, transformed as the scene says: scale, rotate about y, translate
verts, faces = [], []
with open(mesh_path) as f:
    for line in f:
        p = line.split()
        if not p:
            continue
        if p[0] == "v":
            verts.append([float(x) for x in p[1:4]])
        elif p[0] == "f":
            idx = [int(t.split("/")[0]) - 1 for t in p[1:]]
            for k in range(1, len(idx) - 1):
                faces.append([idx[0], idx[k], idx[k + 1]])
verts = np.array(verts) * scale
c, s = np.cos(np.radians(rot_y)), np.sin(np.radians(rot_y))
rot = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
verts = verts @ rot.T + translate
tris = verts[np.array(faces)]


def winding_number(p):
    """Generalized winding number (Jacobson et al. 2013): 1 inside, 0 outside."""
    a, b, cc = tris[:, 0] - p, tris[:, 1] - p, tris[:, 2] - p
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, cc))
    det = np.einsum("ij,ij->i", a, np.cross(b, cc))
    den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc
           + np.einsum("ij,ij->i", b, cc) * la + np.einsum("ij,ij->i", cc, a) * lb)
    return np.sum(2.0 * np.arctan2(det, den)) / (4.0 * np.pi)


grids, meta = vdb.readAll(vdb_path)
print("metadata:", {k: meta[k] for k in sorted(meta)})
for key in ("creator", "voxel_centering", "scene_hash", "frame", "mode"):
    if key not in meta:
        failures.append(f"file metadata lacks '{key}'")
ior = next((g for g in grids if g.name == "ior"), None)
if ior is None:
    failures.append("no 'ior' grid")
else:
    if ior.gridClass != vdb.GridClass.FOG_VOLUME:
        failures.append(f"ior grid class is {ior.gridClass}, expected fog volume")
    voxel = ior.transform.voxelSize()[0]
    acc = ior.getConstAccessor()

    def ior_at(p):
        ijk = ior.transform.worldToIndexCellCentered(tuple(p))
        v = acc.getValue(ijk)
        return v if acc.isValueOn(ijk) or v != 0 else 0.0

    min_vertex_dist = lambda p: np.min(np.linalg.norm(verts - p, axis=1))
    # candidates along the body's vertical axis and a grid of others
    rng = np.random.default_rng(7)
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    candidates = [np.array([0.0, y, 0.0]) for y in np.linspace(lo[1], hi[1], 25)]
    candidates += list(lo + rng.random((200, 3)) * (hi - lo))
    inside = [p for p in candidates if winding_number(p) > 0.9 and min_vertex_dist(p) > 4 * voxel]
    outside = [np.array(p) for p in ([0.9, 0.9, 0.9], [-0.9, -0.9, 0.9], [0.9, -0.95, -0.9])]
    if len(inside) < 3:
        failures.append(f"found only {len(inside)} deep-inside test points")
    for p in inside[:10]:
        v = ior_at(p)
        print(f"inside  {np.round(p, 3)}: ior {v:.5f} (expect {n_in})")
        if abs(v - n_in) > 1e-3:
            failures.append(f"ior at inside point {p} is {v}, expected {n_in}")
    for p in outside:
        assert winding_number(p) < 0.1
        v = ior_at(p)
        print(f"outside {np.round(p, 3)}: ior {v:.5f} (expect {n_out})")
        if abs(v - n_out) > 1e-3:
            failures.append(f"ior at outside point {p} is {v}, expected {n_out}")

if failures:
    print("FAILED:\n  " + "\n  ".join(failures))
    sys.exit(1)
print("armadillo check passed")
