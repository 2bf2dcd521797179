"""`python -m host_emulator bench-faults` (`make bench-faults`): the fault matrix.

Every fault kind of sim/faults.py, injected at FAULT_T0_S into a drive (urban_drive by
default) for several seeds, runs through the unmodified firmware on the CPython runtime (the
board's arithmetic bit for bit) and is scored from what the board sends, against the same
seed's run without the fault:

- raise / non-finite: the run ends normally and every float of every frame and extended
  frame is finite;
- detection: the first extended frame at or after the fault's start whose health is >= 1 with
  one of the kind's expected causes (proto/records.py CAUSES), and its delay from when the
  board first meets the fault (the first tick whose input differs: an edited sentence arrives
  with its epoch, up to a second after the start); the deadline is the health target's
  (docs/requirements.md, targets: 1 s for IMU and GNSS data, 10 s for a 1 deg/s gyro bias
  step; a GNSS loss can only be noticed once fixes are overdue: gnss_timeout_s + 1 s);
- trust: frames whose horizontal or vertical error is above 10 m, and above 3x the no-fault
  run's RMS, that do not say health 2 (the target: none);
- peak errors after the fault's start; recovery: the first time after its end from which the
  horizontal and vertical errors stay within 2x the no-fault RMS for RECOVERED_S; the errors
  30 s after its end.

Writes docs/benchmarks/faults.md and faults.json. `--quick` runs one seed and a shorter drive
(what `make test`'s slow test runs).
"""

import json
import math
import pathlib
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from common.errors import EmulatorError
from common.proto import records, stream
from host_emulator import args as cli_args
from host_emulator.bench import outputs
from host_emulator.eval import evaluate
from host_emulator.sim import board_input
from host_emulator.sim import faults as faults_mod

DEFAULT_OUT = pathlib.Path("docs/benchmarks/faults.md")
SCENARIO = "urban_drive"
FAULT_T0_S = 250.0  # after the drive's 10 s outage at 200 s, before its 30 s one at 400 s
RUN_S = 320.0  # the fault, 30 s after it and the recovery window
SEEDS = (0, 1, 2)
RECOVERED_S = 5.0  # errors within 2x the no-fault RMS this long: recovered
TRUST_M = 10.0  # above this error the health must be 2 (docs/requirements.md, targets)

_IMU_HELD = ("imu_sample_held", "imu_dead")
_SAT = ("imu_saturated",)
_GNSS_FIX = ("gnss_gated", "gnss_rejects", "reset_to_gnss")


@dataclass(frozen=True)
class Case:
    spec: str  # sim/faults.py's KIND@+DURATION[:PARAM], the start left out (FAULT_T0_S)
    causes: tuple  # the CAUSES names that detect it
    deadline_s: float
    # a sensor step, seen by its effect on the solution: one that never moves it beyond 3x
    # the no-fault RMS (too small, or contained) is harmless and does not count in the
    # detection coverage (the table shows it, and whether it was detected anyway)
    by_effect: bool = False


_DRIFT = ("drift", *_GNSS_FIX)


