"""Drive the firmware's Navigator directly with simulated IMU counts and GNSS fixes, and score
it against truth. (The host emulator proper runs the whole firmware loop through emulated
peripherals; this runner isolates the navigation core for its tests and benchmark.)

The navigator runs on CPython through the float32 seam, so what it computes is what the board
computes. Fixes are handed over at the first tick at or after their availability time, with
the PPS tick of their measurement time (the board's loop does the same once PPS is wired).
Tick T holds the state at time T dt: IMU sample k (taken at k dt) is integrated over
[k dt, (k+1) dt] by tick k+1.
Errors are measured in the simulation's frame from the navigator's integrated lat/lon, so
they include everything the board would output (origin choice and re-anchoring too).
"""

import array
import math
import time
from dataclasses import dataclass, field

import numpy as np
import pymap3d

from common import firmware_env
from host_emulator.sim.trajectory import wrap_pi

firmware_env.install()

import f32  # noqa: E402
import geo  # noqa: E402
import nav as nav_mod  # noqa: E402
import navcfg  # noqa: E402
from nav import NAVIGATING, Navigator  # noqa: E402


@dataclass
class NavRun:
    """Navigator outputs sampled every `decimate` ticks (t_s is the sample time)."""

    t_s: np.ndarray
    p_n: np.ndarray  # in the simulation's frame, from the integrated lat/lon
    v_n: np.ndarray
    ypr: np.ndarray
    bg: np.ndarray
    ba: np.ndarray
    p_sigma: np.ndarray  # sqrt of the reported diagonal (15): P's, the position's plus nav.cv
    state: np.ndarray
    health: np.ndarray
    ticks: int
    wall_s: float
    align_time_s: float | None
    gnss_updates: int
    resets: int
    extra: dict = field(default_factory=dict)


def fix_args(fx, dt_s, velocity=True, pps=True):
    """(Navigator.gnss arguments, fix_tick) of one simulated fix as the board's loop gives it:
    integer lat/lon, float32 values, course in radians (-1 when unknown), and the PPS tick of
    its epoch. velocity=False: a receiver that reports no speed or course (both -1);
    pps=False: no PPS (fix_tick -1: the navigator assumes the configured latency)."""
    course = fx.course_deg
    course_rad = -1.0 if (course is None or math.isnan(course)) else math.radians(course)
    speed, course = (f32.f32(fx.speed_m_s), f32.f32(course_rad)) if velocity else (-1.0, -1.0)
    args = (
        int(fx.lat_e7), int(fx.lon_e7), f32.f32(fx.h_m), int(fx.quality), f32.f32(fx.hdop),
        speed, course,
    )  # fmt: skip
    return args, int(round(fx.t_fix_s / dt_s)) if pps else -1


def control(nav, name):
    """The counter `name` of the navigator's control state (nav.py's _C_* layout, lower case
    without the prefix: "since_prop", "speed_tick", "t_timeout")."""
    return nav.ctl[getattr(nav_mod, "_C_" + name.upper())]


def gnss_e7(nav, lat_e7, lon_e7, *args, **kwargs):
    """The firmware navigator's `gnss` with the longitude in 1e-7 deg, as the model takes it
    (the firmware carries it as (degrees, fraction): geo.split_e7)."""
    nav.gnss(lat_e7, *geo.split_e7(lon_e7), *args, **kwargs)


def deliver_fix(nav, fx, dt_s, sentences=("GGA", "RMC"), pps=True):
    """Hand one simulated fix to the navigator as the board's loop will (fix_args), with what
    a receiver printing `sentences` gives: no GGA, no height and no HDOP (the worst accepted
    is assumed, as app.py does); neither RMC nor VTG, no speed and course. pps=False: a board
    without the PPS wire (the fix's time is its arrival less gnss_latency_s)."""
    args, fix_tick = fix_args(fx, dt_s, velocity="RMC" in sentences or "VTG" in sentences, pps=pps)
    if "GGA" in sentences:
        gnss_e7(nav, *args, fix_tick=fix_tick)
        return
    lat, lon, _, quality, _, speed, course = args
    hdop = nav.cfg.gnss_hdop_max
    gnss_e7(nav, lat, lon, 0.0, quality, hdop, speed, course, fix_tick=fix_tick, sigma_v_m=-1.0)


