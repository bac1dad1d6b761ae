#!/usr/bin/python3
"""Tests of the benchmark harness (scripts/bench.cmake).

  bench_check.py metrics SCRIPTS_DIR
      scripts/bench_lib on closed forms: trilinear resampling reproduces a
      linear field, relative L2, Pareto front, power-law fit, the cone/box
      energy integral against a 1D quadrature, grid dims, the parsers of
      baker's printed tables.
  bench_check.py harness SCRIPTS_DIR BAKER BENCH_TOOL OUT_DIR
      runs `scripts/bench --tiny` and checks that its JSON has every field
      the plots and tables read, that the plots are PNG files, that more
      photons gave a smaller radiance error, and that the one energy row
      matches the closed form to 1%; the povray section, when POV-Ray is
      installed, has a time and picture for POV-Ray and both baker runs.
  bench_check.py pov SCRIPTS_DIR BAKER OUT_DIR
      the yardstick's translation (scripts/pov/scene2pov.py): the committed
      scripts/pov/sphere.pov is what it makes of scenes/sphere.json; keys
      it cannot translate are refused (exit 2, naming the key); and its
      units agree with baker's: a fog lit by the spot, no ball, single
      scattering, rendered by POV-Ray and by baker bake + view, has the same
      mean luminance within 5% (POV-Ray media samples 50: with 10 its fog
      is 7% too bright). Exit 77 (skip) when povray is missing.
Exit status 0 when every check passes; each failure is printed.
"""
import json
import math
import os
import subprocess
import sys

FAILS = []


def check(cond, what):
    if not cond:
        FAILS.append(what)
        print("FAIL:", what)
    return cond


def close(a, b, rel, what):
    ok = a is not None and b is not None and abs(a - b) <= rel * max(abs(b), 1e-300)
    return check(ok, f"{what}: got {a}, expected {b} (rel tol {rel:g})")


