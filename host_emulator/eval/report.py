"""Plots (PNG) and report.md of one emulator run.

    trajectory.png  truth, the firmware's track and the GNSS fixes; outages in red, and the
                    end of each of the first three zoomed beside it
    errors.png      position and velocity errors (E, N, U) with the reported 3-sigma
    attitude.png    roll, pitch, yaw errors with 3-sigma, and yaw (unwrapped) against truth;
                    without an attitude reference (a real drive) the 3-sigma alone, said so
    biases.png      gyro and accel bias estimates with 3-sigma against the simulated biases
GNSS outages are shaded in every time plot. Panels are scaled to what follows the start-up
(settled_from): the errors and the typical 3-sigma (error_limit), the settled biases; the
start-up, whose sigma is up to hundreds of times larger, is shaded grey and clipped.
"""

import numpy as np

from host_emulator.eval import board_cost, board_time

_DEG = 180.0 / np.pi
PLOTS = ("trajectory.png", "errors.png", "attitude.png", "biases.png")


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _shade(ax, outages, t_end):
    for i, (start, length) in enumerate(outages):
        if start < t_end:
            ax.axvspan(
                start,
                min(start + length, t_end),
                color="tab:red",
                alpha=0.12,
                lw=0,
                label="GNSS outage" if i == 0 else None,
            )