def feed(nav, imu, gnss, k0, k1, on_tick=None, pps=True):
    """Ticks k0..k1-1: the fixes available by each tick, then the tick's IMU counts;
    on_tick(nav, k) after each tick. The fixes carry what the simulated receiver prints
    (its model's `sentences`), with their PPS tick unless pps=False."""
    dt = float(nav.cfg.dt_s)
    sentences = getattr(getattr(gnss, "model", None), "sentences", ("GGA", "RMC"))
    gyro = imu.gyro_counts[k0:k1].astype(int).tolist()
    accel = imu.accel_counts[k0:k1].astype(int).tolist()
    sat = imu.saturated[k0:k1].tolist()
    fixes = [f for f in gnss if k0 * dt <= f.t_avail_s < k1 * dt]
    fi = 0
    for j, k in enumerate(range(k0, k1)):
        while fi < len(fixes) and fixes[fi].t_avail_s <= k * dt + 1e-9:
            deliver_fix(nav, fixes[fi], dt, sentences, pps)
            fi += 1
        nav.imu_raw(gyro[j], accel[j], sat[j])
        if on_tick:
            on_tick(nav, k)


def run(truth, imu, gnss, cfg=None, duration_s=None, decimate=20, progress=None, pps=True):
    """Run the navigator over a simulated scenario (pps=False: no PPS, see feed); returns a
    NavRun."""
    cfg = cfg or navcfg.NavConfig("car")
    lever = getattr(getattr(gnss, "model", None), "lever_b_m", None)
    if lever is not None:
        for i in range(3):
            cfg.lever_b_m[i] = lever[i]
    nav = Navigator(cfg)
    dt = float(cfg.dt_s)
    # the last truth sample is the state after the last tick
    n = len(truth.t_s) - 1
    if duration_s is not None:
        n = min(n, int(round(duration_s / dt)))
    rows = []
    align_t = None
    e7 = np.zeros(2, dtype=np.int32)
    e7_buf = array.array("i", bytes(12))
    pd = f32.zeros(15)

    def record(nav, k):
        nonlocal align_t
        t = (k + 1) * dt  # tick k+1 holds the state at (k+1) dt: sample k spans [k dt, (k+1) dt]
        if align_t is None and nav.state == NAVIGATING:
            align_t = t
        if k % decimate == 0 and nav.state == NAVIGATING:
            rows.append(_nav_row(nav, t, e7, e7_buf, pd))
        if progress and k % 2000 == 0:
            progress(k, n)

    t0 = time.perf_counter()
    feed(nav, imu, gnss, 0, n, on_tick=record, pps=pps)
    wall = time.perf_counter() - t0
    a = np.array(rows, dtype=float) if rows else np.zeros((0, 34))
    return NavRun(
        t_s=a[:, 0],
        p_n=_enu_m(a, truth.origin),
        v_n=a[:, 4:7],
        ypr=a[:, 7:10],
        bg=a[:, 10:13],
        ba=a[:, 13:16],
        p_sigma=a[:, 16:31],
        state=a[:, 31].astype(int),
        health=a[:, 32].astype(int),
        ticks=n,
        wall_s=wall,
        align_time_s=align_t,
        gnss_updates=nav.updates,
        resets=nav.resets,
        extra={
            "reanchors": nav.reanchors,
            "p_n_final": [float(x) for x in nav.ins.p_n],
            "cv_final": [float(x) for x in nav.cv],  # the receiver's unseen variances, m^2
            # the fixes' lag behind their stamps: found (s) and applied (ticks), at the end
            "lag_s": float(nav.mem[nav_mod._M_CN + nav_mod._CN_LAG]),
            "lag_ticks": int(nav.mem[nav_mod._M_CN + nav_mod._CN_LAGT]),
        },
    )


