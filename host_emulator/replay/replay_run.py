"""`python -m host_emulator replay`: a recorded drive through the unmodified firmware.

    dataset (drive_0708, or a KF-GINS directory) -> to_stimulus.convert -> DIR/stimulus.bin
        -> firmware (a runtime, see runtimes/) -> DIR/frames.bin -> errors against the
        recording's reference -> DIR/metrics.json, report.md, *.png, solution.pos

The outputs are those of `run` (scenario_run.py); solution.pos is the firmware's track as an
RTKLIB solution (10 Hz, at the extended frames) for rtkplot users. The console, report.md and
metrics.json ("notes", "board_config") say what the conversion did with the data (epochs
left out, PPS or not, outages after the end) and the board settings the firmware ran with;
a run that never navigated ends in one line saying why (diagnose.py).

Defaults: drive_0708 keeps the protocol its published figures were measured with (1 Hz, 15 s
outages at t0 + 60/200/400 s, scored from t0 + 30 s: to_stimulus.ReplayOptions()); a KF-GINS
dataset, someone's own recording, runs as it is (`kfgins_options`: no outages, scored from
t0).
"""

import json
import pathlib
import time

import numpy as np

from common.errors import EmulatorError
from common.proto import stream
from host_emulator import args as cli_args
from host_emulator import runtimes
from host_emulator.display import pictures
from host_emulator.eval import evaluate, report, scenario_run
from host_emulator.replay import diagnose, to_stimulus
from host_emulator.replay import run_config as board_settings
from host_emulator.sim import faults as faults_mod

OUTPUTS = (*scenario_run.OUTPUTS, "solution.pos")
TICK_S = to_stimulus.TICK_S
# the output is sampled at 10 Hz: a waypoint falls between two samples this far apart at most
TRACK_GAP_S = 0.25

# docs/requirements.md, reference figures: two open filters on drive_0708 under the same protocol (1
# Hz, 1.5/1.5/3 m, 15 s outages at t0 + 60/200/400 s, metrics from t0 + 30 s)
REFERENCE_ROWS = (
    ("raw 1 Hz GNSS input", "2.13 m", "3.17 m", "-"),
    ("KF-GINS (C++, 21 states, tuned noise)", "2.15 m", "1.69 m", "22.3 / 27.5 / 11.5 m"),
    ("rtklibexplorer GNSS_IMU (Python, 15 states)", "2.41 m", "1.73 m", "19.7 / 32.7 / 16.5 m"),
)


def parse_outages(spec):
    """'60+15,200+15' -> ((60.0, 15.0), (200.0, 15.0)); 'none' -> ()."""
    if spec is None:
        return to_stimulus.PROTOCOL_OUTAGES
    if spec.strip().lower() in ("none", ""):
        return ()
    out = []
    for part in spec.split(","):
        try:
            start, length = (float(x) for x in part.split("+"))
        except ValueError:
            raise EmulatorError(
                f"--outages: {part!r} is not START+LENGTH in seconds after t0 "
                "(e.g. 60+15,200+15, or none)"
            ) from None
        if start < 0 or length <= 0:
            raise EmulatorError(f"--outages: {part!r} needs START >= 0 and LENGTH > 0")
        out.append((start, length))
    return tuple(out)


def kfgins_options(dataset=None, **kw):
    """ReplayOptions for a KF-GINS dataset: no outages, scored from t0, a recorded GNSS file
    as it is (no noise added; without one the input is made from the reference with the
    protocol's noise); keyword arguments override."""
    base = {"outages": (), "skip_s": 0.0}
    if dataset is not None and dataset.gnss is not None:
        base["gnss_noise_m"] = None
    return to_stimulus.ReplayOptions(**{**base, **kw})