def settled_from(s, factor=2.0):
    """Index of the first row after the start-up: where every column of the sigma s (N, k)
    is within `factor` of its median over the run's second half (0 if none is)."""
    s = np.abs(np.asarray(s, float))
    if not len(s):  # a run too short to navigate: nothing drawn, nothing to settle
        return 0
    s = s.reshape(len(s), -1)
    with np.errstate(invalid="ignore", divide="ignore"):
        ref = np.nanmedian(s[len(s) // 2 :], axis=0)
        ratio = np.nanmax(np.where(ref > 0, s / ref, 1.0), axis=1)
    ok = np.flatnonzero(ratio <= factor)
    return int(ok[0]) if ok.size else 0


def error_limit(e, s):
    """The y half-range of an error panel: from the errors and the typical 3-sigma of each
    axis after the start-up (settled_from), not from the start-up's sigma (+-30 deg of
    heading, 100x the settled velocity sigma) nor its errors; what is larger is clipped."""
    k = settled_from(s)
    e = np.abs(np.asarray(e, float))[k:]
    s3 = 3 * np.abs(np.asarray(s, float))[k:]
    fin_e = e[np.isfinite(e)]
    lim = np.percentile(fin_e, 99.5) if fin_e.size else 0.0
    q = 50 if fin_e.size else 99  # without errors the panel is the sigma's: show it whole
    for col in s3.reshape(len(s3), -1).T:
        if np.isfinite(col).any():
            lim = max(lim, float(np.nanpercentile(col, q)))
    return 1.2 * lim if lim > 0 else 1.0


def _bands(s, names):
    """[(column, label)] of the 3-sigma bands to draw: a column equal to an earlier one
    (roll and pitch share the tilt sigma) is drawn once, under both names."""
    out = []
    for j, name in enumerate(names):
        same = [i for i, (c, _) in enumerate(out) if np.array_equal(s[:, c], s[:, j])]
        if same:
            c, label = out[same[0]]
            out[same[0]] = (c, label.replace(" 3-sigma", f"/{name} 3-sigma"))
        else:
            out.append((j, f"{name} 3-sigma"))
    return out


def mark_startup(ax, t, k):
    """Grey span over the start-up (rows before k), whose values run off the panel."""
    if 0 < k < len(t):
        ax.axvspan(t[0], t[k], color="0.5", alpha=0.15, lw=0, label="start-up (off scale)")


def _err_panel(ax, t, e, s, label, unit, outages, t_end, colors=("C0", "C1", "C2")):
    """Errors drawn where they exist (a recording may have no attitude reference) over their
    3-sigma bands clipped to the panel; the legend names only what is drawn."""
    lim = error_limit(e, s) if len(t) else 1.0
    for j, name in enumerate(label):
        if np.isfinite(e[:, j]).any():
            ax.plot(t, e[:, j], color=colors[j], lw=0.8, label=f"{name} error")
    for j, band in _bands(s, label):  # light bands: the errors stay readable over them
        b = np.minimum(3 * s[:, j], lim)
        ax.fill_between(t, -b, b, color=colors[j], alpha=0.08, lw=0, label=band)
    if len(t) and np.nanmax(3 * s) > lim:
        mark_startup(ax, t, settled_from(s))
    _shade(ax, outages, t_end)
    ax.set_ylim(-lim, lim)
    ax.set_ylabel(unit)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=7, ncol=4)


def yaw_for_plot(truth_t, truth_yaw, t, yaw):
    """Truth yaw unwrapped (no jump at +-180 deg) and the firmware's yaw drawn next to it
    (truth at its time plus the wrapped difference), rad; without a truth yaw (NaN: a
    recording), the firmware's own yaw unwrapped, and None for the truth."""
    yaw = np.asarray(yaw, float)
    ty = np.asarray(truth_yaw, float)
    ok = np.isfinite(ty)
    if not ok.any():
        return None, np.unwrap(yaw) if yaw.size else yaw
    tu = np.unwrap(ty[ok])
    at = np.interp(t, np.asarray(truth_t, float)[ok], tu)
    d = (yaw - at + np.pi) % (2 * np.pi) - np.pi
    full = np.full(ty.shape, np.nan)
    full[ok] = tu
    return full, at + d


def _zooms(truth, tr, nav, outages, max_zooms=3):
    """[(start, length, window)] of the first outages the firmware navigated through: the
    window (x0, x1, y0, y1) is centred on the truth at the outage's end, wide enough for the
    error there and the last 10 s of the outage (a long drive hides a few metres of drift)."""
    out = []
    for start, length in outages:
        end = start + length
        i_t = int(np.searchsorted(truth.t_s, end))
        sel_f = nav & (tr.t_s >= start) & (tr.t_s <= end + 10.0)
        if i_t >= len(truth.t_s) or not sel_f.any():
            continue
        j = int(np.flatnonzero(sel_f)[np.argmin(np.abs(tr.t_s[sel_f] - end))])
        c = truth.p_n[i_t, :2]
        err = float(np.hypot(*(tr.p_n[j, :2] - c)))
        last = (truth.t_s >= end - 10.0) & (truth.t_s <= end)
        span = float(np.max(np.hypot(*(truth.p_n[last, :2] - c).T))) if last.any() else 0.0
        h = max(5.0, 1.5 * err, 0.5 * span)
        out.append((start, length, (c[0] - h, c[0] + h, c[1] - h, c[1] + h)))
        if len(out) == max_zooms:
            break
    return out


def _zoom_panel(ax, truth, tr, nav, start, length, window):
    x0, x1, y0, y1 = window
    sel_t = (truth.t_s >= start - 20.0) & (truth.t_s <= start + length + 20.0)
    sel_f = nav & (tr.t_s >= start - 20.0) & (tr.t_s <= start + length + 20.0)
    ax.plot(truth.p_n[sel_t, 0], truth.p_n[sel_t, 1], color="k", lw=1.0)
    out = (truth.t_s >= start) & (truth.t_s < start + length)
    ax.plot(truth.p_n[out, 0], truth.p_n[out, 1], color="tab:red", lw=3, alpha=0.5)
    ax.plot(tr.p_n[sel_f, 0], tr.p_n[sel_f, 1], color="C0", lw=0.9)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="box")
    ax.set_title(f"end of the {length:g} s outage at {start:g} s", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)


