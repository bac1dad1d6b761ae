#!/usr/bin/env python3
"""Untrusted VDB input (issue 17 item 2; docs/reliability.md).

Bakes a small cube (16^3) with blosc, zip and no compression, then for each
flips one byte at seeded random offsets and runs `baker view` on every
corrupted copy (and `baker bake` with medium.density_vdb on a few), under an
address-space cap (RLIMIT_AS, as `prlimit --as`) and a wall-clock limit.
Every run must end with exit 0 (the flip changed nothing that matters; the
image is written) or 2 (refused, the message names the file): never a
signal, never 1, never past the limit. Prints the counts, the worst time
and the largest resident size. First, one known case without the tight cap:
a corrupt metadata length must fail at once (meta_length_case).

  vdb_flip.py BAKER SCENE_DIR WORK_DIR [--flips N] [--bakes N] [--seed S]
              [--mem-gib G] [--timeout S]

ctest runs a few flips per compression; scripts/vdb_flip_sweep runs 200.
"""
import argparse
import json
import os
import random
import resource
import shutil
import subprocess
import sys
import time

COMPRESSIONS = ("blosc", "zip", "none")


# Under AddressSanitizer (scripts/sanitize.sh sets ASAN_OPTIONS) an address-
# space cap stops the sanitizer itself, whose shadow memory is reserved as
# terabytes of address space: there the bound is checked on the peak
# resident size the runs report instead (Tally.add's caller, below).
UNDER_ASAN = "ASAN_OPTIONS" in os.environ


def limited(mem_bytes):
    def set_limits():
        if not UNDER_ASAN:
            resource.setrlimit(resource.RLIMIT_AS, (mem_bytes, mem_bytes))
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    return set_limits


def run(cmd, mem_bytes, timeout, cwd):
    """(rc, seconds, max RSS in MiB, stderr) of cmd under the limits."""
    t0 = time.monotonic()
    p = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         preexec_fn=limited(mem_bytes))
    try:
        _, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        _, err = p.communicate()
        return None, time.monotonic() - t0, 0.0, err.decode(errors="replace")
    # wait4 already happened inside communicate(); RUSAGE_CHILDREN holds the
    # largest child (and grandchild: the reader) so far, a running maximum
    rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    return p.returncode, time.monotonic() - t0, rss, err.decode(errors="replace")


def flip(src, dst, rng):
    data = bytearray(open(src, "rb").read())
    off = rng.randrange(len(data))
    data[off] ^= rng.randrange(1, 256)
    open(dst, "wb").write(data)
    return off


class Tally:
    def __init__(self):
        self.counts = {}
        self.worst = 0.0
        self.problems = []

    def add(self, what, rc, secs, err, name, out=None):
        self.worst = max(self.worst, secs)
        self.counts[rc] = self.counts.get(rc, 0) + 1
        if rc is None:
            self.problems.append(f"{what}: past the time limit")
        elif rc < 0:
            self.problems.append(f"{what}: killed by signal {-rc}: {err.strip()[-300:]}")
        elif rc == 2 and name not in err:
            self.problems.append(f"{what}: exit 2 without naming {name}: {err.strip()}")
        elif rc == 0 and out and not os.path.exists(out):
            self.problems.append(f"{what}: exit 0 without an image")
        elif rc not in (0, 2):
            self.problems.append(f"{what}: exit {rc}: {err.strip()[-300:]}")


def bake_sources(args, work):
    scene = os.path.join(work, "cube.json")
    with open(os.path.join(args.scene_dir, "cube.json")) as f:
        s = json.load(f)
    s["objects"][0]["mesh"] = os.path.join(args.scene_dir, s["objects"][0]["mesh"])
    with open(scene, "w") as f:
        json.dump(s, f)
    small = ["--resolution", "16", "--photons", "2000", "-q"]
    for c in COMPRESSIONS:
        out = os.path.join(work, f"cube_{c}.vdb")
        subprocess.run([args.baker, "bake", scene, *small, "--compression", c, "-o", out],
                       check=True)
    s["medium"]["density_vdb"] = {"file": "bad.vdb", "grid": "density"}
    with open(os.path.join(work, "medium.json"), "w") as f:
        json.dump(s, f)
    return small


