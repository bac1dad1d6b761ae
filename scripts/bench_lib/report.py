"""Markdown tables of a bench result (also what the bench prints at the end).

In: the result dict scripts/bench writes as JSON. Out: one markdown text with
the machine, the per-stage performance table (stages as rows, scenes as
columns, ms), the sweep table with the Pareto fronts and the recommended
settings, the stability report and the scaling fits.
"""
import os


def _f(v, fmt="{:.1f}", none="–"):
    return none if v is None else fmt.format(v)


def _rate(v):
    if v is None:
        return "–"
    return f"{v / 1e6:.2f} M" if v >= 1e5 else f"{v / 1e3:.1f} k"


def _table(header, rows):
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def machine(res):
    m = res["machine"]
    la0, la1 = m.get("loadavg_start"), m.get("loadavg_end")
    lines = [f"Machine: {m.get('nproc')} cores, {m.get('cpu_model', '?')}, {m.get('mem_total_gib', '?')} GiB; "
             f"{m.get('opencl_platform') or m.get('opencl_device') or 'OpenCL ?'}; "
             f"{m.get('baker_version', 'baker ?')} (git {m.get('git_commit') or '?'}).",
             f"Profile `{res['profile']}`, started {res['started']}, took {res.get('elapsed_s', 0) / 60:.1f} min; "
             f"load average (1/5/15 min) {_la(la0)} at the start, {_la(la1)} at the end "
             f"(other processes share the CPU: timings are noisy)."]
    if res.get("sets"):
        lines.append("Every bake with " + ", ".join(f"`--set {kv}`" for kv in res["sets"]) + ".")
    return "\n".join(lines)


def _la(la):
    return "/".join(f"{x:.2f}" for x in la) if la else "?"


def perf(p):
    scenes = p["scenes"]
    res = p["results"]
    st = p["settings"]
    order = []
    for kind in ("bake", "view"):
        for s in scenes:
            rec = res[s].get(kind) or {}
            for row in rec.get("stages") or []:
                key = (kind, row["name"])
                if key not in order:
                    order.append(key)
    # "total" last in each block
    order = [k for k in order if k[1] != "total" and k[0] == "bake"] + [("bake", "total")] + \
            [k for k in order if k[1] != "total" and k[0] == "view"] + [("view", "total")]
    rows = []
    for kind, name in order:
        cells = []
        for s in scenes:
            rec = res[s].get(kind) or {}
            v = next((r["ms"] for r in rec.get("stages") or [] if r["name"] == name), None)
            cells.append(_f(v))
        label = f"**{name}**" if name == "total" else name
        rows.append([("view: " if kind == "view" else "") + label] + cells)
    rows.append(["photons/s (march)"] + [_rate(res[s].get("photons_per_s")) for s in scenes])
    rows.append(["photon-steps/s (march)"] + [_rate(res[s].get("photon_steps_per_s")) for s in scenes])
    rows.append(["ray-steps/s (view march)"] + [_rate(res[s].get("ray_steps_per_s")) for s in scenes])
    rows.append(["peak memory, bake (MiB)"] +
                [_f((res[s].get("bake") or {}).get("max_rss_mib"), "{:.0f}") for s in scenes])
    rows.append(["peak memory, view (MiB)"] +
                [_f((res[s].get("view") or {}).get("max_rss_mib"), "{:.0f}") for s in scenes])
    fails = [f"{s}: {k} {res[s][k]['status']} ({res[s][k].get('error')})" for s in scenes
             for k in ("bake", "view") if res[s].get(k) and res[s][k]["status"] != "ok"]
    head = (f"### Performance per stage (ms)\n\n{st['resolution']}^3 grid, {st['photons']} photons, "
            f"{st['view'][0]}x{st['view'][1]} view; best of {st['repeat']} by total.\n\n")
    return head + _table(["stage (ms)"] + scenes, rows) + ("\n\nFailed: " + "; ".join(fails) if fails else "")


