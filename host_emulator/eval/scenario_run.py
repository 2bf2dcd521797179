"""`python -m host_emulator run`: simulate a scenario, run the firmware on it, evaluate.

    simulate -> DIR/stimulus.bin -> firmware (a runtime, see runtimes/) -> DIR/frames.bin
             -> decode -> errors against truth -> DIR/metrics.json, DIR/report.md, DIR/*.png

The stimulus file is the seam: the firmware run reads it back from disk, so a run can be
repeated from it (`run --stimulus FILE`) on any runtime. A stimulus made by a simulation
carries its scenario, seed and duration, so its truth is rebuilt for the evaluation.

Outputs of an earlier run in DIR are removed first; metrics.json and report.md are written only
when everything succeeded (a failed run leaves no report that could be mistaken for a result).
"""

import json
import pathlib
import shutil
import tempfile
import time

import numpy as np

from common.errors import EmulatorError, write_atomic
from common.progress import Bar, stage
from common.proto import config as board_config
from common.proto import records, stream
from common.proto import stimulus as stim_mod
from host_emulator import args as cli_args
from host_emulator import runtimes
from host_emulator.display import pictures
from host_emulator.eval import board_cost, board_time, evaluate, report
from host_emulator.sim import board_input, trajectory
from host_emulator.sim import faults as faults_mod

SCREEN = "screen.png"  # the board's screen at the end of the run (with --display only)
OUTPUTS = ("frames.bin", "metrics.json", "report.md", *report.PLOTS)


def firmware_bar(label, duration_s, stream=None, enabled=True):
    """The firmware run's progress bar (common/progress.py), in simulated seconds and times
    real time."""

    def detail(k, n, wall):
        sim_s = k / n * duration_s
        rate = f"  {sim_s / wall:.1f}x real time" if wall > 0 else ""
        return f"{sim_s:.0f}/{duration_s:.0f} s{rate}"

    return Bar(label, detail, stream, enabled)


def plots_bar(enabled=True):
    """The plots' progress (seconds each): which PNG is being drawn."""

    def detail(k, n, _wall):
        return f"{k}/{n}, drawing {report.PLOTS[k]}" if k < n else f"{n}/{n} written"

    return Bar("plots", detail, enabled=enabled)


def evaluating(enabled=True):
    """The stage line before the evaluation (seconds on a long run)."""
    stage("  evaluating the output against truth…", enabled=enabled)


def run_firmware(runtime, stim_path, progress=None, kernels=None, board=None, overrides=None):
    """FirmwareRun of the stimulus file (read back from disk: the file is the seam) on the
    runtime (a name of host_emulator.runtimes) with `kernels` ("native", "python"; None: the
    default, native) and, for the f411 runtime, the board's image (None: its default);
    EmulatorError if the firmware sent nothing at all (its console says why, e.g. the IMU did
    not start)."""
    rt = runtimes.get(runtime)
    with tempfile.TemporaryDirectory(prefix="ins-board-") as tmp:
        fw = rt.run(stim_path, pathlib.Path(tmp), config_overrides=overrides, progress=progress,
                    kernels=kernels, board=board)  # fmt: skip
    if not fw.out:
        said = "; ".join(fw.console) or "nothing"
        raise EmulatorError(f"the firmware sent no output in {fw.ticks} ticks; its console: {said}")
    return fw


def _clean(out_dir, keep_stimulus=False):
    """Remove an earlier run's outputs (so a failed run cannot leave them behind)."""
    for name in (*OUTPUTS, SCREEN) if keep_stimulus else (*OUTPUTS, SCREEN, "stimulus.bin"):
        p = out_dir / name
        if p.exists():
            p.unlink()


def health_figures(tr):
    """What the firmware said of itself while navigating: the share of its frames at health 2
    and its resets to GNSS (each rise of the reset_to_gnss cause: position and velocity, with
    the heading at the yaw estimator's, or the height alone)."""
    nav = tr.state == evaluate.NAVIGATING
    if not nav.any():
        return {"health2_share": None, "gnss_resets": 0}
    reset = (tr.causes[nav] & records.CAUSE_BITS["reset_to_gnss"]) != 0
    rises = int(reset[0]) + int(np.count_nonzero(reset[1:] & ~reset[:-1]))
    return {"health2_share": float(np.mean(tr.health[nav] == 2)), "gnss_resets": rises}