def load_dataset(dataset=None, kf_gins=None, data_dir=None, gnss_pos=None, truth_pos=None):
    """The Dataset named by the command line: a built-in recording or a KF-GINS directory,
    optionally with its GNSS input or its reference replaced by RTKLIB .pos files."""
    if kf_gins:
        from host_emulator.replay import kfgins

        ds = kfgins.read(kf_gins)
    elif dataset == "drive_0708":
        from host_emulator.replay import drive_0708

        ds = drive_0708.load(data_dir)
    else:
        raise EmulatorError(f"unknown dataset {dataset!r}: known: drive_0708 (or --kf-gins DIR)")
    if gnss_pos or truth_pos:
        from host_emulator.replay import rtklib_pos

        if gnss_pos:
            ds.gnss = rtklib_pos.read(gnss_pos).positions
        if truth_pos:
            ds.truth = rtklib_pos.read(truth_pos).positions
            ds.truth_point = "antenna"
    return ds


def evaluate_replay(rep, fw, runtime):
    """(metrics, track, errors) of a finished firmware run on a Replay."""
    decoded = stream.decode(fw.out)
    o = rep.truth.origin
    tr = evaluate.track(decoded, rep.stimulus.tick_us * 1e-6, (o.lat_e7, o.lon_e7, o.h_m))
    truth = rep.truth
    err = evaluate.errors(tr, truth.t_s, truth.p_n, truth.v_n, truth.ypr, rep.outages,
                          truth.covered)  # fmt: skip
    acc = evaluate.accuracy(err, rep.outages, from_s=rep.window_s)
    g = rep.gnss
    sel = g.valid & (g.t_fix_s >= rep.window_s)
    if truth.covered is not None:  # the fixes too are scored only where the reference is
        k = np.clip(np.rint(g.t_fix_s / TICK_S).astype(int), 0, truth.covered.size - 1)
        sel &= truth.covered[k]
    opt = rep.options
    metrics = {
        "scenario": rep.name,
        "dataset": rep.name,
        "source": "recording",
        "duration_s": float(rep.stimulus.duration_s),
        "seed": int(opt.seed),
        "runtime": runtime,
        "faults": list(rep.stimulus.header.get("faults", [])),
        **scenario_run.firmware_metrics(fw, decoded, tr, acc, rep.stimulus.duration_s),
        "gnss_horiz_rms_m": evaluate.rms(np.hypot(*g.err_n_m[sel, :2].T)) if sel.any() else None,
        "gnss_vert_rms_m": evaluate.rms(g.err_n_m[sel, 2]) if sel.any() else None,
        # the protocol
        "t0_s": rep.t0_s,
        "metrics_from_s": rep.window_s,
        "t_start_gpst": rep.t_start_gpst,
        "gnss_rate_hz": opt.gnss_rate_hz,
        "gnss_noise_m": opt.gnss_noise_m,
        "gnss_velocity_sigma": opt.gnss_velocity_sigma,
        "imu_ranges": rep.ranges,
        "gnss_epochs": int(g.t_fix_s.size),
        "gnss_pps": rep.pps,
        "board_config": rep.stimulus.config,
        "board_config_sources": {
            name: rep.sources.get(name, board_settings.REPLAY) for name in rep.stimulus.config
        },
        "notes": list(rep.notes),
        "reference": reference_metrics(rep, tr),
    }
    return metrics, tr, err


def reference_metrics(rep, tr):
    """What of the run the reference scores ({"kind", "scored_s", "unscored_s", "max_gap_s"})
    and, for a reference true only at waypoints, the horizontal errors there of the output
    and of the raw fixes ("waypoints": evaluate.spread of each)."""
    truth = rep.truth
    win = truth.t_s >= rep.window_s
    covered = truth.covered if truth.covered is not None else np.ones(truth.t_s.size, bool)
    out = {
        "kind": truth.kind,
        "scored_s": float(np.count_nonzero(covered & win) * TICK_S),
        "unscored_s": float(np.count_nonzero(~covered & win) * TICK_S),
        "max_gap_s": truth.max_gap_s,
    }
    if truth.waypoints is not None:
        t_wp, _ = truth.waypoints
        keep = t_wp >= rep.window_s
        wp = (t_wp[keep], truth.waypoints[1][keep])
        nav = tr.state == evaluate.NAVIGATING
        fw = evaluate.waypoint_errors(tr.t_s[nav], tr.p_n[nav, :2], wp, TRACK_GAP_S)
        g = rep.gnss
        fix_t = g.t_fix_s[g.valid]
        fix_gap = to_stimulus.max_gap_s(fix_t) or 0.0  # the reference's rule, for the fixes
        fixes = evaluate.waypoint_errors(fix_t, (g.p_ant_n + g.err_n_m)[g.valid, :2], wp, fix_gap)
        out["waypoints"] = {"n": int(keep.sum()), "firmware": evaluate.spread(fw),
                            "fixes": evaluate.spread(fixes), "fix_gap_s": fix_gap}  # fmt: skip
    return out