def sweep(sw):
    runs = sorted(sw["runs"], key=lambda r: (r["time_s"] is None, r["time_s"] or 0))
    ref = sw["reference"]
    rows = []
    for r in runs:
        s = r["settings"]
        front = ("G" if r.get("front_grid") else "") + ("I" if r.get("front_image") else "")
        note = r.get("error") or r.get("analysis_error") or ""
        if r["status"] == "ok" and s["mode"] == "adaptive" and not r.get("adaptive_grids"):
            note = "no photon_count grid in the file (adaptive not active?)"
        rows.append([r["label"], s["resolution"], s["photons"], s["integrator"], _f(s["step"], "{:g}"), s["mode"],
                     r["status"], _f(r["time_s"], "{:.2f}"), _f((r.get("march_ms") or None) and r["march_ms"] / 1000, "{:.2f}"),
                     _f(r.get("max_rss_mib"), "{:.0f}"), _f(r["err_grid"], "{:.4f}"), _f(r["err_image"], "{:.4f}"),
                     front, note])
    rs = ref["settings"]
    head = (f"### Trade sweep on {sw['scene_name']}\n\nReference: {rs['resolution']}^3, {rs['photons']} photons, "
            f"{rs['integrator']}, step {rs['step']:g}, {rs['mode']}, seed 7 ({ref['status']}, "
            f"{_f(ref.get('total_ms') and ref['total_ms'] / 1000, '{:.1f}')} s). Runs use seed 1.\n"
            f"Grid error: {sw['metric']['grid']}.\nImage error: {sw['metric']['image']} "
            f"({sw['view'][0]}x{sw['view'][1]}).\nTime: {sw['metric']['time']}.\n"
            f"Front: G = on the radiance-grid Pareto front, I = on the image Pareto front.\n\n")
    tab = _table(["settings", "res", "photons", "integrator", "step", "mode", "status", "bake s", "march s",
                  "peak MiB", "grid err", "image err", "front", "note"], rows)
    rec_rows = []
    for name, rec in (sw.get("recommendations") or {}).items():
        if rec.get("label"):
            rec_rows.append([name, rec["label"], _f(rec["time_s"], "{:.2f}"), _f(rec["err_grid"], "{:.4f}"),
                             _f(rec["err_image"], "{:.4f}"), rec["rule"]])
        else:
            rec_rows.append([name, "none", "–", "–", "–", rec["rule"]])
    return head + tab + "\n\n#### Settings to choose (from the measured front)\n\n" + \
        _table(["quality", "settings", "bake s", "grid err", "image err", "rule"], rec_rows)


def extremes(ex):
    rows = []
    for r in ex["rows"]:
        ps = r.get("photon_summary") or {}
        en = r.get("energy") or {}
        energy = "–"
        if en.get("rel_error") is not None:
            energy = f"{en['rel_error'] * 100:+.3f}% ({en['kind']})"
        rows.append([r["group"], r["input"], f"{r['resolution']}^3", r["photons"],
                     f"{r.get('integrator', '?')} {r.get('step', '?')}", r["status"],
                     _f(r.get("rc"), "{}"), _f(r.get("radiance_finite"), "{}"), _f(r.get("photon_steps"), "{}"),
                     _f(ps.get("step_limit"), "{}"), _f(r.get("total_ms") and r["total_ms"] / 1000, "{:.2f}"),
                     _f(r.get("max_rss_mib"), "{:.0f}"), energy,
                     r.get("error") or r.get("analysis_error") or ""])
    return ("### Stability over the extremes\n\n" + ex["energy_note"] + "\n\n" +
            _table(["group", "input", "grid", "photons", "march", "status", "exit", "finite", "photon-steps",
                    "step-limit", "bake s", "peak MiB", "energy error", "note"], rows))


def _fit(f):
    if not f:
        return "–"
    return f"{f['exponent']:.2f} (R² {f['r2']:.3f}, {f['points']} points)"


def scaling(sc):
    ph, rs = sc["photons"], sc["resolution"]
    rows = [[f"{p['photons']}", _f(p.get("total_s"), "{:.2f}"), _f(p.get("march_s"), "{:.2f}"),
             _f(p.get("max_rss_mib"), "{:.0f}"), p["status"]] for p in ph["points"]]
    out = [f"### Scaling\n\nTime against photon count at {ph['resolution']}^3 ({sc['scene']}):\n",
           _table(["photons", "total s", "march s", "peak MiB", "status"], rows),
           f"\nFitted exponent (time ∝ N^k, least squares on log-log): total {_fit(ph.get('fit_total'))}; "
           f"photon marching {_fit(ph.get('fit_march'))}"
           + (f"; over the larger half of the counts: total {_fit(ph.get('fit_total_upper'))}, "
              f"photon marching {_fit(ph.get('fit_march_upper'))}" if ph.get("fit_total_upper") else "") + ".\n",
           f"Time and peak memory against resolution, {rs['photons']} photons:\n"]
    rows = [[f"{p['resolution']}^3", _f(p.get("total_s"), "{:.2f}"), _f(p.get("march_s"), "{:.2f}"),
             _f(p.get("max_rss_mib"), "{:.0f}"), p["status"] + (f" ({p['error']})" if p.get("error") else "")]
            for p in rs["points"]]
    out.append(_table(["grid", "total s", "march s", "peak MiB", "status"], rows))
    out.append(f"\nFitted exponents against resolution R: total time {_fit(rs.get('fit_total'))}; "
               f"photon marching {_fit(rs.get('fit_march'))}; peak memory {_fit(rs.get('fit_rss'))}"
               + (f"; over the larger half: total time {_fit(rs.get('fit_total_upper'))}, photon marching "
                  f"{_fit(rs.get('fit_march_upper'))}, peak memory {_fit(rs.get('fit_rss_upper'))}"
                  if rs.get("fit_total_upper") else "")
               + (f"; {rs['bytes_per_voxel']:.0f} bytes per voxel between the two largest grids"
                  if rs.get("bytes_per_voxel") else "") + ".")
    return "\n".join(out)