def plots(out_dir, title, tr, err, truth, outages, gnss_fixes=None, bias_truth=None,
          progress=None):  # fmt: skip
    """Write the PNGs of PLOTS into out_dir. truth: object with t_s, p_n, ypr (truth frame;
    ypr NaN where there is no truth attitude); gnss_fixes: (K, 3) valid fix positions in the
    truth frame (optional); bias_truth: (t_s, bg (N, 3) rad/s, ba (N, 3) m/s^2) or None;
    progress(k, n): k of the n PLOTS written (seconds each). Returns what was drawn:
    {"insets", "attitude_ylim", "truth_yaw"}."""
    done = _counter(progress or (lambda _k, _n: None), len(PLOTS))
    plt = pyplot()
    t_end = float(truth.t_s[-1])
    nav = tr.state == 2
    fig, insets = trajectory_figure(plt, title, tr, truth, nav, outages, gnss_fixes)
    save_figure(plt, fig, out_dir / "trajectory.png")
    done()
    save_figure(plt, errors_figure(plt, title, err, outages, t_end), out_dir / "errors.png")
    done()
    fig = attitude_figure(plt, title, tr, err, truth, nav, outages, t_end)
    truth_yaw = any(ln.get_label() == "truth yaw" for ln in fig.axes[1].lines)
    info = {"insets": insets, "attitude_ylim": fig.axes[0].get_ylim(), "truth_yaw": truth_yaw}
    save_figure(plt, fig, out_dir / "attitude.png")
    done()
    fig = biases_figure(plt, title, tr, nav, bias_truth, outages, t_end)
    save_figure(plt, fig, out_dir / "biases.png")
    done()
    return info