def firmware_metrics(fw, decoded, tr, acc, duration_s):
    """The metrics.json figures every evaluated run has (a simulation's or a replay's): run
    time, accuracy (evaluate.accuracy's dict), GC blocks, output frames, firmware counters."""
    fe = evaluate.frame_errors(decoded)
    blocks = fw.blocks_per_tick
    m = {
        "ticks": int(fw.ticks),
        "wall_s": float(fw.wall_s),
        "realtime_factor": float(duration_s / fw.wall_s) if fw.wall_s > 0 else None,
        "horiz_rms_m": acc["horiz_rms_m"],
        "vert_rms_m": acc["vert_rms_m"],
        "vel_rms_m_s": acc["vel_rms_m_s"],
        "roll_rms_deg": acc["roll_rms_deg"],
        "pitch_rms_deg": acc["pitch_rms_deg"],
        "yaw_rms_deg": acc["yaw_rms_deg"],
        "outages": acc["outages"],
        "gc_blocks_per_tick_mean": None if blocks is None else float(np.mean(blocks)),
        "gc_blocks_per_tick_max": None if blocks is None else int(np.max(blocks)),
        "tick_float_ops_max": None,  # not counted separately: GC blocks are the proxy
        "align_time_s": tr.align_time_s,
        **health_figures(tr),
        "frames": len(decoded.frames),
        "frame_errors": fe["total"],
        # more detail
        "horiz_rms_gnss_m": acc["horiz_rms_gnss_m"],
        "horiz_max_m": acc["horiz_max_m"],
        "vel_rms_gnss_m_s": acc["vel_rms_gnss_m_s"],
        "pos_3sigma_coverage": acc["pos_3sigma_coverage"],
        "pos_nees_h": acc["pos_nees_h"],
        "frame_error_detail": fe,
        "ext_frames": len(decoded.ext),
        "nmea_rejected": fw.stats.get("nmea_rejected"),
        "gnss_rx_overflow": fw.stats.get("gnss_rx_overflow"),
        "overruns": fw.stats.get("overruns"),
        "kernels": fw.stats.get("kernels"),  # native (navk) or python; None: the model
    }
    if blocks is not None:
        m["gc_blocks_per_tick_p99"] = float(np.percentile(blocks, 99))
        m["gc_blocks_by_state"] = fw.stats.get("blocks_by_state")
    per_tick = getattr(fw, "per_tick", None)
    if per_tick is not None and fw.runtime == "f411":  # the image: its time per tick
        tick_states = board_time.states(fw.out, fw.ticks)
        m["board_time"] = board_time.summary(per_tick, tick_states, fw.stats["hclk_hz"],
                                             fw.stats["cpi"])  # fmt: skip
        m["board_run"] = {k: fw.stats.get(k) for k in board_time.RUN_KEYS}
    elif per_tick is not None:  # the m4f runtime: instructions per tick on the board's CPU
        m["board_cost"] = board_cost.summary(per_tick)
        m["board_heap"] = {k: fw.stats.get(k) for k in board_cost.HEAP_KEYS}
    return m