def _nav_row(nav, t_s, e7, e7_buf, pd):
    """One row of run's table at t_s: time, lat/lon (1e-7 deg, through the int32 e7),
    height, v_n, yaw/pitch/roll, gyro and accel biases, the 15 sigmas, state, health.
    e7, e7_buf and pd are run's buffers, reused from row to row."""
    h = nav.lat_lon(e7_buf)
    e7[:] = e7_buf[0], geo.join_e7(e7_buf[1], e7_buf[2])
    nav.euler()
    nav.p_diag(pd)
    ins = nav.ins
    return (
        t_s,
        int(e7[0]),
        int(e7[1]),
        float(h),
        *map(float, ins.v_n),
        *map(float, nav.ypr),
        *map(float, ins.bg),
        *map(float, ins.ba),
        *np.sqrt(np.maximum(np.asarray(pd, float), 0)),
        nav.state,
        nav.health,
    )


def _enu_m(a, origin):
    """ENU positions (m, from origin) of the rows' lat/lon/height; (0, 3) without rows."""
    if not len(a):
        return np.zeros((0, 3))
    e, nn, u = pymap3d.geodetic2enu(
        a[:, 1] / 1e7, a[:, 2] / 1e7, a[:, 3], origin.lat_e7 / 1e7, origin.lon_e7 / 1e7, origin.h_m
    )
    return np.stack([e, nn, u], axis=-1)


def metrics(run_, truth, outages=(), skip_s=0.0):
    """Errors over the navigation phase (after `skip_s` more seconds), angles wrapped; the
    `_gnss` figures leave out the outage windows."""
    dt = float(truth.t_s[1] - truth.t_s[0])
    idx = np.rint(run_.t_s / dt).astype(int)
    keep = run_.t_s >= (run_.align_time_s or 0.0) + skip_s
    i = idx[keep]
    dp = run_.p_n[keep] - truth.p_n[i]
    dv = run_.v_n[keep] - truth.v_n[i]
    da = wrap_pi(run_.ypr[keep] - truth.ypr[i])
    rms = lambda x: float(np.sqrt(np.mean(x**2))) if len(x) else float("nan")  # noqa: E731
    t = run_.t_s[keep]
    gnss_ok = np.ones(len(t), bool)
    for start, length in outages:
        gnss_ok &= ~((t >= start) & (t < start + length))
    out = {
        "horiz_rms_m": rms(np.hypot(dp[:, 0], dp[:, 1])),
        "horiz_rms_gnss_m": rms(np.hypot(dp[gnss_ok, 0], dp[gnss_ok, 1])),
        "vel_rms_gnss_m_s": rms(np.linalg.norm(dv[gnss_ok], axis=1)),
        "vert_rms_m": rms(dp[:, 2]),
        "vel_rms_m_s": rms(np.linalg.norm(dv, axis=1)),
        "yaw_rms_deg": float(np.degrees(rms(da[:, 0]))),
        "pitch_rms_deg": float(np.degrees(rms(da[:, 1]))),
        "roll_rms_deg": float(np.degrees(rms(da[:, 2]))),
        "align_time_s": run_.align_time_s,
        "outages": [],
    }
    for start, length in outages:
        end = start + length
        j = np.searchsorted(run_.t_s, end)
        if j < len(run_.t_s) and run_.t_s[j] - end < 1.0:
            k = int(round(run_.t_s[j] / dt))
            e = run_.p_n[j] - truth.p_n[k]
            out["outages"].append(
                {
                    "start_s": start,
                    "length_s": length,
                    "horiz_err_end_m": float(np.hypot(e[0], e[1])),
                }
            )
    return out