def save_figure(plt, fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _counter(progress, n):
    """done(): one more of n steps, told to progress(k, n); progress(0, n) at once."""
    k = [0]
    progress(0, n)

    def done():
        k[0] += 1
        progress(k[0], n)

    return done


def trajectory_figure(plt, title, tr, truth, nav, outages, gnss_fixes):
    """trajectory.png's figure and the number of zoomed insets drawn."""
    zooms = _zooms(truth, tr, nav, list(outages))
    if zooms:  # the drive on the left, the end of each outage zoomed on the right
        fig = plt.figure(figsize=(11, 7))
        gs = fig.add_gridspec(len(zooms), 2, width_ratios=(2.2, 1.0))
        ax = fig.add_subplot(gs[:, 0])
        for i, z in enumerate(zooms):
            _zoom_panel(fig.add_subplot(gs[i, 1]), truth, tr, nav, *z)
    else:
        fig, ax = plt.subplots(figsize=(8, 7))
    ax.plot(truth.p_n[:, 0], truth.p_n[:, 1], color="k", lw=1.0, label="truth")
    if gnss_fixes is not None and len(gnss_fixes):
        ax.plot(gnss_fixes[:, 0], gnss_fixes[:, 1], ".", ms=2, color="C2", label="GNSS fixes")
    ax.plot(tr.p_n[nav, 0], tr.p_n[nav, 1], color="C0", lw=0.9, label="firmware (navigating)")
    for i, (start, length) in enumerate(outages):
        sel = (truth.t_s >= start) & (truth.t_s < start + length)
        if sel.any():
            ax.plot(
                truth.p_n[sel, 0],
                truth.p_n[sel, 1],
                color="tab:red",
                lw=3,
                alpha=0.5,
                label="GNSS outage" if i == 0 else None,
            )
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("East, m")
    ax.set_ylabel("North, m")
    ax.set_title(f"{title}: trajectory")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig, len(zooms)


def errors_figure(plt, title, err, outages, t_end):
    """errors.png's figure: position and velocity errors (E, N, U) with the reported 3-sigma."""
    t = err.t_s
    fig, axs = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    _err_panel(axs[0], t, err.dp, err.sigma[:, 0:3], "ENU", "position, m", outages, t_end)
    _err_panel(axs[1], t, err.dv, err.sigma[:, 3:6], "ENU", "velocity, m/s", outages, t_end)
    axs[0].set_title(f"{title}: errors (bands: the reported 3-sigma)")
    axs[1].set_xlabel("time, s")
    return fig


def attitude_figure(plt, title, tr, err, truth, nav, outages, t_end):
    """attitude.png's figure: attitude errors with 3-sigma above, yaw below."""
    t = err.t_s
    fig, axs = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    tilt = np.sqrt(0.5 * (err.sigma[:, 6] ** 2 + err.sigma[:, 7] ** 2))
    s_att = np.stack([err.sigma[:, 8], tilt, tilt], axis=-1) * _DEG
    _err_panel(axs[0], t, err.da * _DEG, s_att, ("yaw", "pitch", "roll"), "deg", outages, t_end)
    if not np.isfinite(err.da).any():
        axs[0].text(
            0.01,
            0.04,
            "no attitude reference: only the reported 3-sigma is drawn",
            transform=axs[0].transAxes,
            fontsize=8,
            bbox={"fc": "w", "ec": "0.7"},
        )
    nav_t = tr.t_s[nav]
    truth_yaw, fw_yaw = yaw_for_plot(truth.t_s, truth.ypr[:, 0], nav_t, tr.ypr[nav, 0])
    if truth_yaw is not None:
        axs[1].plot(truth.t_s, truth_yaw * _DEG, color="k", lw=1.0, label="truth yaw")
    axs[1].plot(nav_t, fw_yaw * _DEG, color="C0", lw=0.8, label="firmware yaw")
    _shade(axs[1], outages, t_end)
    axs[1].set_ylabel("yaw, deg (CCW from north, unwrapped)")
    axs[1].set_xlabel("time, s")
    axs[1].grid(alpha=0.3)
    axs[1].legend(fontsize=7)
    axs[0].set_title(f"{title}: attitude errors (bands: 3-sigma; tilt sigma for roll/pitch)")
    return fig


def biases_figure(plt, title, tr, nav, bias_truth, outages, t_end):
    """biases.png's figure: gyro and accel bias estimates with 3-sigma, and the simulated biases."""
    fig, axs = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    g_scale = _DEG * 3600.0  # rad/s -> deg/h
    a_scale = 1000.0 / 9.80665  # m/s^2 -> mg
    t = tr.t_s[nav]
    for ax, est, idx, scale, unit, key in (
        (axs[0], tr.bg, 9, g_scale, "gyro bias, deg/h", 1),
        (axs[1], tr.ba, 12, a_scale, "accel bias, mg", 2),
    ):
        sim = None if bias_truth is None else (bias_truth[0], bias_truth[key] * scale)
        _bias_panel(ax, t, est[nav] * scale, tr.sigma[nav, idx : idx + 3] * scale, sim)
        _shade(ax, outages, t_end)
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=3)
    axs[0].set_title(f"{title}: bias estimates (band: 3-sigma)")
    axs[1].set_xlabel("time, s")
    return fig


def _bias_panel(ax, t, est, sig, sim):
    """Estimates (N, 3) with 3-sigma bands, and the simulated biases sim (t, (K, 3)) or None.
    The y-range is the settled part's (settled_from): the start-up transient, hundreds of
    times the settled sigma, is marked and clipped instead of flattening the estimates."""
    k = settled_from(sig, factor=4.0)  # a bias sigma keeps shrinking slowly long after
    lo, hi = _settled_range(est[k:], sig[k:], sim)
    for j, name in enumerate("xyz"):
        c = f"C{j}"
        ax.plot(t, est[:, j], color=c, lw=0.9, label=f"{name} estimate")
        ax.fill_between(
            t,
            np.clip(est[:, j] - 3 * sig[:, j], lo, hi),
            np.clip(est[:, j] + 3 * sig[:, j], lo, hi),
            color=c,
            alpha=0.1,
            lw=0,
        )
        if sim is not None:
            ax.plot(sim[0], sim[1][:, j], color=c, ls=":", lw=1.0, label=f"{name} simulated")
    if len(t) and (np.nanmax(est + 3 * sig) > hi or np.nanmin(est - 3 * sig) < lo):
        mark_startup(ax, t, k)
    ax.set_ylim(lo, hi)