MATRIX = (
    Case("imu-stuck@+1", _IMU_HELD, 1.0),
    Case("imu-silent@+1", _IMU_HELD, 1.0),
    Case("imu-zeros@+1", _IMU_HELD, 1.0),
    Case("imu-ones@+1", _IMU_HELD, 1.0),
    Case("gyro-over@+2", _SAT, 1.0),
    Case("accel-over@+2", _SAT, 1.0),
    Case("gyro-vibe@+2", _SAT, 1.0),
    Case("accel-vibe@+2", _SAT, 1.0),
    # sensor steps of several sizes, so that the smallest the board detects shows: gyro bias
    # 0.1 / 0.3 / 1 deg/s, accel bias 0.1 / 0.5 m/s^2, accel scale 1 / 3 / 5 %
    Case("gyro-bias@+30:0.1", _DRIFT, 10.0, True),
    Case("gyro-bias@+30:0.3", _DRIFT, 10.0, True),
    Case("gyro-bias@+30:1", _DRIFT, 10.0, True),
    Case("accel-bias@+30:0.1", _DRIFT, 10.0, True),
    Case("accel-bias@+30:0.5", _DRIFT, 10.0, True),
    Case("accel-scale@+30:1.01", _DRIFT, 10.0, True),
    Case("accel-scale@+30:1.03", _DRIFT, 10.0, True),
    Case("accel-scale@+30:1.05", _DRIFT, 10.0, True),
    Case("gnss-loss@+10", ("gnss_lost",), 3.0),
    Case("uart-corrupt@+10:0.01", ("nmea_errors", "gnss_bad_data", "gnss_lost"), 1.0),
    Case("pps-missing@+10", ("pps_irregular",), 1.5),
    Case("pps-spurious@+10", ("pps_irregular",), 1.0),
    Case("gnss-jump@+5:100", _GNSS_FIX, 1.0),
    # a receiver that stays 20 or 40 m off for 30 s, within what a faulty INS can drift:
    # refused where it began with a jump (docs/health.md)
    Case("gnss-jump@+30:20", ("gnss_implausible", *_GNSS_FIX), 1.0),
    Case("gnss-jump@+30:40", ("gnss_implausible", *_GNSS_FIX), 1.0),
    Case("gnss-height@+5:100", _GNSS_FIX, 1.0),
    Case("gnss-height@+5:900000", ("gnss_bad_data",), 1.0),
    Case("gnss-speed@+5:51000", ("gnss_bad_data",), 1.0),
    Case("gnss-course@+5:400", ("gnss_bad_data",), 1.0),
    Case("gnss-quality@+5:6", ("gnss_bad_data",), 1.0),
    Case("gnss-quality@+5:8", ("gnss_bad_data",), 1.0),
    Case("gnss-hdop@+5:0", ("gnss_bad_data",), 1.0),
    Case("gnss-late@+30:1.4", ("gnss_late", *_GNSS_FIX), 1.0),
    # the first epoch of a step back has a time going back: the parser refuses it (bad data)
    Case("gnss-clock@+30:-18", ("gnss_clock", "gnss_bad_data"), 1.0),
    Case("gnss-clock@+30:3600", ("gnss_clock",), 1.0),
    Case("gnss-frozen@+20", ("gnss_implausible", *_GNSS_FIX), 1.0),
    Case("gnss-pole@+5", ("gnss_implausible", *_GNSS_FIX), 1.0),
    Case("gnss-jump@+30:2000000", ("gnss_implausible", *_GNSS_FIX), 1.0),
    Case("stall@+0.2", ("overrun",), 1.0),
)
# receivers at other rates than the drive's 1 Hz, without a fault: scored like a fault run
# against the 1 Hz run (frames above TRUST_M without health 2 count in the target)
RATES_HZ = (5.0, 10.0)
_RATE = "receiver at "  # a _run task's spec: the drive with a receiver at this many Hz
# run in the MicroPython VM as well (unix port, seed 0): the same firmware on MicroPython
VM_SUBSET = ("imu-zeros@+1", "accel-vibe@+2", "gnss-height@+5:100", "gnss-quality@+5:6")


def _mask(names):
    """The CAUSES bits of `names`; a name the firmware does not have yet counts as no bit."""
    return sum(records.CAUSE_BITS.get(n, 0) for n in names)


def _spec(case, t0):
    kind, rest = case.spec.split("@+")
    return f"{kind}@{t0:g}+{rest}"


def _duration(case):
    return float(case.spec.split("@+")[1].split(":")[0])