def markdown(m, rep, console=()):
    """report.md of a replay: the protocol, the figures, the reference filters' figures."""
    lines = [f"# Replay: {m['dataset']} ({m['duration_s']:g} s, {m['runtime']})", ""]
    lines += _protocol_lines(m, rep)
    lines += _figures_table(m)
    lines += _waypoint_table(m)
    lines += _outage_table(m)
    lines += _reference_table(m, rep.options)
    if m["yaw_rms_deg"] is None:
        lines += ["The reference has no attitude: attitude errors are not scored.", ""]
    lines += [
        "## The run",
        "",
        f"- {m['ticks']} ticks in {m['wall_s']:.1f} s: {m['realtime_factor']:.1f}x real time.",
        f"- Output: {m['frames']} frames, {m['frame_errors']} frame errors; "
        f"{m['nmea_rejected']} NMEA sentences rejected.",
        "",
        "## Plots",
        "",
    ]
    for p in report.PLOTS:
        lines += [f"![{p[:-4]}]({p})", ""]
    lines += report.screen_section(m)
    if console:
        lines += ["## Firmware console", "", "```", *console, "```", ""]
    return "\n".join(lines)


def _protocol_lines(m, rep):
    """report.md's account of what the board was fed: IMU, GNSS, outages, ranges, settings."""
    fmt = report.fmt
    opt = rep.options
    outs = ", ".join(f"t0+{s:g} s for {n:g} s" for s, n in opt.outages) or "none"
    vel = (
        "no velocity (RMC speed and course empty)"
        if opt.gnss_velocity_sigma is None
        else f"velocity with {opt.gnss_velocity_sigma:g} m/s noise per axis"
    )
    noise = "as recorded" if opt.gnss_noise_m is None else (
        f"white noise {opt.gnss_noise_m:g}/{opt.gnss_noise_m:g}/{2 * opt.gnss_noise_m:g} m "
        f"(N/E/D, numpy default_rng({opt.seed}))"
    )  # fmt: skip
    made = (
        ("the recording's GNSS fixes" + (" with added noise" if opt.gnss_noise_m else ""))
        if rep.gnss_recorded
        else "the reference positions degraded into GNSS fixes"
    )
    timing = "with PPS" if rep.pps else f"without PPS (gnss_latency_s {rep.latency_s:.3f} s)"
    rate = f"up to {rep.stimulus.header['gnss_rate_hz']:g} Hz"
    return [
        "The unmodified firmware loop ran on an emulated board fed from the recording: the "
        f"IMU as BMI055 registers at 200 Hz, {made} as NMEA bytes on the GNSS UART {timing}. "
        "Errors are those of its output frames against the recording's reference, at 10 Hz.",
        "",
        f"- GNSS input: {m['gnss_epochs']} epochs at {rate}, {noise}, {vel}; outages: {outs}.",
        f"- t0 (first GNSS epoch) = {m['t0_s']:.1f} s into the run; metrics from "
        f"{m['metrics_from_s']:.1f} s; navigating from {fmt(m['align_time_s'], 1, unit='s')}.",
        f"- IMU ranges: gyro +-{rep.ranges['gyro_range_dps']} deg/s (peak "
        f"{rep.ranges['gyro_peak_dps']:.1f}), accel +-{rep.ranges['accel_range_g']} g (peak "
        f"{rep.ranges['accel_peak_g']:.2f}).",
        f"- Board settings (ins.cfg) other than the firmware's defaults: "
        f"{board_settings.describe(rep.stimulus.config, rep.sources)}.",
        _reference_line(m["reference"]),
        *[f"- {note[0].upper()}{note[1:]}." for note in rep.notes],
        "",
    ]