def _settled_range(est, sig, sim):
    """(lo, hi) holding the settled estimates, their 3-sigma and the simulated biases."""
    parts = [est - 3 * sig, est + 3 * sig] + ([] if sim is None else [sim[1]])
    vals = np.concatenate([np.ravel(p) for p in parts])
    vals = vals[np.isfinite(vals)]
    if not vals.size:
        return -1.0, 1.0
    lo, hi = float(vals.min()), float(vals.max())
    pad = 0.1 * (hi - lo) or 1.0
    return lo - pad, hi + pad


def fmt(x, digits=2, unit=""):
    """x with `digits` decimals and its unit, or n/a for None."""
    if x is None:
        return "n/a"
    text = f"{x:.{digits}f}" if isinstance(x, float) else str(x)
    return f"{text} {unit}" if unit else text


def screen_section(m):
    """report.md's lines on the board's screen (a run with --display), else none."""
    if m.get("display_bytes") is None:
        return []
    return [
        "## The board's screen",
        "",
        "![the status page at the end of the run](screen.png)",
        "",
        f"The status page at the end of the run (docs/display.md): {m['display_bytes']} "
        f"bytes to the screen, {m['display_bytes_per_s']:.0f} bytes/s.",
        "",
    ]


def markdown(m, description="", console=(), notes=()):
    """report.md text from the metrics dict."""
    lines = _title_lines(m, description)
    lines += _figures_table(m)
    lines += screen_section(m)
    lines += _outage_table(m)
    lines += _run_lines(m)
    lines += _gc_lines(m)
    lines += _board_lines(m)
    lines += [f"- {n}" for n in notes]
    lines += ["", "## Plots", ""]
    for p in PLOTS:
        lines.append(f"![{p[:-4]}]({p})")
        lines.append("")
    if console:
        lines += ["## Firmware console", "", "```", *console, "```", ""]
    return "\n".join(lines)


def _title_lines(m, description):
    """report.md's title, the description, and a note if the run never navigated."""
    lines = [
        f"# Emulator run: {m['scenario']} ({m['duration_s']:g} s, seed {m['seed']}, "
        f"{m['runtime']})",
        "",
    ]
    if description:
        lines += [description, ""]
    if m.get("align_time_s") is None:
        lines += [
            "**The navigator never reached the navigating state in this run**, so there is no "
            "navigation phase to score. That is expected while the board does not move: it "
            "levels itself at rest but has no magnetometer, and takes its heading from the "
            "GNSS course once moving faster than the heading threshold.",
            "",
        ]
    return lines


def _figures_table(m):
    """report.md's paragraph on what ran and its table of errors against the truth."""
    return [
        "The unmodified firmware loop ran on an emulated board (BMI055 registers over SPI, NMEA "
        "bytes on the GNSS UART at the receiver's baud rate, PPS interrupt, 5 ms timer on a "
        "virtual clock). Errors are those of its output frames against the simulation's truth, "
        "over the navigation phase (from the first navigating frame), at 10 Hz. The board "
        "spec is the specification of the WMH601, the original board this firmware ports "
        "(docs/requirements.md).",
        "",
        "| figure | value | reference |",
        "|---|---|---|",
        f"| horizontal position RMS | {fmt(m['horiz_rms_m'], unit='m')} | board spec 3 m |",
        f"| ... with GNSS available | {fmt(m.get('horiz_rms_gnss_m'), unit='m')} | "
        f"raw GNSS input {fmt(m['gnss_horiz_rms_m'], unit='m')} |",
        f"| vertical position RMS | {fmt(m['vert_rms_m'], unit='m')} | |",
        f"| velocity RMS (3D) | {fmt(m['vel_rms_m_s'], 3, unit='m/s')} | board spec 0.05 m/s |",
        f"| roll / pitch RMS | {fmt(m['roll_rms_deg'])} / "
        f"{fmt(m['pitch_rms_deg'], unit='deg')} | board spec 0.5 deg |",
        f"| yaw RMS | {fmt(m['yaw_rms_deg'], unit='deg')} | board spec 3 deg |",
        f"| position inside 3-sigma (E, N) | {fmt(m.get('pos_3sigma_coverage'), 3)} | "
        "0.997 if the reported covariance were right |",
        f"| mean (error / sigma)^2, E and N (NEES) | {fmt(m.get('pos_nees_h'))} | "
        "1 when the reported sigma is right, < 1 larger than the errors, > 1 too small |",
        f"| time to navigation | {fmt(m['align_time_s'], 1, unit='s')} | |",
        "",
    ]


