"""Why the firmware never navigated on a replay: one line, the cause and what to do.

The firmware starts navigating (firmware/lib/nav_align.py) once it has, in this order:
levelled on the accelerometer (the mean specific force over `level_s` must exceed 4.9 m/s^2:
gravity), `gnss_stable_fixes` usable fixes in a row (quality >= `gnss_min_quality`, HDOP <=
`gnss_hdop_max`), and a heading: the receiver's course at a speed >= `heading_speed_m_s`, or
without a course the track: a chord of `track_min_m` or more between two fixes `track_s` to
`track_max_s` apart, at that mean speed and turning at most `track_turn_max`; or the yaw
estimator's (yaw_gsf.py) once it is sure, on fixes with a velocity. `why` checks
each condition on what the board was sent (the stimulus: BMI055 counts, the GNSS epochs) with
the thresholds of the configuration it ran with, and names the first that failed; if all held,
it says so and quotes the console.
"""

import math
from dataclasses import dataclass

import numpy as np

from common.proto import stimulus as stim_mod
from host_emulator.replay import run_config
from host_emulator.sim import imu as imu_mod

MIN_LEVEL_M_S2 = 4.9  # nav_align.MIN_LEVEL_F


def _f(x):
    return float(x)


def _levels(rep, cfg, tick_s):
    """(levelled, the largest mean specific force over a levelling window, m/s^2)."""
    counts = stim_mod.accel_counts(rep.stimulus.accel_regs).astype(float)
    lsb = imu_mod.ACCEL_LSB_PER_G_BY_RANGE[rep.stimulus.config["accel_range_g"]]
    f = counts / lsb * 9.80665
    n = max(int(_f(cfg.level_s) / tick_s + 0.5), 1)
    k = f.shape[0] // n
    if k == 0:
        return False, 0.0
    means = np.linalg.norm(f[: k * n].reshape(k, n, 3).mean(axis=1), axis=1)
    best = float(means.max())
    return best > MIN_LEVEL_M_S2, best


def _runs(ok):
    """Length of the longest run of True."""
    best = run = 0
    for x in ok:
        run = run + 1 if x else 0
        best = max(best, run)
    return best


def _yaw(rep, k):
    """Truth yaw at tick indices k (rad; from the course where the reference has no
    attitude): only its changes are used."""
    tr = rep.truth
    if tr.has_attitude:
        return tr.ypr[k, 0]
    return -np.arctan2(tr.v_n[k, 0], tr.v_n[k, 1])


def _track_chord(cfg, t, p, usable, yaw):
    """nav_align's track, anchors taken as every earlier fix of the run (the firmware keeps
    one per 2.5 s): at each fix after a stable run, the newest anchor track_s to track_max_s
    old whose chord reaches track_min_m makes a window; fast enough and turning little enough,
    navigation starts, else the anchors are dropped. An unusable fix resets the run."""
    t_min, t_max, d_min = _f(cfg.track_s), _f(cfg.track_max_s), _f(cfg.track_min_m)
    hs, turn_max, need = _f(cfg.heading_speed_m_s), _f(cfg.track_turn_max), cfg.gnss_stable_fixes
    first, stable = None, 0  # the oldest anchor of the run
    out = Track(False, 0.0, 0.0, 0, 0, f"{d_min:g} m or more, {t_min:g} to {t_max:g} s")
    for i in range(t.size):
        if not usable[i]:
            stable, first = 0, None
            continue
        stable += 1
        if stable < need:
            continue
        if first is None:
            first = i
            continue
        for a in range(i - 1, first - 1, -1):
            if t[i] - t[a] > t_max + 1e-9:
                break
            if t[i] - t[a] < t_min - 1e-9:
                continue
            d = float(np.hypot(*(p[i, :2] - p[a, :2])))
            out.chord_m = max(out.chord_m, d)
            if d >= d_min:
                if out.count(d / (t[i] - t[a]), yaw[i] - yaw[a], hs, turn_max):
                    return out
                first = i  # the anchors are dropped: this fix is the first of new ones
                break
    return out


@dataclass
class Track:
    """What the track windows of a run showed."""

    started: bool
    chord_m: float  # the longest chord looked at
    best_m_s: float  # the best mean speed of a window
    windows: int
    turned: int  # windows fast enough that turned more than track_turn_max
    rule: str  # which windows the firmware looks at

    def count(self, speed, dyaw, hs, turn_max):
        """Book a window; True if navigation starts on it."""
        self.windows += 1
        self.best_m_s = max(self.best_m_s, speed)
        dyaw = (dyaw + math.pi) % (2.0 * math.pi) - math.pi
        if speed >= hs:
            if abs(dyaw) <= turn_max:
                self.started = True
                return True
            self.turned += 1
        return False


def _track(rep, cfg, t, p, usable, tick_s):
    """The track windows of the firmware's alignment on the fixes sent."""
    k = np.clip(np.rint(t / tick_s).astype(int), 0, rep.truth.t_s.size - 1)
    return _track_chord(cfg, t, p, usable, _yaw(rep, k))