def _reference_line(ref):
    """report.md's line on where the reference scores the output."""
    if ref["kind"] == "waypoints":
        return (f"- Reference: true only at its {ref['waypoints']['n']} waypoints (the line "
                "between them is not truth): the output is scored there alone, interpolated "
                "at each waypoint's instant (the table below; the figures above are those of "
                "the output samples within "
                f"{to_stimulus.WAYPOINT_TOL_S:g} s of a waypoint).")  # fmt: skip
    if ref["kind"] == "gaps":
        return (f"- Reference: with gaps: {ref['unscored_s']:.1f} s of the scored window lie in "
                f"gaps longer than {ref['max_gap_s']:.2f} s between its epochs and are not "
                f"scored (no straight line is drawn across a gap); {ref['scored_s']:.1f} s "
                "are.")  # fmt: skip
    gap = ""
    if ref["max_gap_s"]:
        gap = f" (no gap longer than {ref['max_gap_s']:.2f} s between its epochs)"
    return f"- Reference: continuous{gap}: every navigating output sample is scored."


def _waypoint_table(m):
    """report.md's table of the horizontal errors at the waypoints, if the reference has
    them."""
    wp = m["reference"].get("waypoints")
    if wp is None:
        return []
    fmt = report.fmt
    fw, fx = wp["firmware"], wp["fixes"]
    return [
        "| horizontal error at the waypoints | firmware | raw GNSS input |",
        "|---|---|---|",
        *[
            f"| {k} | {fmt(fw[k], unit='m')} | {fmt(fx[k], unit='m')} |"
            for k in ("median", "p75", "max")
        ],  # fmt: skip
        f"| waypoints scored | {fw['n']} of {wp['n']} | {fx['n']} of {wp['n']} |",
        "",
    ]


def _figures_table(m):
    """report.md's table of the firmware's errors against the reference, and the GNSS's."""
    fmt = report.fmt
    return [
        "| figure | firmware | raw GNSS input |",
        "|---|---|---|",
        f"| horizontal RMS, GNSS available | {fmt(m['horiz_rms_gnss_m'], unit='m')} | "
        f"{fmt(m['gnss_horiz_rms_m'], unit='m')} |",
        f"| horizontal RMS, all | {fmt(m['horiz_rms_m'], unit='m')} | |",
        f"| vertical RMS | {fmt(m['vert_rms_m'], unit='m')} | "
        f"{fmt(m['gnss_vert_rms_m'], unit='m')} |",
        f"| velocity RMS (3D) | {fmt(m['vel_rms_m_s'], 3, unit='m/s')} | |",
        f"| yaw / pitch / roll RMS | {fmt(m['yaw_rms_deg'])} / {fmt(m['pitch_rms_deg'])} / "
        f"{fmt(m['roll_rms_deg'], unit='deg')} | |",
        f"| position inside 3-sigma | {fmt(m['pos_3sigma_coverage'], 3)} | |",
        f"| mean (error / sigma)^2, E and N (NEES) | {fmt(m.get('pos_nees_h'))} | |",
        "",
    ]


def _outage_table(m):
    """report.md's table of the horizontal error at the end of each GNSS outage, if any."""
    lines = []
    if m["outages"]:
        lines += ["| GNSS outage (run clock) | length | horizontal error at its end |",
                  "|---|---|---|"]  # fmt: skip
        for o in m["outages"]:
            lines.append(
                f"| from {o['start_s']:g} s | {o['length_s']:g} s | "
                f"{report.fmt(o['horiz_err_end_m'], unit='m')} |"
            )
        lines.append("")
    return lines