def evaluate_run(sim, fw, stim, out_dir, runtime, extra=None):
    """metrics dict (and the report's inputs) of a finished firmware run."""
    tick_s = stim.tick_us * 1e-6
    decoded = stream.decode(fw.out)
    o = sim.truth.origin
    tr = evaluate.track(decoded, tick_s, (o.lat_e7, o.lon_e7, o.h_m))
    outages = [tuple(x) for x in stim.header.get("outages", [])]
    truth = sim.truth
    err = evaluate.errors(tr, truth.t_s, truth.p_n, truth.v_n, truth.ypr, outages)
    acc = evaluate.accuracy(err, outages)
    g = sim.gnss
    align = tr.align_time_s
    ok = g.valid & (g.t_fix_s >= (align if align is not None else np.inf))
    metrics = {
        "scenario": sim.name,
        "duration_s": float(stim.duration_s),
        "seed": int(sim.seed),
        "runtime": runtime,
        **firmware_metrics(fw, decoded, tr, acc, stim.duration_s),
        "gnss_horiz_rms_m": evaluate.rms(np.hypot(*g.err_n_m[ok, :2].T)) if ok.any() else None,
        "nmea_damaged_sentences": int(sim.damaged_sentences),
        "faults": list(stim.header.get("faults", [])),
    }
    metrics.update(extra or {})
    return metrics, tr, err


def write_outputs(out_dir, sim, metrics, tr, err, console, progress=None):
    truth = sim.truth
    g = sim.gnss
    fixes = (g.p_ant_n + g.err_n_m)[g.valid]
    outages = [tuple(x) for x in sim.stimulus.header.get("outages", [])]
    title = f"{sim.name} ({metrics['runtime']})"
    report.plots(
        out_dir,
        title,
        tr,
        err,
        truth,
        outages,
        fixes,
        (sim.imu.t_s, sim.imu.bg_rad_s, sim.imu.ba_m_s2),
        progress,
    )
    desc = trajectory.SCENARIOS[sim.name].description
    notes = [profile_note(sim.stimulus.config, sim.name)]
    write_atomic(out_dir / "report.md", report.markdown(metrics, desc, console, notes))
    write_atomic(out_dir / "metrics.json", json.dumps(metrics, indent=2) + "\n")


def profile_note(config, scenario):
    """Which profile the board ran and why (a simulated scenario sets it)."""
    if config.get("profile", 0) == 1:
        return f"Profile 1 (handheld): {scenario} carries the board in a person's hand."
    return f"Profile 0 (car): {scenario}'s board rides a vehicle."


def _log_faults(stim, log):
    for f in stim.header.get("faults", []):
        log(f"fault injected: {f}")