def povray(p):
    if "skipped" in p:
        return f"### Against POV-Ray 3.7 (issue 15)\n\nSkipped: {p['skipped']}."
    st, povs = p["settings"], p["pov"]
    w, h = st["size"]
    head = (f"### Against POV-Ray 3.7 (issue 15)\n\n`{st['scene']}` scene, {w}x{h}. baker: `baker bake` at "
            f"{st['resolution']}^3 with {st['photons']} photons (Euler, step 0.5) + `baker view`, wall time "
            f"of both processes, best of the runs. POV-Ray {st['pov_version']}: the scene from "
            f"scripts/pov/scene2pov.py (photon spacing {st['spacing']:g} m, media photons, media method 3, "
            f"intervals 1, the samples shown), `{povs[0].get('pov_cmd')}`, one run each, wall time of the "
            f"process (CPU s: user + system time of the processes, less sensitive to other users of the "
            f"machine). Pictures: baker view --png against POV-Ray's PNG (both 8-bit sRGB), linear "
            f"luminance, POV-Ray's mirrored back.\n\n")
    labels = {"scene": "baker, the scene's transport (multiple scattering)",
              "single": "baker, single scattering (`--set photons.bounces=0`), as POV-Ray"}
    header = ["run", "bake s", "view s", "total s", "CPU s"]
    for pv in povs:
        header += [f"time / POV-Ray ({pv['samples']} samples)", f"mean luminance / POV-Ray ({pv['samples']})",
                   f"rel. RMS diff. ({pv['samples']})"]
    rows = []
    for key, label in labels.items():
        r = p["baker"].get(key) or {}
        if r.get("status") != "ok":
            rows.append([label, "failed"] + ["–"] * (len(header) - 2))
            continue
        cpu = (r["bake"].get("cpu_s") or 0) + (r["view"].get("cpu_s") or 0)
        row = [label, _f(r["bake"]["wall_s"], "{:.2f}"), _f(r["view"]["wall_s"], "{:.2f}"), _f(r["wall_s"], "{:.2f}"),
               _f(cpu, "{:.2f}")]
        for pv in povs:
            c = (pv.get("vs_baker") or {}).get(key) or {}
            row += [f"1/{1 / c['time_ratio']:.1f}" if c.get("time_ratio") else "–",
                    _f(c.get("mean_ratio"), "{:.3f}"), _f(c.get("rel_rms"), "{:.3f}")]
        rows.append(row)
    for pv in povs:
        pt = pv.get("povray") or {}
        rows.append([f"POV-Ray, media samples {pv['samples']} ({pv['status']}; photons {_f(pt.get('photon_s'), '{:.1f}')} s, "
                     f"trace {_f(pt.get('trace_s'), '{:.1f}')} s; {pt.get('media_photons')} media photons; load "
                     f"{_la(pv.get('load_before'))} before, {_la(pv.get('load_after'))} after)", "", "",
                     _f(pv.get("wall_s"), "{:.1f}"), _f(pv.get("cpu_s"), "{:.1f}")] + [""] * (len(header) - 5))
    return head + _table(header, rows) + "\n\n![baker and POV-Ray](povray.png)"


def markdown(res):
    parts = ["## Benchmark results", machine(res)]
    for sec, fn in (("perf", perf), ("sweep", sweep), ("extremes", extremes), ("scaling", scaling),
                    ("povray", povray)):
        if sec in res:
            parts.append(fn(res[sec]))
    for p in res.get("plots") or []:
        parts.append(f"![{os.path.splitext(os.path.basename(p))[0]}]({os.path.basename(p)})")
    return "\n\n".join(parts) + "\n"