def metrics_tests(scripts):
    sys.path.insert(0, scripts)
    import numpy as np
    from bench_lib import metrics, runner

    # trilinear reproduces a linear field wherever it does not clamp
    n, lo, hi = 16, -1.0, 1.0
    vs = (hi - lo) / n
    c = lo + (np.arange(n) + 0.5) * vs
    x, y, z = np.meshgrid(c, c, c, indexing="ij")
    f = (0.3 * x - 1.2 * y + 2.0 * z + 5.0).astype(np.float32)
    src = metrics.GridRead(np.stack([f, 2 * f, 3 * f], axis=-1), (c[0],) * 3, vs, {})
    m = 40
    dvs = (hi - lo) / m
    dc = lo + (np.arange(m) + 0.5) * dvs
    out = metrics.resample_trilinear(src, (dc[0],) * 3, dvs, (m, m, m))
    X, Y, Z = np.meshgrid(dc, dc, dc, indexing="ij")
    exact = 0.3 * X - 1.2 * Y + 2.0 * Z + 5.0
    inner = (np.abs(X) <= c[-1]) & (np.abs(Y) <= c[-1]) & (np.abs(Z) <= c[-1])
    err = np.abs(out[..., 1] - 2 * exact)[inner].max()
    check(err < 1e-4, f"trilinear on a linear field: max error {err} >= 1e-4")
    check(out.shape == (m, m, m, 3), f"resampled shape {out.shape}")
    same = metrics.resample_trilinear(src, src.origin, vs, (n, n, n))
    check(np.array_equal(same, src.data), "resampling onto the same grid must be the identity")

    ref = np.ones((4, 4, 4, 3), np.float32)
    close(metrics.rel_l2(ref * 1.1, ref), 0.1, 1e-6, "rel_l2 of a 10% offset")
    check(metrics.rel_l2(ref, ref) == 0.0, "rel_l2 of identical grids is 0")
    check(metrics.rel_l2(ref, ref * 0) is None, "rel_l2 against a black reference is undefined")

    flags = metrics.pareto_front([1, 2, 3, 2, 4, None], [5, 3, 1, 4, 1, 0.1])
    check(flags == [True, True, True, False, False, False], f"pareto flags {flags}")

    xs = [10, 100, 1000, 10000]
    fit = metrics.fit_power_law(xs, [3 * v ** 1.5 for v in xs])
    close(fit["exponent"], 1.5, 1e-9, "power-law exponent")
    close(fit["prefactor"], 3.0, 1e-9, "power-law prefactor")
    check(metrics.fit_power_law([1], [1]) is None, "a fit needs two points")

    # a 1 degree spot straight down from (0, 3, 0) into [-1, 1]^3: every ray
    # crosses y = 1 and y = -1 inside the box, chord l = 2 / cos t; with
    # sigma_t = 0 the integral is 4 pi I ln(1 / cos t_max)
    I, th = 7.0, math.radians(1.0)
    e0 = metrics.spot_energy_analytic((0, 3, 0), (0, -1, 0), 1.0, I, 0.0, (-1, -1, -1), (1, 1, 1), m=400)
    close(e0, 4 * math.pi * I * math.log(1 / math.cos(th)), 1e-6, "cone energy, sigma_t = 0")
    st = 0.8
    mu = 1 - (np.arange(200000) + 0.5) / 200000 * (1 - math.cos(th))
    ell = 2 / mu
    omega = 2 * math.pi * (1 - math.cos(th))
    want = I * omega * float(np.mean(-np.expm1(-st * ell) / st))
    e1 = metrics.spot_energy_analytic((0, 3, 0), (0, -1, 0), 1.0, I, st, (-1, -1, -1), (1, 1, 1), m=400)
    close(e1, want, 1e-6, "cone energy, sigma_t = 0.8")
    ch = metrics.box_chords((0, 3, 0), np.array([[0.0, -1, 0], [1.0, 0, 0], [0.0, 1, 0]]), (-1, -1, -1),
                            (1, 1, 1))
    check(np.allclose(ch, [2, 0, 0]), f"box chords {ch}")

    dims, lo3, hi3, voxel = metrics.dims_from_meta({"grid_bounds": "[[0,0,0],[2,1,0.5]]",
                                                    "grid_resolution": 8})
    check(dims == [8, 4, 2] and voxel == 0.25, f"dims from metadata {dims} {voxel}")

    table = ("baked a -> b\nphotons: 122000 traced, 1 missed the grid, 2 left it, 3 absorbed, "
             "4 stopped at the step limit\nstage                              ms  \n"
             "scene load                        0.1  1 objects, 1 lights\n"
             "photon marching                 738.4  3.7 M photon-steps/s (40 M Euler-equivalent)\n"
             "write                           691.4  \n"
             "total                          1650.4\n")
    rows = runner.parse_timings(table)
    check([r[0] for r in rows] == ["scene load", "photon marching", "write", "total"], f"timing rows {rows}")
    check(rows[1][1] == 738.4 and rows[3][1] == 1650.4, f"timing values {rows}")
    ps = runner.parse_photon_summary(table)
    check(ps == {"traced": 122000, "missed_grid": 1, "left_grid": 2, "absorbed": 3, "step_limit": 4},
          f"photon summary {ps}")
    check(runner.parse_ray_steps("36535240 ray-steps, 13.00 M ray-steps/s, 480000 rays") == 36535240,
          "ray-steps note")