def _outage_table(m):
    """report.md's table of the horizontal error at the end of each GNSS outage, if any."""
    lines = []
    if m["outages"]:
        lines += ["| GNSS outage | length | horizontal error at its end |", "|---|---|---|"]
        for o in m["outages"]:
            lines.append(
                f"| from {o['start_s']:g} s | {o['length_s']:g} s | "
                f"{fmt(o['horiz_err_end_m'], unit='m')} |"
            )
        lines += ["", "(Board spec: about 30 m after 20 s without GNSS.)", ""]
    return lines


def _run_lines(m):
    """The first lines of report.md's "The run" section: ticks, wall time, frames, GNSS input."""
    rt = m["realtime_factor"]
    return [
        "## The run",
        "",
        f"- {m['ticks']} ticks in {m['wall_s']:.1f} s of wall time: {rt:.1f}x real time "
        f"({m['runtime']}).",
        f"- Output: {m['frames']} frames, {m['frame_errors']} frame errors "
        "(checksum/CRC failures, undecodable bytes, counter gaps).",
        f"- GNSS input: {m.get('nmea_damaged_sentences', 'n/a')} damaged NMEA sentences sent, "
        f"{m.get('nmea_rejected', 'n/a')} rejected by the firmware's parser; "
        f"{m.get('gnss_rx_overflow', 'n/a')} bytes lost to a full UART ring.",
    ]


def gc_verdict(m):
    """The design's allocation rule (docs/requirements.md: zero allocations once navigating)
    against the navigating ticks' maximum; None when the run never navigated or was not
    counted. A mean over every tick says nothing about it: the aligning ticks that screen a
    fix allocate by design."""
    nav = (m.get("gc_blocks_by_state") or {}).get("navigating")
    if nav is None:
        return None
    if nav["max"] == 0:
        return "design: no allocation once navigating: met"
    return f"design: no allocation once navigating: NOT met (max {nav['max']} blocks)"


def _gc_lines(m):
    """The run's GC blocks per tick (MicroPython VM), overall and per state; else none."""
    lines = []
    if m.get("gc_blocks_per_tick_mean") is not None:
        lines.append(
            f"- GC blocks allocated per tick (MicroPython VM): mean "
            f"{m['gc_blocks_per_tick_mean']:.4g}, max {m['gc_blocks_per_tick_max']}."
        )
        verdict = gc_verdict(m)
        if verdict:
            lines.append(f"  ({verdict[0].upper() + verdict[1:]}.)")
        for state, b in (m.get("gc_blocks_by_state") or {}).items():
            lines.append(
                f"  - {state}: {b['ticks']} ticks, min {b['min']}, mean {b['mean']:.4g}, "
                f"p99 {b['p99']:.0f}, max {b['max']}"
            )
    return lines


def _board_lines(m):
    """The run's cost and time per tick on the emulated board, where measured; else none."""
    lines = []
    if m.get("board_cost"):
        lines.append(
            "- Cost on the board's CPU (emulated Cortex-M4F, instructions counted; "
            "docs/benchmarks/board.md says how to read them):"
        )
        lines += [f"  - {t.strip()}" for t in board_cost.lines(m["board_cost"])]
    if m.get("board_time"):
        lines.append(
            "- Time per tick of the image on the emulated STM32F411 (docs/image.md says what "
            "it models):"
        )
        lines += [f"  - {t.strip()}" for t in board_time.lines(m["board_time"],
                                                               m.get("board_run"))]  # fmt: skip
    return lines
