"""PNG plots of the bench results (matplotlib, no display needed).

pareto(): time vs error, log-log, one panel per error measure (radiance grid,
rendered image); the Pareto front drawn as a line through its points, every
point labelled with its settings, the recommended settings starred.
scaling(): time against photon count and resolution with the least-squares
power law, peak memory against resolution.
"""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)
import matplotlib.ticker  # noqa: E402

_MODE_COLOUR = {"reference": "tab:blue", "adaptive": "tab:orange"}
_INTEG_MARKER = {"euler": "o", "rk4": "s"}


def _place_labels(ax, items, fontsize):
    """Greedy label placement: each label (front points first) takes the
    first of a few offsets around its point whose box overlaps no label
    placed before it, else the least crowded one."""
    fig = ax.figure
    fig.canvas.draw()  # fixes the axis limits, so data -> pixel is final
    scale = fig.dpi / 72.0
    h = fontsize * 1.25 * scale
    placed = []
    for x, y, text, colour in items:
        px, py = ax.transData.transform((x, y))
        w = len(text) * fontsize * 0.55 * scale
        best, best_hits = None, None
        for dx, dy in ((4, 2), (4, -h - 2), (-w - 4, 2), (-w - 4, -h - 2), (4, h + 2), (4, -2 * h - 2),
                       (-w - 4, h + 2), (-w - 4, -2 * h - 2), (-w / 2, h + 4), (-w / 2, -2 * h - 4)):
            box = (px + dx, py + dy, px + dx + w, py + dy + h)
            hits = sum(1 for b in placed if box[0] < b[2] and b[0] < box[2] and box[1] < b[3] and b[1] < box[3])
            if best_hits is None or hits < best_hits:
                best, best_hits = (dx, dy, box), hits
            if hits == 0:
                break
        dx, dy, box = best
        placed.append(box)
        ax.annotate(text, (x, y), xytext=(dx / scale, dy / scale), textcoords="offset points",
                    fontsize=fontsize, color=colour, zorder=4)


def _panel(ax, runs, err_key, front_key, title, recs):
    pts = [r for r in runs if r.get("time_s") and r.get(err_key)]
    for r in pts:
        s = r["settings"]
        on = r.get(front_key)
        ax.scatter(r["time_s"], r[err_key], s=46 if on else 22,
                   c=_MODE_COLOUR.get(s["mode"], "grey"), marker=_INTEG_MARKER.get(s["integrator"], "^"),
                   edgecolors="black" if on else "none", linewidths=1.2, zorder=3)
    front = sorted((r for r in pts if r.get(front_key)), key=lambda r: r["time_s"])
    if front:
        ax.step([r["time_s"] for r in front], [r[err_key] for r in front], where="post",
                color="black", lw=1.0, alpha=0.7, zorder=2, label="Pareto front")
    for name, r in (recs or {}).items():
        if r and r.get(err_key):
            ax.scatter(r["time_s"], r[err_key], marker="*", s=260, facecolors="none",
                       edgecolors="crimson", linewidths=1.3, zorder=5)
            ax.annotate(name, (r["time_s"], r[err_key]), fontsize=8, color="crimson",
                        xytext=(-6, -13), textcoords="offset points", zorder=5)
    ax.set_xscale("log")
    ax.set_yscale("log")
    # log axes spanning less than a decade show no numbers: label the minor ticks too
    ax.yaxis.set_minor_locator(matplotlib.ticker.LogLocator(subs=(2, 3, 5)))
    ax.yaxis.set_minor_formatter(matplotlib.ticker.FormatStrFormatter("%.3g"))
    ax.tick_params(axis="y", which="minor", labelsize=7)
    ordered = sorted(pts, key=lambda r: not r.get(front_key))
    _place_labels(ax, [(r["time_s"], r[err_key], r["label"], "black" if r.get(front_key) else "dimgray")
                       for r in ordered], 5.5)
    ax.set_xlabel("bake time (s, baker's total)")
    ax.set_ylabel("relative L2 error" if "grid" in err_key else "relative RMS error")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.25)