def _run(task):
    """(case spec or None, seed, run_s[, runtime]): the firmware's track and errors, or what
    went wrong."""
    spec, seed, run_s, *rt = task
    runtime = rt[0] if rt else "cpython"
    gnss_model = None
    if spec is not None and spec.startswith(_RATE):
        from host_emulator.sim import gnss as sim_gnss

        # 9600 baud carries GGA+GSA+RMC at 1 Hz only: a faster receiver needs a faster link
        gnss_model = sim_gnss.GnssModel(rate_hz=float(spec[len(_RATE) :]), baud=115200)
    sim = board_input.simulate(SCENARIO, run_s, seed, gnss_model=gnss_model)
    stim = sim.stimulus
    met = None
    if spec is not None and gnss_model is None:
        stim = faults_mod.apply(stim, [spec], seed)
        met = _first_change_s(sim.stimulus, stim)
    from host_emulator.eval import scenario_run

    with tempfile.TemporaryDirectory(prefix="ins-faults-") as tmp:
        path = pathlib.Path(tmp) / "stimulus.bin"
        stim.write(path)
        try:
            fw = scenario_run.run_firmware(runtime, path)
        except Exception as e:  # the firmware raised: a result of the matrix, not a crash
            return {"spec": spec, "seed": seed, "runtime": runtime,
                    "error": f"{type(e).__name__}: {e}"}  # fmt: skip
    decoded = stream.decode(fw.out)
    finite = all(
        all(np.all(np.isfinite(np.asarray(v, float))) for v in e.values() if v is not None)
        for e in decoded.ext
    ) and all(
        np.all(np.isfinite(np.asarray(v, float)))
        for f in decoded.frames
        for k, v in f.items()
        if k != "raw"
    )
    o = sim.truth.origin
    tr = evaluate.track(decoded, stim.tick_us * 1e-6, (o.lat_e7, o.lon_e7, o.h_m))
    t = sim.truth
    outages = [tuple(x) for x in stim.header.get("outages", [])]
    err = evaluate.errors(tr, t.t_s, t.p_n, t.v_n, t.ypr, outages)
    nav = tr.state == evaluate.NAVIGATING
    return {
        "spec": spec,
        "seed": seed,
        "runtime": runtime,
        "met_s": met,
        "finite": bool(finite),
        "t": err.t_s,
        "h": np.hypot(err.dp[:, 0], err.dp[:, 1]),
        "v": np.abs(err.dp[:, 2]),
        "health": tr.health[nav][: err.t_s.size],
        "causes": tr.causes[nav][: err.t_s.size],
        "t_all": tr.t_s,
        "health_all": tr.health,
        "causes_all": tr.causes,
    }


def _rate_rows(results, nominal, seeds, rates=RATES_HZ):
    """The receivers at `rates` against the 1 Hz runs: RMS, frames above TRUST_M and how
    many of them did not say health 2."""
    rows = []
    for hz in rates:
        for s in seeds:
            r = results[(f"{_RATE}{hz:g}", s)]
            if "error" in r:
                rows.append({"rate_hz": hz, "seed": s, "error": r["error"]})
                continue
            over = (r["h"] > TRUST_M) | (r["v"] > TRUST_M)
            n = nominal[s]
            rows.append({
                "rate_hz": hz, "seed": s, "finite": r["finite"],
                "rms_h_m": float(np.sqrt(np.mean(r["h"] ** 2))),
                "rms_v_m": float(np.sqrt(np.mean(r["v"] ** 2))),
                "rms_h_1hz_m": float(np.sqrt(np.mean(n["h"] ** 2))),
                "frames_over_10m": int(over.sum()),
                "missed_over_10m": int((over & (r["health"] < 2)).sum()),
                "health2": int((r["health_all"] == 2).sum()),
            })  # fmt: skip
    return rows


def _first_change_s(clean, faulted):
    """When the board first meets the fault: the time of the first tick whose input differs
    (registers, the silent and stall flags, PPS edges, GNSS bytes; an edited sentence arrives
    with its epoch, up to a second after the fault's start). None if nothing differs."""
    k = None
    n = len(clean.gyro_regs)

    for a, b in ((clean.gyro_regs, faulted.gyro_regs), (clean.accel_regs, faulted.accel_regs),
                 (clean.imu_silent, faulted.imu_silent), (clean.stalled, faulted.stalled),
                 (clean.pps_before_us, faulted.pps_before_us)):  # fmt: skip
        d = np.flatnonzero(np.any((a != b).reshape(n, -1), axis=1))
        if d.size and (k is None or d[0] < k):
            k = int(d[0])
    oc, of = clean.uart_offsets, faulted.uart_offsets
    uc, uf = clean.uart_bytes, faulted.uart_bytes
    for j in range(len(oc) - 1):
        if k is not None and j >= k:
            break
        if uc[oc[j] : oc[j + 1]] != uf[of[j] : of[j + 1]]:
            k = j
            break
    return None if k is None else k * clean.tick_us * 1e-6