def _reference_table(m, opt):
    """The reference filters' figures, on drive_0708 replayed under the protocol's options
    (every option at its default, the whole recording); else none."""
    lines = []
    if m["dataset"] == "drive_0708" and opt == to_stimulus.ReplayOptions(duration_s=None):
        lines += [
            "Other filters under the same protocol (docs/requirements.md, reference figures):",
            "",
            "| filter | horizontal RMS with GNSS | vertical RMS | end of outages 1/2/3 |",
            "|---|---|---|---|",
        ]
        lines += [f"| {a} | {b} | {c} | {d} |" for a, b, c, d in REFERENCE_ROWS]
        lines.append("")
    return lines


def write_solution_pos(path, rep, tr):
    """The firmware's navigating track as an RTKLIB .pos (GPST, lat/lon/height, sigmas,
    velocity; Q 7 "dead reckoning" where the frame said GNSS was not valid)."""
    import pymap3d

    from host_emulator.replay import rtklib_pos

    nav = tr.state == 2
    o = rep.truth.origin
    p = tr.p_n[nav]
    lat, lon, h = pymap3d.enu2geodetic(
        p[:, 0], p[:, 1], p[:, 2], o.lat_e7 * 1e-7, o.lon_e7 * 1e-7, o.h_m
    )
    positions, q = rtklib_pos.from_track(
        rep.t_start_gpst + tr.t_s[nav], lat, lon, h, tr.sigma[nav, 0:3], tr.v_n[nav],
        dead_reckoning=~tr.gnss_valid[nav],
    )  # fmt: skip
    rtklib_pos.write(path, positions, q, comment=f"firmware solution, replay of {rep.name}")