def sweep(args, work, c, rng, small, tally):
    src = os.path.join(work, f"cube_{c}.vdb")
    mem = int(args.mem_gib * (1 << 30))
    for n in range(args.flips):
        off = flip(src, os.path.join(work, "bad.vdb"), rng)
        out = os.path.join(work, "bad.exr")
        if os.path.exists(out):
            os.remove(out)
        cmd = [args.baker, "view", "bad.vdb", "-o", "bad.exr", "--resolution", "64x48", "-q"]
        rc, secs, rss, err = run(cmd, mem, args.timeout, work)
        tally.add(f"{c} view flip at byte {off}", rc, secs, err, "bad.vdb", out)
        if n < args.bakes:
            cmd = [args.baker, "bake", "medium.json", *small, "-o", "baked.vdb", "--force"]
            rc, secs, rss, err = run(cmd, mem, args.timeout, work)
            tally.add(f"{c} bake density_vdb flip at byte {off}", rc, secs, err, "bad.vdb")
        tally.rss = rss


def meta_length_case(args, work):
    """The corrupt length field of docs/reliability.md: a grid metadata name
    length ("vector_type", 11) made 2 080 374 795. Run without the sweep's
    tight cap (a wide one guards the machine), it must fail at once, not
    after filling the memory there is: the reader's parse limit."""
    data = bytearray(open(os.path.join(work, "cube_zip.vdb"), "rb").read())
    off = data.find(b"\x0b\x00\x00\x00vector_type")
    if off < 0:
        return ["meta length case: no \"vector_type\" entry in cube_zip.vdb"]
    data[off + 3] = 0x7C
    open(os.path.join(work, "bad.vdb"), "wb").write(data)
    cmd = [args.baker, "view", "bad.vdb", "-o", "bad.exr", "--resolution", "64x48", "-q"]
    rc, secs, rss, err = run(cmd, 6 << 30, args.timeout, work)
    print(f"meta length flip at byte {off + 3}: exit {rc}, {secs:.2f} s, "
          f"largest resident {rss:.0f} MiB (bound 1024 MiB, cap 6 GiB)")
    problems = []
    if rc != 2 or "bad.vdb" not in err:
        problems.append(f"meta length case: exit {rc}, not 2 naming bad.vdb: {err.strip()[-300:]}")
    if rss > 1024:
        problems.append(f"meta length case: largest resident {rss:.0f} MiB over 1024 MiB")
    return problems


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("baker")
    ap.add_argument("scene_dir")
    ap.add_argument("work")
    ap.add_argument("--flips", type=int, default=200)
    ap.add_argument("--bakes", type=int, default=5)
    ap.add_argument("--seed", type=int, default=17)
    ap.add_argument("--mem-gib", type=float, default=3.0)
    ap.add_argument("--timeout", type=float, default=60.0)
    args = ap.parse_args()
    args.baker = os.path.abspath(args.baker)
    args.scene_dir = os.path.abspath(args.scene_dir)
    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    small = bake_sources(args, args.work)
    rc = 0
    for p in meta_length_case(args, args.work):
        print("  FAIL", p)
        rc = 1
    for c in COMPRESSIONS:
        tally = Tally()
        tally.rss = 0.0
        sweep(args, args.work, c, random.Random(f"{args.seed}-{c}"), small, tally)
        counts = ", ".join(f"exit {k}: {v}" for k, v in sorted(tally.counts.items(),
                                                                key=lambda kv: str(kv[0])))
        print(f"{c}: {args.flips} flips ({min(args.flips, args.bakes)} also baked): {counts}; "
              f"worst {tally.worst:.2f} s, largest resident {tally.rss:.0f} MiB "
              f"(cap {args.mem_gib:g} GiB)")
        if UNDER_ASAN and tally.rss > args.mem_gib * 1024:
            tally.problems.append(f"largest resident {tally.rss:.0f} MiB over the "
                                  f"{args.mem_gib:g} GiB bound (checked on RSS under ASan)")
        for p in tally.problems:
            print("  FAIL", p)
            rc = 1
    return rc


if __name__ == "__main__":
    sys.exit(main())