def why(rep, console=()):
    """One line: why the firmware did not navigate on this replay, and what to do."""
    values = rep.stimulus.config
    cfg = run_config.nav_config(values)
    tick_s = rep.stimulus.tick_us * 1e-6
    src = {name: rep.sources.get(name, run_config.REPLAY) for name in values}

    levelled, f_best = _levels(rep, cfg, tick_s)
    if not levelled:
        return (
            f"it never levelled: the accelerometer's mean specific force over "
            f"{_f(cfg.level_s):g} s is at most {f_best:.3g} m/s^2, where gravity gives 9.8 "
            f"(it needs more than {MIN_LEVEL_M_S2}): check the accelerometer's units (a KF-GINS "
            "IMU file holds velocity increments in m/s over each row's interval)"
        )
    g = rep.gnss
    fixes = g.quality > 0
    if not fixes.any():
        where = "every epoch falls in an outage (--outages)" if g.outages else "no epoch had one"
        return f"no GNSS fix was sent ({g.t_fix_s.size} epochs: {where})"
    hdop_max = _f(cfg.gnss_hdop_max)
    usable = fixes & (g.quality >= cfg.gnss_min_quality) & (np.nan_to_num(g.hdop) <= hdop_max)
    need = int(cfg.gnss_stable_fixes)
    longest = _runs(usable)
    if longest < need:
        high = int((fixes & ~usable).sum())
        return (
            f"never {need} usable GNSS fixes in a row (gnss_stable_fixes; the longest run is "
            f"{longest}): {high} of the {int(fixes.sum())} fixes have an HDOP above "
            f"gnss_hdop_max {hdop_max:g} ({src['gnss_hdop_max']}; a GNSS file's sd columns "
            "set the HDOP sent: sigma / their median); raise it with --set gnss_hdop_max=... "
            "or check the sd columns"
            if high
            else f"never {need} usable GNSS fixes in a row (gnss_stable_fixes; the longest "
            f"run is {longest}): the fixes come between outages or gaps; send more"
        )
    hs = _f(cfg.heading_speed_m_s)
    if np.isfinite(g.course_deg[usable]).any():
        no_heading = _course_too_slow(rep, usable, hs)
    else:
        no_heading = _track_fails(rep, cfg, usable, hs, tick_s)
    if no_heading is not None:
        if cfg.yaw_gsf:  # nav_align._gsf_align: yaw_gsf._result's bounds
            ready_deg = math.degrees(_f(cfg.yaw_gsf_ready_sigma))
            no_heading += (
                "; nor did the yaw estimator become sure of one (its 1-sigma under "
                f"yaw_gsf_ready_sigma {ready_deg:.0f} deg at a fix with speed and course, "
                f"under {ready_deg / 2:.0f} deg on positions alone: it needs turns or "
                "changes of speed)"
            )
        return no_heading
    said = "; ".join(console) or "nothing"
    return (
        "the data meets every condition of the alignment (levelled, "
        f"{need} usable fixes in a row, a heading at {hs:g} m/s), yet it did not start: "
        f"report this with the dataset (firmware console: {said})"
    )


def _course_too_slow(rep, usable, hs):
    """Why no heading came from the receiver's course (never at heading_speed_m_s hs), or
    None if one could."""
    g = rep.gnss
    run_end = rep.stimulus.duration_s
    fast = usable & (np.nan_to_num(g.speed_m_s) >= hs) & np.isfinite(g.course_deg)
    if fast.any():
        return None
    top = float(np.nanmax(g.speed_m_s[usable]))
    return (
        f"the GNSS speed never reached heading_speed_m_s {hs:g} m/s (at most "
        f"{top:.2f} m/s in the {run_end:.0f} s replayed): without a magnetometer the "
        "heading comes from the course over ground of a moving vehicle; replay a "
        "part of the recording where it drives"
    )


def _track_fails(rep, cfg, usable, hs, tick_s):
    """Why no heading came from the track of fixes without a course (no window, too slow,
    turning), or None if navigation starts on one."""
    g = rep.gnss
    run_end = rep.stimulus.duration_s
    p = g.p_ant_n + g.err_n_m  # the positions sent
    tr = _track(rep, cfg, g.t_fix_s, p, usable, tick_s)
    if tr.started:
        return None
    no_course = "no course in the fixes (RMC speed and course empty), and "
    velocity = "send the GNSS velocity (--gnss-velocity SIGMA)"
    top = float(np.max(np.hypot(rep.truth.v_n[:, 0], rep.truth.v_n[:, 1])))
    moves = f"the reference moves at most {top:.2f} m/s in the {run_end:.0f} s replayed"
    if tr.windows == 0:
        gaps = np.diff(g.t_fix_s[usable])
        if tr.chord_m > 0.0:
            return (
                f"{no_course}their track never covered track_min_m "
                f"{_f(cfg.track_min_m):g} m in track_s to track_max_s "
                f"({_f(cfg.track_s):g} to {_f(cfg.track_max_s):g} s) "
                f"(at most {tr.chord_m:.1f} m; {moves}): without a magnetometer the "
                "heading comes from a moving vehicle's course; replay a part of the "
                f"recording where it moves, or {velocity}"
            )
        gap = f"{float(np.median(gaps)):.3g} s" if gaps.size else "never"
        return (
            f"{no_course}no track: it needs two usable fixes {tr.rule} apart, they "
            f"come every {gap}; send fixes more often or {velocity}"
        )
    if tr.best_m_s < hs:
        return (
            f"{no_course}their track never reached heading_speed_m_s {hs:g} m/s (at "
            f"most {tr.best_m_s:.2f} m/s over {tr.rule}; {moves}): without a "
            "magnetometer the heading comes from a moving vehicle's course; replay a "
            f"part of the recording where it moves, or {velocity}"
        )
    return (
        f"{no_course}every track window fast enough ({tr.turned}) turned more than "
        f"track_turn_max {math.degrees(_f(cfg.track_turn_max)):.0f} deg: {velocity} "
        "or replay a straighter stretch"
    )