def _first(t, cond):
    i = np.flatnonzero(cond)
    return float(t[i[0]]) if i.size else None


def score(case, r, nominal, t0):
    """One faulted run against its seed's no-fault run: the figures of the matrix."""
    if "error" in r:
        return {"spec": _spec(case, t0), "seed": r["seed"], "error": r["error"]}
    end = t0 + _duration(case)
    rms_h = float(np.sqrt(np.mean(nominal["h"] ** 2)))
    rms_v = float(np.sqrt(np.mean(nominal["v"] ** 2)))
    mask = _mask(case.causes)
    ta, ha, ca = r["t_all"], r["health_all"], r["causes_all"]
    # a cause the no-fault run has at the same frame (a damaged sentence of the simulated
    # receiver, say) is not the fault's detection
    tn, cn = nominal["t_all"], nominal["causes_all"]
    j = np.minimum(np.searchsorted(tn, ta - 1e-6), tn.size - 1)
    same = (np.abs(tn[j] - ta) < 1e-6) & ((cn[j] & mask) == (ca & mask))
    after = ta >= t0
    det = _first(ta, after & (ha >= 1) & ((ca & mask) != 0) & ~same)
    met = r["met_s"] if r["met_s"] is not None else t0  # when the board first meets it
    t, h, v, health = r["t"], r["h"], r["v"], r["health"]
    post = t >= t0
    over10 = post & ((h > TRUST_M) | (v > TRUST_M))
    over3 = post & ((h > 3 * rms_h) | (v > 3 * rms_v))
    good = (h <= 2 * rms_h) & (v <= 2 * rms_v)
    recovered = None
    for i in np.flatnonzero((t >= end) & good):
        win = (t >= t[i]) & (t < t[i] + RECOVERED_S)
        if good[win].all() and t[win][-1] - t[i] >= RECOVERED_S - 0.2:
            recovered = float(t[i] - end)
            break
    j = np.searchsorted(t, end + 30.0)
    at30 = (float(h[j]), float(v[j])) if j < t.size else (None, None)
    return {
        "spec": _spec(case, t0),
        "seed": r["seed"],
        "finite": r["finite"],
        "met_s": met - t0,
        "detect_s": None if det is None else det - met,
        "detected": det is not None and det - met <= case.deadline_s,
        # counted in the coverage: a kind detected by its input, or a step with an effect
        "counts": not case.by_effect or bool(over3.any()),
        "frames_over_10m": int(over10.sum()),
        "missed_over_10m": int((over10 & (health < 2)).sum()),
        "frames_over_3x": int(over3.sum()),
        "missed_over_3x": int((over3 & (health < 2)).sum()),
        "peak_h_m": float(h[post].max()) if post.any() else None,
        "peak_v_m": float(v[post].max()) if post.any() else None,
        "recover_s": recovered,
        "h_30s_m": at30[0],
        "v_30s_m": at30[1],
        "rms_h_nominal_m": rms_h,
        "rms_v_nominal_m": rms_v,
        "health2_before_fault": int(((r["t_all"] < t0) & (r["health_all"] == 2)).sum()),
    }


def _fmt(x, d=1):
    if x is None:
        return "-"
    if isinstance(x, float) and not math.isfinite(x):
        return str(x)
    return f"{x:.{d}f}"