def harness_tests(scripts, baker, tool, out):
    bench = os.path.join(scripts, "bench")
    p = subprocess.run(["/usr/bin/python3", bench, "--tiny", "--out", out, "--baker", baker,
                        "--bench-tool", tool], capture_output=True, text=True)
    sys.stdout.write(p.stdout[-4000:])
    sys.stderr.write(p.stderr[-4000:])
    if not check(p.returncode == 0, f"scripts/bench --tiny exited {p.returncode}"):
        return
    with open(os.path.join(out, "bench.json")) as f:
        res = json.load(f)
    m = res.get("machine", {})
    for k in ("nproc", "cpu_model", "loadavg_start", "loadavg_end"):
        check(m.get(k) is not None, f"machine.{k} missing")

    perf = res.get("perf", {}).get("results", {}).get("sphere", {})
    bake = perf.get("bake") or {}
    check(bake.get("status") == "ok", f"perf bake status {bake.get('status')}: {bake.get('error')}")
    names = [s["name"] for s in bake.get("stages", [])]
    for st in ("voxelize", "photon marching", "write", "total"):
        check(st in names, f"perf bake stage '{st}' missing from {names}")
    for k in ("photons_per_s", "photon_steps_per_s", "ray_steps_per_s"):
        check((perf.get(k) or 0) > 0, f"perf.{k} = {perf.get(k)}")
    check((bake.get("max_rss_mib") or 0) > 0, "perf bake peak memory missing")
    check(bake.get("max_rss_mib", 0) < 2000, f"peak memory of a 32^3 bake {bake.get('max_rss_mib')} MiB: "
          "the measurement is picking up another process")

    sw = res.get("sweep", {})
    runs = sw.get("runs", [])
    check(len(runs) >= 3, f"{len(runs)} sweep runs, expected 3")
    for r in runs:
        for k in ("settings", "label", "status", "time_s", "err_grid", "err_image", "front_grid",
                  "front_image", "max_rss_mib", "load_before"):
            check(k in r, f"sweep run {r.get('label')}: field {k} missing")
        for k in ("resolution", "photons", "integrator", "step", "mode"):
            check(k in r.get("settings", {}), f"sweep run {r.get('label')}: settings.{k} missing")
    ok = [r for r in runs if r["status"] == "ok" and r["err_grid"] is not None and r["err_image"] is not None]
    check(len(ok) >= 2, f"only {len(ok)} sweep runs measured both errors")
    for r in ok:
        check(0 < r["err_grid"] < 10 and math.isfinite(r["err_image"]),
              f"{r['label']}: errors {r['err_grid']} {r['err_image']}")
        check(r.get("radiance_finite") is True, f"{r['label']}: radiance not finite")
    check(any(r.get("front_grid") for r in runs), "no point on the grid Pareto front")
    by = {(r["settings"]["photons"], r["settings"]["mode"]): r for r in ok}
    a, b = by.get((2000, "reference")), by.get((8000, "reference"))
    if check(a and b, "the 2000- and 8000-photon reference-mode runs must both succeed"):
        check(b["err_grid"] < a["err_grid"], f"4x the photons must lower the radiance error: "
              f"{a['err_grid']} -> {b['err_grid']}")
    check(sw.get("reference", {}).get("status") == "ok", "sweep reference bake failed")
    check("preview" in sw.get("recommendations", {}), "recommendations missing")

    rows = res.get("extremes", {}).get("rows", [])
    check(len(rows) >= 1, "no extremes rows")
    for r in rows:
        check(r.get("status") == "ok" and r.get("radiance_finite") is True,
              f"extremes {r.get('input')}: {r.get('status')} finite {r.get('radiance_finite')}")
        en = r.get("energy") or {}
        if check(en.get("rel_error") is not None, f"extremes {r.get('input')}: no energy check"):
            check(abs(en["rel_error"]) < 0.01, f"extremes {r.get('input')}: deposited energy off by "
                  f"{en['rel_error'] * 100:.3f}% from the closed form")
        check(r.get("photon_steps") is not None and (r.get("photon_summary") or {}).get("step_limit") is not None,
              f"extremes {r.get('input')}: photon steps / step-limit count missing")

    sc = res.get("scaling", {})
    for axis in ("photons", "resolution"):
        pts = sc.get(axis, {}).get("points", [])
        check(len(pts) >= 2 and all(q.get("total_s") for q in pts), f"scaling.{axis} points {pts}")
        check(sc.get(axis, {}).get("fit_total") is not None, f"scaling.{axis} fit missing")

    for name in ("pareto.png", "scaling.png"):
        path = os.path.join(out, name)
        if check(os.path.exists(path), f"{name} not written"):
            with open(path, "rb") as f:
                head = f.read(8)
            check(head == b"\x89PNG\r\n\x1a\n" and os.path.getsize(path) > 10000, f"{name} is not a plot")
    check(os.path.exists(os.path.join(out, "bench.md")), "bench.md not written")

    pv = res.get("povray", {})
    if "skipped" in pv:
        print(f"povray section skipped: {pv['skipped']}")
    else:
        povs = pv.get("pov") or []
        check(len(povs) >= 1, "povray section: no POV-Ray run")
        for pov in povs:
            check(pov.get("status") == "ok" and (pov.get("wall_s") or 0) > 0,
                  f"povray run, {pov.get('samples')} samples: {pov.get('status')} {pov.get('error')}")
            for k in ("scene", "single"):
                r = pv.get("baker", {}).get(k) or {}
                check(r.get("status") == "ok" and (r.get("wall_s") or 0) > 0, f"povray baker {k}: {r.get('status')}")
                c = (pov.get("vs_baker") or {}).get(k) or {}
                check((c.get("time_ratio") or 0) > 0 and c.get("mean_ratio") is not None,
                      f"povray baker {k} against {pov.get('samples')} samples: no time ratio or image comparison")
        check(os.path.exists(os.path.join(out, "povray.png")), "povray.png not written")


