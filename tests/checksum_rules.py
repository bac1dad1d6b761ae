#!/usr/bin/python3
"""The per-grid checksum rules of formats/vdbio.h, implemented again here from
their description and checked against baker (run with /usr/bin/python3, which
has Debian's pyopenvdb).

usage: checksum_rules.py BAKER SCENES WORKDIR

1. Bakes the cube at 17^3 (a slice of 289 words: the lanes wrap across
   slices), plain and --half, and recomputes every checksum_v2_<grid> from
   the values OpenVDB reads back.
2. Writes a copy of the plain bake that holds only the older serial rule's
   checksum_<grid> (computed here), as bakers before the eight-lane rule
   wrote it: `baker verify` must pass it and `baker view` render it without
   the warning for files that record no checksums.
3. The same copy with one recorded checksum changed must be reported
   CORRUPT for that grid alone."""
import os
import shutil
import subprocess
import sys

import numpy as np
import pyopenvdb as vdb

M32, M64 = 0xFFFFFFFF, 0xFFFFFFFFFFFFFFFF
P32, O32 = 16777619, 2166136261
P64, O64 = 1099511628211, 14695981039346656037


def fnv64(h, words):
    for w in words:
        h = ((h ^ int(w)) * P64) & M64
    return h


def box_values(grid, n):
    """The grid's values over [0, n)^3 as float32, x fastest, channels last."""
    vec = "vec3" in grid.valueTypeName
    a = np.zeros((n, n, n, 3) if vec else (n, n, n), dtype=np.float32)
    grid.copyToArray(a, ijk=(0, 0, 0))
    a = a.transpose(2, 1, 0, 3) if vec else a.transpose(2, 1, 0)
    return np.ascontiguousarray(a), (3 if vec else 1)


def background_words(grid, ch):
    bg = np.array(grid.background, dtype=np.float32).reshape(ch)
    bg[bg == 0.0] = 0.0  # -0 -> +0
    return bg.view(np.uint32)


def lanes_rule(grid, n):
    values, ch = box_values(grid, n)
    w = values.ravel().view(np.uint32)
    keep = ((w & np.uint32(0x7FFFFFFF)) - np.uint32(1)) < np.uint32(0x7F800000)
    w = np.where(keep, w, np.uint32(0))
    lanes = []
    for j in range(8):
        h = O32
        for x in w[j::8]:
            h = ((h ^ int(x)) * P32) & M32
        lanes.append(h)
    return fnv64(fnv64(O64, lanes), background_words(grid, ch))


def serial_rule(grid, n):
    values, ch = box_values(grid, n)
    v = values.reshape(-1, ch)
    background = np.all(~(np.abs(v) > 0.0), axis=1)  # all channels 0 or NaN
    v = v.copy()
    v[v == 0.0] = 0.0
    w = v.view(np.uint32).copy()
    w[background] = 0
    return fnv64(fnv64(O64, w.ravel()), background_words(grid, ch))


def run(cmd, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, **kw)


def main(baker, scenes, work):
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    shutil.copytree(os.path.join(scenes, "meshes"), os.path.join(work, "meshes"))
    shutil.copy(os.path.join(scenes, "cube.json"), os.path.join(work, "scene.json"))
    fails = []
    n = 17
    for name, extra in (("plain.vdb", []), ("half.vdb", ["--half"])):
        p = run([baker, "bake", "scene.json", "--resolution", str(n), "--photons", "2000", "-q",
                 "-o", name] + extra, cwd=work)
        if p.returncode:
            sys.exit(f"bake {name} failed: {p.stderr}")
        grids, meta = vdb.readAll(os.path.join(work, name))
        if meta.get("checksum_box") != f"{n} {n} {n}":
            sys.exit(f"{name}: checksum_box {meta.get('checksum_box')}, expected {n} {n} {n}")
        for g in grids:
            want = meta.get("checksum_v2_" + g.name)
            got = f"{lanes_rule(g, n):016x}"
            print(f"{name} {g.name}: recorded {want}, recomputed {got}")
            if want != got:
                fails.append(f"{name} {g.name}: recorded {want}, recomputed {got}")
            if ("checksum_" + g.name) in meta:
                fails.append(f"{name}: also records the old key checksum_{g.name}")

    # 2: the plain bake with the serial rule's keys only
    grids, meta = vdb.readAll(os.path.join(work, "plain.vdb"))
    old = {k: v for k, v in meta.items() if not k.startswith("checksum_v2_")}
    for g in grids:
        old["checksum_" + g.name] = f"{serial_rule(g, n):016x}"
    vdb.write(os.path.join(work, "old.vdb"), grids=grids, metadata=old)
    p = run([baker, "verify", "old.vdb"], cwd=work)
    print(p.stdout.strip())
    if p.returncode != 0 or p.stdout.count(" OK") != len(grids):
        fails.append(f"verify of the serial-rule copy: exit {p.returncode}: {p.stdout}{p.stderr}")
    p = run([baker, "view", "old.vdb", "-o", "old.exr", "--resolution", "32x24", "-q"], cwd=work)
    if p.returncode != 0 or "no checksums" in p.stderr:
        fails.append(f"view of the serial-rule copy: exit {p.returncode}: {p.stderr}")

    # 3: one recorded checksum wrong
    bad = dict(old)
    h = bad["checksum_radiance"]
    bad["checksum_radiance"] = ("1" if h[0] != "1" else "2") + h[1:]
    vdb.write(os.path.join(work, "bad.vdb"), grids=grids, metadata=bad)
    p = run([baker, "verify", "bad.vdb"], cwd=work)
    print(p.stdout.strip())
    lines = [l for l in p.stdout.splitlines() if "CORRUPT" in l]
    if p.returncode != 1 or len(lines) != 1 or "radiance" not in lines[0]:
        fails.append(f"verify of a wrong serial checksum: exit {p.returncode}: {p.stdout}")

    for f in fails:
        print("FAIL", f)
    print("ok" if not fails else f"{len(fails)} failures")
    return 1 if fails else 0


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    sys.exit(main(*sys.argv[1:]))