def run(scenario, duration_s, seed, runtime, out_dir, show_progress=True, log=print,
        kernels=None, faults=(), board=None, display=None):  # fmt: skip
    """The whole `run` command; returns the metrics. EmulatorError on bad input or failure.
    faults: sim/faults.py Faults (or specs) injected into the simulated input. display: a .png
    path: the board runs its screen (the display setting on) and the screen is drawn there
    (display/pictures.py), and as screen.png in the report."""
    if display is not None:
        display = pictures.check_path(display)
    cli_args.check_scenario(scenario)
    cli_args.check_duration(duration_s)
    cli_args.check_seed(seed)
    runtime = runtimes.get(runtime).name  # an alias runs under its runtime's name
    out_dir = pathlib.Path(out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise EmulatorError(f"cannot create output directory {out_dir}: {e.strerror}") from None
    _clean(out_dir)
    t0 = time.perf_counter()
    sim = board_input.simulate(scenario, duration_s, seed)
    if faults:
        sim.stimulus = faults_mod.apply(sim.stimulus, faults, seed)
    stim_path = out_dir / "stimulus.bin"
    sim.stimulus.write(stim_path)
    log(
        f"simulated {scenario}: {sim.stimulus.duration_s:g} s, seed {seed} "
        f"({time.perf_counter() - t0:.1f} s) -> {stim_path}"
    )
    log("  " + profile_note(sim.stimulus.config, scenario))
    _log_faults(sim.stimulus, log)
    prog = firmware_bar(runtime, sim.stimulus.duration_s, enabled=show_progress)
    fw = run_firmware(runtime, stim_path, prog, kernels, board, screen_overrides(display))
    write_atomic(out_dir / "frames.bin", fw.out)
    evaluating(show_progress)
    metrics, tr, err = evaluate_run(sim, fw, sim.stimulus, out_dir, runtime)
    if not tr.t_s.size:
        raise EmulatorError("the firmware sent no extended frames: nothing to evaluate")
    write_screen(fw, sim.stimulus, display, out_dir, metrics, log)
    write_outputs(out_dir, sim, metrics, tr, err, fw.console, plots_bar(show_progress))
    return metrics


def screen_overrides(display):
    return {"display": 1} if display is not None else None


def write_screen(fw, stim, display, out_dir, metrics, log):
    """With --display: the screen's pictures (the end at `display` and in the run's
    screen.png, the strip beside `display`) and what it cost in bytes."""
    if display is None:
        return
    cfg = board_config.from_values(board_config.run_values(stim, screen_overrides(display)))
    size = (cfg.display_w, cfg.display_h)
    args = (fw, size, stim.tick_us * 1e-6, stim.duration_s)
    written = pictures.write(*args, display)
    pictures.write(*args, out_dir / SCREEN)
    pictures.strip_path(out_dir / SCREEN).unlink(missing_ok=True)
    metrics["display_bytes"] = len(fw.display)
    metrics["display_bytes_per_s"] = len(fw.display) / stim.duration_s
    log(f"screen: {written[0]} (the end), {written[1]} (over the run)")


def run_stimulus(path, runtime, out_dir, show_progress=True, log=print, kernels=None,
                 faults=(), board=None, display=None):  # fmt: skip
    """`run --stimulus FILE`: replay a stimulus file. If it came from a simulation, its truth
    is rebuilt (same scenario, seed, duration) and the run is evaluated like `run`; otherwise
    only the output is checked (frames, frame errors, time to navigation). faults: injected
    into the file's input (the run's stimulus.bin then holds them). display: as `run`'s."""
    if display is not None:
        display = pictures.check_path(display)
    runtime = runtimes.get(runtime).name  # an alias runs under its runtime's name
    stim = stim_mod.read(path)  # StimulusError (an EmulatorError) if unusable
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    _clean(out_dir, keep_stimulus=True)
    h = stim.header
    src = pathlib.Path(path)
    local = out_dir / "stimulus.bin"
    if faults:
        stim = faults_mod.apply(stim, faults, h.get("seed", 0))
        h = stim.header
        stim.write(local)
        _log_faults(stim, log)
    elif src.resolve() != local.resolve():
        shutil.copyfile(src, local)
    prog = firmware_bar(runtime, stim.duration_s, enabled=show_progress)
    fw = run_firmware(runtime, local, prog, kernels, board, screen_overrides(display))
    write_atomic(out_dir / "frames.bin", fw.out)
    if h.get("source") == "simulation" and h.get("scenario") in trajectory.SCENARIOS:
        evaluating(show_progress)
        sim = board_input.simulate(h["scenario"], h.get("duration_s"), h.get("seed", 0))
        if not faults and sim.stimulus.to_bytes() != stim.to_bytes():
            log("note: the file differs from a fresh simulation of its scenario; evaluating "
                "against that simulation's truth anyway")  # fmt: skip
        sim.stimulus = stim
        metrics, tr, err = evaluate_run(sim, fw, stim, out_dir, runtime)
        write_screen(fw, stim, display, out_dir, metrics, log)
        write_outputs(out_dir, sim, metrics, tr, err, fw.console, plots_bar(show_progress))
        return metrics
    decoded = stream.decode(fw.out)
    tr = evaluate.track(decoded, stim.tick_us * 1e-6, (0, 0, 0.0))
    fe = evaluate.frame_errors(decoded)
    metrics = {
        "source": h.get("source"),
        "duration_s": stim.duration_s,
        "runtime": runtime,
        "ticks": fw.ticks,
        "wall_s": fw.wall_s,
        "realtime_factor": stim.duration_s / fw.wall_s if fw.wall_s > 0 else None,
        "align_time_s": tr.align_time_s,
        "frames": len(decoded.frames),
        "frame_errors": fe["total"],
        "note": "no truth for this stimulus: accuracy not evaluated",
        "faults": list(h.get("faults", [])),
    }
    write_screen(fw, stim, display, out_dir, metrics, log)
    write_atomic(out_dir / "metrics.json", json.dumps(metrics, indent=2) + "\n")
    return metrics