def pareto(sweep, path, machine_line):
    runs = sweep["runs"]
    recs_by_name = {}
    for name, rec in (sweep.get("recommendations") or {}).items():
        if rec and rec.get("label"):
            recs_by_name[name] = next((r for r in runs if r["label"] == rec["label"]), None)
    fig, axes = plt.subplots(1, 2, figsize=(14, 6.2))
    _panel(axes[0], runs, "err_grid", "front_grid",
           "radiance grid vs reference (trilinear onto the reference grid)", recs_by_name)
    _panel(axes[1], runs, "err_image", "front_image",
           "rendered image vs reference render (same camera)", recs_by_name)
    handles = [plt.Line2D([], [], ls="", marker=_INTEG_MARKER[i], color=_MODE_COLOUR[m],
                          label=f"{m}, {i}") for m in _MODE_COLOUR for i in _INTEG_MARKER]
    handles.append(plt.Line2D([], [], color="black", label="Pareto front (black edge)"))
    axes[0].legend(handles=handles, fontsize=7, loc="lower left")
    ref = sweep["reference"]["settings"]
    fig.suptitle(f"{sweep['scene_name']}: speed/accuracy trade. Labels: resolution, photons, "
                 f"E(uler)/R(K4)+step (voxels), ad = adaptive.  Reference: {ref['resolution']}^3, "
                 f"{ref['photons']} photons, {ref['integrator']} step {ref['step']:g}\n{machine_line}",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def _fit_line(ax, fit, xs, style, label):
    if not fit:
        return
    lo, hi = min(xs), max(xs)
    x = [lo, hi]
    ax.plot(x, [fit["prefactor"] * v ** fit["exponent"] for v in x], style, lw=1,
            label=f"{label}: exponent {fit['exponent']:.2f}")


def _time_panel(ax, block, xkey, upper_fit, upper_label, xlabel, title):
    """Total and march time against xkey, log-log, with the fitted power laws."""
    pts = [p for p in block.get("points", []) if p.get("total_s")]
    if pts:
        xs = [p[xkey] for p in pts]
        ax.loglog(xs, [p["total_s"] for p in pts], "o", color="tab:blue", label="total")
        ax.loglog(xs, [p["march_s"] for p in pts if p.get("march_s")], "s", color="tab:orange",
                  label="photon marching")
        _fit_line(ax, block.get("fit_total"), xs, "--", "total fit")
        _fit_line(ax, block.get("fit_march"), xs, ":", "march fit")
        _fit_line(ax, block.get(upper_fit), xs[len(xs) // 2:], "-", upper_label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("time (s)")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.25)


def scaling(sc, path, machine_line):
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    ph = sc.get("photons") or {}
    _time_panel(axes[0], ph, "photons", "fit_march_upper", "march fit, larger half", "photons",
                f"time vs photons at {ph.get('resolution', '?')}^3")
    rs = sc.get("resolution") or {}
    _time_panel(axes[1], rs, "resolution", "fit_total_upper", "total fit, larger half",
                "resolution (voxels per side)",
                f"time vs resolution, {rs.get('photons', '?')} photons")

    ax = axes[2]
    pts = [p for p in rs.get("points", []) if p.get("max_rss_mib")]
    if pts:
        xs = [p["resolution"] for p in pts]
        ax.loglog(xs, [p["max_rss_mib"] for p in pts], "o", color="tab:green", label="peak RSS")
        _fit_line(ax, rs.get("fit_rss"), xs, "--", "fit")
        _fit_line(ax, rs.get("fit_rss_upper"), xs[len(xs) // 2:], "-", "fit, larger half")
    ax.set_xlabel("resolution (voxels per side)")
    ax.set_ylabel("peak memory of baker (MiB)")
    ax.set_title("peak memory vs resolution", fontsize=10)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.25)
    fig.suptitle(machine_line, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
