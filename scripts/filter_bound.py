#!/usr/bin/python3
"""filter_bound.py DUMPS SCENE RES: how far any reconstruction filter could
take the adaptive mode (issue 12, "Pays"; docs/bench.md). Run by
scripts/bench_filter_bound, which fills DUMPS; needs numpy and scipy (Debian's
python3-numpy, python3-scipy).

Reads, as raw RGB floats x fastest (scripts/bench_error_run.c, BENCH_DUMP):
  DUMPS/truth-0.0000.raw             the truth (RK4 1/8 voxel, 16x the photons)
  DUMPS/ref-F/ref-1.0000.raw         the reference mode with F x N photons
  DUMPS/filtered/ad-F.raw            the adaptive mode as it ships (filtered)
  DUMPS/raw/ad-F.raw                 the adaptive mode unfiltered
and prints, per estimate, its true error ε (DESIGN.md §8) and the ε an oracle
filter gives: for every voxel the filter, out of a set, whose squared error
against the truth averaged over the 5^3 voxels around is least (the truth
chooses, so no filter that sees only the estimate does better with that set;
the 5^3 average keeps the oracle from picking each voxel's lucky draw). Two
sets: isotropic Gaussians of standard deviation 0.5-3 voxels, as the
adaptive filter's radii are, and those plus four anisotropic ones that
follow the edges (the structure tensor of the estimate smoothed by 1 voxel:
narrow across the strongest direction, wide along the others). Last, the
fraction of N at which each way reaches the reference's ε at N, log-log
between the counts around it."""
import math
import os
import sys

import numpy as np
from scipy import ndimage as nd

ISO_SIGMAS = (0.5, 0.75, 1.0, 1.5, 2.0, 3.0)
# (across the strongest direction, the middle, the weakest), voxels
ANISO_SIGMAS = ((0.3, 1.5, 1.5), (0.3, 0.3, 1.5), (0.4, 1.0, 1.0), (0.3, 2.0, 2.0))
ANISO_REACH = 2  # the anisotropic kernels' half-width, voxels


def load(path, res):
    return np.fromfile(path, dtype=np.float32).reshape(res, res, res, 3)


def luminance(a):
    return 0.2126 * a[..., 0] + 0.7152 * a[..., 1] + 0.0722 * a[..., 2]


def true_error(lum, truth, lit):
    """ε of DESIGN.md §8 on luminance."""
    return math.sqrt(((lum - truth)[lit] ** 2).mean()) / truth[lit].mean()


def structure_axes(lum):
    """Per voxel, the structure tensor's eigenvectors, strongest first."""
    grads = np.gradient(nd.gaussian_filter(lum, 1.0, mode="nearest"))
    tensor = np.empty(lum.shape + (3, 3), np.float32)
    for i in range(3):
        for j in range(i, 3):
            tensor[..., i, j] = tensor[..., j, i] = nd.gaussian_filter(
                grads[i] * grads[j], 1.5, mode="nearest")
    _, vectors = np.linalg.eigh(tensor)  # eigenvalues ascending
    return [vectors[..., :, 2], vectors[..., :, 1], vectors[..., :, 0]]


def anisotropic(lum, axes, sigmas):
    """A Gaussian per voxel with the given widths along its structure axes."""
    r, n = ANISO_REACH, lum.shape[0]
    padded = np.pad(lum, r, mode="edge")
    num, den = np.zeros_like(lum), np.zeros_like(lum)
    for dz in range(-r, r + 1):
        for dy in range(-r, r + 1):
            for dx in range(-r, r + 1):
                d = np.array([dz, dy, dx], np.float32)
                w = np.exp(-sum((axes[k] @ d) ** 2 / (2 * sigmas[k] ** 2) for k in range(3)))
                num += w * padded[r + dz:r + dz + n, r + dy:r + dy + n, r + dx:r + dx + n]
                den += w
    return num / den


def oracle(candidates, truth):
    """Per voxel the candidate with the least local (5^3) squared error."""
    local = np.stack([nd.uniform_filter((c - truth) ** 2, 5, mode="nearest") for c in candidates])
    best = np.argmin(local, axis=0)
    return np.take_along_axis(np.stack(candidates), best[None], 0)[0]


def bounds(lum, truth, lit):
    """(raw ε, isotropic-oracle ε, isotropic+anisotropic-oracle ε)."""
    iso = [lum] + [nd.gaussian_filter(lum, s, mode="nearest", truncate=2.0) for s in ISO_SIGMAS]
    axes = structure_axes(lum)
    both = iso + [anisotropic(lum, axes, s) for s in ANISO_SIGMAS]
    return tuple(true_error(x, truth, lit) for x in (lum, oracle(iso, truth), oracle(both, truth)))


def reach(points, want):
    """The fraction whose ε is `want`, log-log between (fraction, ε) points."""
    points = sorted(points)
    for (f0, e0), (f1, e1) in zip(points, points[1:]):
        if (e0 - want) * (e1 - want) <= 0 and e0 != e1:
            t = math.log(want / e0) / math.log(e1 / e0)
            return "%.2f" % math.exp(math.log(f0) + t * math.log(f1 / f0))
    return "< %.2f" % points[0][0] if points[0][1] <= want else "> %.2f" % points[-1][0]


def main():
    dumps, scene, res = sys.argv[1], sys.argv[2], int(sys.argv[3])
    truth = luminance(load(os.path.join(dumps, "truth-0.0000.raw"), res))
    lit = truth >= 0.02 * np.percentile(truth, 99.9)
    ref_fractions = sorted(float(d[4:]) for d in os.listdir(dumps) if d.startswith("ref-"))
    ad_fractions = sorted(float(f[3:-4]) for f in os.listdir(os.path.join(dumps, "raw")))
    target = true_error(luminance(load(os.path.join(dumps, "ref-1.0000/ref-1.0000.raw"), res)), truth, lit)
    print("%s, %d^3: the reference's ε at N: %.4f" % (scene, res, target))
    print("| estimate | fraction of N | ε | ε, isotropic oracle | ε, isotropic + anisotropic oracle |")
    print("|---|---|---|---|---|")
    ways = {"uniform photons (reference)": [], "adaptive tables, unfiltered": []}
    shipped = []
    for kind, fractions, path in (("uniform photons (reference)", ref_fractions, "ref-%.4f/ref-1.0000.raw"),
                                  ("adaptive tables, unfiltered", ad_fractions, "raw/ad-%.4f.raw")):
        for f in fractions:
            if 0.2 <= f <= 0.55:
                e = bounds(luminance(load(os.path.join(dumps, path % f), res)), truth, lit)
                ways[kind].append((f, e))
                print("| %s | %.3f | %.4f | %.4f | %.4f |" % ((kind, f) + e), flush=True)
    for f in ad_fractions:
        lum = luminance(load(os.path.join(dumps, "filtered/ad-%.4f.raw" % f), res))
        shipped.append((f, true_error(lum, truth, lit)))
    print("\nFraction of N that reaches the reference's ε at N:")
    print("  adaptive as it ships (its filter): %s" % reach(shipped, target))
    for kind, rows in ways.items():
        print("  %s: no filter %s, isotropic oracle %s, isotropic + anisotropic oracle %s" % (
            kind, reach([(f, e[0]) for f, e in rows], target),
            reach([(f, e[1]) for f, e in rows], target), reach([(f, e[2]) for f, e in rows], target)))


if __name__ == "__main__":
    main()