def markdown(rows, nominal_rows, seeds, run_s, t0, cmd, vm_rows=(), rate_rows=()):
    """docs/benchmarks/faults.md: the matrix (a row per kind, its seeds together), the
    coverage and the no-fault runs, the receivers at other rates, the subset run in the
    MicroPython VM."""
    lines = [
        "# Fault benchmark",
        "",
        f"`{cmd}`: every fault kind injected at {t0:g} s into {SCENARIO} ({run_s:g} s), "
        f"seeds {', '.join(map(str, seeds))}, CPython runtime (the board's float32 arithmetic "
        "bit for bit), scored from the frames the firmware sends against the same seed's run "
        "without the fault. Targets: no raise and no non-finite float; detection "
        "(health >= 1 with the kind's cause) within the deadline; health 2 on every frame "
        f"whose error is above {TRUST_M:g} m; errors back within 2x the no-fault RMS within "
        "30 s of the fault's end; detection coverage >= 90 %.",
        "",
        "Columns, per kind (worst seed; detection: the slowest; counts: summed over seeds): "
        "**detect** the delay from when the board first meets the fault (its first changed "
        "input) to the first extended frame with health >= 1 and an expected cause that the "
        "same seed's no-fault run does not have in that frame (- never); "
        "**>10 m (not 2)** frames with the horizontal or vertical error above 10 m, and how "
        "many of them did not say health 2; **>3x (not 2)** the same above 3x "
        "the no-fault RMS; **peak** horizontal / vertical error after the start; **recover** "
        f"the time after the fault's end until both errors stay within 2x the no-fault RMS "
        f"for {RECOVERED_S:g} s (- not within the run); **at +30 s** the errors 30 s after "
        "its end.",
        "",
        "| fault | causes expected | detect (deadline) | >10 m (not 2) | >3x (not 2) "
        "| peak h / v m | recover s | at +30 s h / v m | finite |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    by_spec = {}
    for r in rows:
        by_spec.setdefault(r["spec"], []).append(r)
    lines += [_matrix_row(case, by_spec.get(_spec(case, t0), []), t0) for case in MATRIX]
    lines += _coverage_lines(rows, nominal_rows, rate_rows)
    lines += _rate_lines(rate_rows)
    lines += _vm_lines(vm_rows)
    return "\n".join(lines)


def _matrix_row(case, rs, t0):
    """The matrix's row of a kind over its seeds' rows rs (the first that raised, if one
    did)."""
    errs = [r for r in rs if "error" in r]
    if errs:
        return f"| `{_spec(case, t0)}` | | raised: {errs[0]['error']} | | | | | | |"
    counted = [r for r in rs if r["counts"]]
    seen = [r["detect_s"] for r in rs if r["detect_s"] is not None]
    if any(r["detect_s"] is None for r in counted) or not seen:
        det_s = "-"
    else:  # the slowest, harmless runs included: a step is detected whatever its effect
        det_s = _fmt(max(seen), 2)
    if len(counted) < len(rs):
        n_missed = sum(1 for r in rs if not r["counts"] and r["detect_s"] is None)
        det_s += f", {len(rs) - len(counted)} harmless"
        if n_missed:
            det_s += f" ({n_missed} never detected)"
    known = [c for c in case.causes if c in records.CAUSE_BITS]
    return (
        f"| `{_spec(case, t0)}` | {', '.join(known) or '(none yet)'} "
        f"| {det_s} ({case.deadline_s:g}) "
        f"| {sum(r['frames_over_10m'] for r in rs)} ({sum(r['missed_over_10m'] for r in rs)}) "
        f"| {sum(r['frames_over_3x'] for r in rs)} ({sum(r['missed_over_3x'] for r in rs)}) "
        f"| {_fmt(max(r['peak_h_m'] for r in rs))} / {_fmt(max(r['peak_v_m'] for r in rs))} "
        f"| {_recover(rs)} "
        f"| {_worst(rs, 'h_30s_m')} / {_worst(rs, 'v_30s_m')} "
        f"| {'yes' if all(r['finite'] for r in rs) else '**no**'} |"
    )


def _coverage_lines(rows, nominal_rows, rate_rows):
    """The detection coverage, the frames above TRUST_M without health 2, the no-fault
    runs."""
    detected, total, harmless, misses10, every = totals(rows, rate_rows)
    cov = 100.0 * detected / total if total else 0.0
    nom = ", ".join(
        f"seed {n['seed']}: {n['rms_h']:.2f} / {n['rms_v']:.2f} m, health 2 on "
        f"{n['health2']} of {n['frames']} frames"
        for n in nominal_rows
    )
    return [
        "",
        f"Detection coverage: {detected} of {total} injected faults ({cov:.0f} %; target "
        f">= 90 %; {harmless} sensor steps that never moved the solution beyond 3x the "
        f"no-fault RMS not counted; of every injected fault, harmless ones included, "
        f"{every} of {len(rows)} detected in time, {100.0 * every / len(rows):.0f} %). "
        f"Frames above {TRUST_M:g} m without health 2: {misses10} "
        "(target 0). "
        "Why a target is missed, kind by kind: [docs/health.md](../health.md), "
        '"How well: the fault benchmark".',
        "",
        f"No-fault runs (horizontal / vertical RMS over the navigation phase): {nom}.",
        "",
    ]


def _rate_lines(rate_rows):
    """The receivers at other rates than 1 Hz (none: no section)."""
    if not rate_rows:
        return []
    lines = [
        "## Receivers by their rate",
        "",
        "The same drive without a fault, its receiver at another rate (the same sentences "
        "and error model, at 115200 baud), against the 1 Hz run of the same seed; its "
        "frames above "
        f"{TRUST_M:g} m without health 2 count in the target above.",
        "",
        "| receiver | seed | horizontal / vertical RMS m | 1 Hz horizontal m "
        "| >10 m (not 2) | health 2 frames | finite |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rate_rows:
        if "error" in r:
            lines.append(f"| {r['rate_hz']:g} Hz | {r['seed']} | raised: {r['error']} "
                         "| | | | |")  # fmt: skip
            continue
        lines.append(
            f"| {r['rate_hz']:g} Hz | {r['seed']} | {r['rms_h_m']:.2f} / {r['rms_v_m']:.2f} "
            f"| {r['rms_h_1hz_m']:.2f} | {r['frames_over_10m']} ({r['missed_over_10m']}) "
            f"| {r['health2']} | {'yes' if r['finite'] else '**no**'} |"
        )
    lines.append("")
    return lines


def _vm_lines(vm_rows):
    """The subset run in the MicroPython VM (none: no section)."""
    if not vm_rows:
        return []
    lines = [
        "## In the MicroPython VM",
        "",
        "A subset on the unix port of MicroPython (double-precision floats: the firmware's "
        "logic on MicroPython, not the board's bits), seed 0, against the VM's own run "
        "without the fault:",
        "",
        "| fault | detect s | >10 m (not 2) | peak h / v m | recover s | finite |",
        "|---|---|---|---|---|---|",
    ]
    for r in vm_rows:
        if "error" in r:
            lines.append(f"| `{r['spec']}` | raised: {r['error']} | | | | |")
            continue
        lines.append(
            f"| `{r['spec']}` | {_fmt(r['detect_s'], 2)} "
            f"| {r['frames_over_10m']} ({r['missed_over_10m']}) "
            f"| {_fmt(r['peak_h_m'])} / {_fmt(r['peak_v_m'])} | {_fmt(r['recover_s'])} "
            f"| {'yes' if r['finite'] else '**no**'} |"
        )
    lines.append("")
    return lines


def totals(rows, rate_rows=()):
    """(detected, counted, harmless, frames above TRUST_M without health 2, detected of every
    injected fault) over the matrix's rows (a run that raised counts, undetected) and the
    receivers at other rates."""
    counted = [r for r in rows if "error" in r or r["counts"]]
    detected = sum(1 for r in counted if "error" not in r and r["detected"])
    misses10 = sum(r.get("missed_over_10m", 0) for r in (*rows, *rate_rows))
    every = sum(1 for r in rows if "error" not in r and r["detected"])
    return detected, len(counted), len(rows) - len(counted), misses10, every


def verdict(rows, rate_rows=()):
    """The two targets, one line each: measured, target, met or not."""
    detected, total, _harmless, misses10, every = totals(rows, rate_rows)
    cov = 100.0 * detected / total if total else 0.0
    return [
        f"detection coverage: {detected} of {total} ({cov:.0f} %; target >= 90 %): "
        + ("met" if cov >= 90.0 else "NOT met")
        + f" (every injected fault, harmless steps included: {every} of {len(rows)}, "
        f"{100.0 * every / len(rows):.0f} %)",
        f"frames above {TRUST_M:g} m without health 2: {misses10} (target 0): "
        + ("met" if misses10 == 0 else "NOT met"),
    ]


def _recover(rs):
    v = [r["recover_s"] for r in rs]
    return "-" if any(x is None for x in v) else _fmt(max(v))


def _worst(rs, key):
    v = [r[key] for r in rs]
    return "-" if any(x is None for x in v) else _fmt(max(v))


def main(argv=None):
    what = __doc__.split("\n\n")[1].rstrip(":") + "."  # the paragraph's list is not for --help
    p = cli_args.Parser(prog="python -m host_emulator bench-faults", description=what)
    p.add_argument("--out", default=str(DEFAULT_OUT), help="markdown file (default %(default)s)")
    cli_args.add_jobs_option(p)
    p.add_argument("--quick", action="store_true", help="one seed, a shorter drive")
    try:
        args = p.parse_args(argv)
    except (cli_args.UsageError, EmulatorError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2

    def command():
        out = pathlib.Path(args.out)
        outputs.announce("bench-faults", [out, out.with_suffix(".json")])
        seeds = SEEDS[:1] if args.quick else SEEDS
        run_s = RUN_S
        t0 = FAULT_T0_S
        tasks = [(None, s, run_s) for s in seeds]
        tasks += [(_spec(c, t0), s, run_s) for c in MATRIX for s in seeds]
        tasks += [(f"{_RATE}{hz:g}", s, run_s) for hz in RATES_HZ for s in seeds]
        vm_cases = [] if args.quick else [c for c in MATRIX if c.spec in VM_SUBSET]
        tasks += [(None, 0, run_s, "mpy_unix")]
        tasks += [(_spec(c, t0), 0, run_s, "mpy_unix") for c in vm_cases]
        tasks = tasks if vm_cases else [t for t in tasks if len(t) == 3]
        print(f"bench-faults: {len(MATRIX)} kinds and {len(RATES_HZ)} receiver rates x "
              f"{len(seeds)} seeds on {SCENARIO} ({run_s:g} s, fault at {t0:g} s), CPython "
              "runtime", flush=True)  # fmt: skip
        results = {}
        with ProcessPoolExecutor(max_workers=args.jobs) as ex:
            for i, r in enumerate(ex.map(_run, tasks)):
                results[(r["spec"], r["seed"], r["runtime"])] = r
                print(f"  {i + 1}/{len(tasks)} {r['spec'] or 'no fault'} seed {r['seed']} "
                      f"({r['runtime']})", flush=True)  # fmt: skip
        vm = {(k[0], k[1]): v for k, v in results.items() if k[2] == "mpy_unix"}
        results = {(k[0], k[1]): v for k, v in results.items() if k[2] == "cpython"}
        nominal = {s: results[(None, s)] for s in seeds}
        vm_rows = [score(c, vm[(_spec(c, t0), 0)], vm[(None, 0)], t0) for c in vm_cases]
        rows = [score(c, results[(_spec(c, t0), s)], nominal[s], t0) for c in MATRIX for s in seeds]
        nominal_rows = [
            {
                "seed": s,
                "rms_h": float(np.sqrt(np.mean(n["h"] ** 2))),
                "rms_v": float(np.sqrt(np.mean(n["v"] ** 2))),
                "health2": int((n["health_all"] == 2).sum()),
                "frames": int(n["health_all"].size),
            }
            for s, n in nominal.items()
        ]
        cmd = "python -m host_emulator bench-faults" + (" --quick" if args.quick else "")
        rate_rows = _rate_rows(results, nominal, seeds)
        text = markdown(rows, nominal_rows, seeds, run_s, t0, cmd, vm_rows, rate_rows)
        out = pathlib.Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
        out.with_suffix(".json").write_text(
            json.dumps(
                {"rows": rows, "nominal": nominal_rows, "vm_rows": vm_rows, "rate_rows": rate_rows},
                indent=2,
            )
            + "\n"  # fmt: skip
        )
        print(text)
        print("\n".join(verdict(rows, rate_rows)))
        print(f"wrote {out}, {out.with_suffix('.json')}")
        return 0

    return cli_args.run_reporting(command)