def replay(ds, options=None, runtime="cpython", out_dir="out/replay", show_progress=True,
           log=print, kernels=None, faults=(), board=None, display=None):  # fmt: skip
    """The whole `replay` command on a Dataset; returns the metrics. EmulatorError on bad
    input or when the firmware never navigates. faults: sim/faults.py Faults (or specs)
    injected into the converted input. display: a .png path for the board's screen (as
    `run --display`)."""
    if display is not None:
        display = pictures.check_path(display)
    runtime = runtimes.get(runtime).name  # an alias runs under its runtime's name
    options = options or to_stimulus.ReplayOptions()
    if options.duration_s is not None:
        cli_args.check_duration(options.duration_s)
    out_dir = pathlib.Path(out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise EmulatorError(f"cannot create output directory {out_dir}: {e.strerror}") from None
    for name in (*OUTPUTS, scenario_run.SCREEN, "stimulus.bin"):
        if (out_dir / name).exists():
            (out_dir / name).unlink()
    t0 = time.perf_counter()
    rep = to_stimulus.convert(ds, options)
    if rep.window_s >= rep.stimulus.duration_s:
        raise EmulatorError(
            f"--score-from {options.skip_s:g}: scoring would start {rep.window_s:.1f} s into "
            f"the run (t0, the first GNSS epoch, is at {rep.t0_s:.1f} s), after its end "
            f"({rep.stimulus.duration_s:.1f} s)"
        )
    if faults:
        rep.stimulus = faults_mod.apply(rep.stimulus, faults, options.seed)
    stim_path = out_dir / "stimulus.bin"
    rep.stimulus.write(stim_path)
    log(
        f"converted {ds.name}: {rep.stimulus.duration_s:.0f} s, {len(rep.gnss)} GNSS epochs "
        f"({time.perf_counter() - t0:.1f} s) -> {stim_path}"
    )
    for note in rep.notes:
        log(f"  {note}")
    log(f"  board settings: {board_settings.describe(rep.stimulus.config, rep.sources)}")
    for f in rep.stimulus.header.get("faults", []):
        log(f"fault injected: {f}")
    prog = scenario_run.firmware_bar(runtime, rep.stimulus.duration_s, enabled=show_progress)
    overrides = scenario_run.screen_overrides(display)
    fw = scenario_run.run_firmware(runtime, stim_path, prog, kernels, board, overrides)
    (out_dir / "frames.bin").write_bytes(fw.out)
    scenario_run.evaluating(show_progress)
    metrics, tr, err = evaluate_replay(rep, fw, runtime)
    if not err.t_s.size:
        if metrics["align_time_s"] is None:
            raise EmulatorError(
                f"the firmware never navigated on {ds.name}: {diagnose.why(rep, fw.console)}"
            )
        raise EmulatorError(
            f"the firmware navigated on {ds.name} only after the reference ends "
            f"({metrics['align_time_s']:.1f} s): nothing to score"
        )
    if metrics["horiz_rms_m"] is None:
        raise EmulatorError(
            f"nothing to score on {ds.name}: the firmware navigated from "
            f"{metrics['align_time_s']:.1f} s, scoring starts at {rep.window_s:.1f} s (t0 + "
            f"--score-from {rep.options.skip_s:g} s) and the run ends at "
            f"{rep.stimulus.duration_s:.1f} s: lower --score-from"
        )
    g = rep.gnss
    report.plots(
        out_dir,
        f"{ds.name} ({runtime})",
        tr,
        err,
        rep.truth,
        rep.outages,
        (g.p_ant_n + g.err_n_m)[g.valid],
        progress=scenario_run.plots_bar(show_progress),
    )
    write_solution_pos(out_dir / "solution.pos", rep, tr)
    scenario_run.write_screen(fw, rep.stimulus, display, out_dir, metrics, log)
    (out_dir / "report.md").write_text(markdown(metrics, rep, fw.console))
    (out_dir / "metrics.json").write_text(json.dumps(metrics, indent=2) + "\n")
    return metrics


def export_scenario(scenario, duration_s, seed, out_dir):
    """A simulated scenario as KF-GINS files (IMU, GNSS fixes, truth .nav, dataset.yaml) and
    its GNSS fixes as an RTKLIB .pos; returns the paths written."""
    from host_emulator.replay import kfgins, rtklib_pos
    from host_emulator.sim import board_input

    sim = board_input.simulate(scenario, duration_s, seed)
    ds = kfgins.from_simulation(sim)
    out = pathlib.Path(out_dir)
    yaml = kfgins.write(out, ds)
    rtklib_pos.write(out / "gnss.pos", ds.gnss, comment=f"GNSS fixes of {scenario}, seed {seed}")
    return [yaml, out / "gnss.pos"]


def export_replay(ds, options, out_dir):
    """A replay's input as KF-GINS files: the recording's IMU (rotated into body FRD), the
    GNSS fixes the firmware is sent (noise and outages applied, with the sigmas it is told),
    the reference; plus those fixes as an RTKLIB .pos. Another filter run on these files sees
    what the firmware sees."""
    from host_emulator.replay import dataset as dsm
    from host_emulator.replay import kfgins, rtklib_pos

    rep = to_stimulus.convert(ds, options)
    g = rep.gnss
    ok = g.valid
    t = rep.t_start_gpst + g.t_fix_s[ok]
    sig = np.stack([g.sigma_h_m[ok], g.sigma_h_m[ok], g.sigma_v_m[ok]], axis=-1)
    fixes = dsm.Positions(t, g.lat_e7[ok] * 1e-7, g.lon_e7[ok] * 1e-7, g.h_m[ok].astype(float), sig)
    span = (ds.imu.t_s > rep.t_start_gpst) & (
        ds.imu.t_s <= rep.t_start_gpst + rep.stimulus.duration_s
    )
    cut = dsm.Dataset(
        name=ds.name,
        imu=dsm.Imu(ds.imu.t_s[span], ds.imu.gyro_rad_s[span], ds.imu.accel_m_s2[span]),
        truth=ds.truth,
        truth_point=ds.truth_point,
        gnss=fixes,
        mount_rpy_deg=ds.mount_rpy_deg,
        lever_frd_m=ds.lever_frd_m,
        gravity_m_s2=ds.gravity_m_s2,
        description=f"{ds.description}; replay input (seed {options.seed})",
        board_config={**ds.board_config, **dict(options.config)},
    )
    out = pathlib.Path(out_dir)
    yaml = kfgins.write(out, cut)
    rtklib_pos.write(out / "gnss.pos", fixes, comment=f"GNSS input of the {ds.name} replay")
    return [yaml, out / "gnss.pos"]
