"""`python -m host_emulator demo` (`make demo`): the urban_drive scenario through the firmware on
CPython, and a short table of how well it navigated, for someone new to the project.

Same as `python -m host_emulator run --scenario urban_drive --out out/demo`.
"""

from host_emulator.eval import board_cost, board_time, scenario_run
from host_emulator.eval.report import fmt, gc_verdict


def summary(m, out_dir):
    """A table a newcomer understands, from a metrics dict."""
    if "scenario" not in m:  # a stimulus without truth
        return (
            f"\n{m['frames']} frames, {m['frame_errors']} frame errors; navigating after "
            f"{fmt(m['align_time_s'], 1, 's')}. No truth: accuracy not evaluated.\n"
            f"Output in {out_dir}/ (frames.bin, metrics.json)"
        )
    att = "/".join("n/a" if m[k] is None else f"{m[k]:.2f}" for k in
                   ("roll_rms_deg", "pitch_rms_deg", "yaw_rms_deg"))  # fmt: skip
    rows = [
        ("", "firmware", "GNSS alone", "board spec"),
        ("horizontal error with GNSS (RMS)", fmt(m.get("horiz_rms_gnss_m"), unit="m"),
         fmt(m["gnss_horiz_rms_m"], unit="m"), "3 m"),
        ("horizontal error, whole run (RMS)", fmt(m["horiz_rms_m"], unit="m"), "", ""),
        ("vertical position error (RMS)", fmt(m["vert_rms_m"], unit="m"), "", ""),
        ("velocity error (RMS)", fmt(m["vel_rms_m_s"], 3, "m/s"), "", "0.05 m/s"),
        ("roll / pitch / yaw error (RMS)", att + " deg", "", "0.5/0.5/3 deg"),
    ]  # fmt: skip
    w = [max(len(r[i]) for r in rows) for i in range(4)]
    if m.get("source") == "recording":  # a replay: no simulation; a seed only for added noise
        noise = m.get("gnss_noise_m")
        added = f", GNSS noise {noise:g} m (seed {m['seed']})" if noise else ""
        what = f"recording {m['dataset']}: {m['duration_s']:.1f} s{added}"
    else:
        what = f"{m['scenario']}: {m['duration_s']:g} s simulated drive (seed {m['seed']})"
    lines = ["", f"{what}, firmware on {m['runtime']}", ""]
    if m.get("source") != "recording":
        lines[-1:-1] = [
            "GNSS errors as a real receiver's: half of their variance correlated over 60 s,",
            "which the filter follows (white errors it averages out: docs/navigation.md)",
        ]
    lines += ["  ".join(c.ljust(w[i]) for i, c in enumerate(r)).rstrip() for r in rows]
    lines.append("")
    if m["align_time_s"] is None:
        lines.append("navigating after       never: no heading without motion (no magnetometer)")
    else:
        lines.append(f"navigating after       {m['align_time_s']:.1f} s from power-on")
    if m.get("pos_3sigma_coverage") is not None:
        nees = m.get("pos_nees_h")
        lines.append(f"position inside 3-sigma {100 * m['pos_3sigma_coverage']:.1f} % of the time")
        if nees is not None:
            lines.append(f"position NEES          {nees:.2f} (1 when the reported sigma is right)")
    for o in m["outages"]:
        lines.append(
            f"GNSS outage            {o['length_s']:g} s at {o['start_s']:g} s: "
            f"{fmt(o['horiz_err_end_m'], unit='m')} off at its end"
        )
    if m.get("faults"):
        lines.append(f"faults injected        {', '.join(m['faults'])}")
    lines.append(
        f"run speed              {m['ticks']} ticks of 5 ms in {m['wall_s']:.1f} s: "
        f"{m['realtime_factor']:.{0 if m['realtime_factor'] >= 10 else 2}f}x real time"
    )
    if m.get("gc_blocks_per_tick_mean") is not None:
        mean, mx = m["gc_blocks_per_tick_mean"], m["gc_blocks_per_tick_max"]
        lines.append(f"GC blocks per tick     mean {mean:.4g}, max {mx}")
        for state, b in (m.get("gc_blocks_by_state") or {}).items():
            lines.append(f"  {state:<20} mean {b['mean']:.4g}, max {b['max']}")
        verdict = gc_verdict(m)
        if verdict:
            lines.append(f"  {verdict}")
    if m.get("board_cost"):
        lines.append("board CPU cost         (emulated Cortex-M4F, firmware instructions per tick)")
        lines += [f"  {t}" for t in board_cost.lines(m["board_cost"])]
    if m.get("board_time"):
        lines.append("board time per tick    (the image on the emulated STM32F411)")
        lines += [f"  {t}" for t in board_time.lines(m["board_time"], m.get("board_run"))]
    lines.append(f"frames                 {m['frames']} sent, {m['frame_errors']} errors")
    lines.append("")
    # two lines: one would not fit an 80-column terminal
    lines.append(f"report: {out_dir}/report.md   metrics: {out_dir}/metrics.json")
    lines.append(f"plots: {out_dir}/*.png")
    return "\n".join(lines)


def main(out_dir="out/demo"):
    m = scenario_run.run("urban_drive", None, 0, "cpython", out_dir)
    print(summary(m, out_dir))
    return 0