def pov_tests(scripts, baker, out):
    import shutil
    root = os.path.dirname(scripts)
    gen = os.path.join(scripts, "pov", "scene2pov.py")
    scene = os.path.join(root, "scenes", "sphere.json")
    p = subprocess.run([sys.executable, gen, scene], capture_output=True, text=True)
    with open(os.path.join(scripts, "pov", "sphere.pov")) as f:
        check(p.returncode == 0 and p.stdout == f.read(),
              "scripts/pov/sphere.pov differs from scene2pov.py scenes/sphere.json: regenerate it")
    os.makedirs(out, exist_ok=True)
    with open(scene) as f:
        s = json.load(f)
    bad = dict(s, lights=[{"type": "directional", "direction": [0, -1, 0], "irradiance": 1}])
    bad_path = os.path.join(out, "bad.json")
    with open(bad_path, "w") as f:
        json.dump(bad, f)
    p = subprocess.run([sys.executable, gen, bad_path], capture_output=True, text=True)
    check(p.returncode == 2 and "lights[0].type" in p.stderr and not p.stdout,
          f"a directional light must be refused naming lights[0].type: {p.returncode} {p.stderr!r}")
    exe = shutil.which("povray")
    if not exe:
        print("SKIP: povray is not installed (scripts/setup.sh --bench); only the generator was checked")
        return 77
    sys.path.insert(0, scripts)
    from bench_lib import povray
    fog = dict(s, objects=[], photons=dict(s["photons"], bounces=0))
    fog_path = os.path.join(out, "fog.json")
    with open(fog_path, "w") as f:
        json.dump(fog, f)
    w, h = 160, 120
    with open(os.path.join(out, "fog.pov"), "w") as f:
        f.write(povray.scene2pov.convert(fog, w, h, 0.01, 50, 0.0, "fog.json"))  # 50: see docs/bench.md
    runs = [[baker, "bake", fog_path, "-o", os.path.join(out, "fog.vdb"), "--force", "-q",
             "--resolution", "64", "--photons", "200000"],
            [baker, "view", os.path.join(out, "fog.vdb"), "--scene", fog_path, "-o",
             os.path.join(out, "fog.exr"), "--png", os.path.join(out, "fog_baker.png"),
             "--resolution", f"{w}x{h}", "-q"]]
    for cmd in runs:
        p = subprocess.run(cmd, capture_output=True, text=True)
        if not check(p.returncode == 0, f"{' '.join(cmd[:2])}: exit {p.returncode} {p.stderr[-500:]}"):
            return 1
    p = subprocess.run(povray.command(exe, "fog.pov", "fog_pov.png", (w, h), os.cpu_count() or 1),
                       cwd=out, capture_output=True, text=True)
    if not check(p.returncode == 0, f"povray: exit {p.returncode} {p.stderr[-500:]}"):
        return 1
    c = povray.compare(os.path.join(out, "fog_baker.png"), os.path.join(out, "fog_pov.png"))
    print(f"fog, single scattering: baker / POV-Ray mean luminance {c.get('mean_ratio')}, "
          f"rel. RMS difference {c.get('rel_rms')}")
    close(c.get("mean_ratio"), 1.0, 0.05, "baker / POV-Ray mean luminance of the lit fog")
    check((c.get("rel_rms") or 1) < 0.15, f"baker / POV-Ray fog pictures differ by {c.get('rel_rms')} RMS")
    return 0


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "metrics":
        metrics_tests(sys.argv[2])
    elif len(sys.argv) == 6 and sys.argv[1] == "harness":
        harness_tests(*sys.argv[2:])
    elif len(sys.argv) == 5 and sys.argv[1] == "pov":
        if pov_tests(*sys.argv[2:]) == 77 and not FAILS:
            return 77
    else:
        print(__doc__)
        return 2
    print(f"{len(FAILS)} failure(s)")
    return 1 if FAILS else 0


if __name__ == "__main__":
    sys.exit(main())
