"""filter_bias.py DIR RES: the adaptive filter's error terms against what
seeds measure (scripts/bench_filter_bias; docs/error.md, "The filter").

DIR holds one folder per seed with bench_error_run's rows.json and raw grids
(ad-F.raw RGB, truth-0.0000.raw RGB; x fastest). Per photon fraction F it
prints each seed's ε̂/ε and filter term, and over the seeds, on the truth's
lit voxels (DESIGN.md §8), the filtered grid's noise (the seeds' spread)
and bias (their mean's distance from the truth, less the spread's share),
both relative to the truth's lit mean like ε (the bias includes the step's:
the truth is RK4 at 1/8 voxel, the bakes at 1/4)."""
import glob
import json
import sys

import numpy as np

LUM = np.array([0.2126, 0.7152, 0.0722], np.float32)


def lum(path, n):
    return (np.fromfile(path, np.float32).reshape(-1, 3) @ LUM).reshape(n, n, n)


def main(folder, n):
    seeds = sorted(glob.glob(folder + "/*/"))
    truth = lum(seeds[0] + "truth-0.0000.raw", n)
    lit = truth >= 0.02 * np.percentile(truth, 99.9)
    mean_t = truth[lit].mean()
    rows = {s: [json.loads(l) for l in open(s + "rows.json")] for s in seeds}
    print("| fraction of N | ε̂/ε per seed | filter term per seed | seeds' noise | seeds' bias |")
    print("|---|---|---|---|---|")
    for r0 in rows[seeds[0]]:
        if r0["mode"] == "reference":
            continue
        f = r0["fraction"]
        at = [next(r for r in rows[s] if r.get("fraction") == f) for s in seeds]
        x = np.stack([lum(s + "ad-%.4f.raw" % f, n)[lit] for s in seeds])
        var = x.var(0, ddof=1).mean()
        bias2 = ((x.mean(0) - truth[lit]) ** 2).mean() - var / len(seeds)
        print("| %.4f | %s | %s | %.4f | %.4f |" % (
            f, " ".join("%.2f" % (r["estimate"] / r["true"]) for r in at),
            " ".join("%.3f" % r["filter"] for r in at), np.sqrt(var) / mean_t,
            np.sqrt(max(bias2, 0.0)) / mean_t))


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
