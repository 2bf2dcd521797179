"""A recorded drive (`dataset.Dataset`) as the board's input: a `host_emulator.stimulus`.

    rep = convert(dataset, ReplayOptions())
    rep.stimulus   # per 5 ms tick: BMI055 registers, PPS, GNSS UART bytes
    rep.truth      # the reference on the run's clock, in the firmware's ENU frame
    rep.gnss       # the fixes sent (after noise and outages), for the report

Time: tick k's state time is T_k = t_start + k * 5 ms (GPST), t_start a whole GPST second
(so the NMEA times and PPS edges fall on whole seconds of the run's clock). The IMU sample of
tick k is the mean rate over [T_k, T_k + 5 ms] (the firmware integrates tick k's sample up to
tick k + 1), cut from the recording's samples by their cumulative integral, so nothing is
lost or counted twice when 100 Hz becomes 200 Hz.

Registers: each axis is quantised to BMI055 counts at the smallest range that keeps the drive
at most 90 % of full scale, carrying the rounding remainder to the next sample (the sum of
the counts stays within one count of the sum of the values: increments are kept, as an
analogue sensor's noise would dither them). The sensor keeps its own axes: the firmware's
`mount_ypr_deg` setting rotates them into its body frame, as on a board bolted in at an
angle. The temperature register reads 23 degC (the recording has none).

GNSS: fixes at the epochs of the chosen rate (the RTK solution's .999 s epochs are "whole
seconds": the fix is sent as measured at the whole second, 1 ms late, <2 cm at this drive's
speeds), white noise (north, east, down) from numpy.random.default_rng(seed) drawn for every
epoch in order, no fix during outages (an empty GGA and RMC V, as receivers print). Sent as
GGA, GSA and RMC at 9600 baud with 0.1 +- 0.03 s latency, a PPS edge at every whole second
with a fix, HDOP 1.00 and the firmware's `gnss_uere_m` set to the noise's sigma (so the filter
is told sigma_h, and twice that vertically). No velocity by default (RMC speed and course
empty: the firmware takes its heading from the track); `gnss_velocity_sigma` adds the RTK
velocity with that noise, as a receiver's Doppler speed.
"""

import datetime
from dataclasses import dataclass, field

import numpy as np
import pymap3d

from host_emulator.errors import EmulatorError
from host_emulator.proto import stimulus as stim_mod
from host_emulator.replay import dataset as ds
from host_emulator.sim import board_input, nmea, trajectory
from host_emulator.sim import gnss as gnss_mod
from host_emulator.sim import imu as imu_mod

TICK_US = stim_mod.TICK_US
TICK_S = TICK_US * 1e-6
LEAP_S = 18  # GPST - UTC since 2017
G0 = 9.80665  # the unit g of the BMI055's sensitivity
FULL_SCALE_USE = 0.9
PROTOCOL_OUTAGES = ((60.0, 15.0), (200.0, 15.0), (400.0, 15.0))  # after t0, s
P_FRD_RFU = ds.SWAP_FRD_RFU  # FRD body -> the firmware's RFU body (and NED -> ENU)


@dataclass(frozen=True)
class ReplayOptions:
    """How the recording is turned into the board's input (defaults: the protocol of
    DESIGN.md 10, the one other filters were measured with)."""

    gnss_rate_hz: float = 1.0
    gnss_noise_m: float | None = 1.5  # per horizontal axis; vertical twice that; None: as given
    outages: tuple = PROTOCOL_OUTAGES  # (start after t0, length) s
    skip_s: float = 30.0  # metrics from t0 + skip_s
    seed: int = 1
    duration_s: float | None = None  # replay only the first seconds
    gnss_velocity_sigma: float | None = None  # m/s per axis: send velocity (None: positions)
    latency_s: float = 0.1
    latency_jitter_s: float = 0.03
    sensor_defaults: bool = False  # ignore the dataset's board settings (BMI055 defaults)
    config: tuple = ()  # (name, value) board settings applied last (experiments, reports)


@dataclass(eq=False)
class RunTruth:
    """The reference on the run's clock (t = 0 at tick 0), ENU from `origin`, sampled every
    tick (evaluate.errors looks it up by index); ypr NaN where the reference has no
    attitude."""

    t_s: np.ndarray
    p_n: np.ndarray
    v_n: np.ndarray
    ypr: np.ndarray
    origin: trajectory.Origin
    has_attitude: bool


@dataclass(eq=False)
class Replay:
    name: str
    stimulus: stim_mod.Stimulus
    truth: RunTruth
    gnss: gnss_mod.GnssData
    t_start_gpst: float  # GPST of tick 0
    t0_s: float  # first GNSS epoch used, run clock
    window_s: float  # metrics from here (run clock)
    outages: list  # (start, length) on the run clock
    options: ReplayOptions
    ranges: dict = field(default_factory=dict)


def mount_ypr_deg(rpy_deg):
    """The firmware's `mount_ypr_deg` (rot.py convention: sensor axes as a "body" in the
    right-forward-up frame) of a dataset's FRD mounting."""
    c = P_FRD_RFU @ ds.mount_matrix(rpy_deg)  # sensor -> RFU, the firmware's C_bn form
    pitch = np.arcsin(np.clip(c[2, 1], -1.0, 1.0))
    roll = np.arctan2(-c[2, 0], c[2, 2])
    yaw = np.arctan2(-c[0, 1], c[1, 1])
    return np.degrees([yaw, pitch, roll])


def resample(t_s, rate, t_ticks):
    """Mean of a piecewise-constant rate (value i over (t[i-1], t[i]]) over each interval
    [t_ticks[k], t_ticks[k] + TICK_S]: differences of its cumulative integral."""
    dt = np.diff(t_s, prepend=t_s[0] - np.median(np.diff(t_s)))
    cum = np.concatenate([np.zeros((1, 3)), np.cumsum(rate * dt[:, None], axis=0)])
    t_cum = np.concatenate([[t_s[0] - dt[0]], t_s])
    edges = np.concatenate([t_ticks, [t_ticks[-1] + TICK_S]])
    c = np.stack([np.interp(edges, t_cum, cum[:, j]) for j in range(3)], axis=-1)
    return np.diff(c, axis=0) / TICK_S


def quantise(x, per_count):
    """Counts of x (N, 3) with the rounding remainder carried forward (error feedback)."""
    q = np.rint(np.cumsum(x / per_count, axis=0))
    return np.diff(q, axis=0, prepend=np.zeros((1, 3))).astype(np.int64)


def pick_range(peak, lsb_by_range, full_counts, what):
    """The smallest range (largest LSB per unit) whose full scale covers peak / 0.9."""
    for rng in sorted(lsb_by_range, key=lambda r: -lsb_by_range[r]):
        if peak * lsb_by_range[rng] <= FULL_SCALE_USE * full_counts:
            return rng
    raise EmulatorError(f"the recording's {what} peak {peak:.1f} exceeds every BMI055 range")


def antenna_to_imu(truth_enu, v_enu, lever_frd_m):
    """IMU positions from antenna positions: p_imu = p_ant - C_bn l, with the heading from
    the reference's course (held below 1 m/s) and the vehicle taken level (the lever arms
    of interest are centimetres: this is exact to a fraction of them)."""
    course = np.arctan2(v_enu[:, 0], v_enu[:, 1])
    moving = np.hypot(v_enu[:, 0], v_enu[:, 1]) > 1.0
    if moving.any():
        idx = np.maximum.accumulate(np.where(moving, np.arange(len(course)), 0))
        first = np.argmax(moving)
        idx[:first] = first
        course = course[idx]
    else:
        course = np.zeros(len(course))
    f, r, d = lever_frd_m
    sc, cc = np.sin(course), np.cos(course)
    east = f * sc + r * cc
    north = f * cc - r * sc
    return truth_enu - np.stack([east, north, -d * np.ones_like(east)], axis=-1)


def _truth_on_ticks(dataset, t_start, n_ticks):
    """RunTruth sampled at every tick's state time (linear interpolation of the reference)."""
    tr = dataset.truth
    t_run = np.arange(n_ticks + 1) * TICK_S
    t_abs = t_start + t_run
    if t_abs[-1] > tr.t_s[-1] + 1e-6 or t_abs[0] < tr.t_s[0] - 1e-6:
        raise EmulatorError("the reference trajectory does not cover the replayed span")
    origin = trajectory.Origin(
        int(round(tr.lat_deg[0] * 1e7)), int(round(tr.lon_deg[0] * 1e7)), float(tr.h_m[0])
    )
    lat0, lon0, h0 = origin.lat_e7 * 1e-7, origin.lon_e7 * 1e-7, origin.h_m
    e, n, u = pymap3d.geodetic2enu(tr.lat_deg, tr.lon_deg, tr.h_m, lat0, lon0, h0)
    p = np.stack([np.interp(t_abs, tr.t_s, x) for x in (e, n, u)], axis=-1)
    if tr.v_ned_m_s is not None:
        v_ned = np.stack([np.interp(t_abs, tr.t_s, tr.v_ned_m_s[:, j]) for j in range(3)], -1)
        v = v_ned @ P_FRD_RFU.T
    else:
        v = np.gradient(p, TICK_S, axis=0)
    if dataset.truth_point == "antenna":
        p = antenna_to_imu(p, v, dataset.lever_frd_m)
    ypr = np.full((t_run.size, 3), np.nan)
    if tr.rpy_deg is not None:
        rpy = np.radians(tr.rpy_deg)
        yaw = np.unwrap(rpy[:, 2])
        ypr[:, 0] = trajectory.wrap_pi(-np.interp(t_abs, tr.t_s, yaw))
        ypr[:, 1] = np.interp(t_abs, tr.t_s, rpy[:, 1])
        ypr[:, 2] = np.interp(t_abs, tr.t_s, rpy[:, 0])
    return RunTruth(t_run, p, v, ypr, origin, tr.rpy_deg is not None)


def _gnss_epochs(dataset, opt, t_start, t_end):
    """(Positions of the GNSS input epochs inside the run, noise NED (M, 3))."""
    src = dataset.gnss if dataset.gnss is not None else dataset.truth
    period = 1.0 / opt.gnss_rate_hz
    # epochs at multiples of the period (RTK .999 epochs count as the next whole second)
    phase = np.abs((src.t_s + 0.0015) % period - 0.0015)
    keep = (phase < 0.002) & (src.t_s > t_start + 0.5) & (src.t_s < t_end - 0.5)
    pos = src.select(np.nonzero(keep)[0])
    if len(pos) < 10:
        raise EmulatorError(
            f"only {len(pos)} GNSS epochs at {opt.gnss_rate_hz:g} Hz in the replayed span"
        )
    rng = np.random.default_rng(opt.seed)
    noise = np.zeros((len(pos), 3))
    if opt.gnss_noise_m:
        s = opt.gnss_noise_m
        noise = rng.standard_normal((len(pos), 3)) * np.array([s, s, 2.0 * s])
    return pos, noise


def _gnss_sigmas(dataset, pos, opt):
    """(sigma_h told per unit HDOP = the firmware's gnss_uere_m, HDOP per epoch, the HDOP
    gate). With added noise (or no sigmas in the source) every fix says HDOP 1.00 and
    gnss_uere_m is the noise's sigma (the source's own error, centimetres for RTK, is left
    out). A GNSS file given with its sigmas keeps them: HDOP = sigma / median sigma, so the
    firmware's HDOP gate (2) drops fixes more than twice as uncertain as usual."""
    if opt.gnss_noise_m or pos.sigma_ned_m is None or dataset.gnss is None:
        s = opt.gnss_noise_m or 1.5
        return s, np.ones(len(pos)), 2.0
    sig = np.sqrt(0.5 * (pos.sigma_ned_m[:, 0] ** 2 + pos.sigma_ned_m[:, 1] ** 2))
    uere = float(np.median(sig))
    if not uere > 0.0:
        raise EmulatorError("the GNSS file's horizontal sigmas are zero")
    hdop = np.maximum(np.round(sig / uere, 2), 0.01)
    return uere, hdop, 2.0  # the firmware's gate: fixes twice as bad as usual are dropped


def convert(dataset, opt=None):
    """Replay of a Dataset under the options (EmulatorError when they cannot be met)."""
    opt = opt or ReplayOptions()
    if opt.gnss_rate_hz not in (1.0, 2.0, 4.0, 5.0, 10.0):
        raise EmulatorError("--gnss-rate must be 1, 2, 4, 5 or 10 Hz")
    if opt.gnss_noise_m is not None and not 0.0 <= opt.gnss_noise_m <= 100.0:
        raise EmulatorError("--gnss-noise must be 0 to 100 m")
    imu = dataset.imu
    t_start = float(np.ceil(imu.t_s[0]))
    t_end = min(float(imu.t_s[-1]), float(dataset.truth.t_s[-1]))
    if opt.duration_s is not None:
        t_end = min(t_end, t_start + opt.duration_s)
    n = int(np.floor((t_end - t_start) / TICK_S + 1e-9)) - 1
    if n < 200 * 20:
        raise EmulatorError("less than 20 s of IMU data to replay")
    t_ticks = t_start + np.arange(n) * TICK_S
    gyro = resample(imu.t_s, imu.gyro_rad_s, t_ticks)
    accel = resample(imu.t_s, imu.accel_m_s2, t_ticks)

    g_peak = float(np.degrees(np.abs(gyro).max()))
    a_peak = float(np.abs(accel).max() / G0)
    g_range = pick_range(g_peak, imu_mod.GYRO_LSB_PER_DPS_BY_RANGE, 32767, "gyro")
    a_range = pick_range(a_peak, imu_mod.ACCEL_LSB_PER_G_BY_RANGE, 2047, "accelerometer")
    g_lsb = imu_mod.GYRO_LSB_PER_DPS_BY_RANGE[g_range]
    a_lsb = imu_mod.ACCEL_LSB_PER_G_BY_RANGE[a_range]
    gyro_counts = quantise(np.degrees(gyro), 1.0 / g_lsb)
    accel_counts = quantise(accel / G0, 1.0 / a_lsb)

    truth = _truth_on_ticks(dataset, t_start, n)
    pos, noise = _gnss_epochs(dataset, opt, t_start, t_end)
    t_fix = np.round((pos.t_s - t_start) * opt.gnss_rate_hz) / opt.gnss_rate_hz
    t0 = float(t_fix[0])
    outages = [(t0 + s, length) for s, length in opt.outages]
    in_out = np.zeros(t_fix.size, bool)
    for s, length in outages:
        in_out |= (t_fix >= s) & (t_fix < s + length)

    o = truth.origin
    lat, lon, h = pymap3d.ned2geodetic(
        noise[:, 0], noise[:, 1], noise[:, 2], pos.lat_deg, pos.lon_deg, pos.h_m
    )
    fix = ~in_out
    m = t_fix.size
    lat_e7 = np.where(fix, np.rint(np.asarray(lat) * 1e7), 0).astype(np.int64)
    lon_e7 = np.where(fix, np.rint(np.asarray(lon) * 1e7), 0).astype(np.int64)
    e, nn, u = pymap3d.geodetic2enu(
        pos.lat_deg, pos.lon_deg, pos.h_m, o.lat_e7 * 1e-7, o.lon_e7 * 1e-7, o.h_m
    )
    p_ant = np.stack([e, nn, u], axis=-1)
    err_enu = noise @ P_FRD_RFU.T
    if dataset.gnss is not None:  # a recorded GNSS input: its error against the reference
        k = np.clip(np.rint(t_fix / TICK_S).astype(np.int64), 0, n)
        err_enu = p_ant + err_enu - truth.p_n[k]  # (includes the lever arm, if any)
        p_ant = truth.p_n[k]
    sigma_h, hdop, hdop_max = _gnss_sigmas(dataset, pos, opt)
    nan = np.full(m, np.nan)
    speed, course = nan.copy(), nan.copy()
    v_ant = np.zeros((m, 3))
    if pos.v_ned_m_s is not None:
        v_ant = pos.v_ned_m_s @ P_FRD_RFU.T
    if opt.gnss_velocity_sigma is not None:
        if pos.v_ned_m_s is None:
            raise EmulatorError("the GNSS source has no velocities to send")
        vrng = np.random.default_rng([opt.seed, 0x56454C])
        v_meas = v_ant + opt.gnss_velocity_sigma * vrng.standard_normal((m, 3))
        speed = np.hypot(v_meas[:, 0], v_meas[:, 1])
        course = np.degrees(np.arctan2(v_meas[:, 0], v_meas[:, 1])) % 360.0
        course[speed < 0.5] = np.nan
    lat_rng = np.random.default_rng([opt.seed, 0x4C4154])
    t_avail = t_fix + opt.latency_s + opt.latency_jitter_s * lat_rng.uniform(-1, 1, m)
    utc = ds.gpst_datetime(t_start) - datetime.timedelta(seconds=LEAP_S)
    model = gnss_mod.GnssModel(
        rate_hz=opt.gnss_rate_hz,
        sigma_h_m=sigma_h,
        sigma_v_m=2.0 * sigma_h,
        corrupt_per_sentence=0.0,
        utc_start=utc.isoformat(),
        lever_b_m=tuple(P_FRD_RFU @ np.asarray(dataset.lever_frd_m, float)),
    )
    gnss = gnss_mod.GnssData(
        t_fix_s=t_fix,
        t_avail_s=t_avail,
        lat_e7=lat_e7,
        lon_e7=lon_e7,
        h_m=np.where(fix, np.asarray(h), 0.0),
        speed_m_s=np.where(fix, speed, np.nan),
        course_deg=np.where(fix, course, np.nan),
        hdop=np.where(fix, hdop, np.nan),
        quality=np.where(fix, 1, 0).astype(np.int8),
        nsat=np.where(fix, 12, 0).astype(np.int8),
        sigma_h_m=np.where(fix, sigma_h * hdop, np.nan),
        sigma_v_m=np.where(fix, 2.0 * sigma_h * hdop, np.nan),
        sigma_vel_m_s=np.where(fix, opt.gnss_velocity_sigma or np.nan, np.nan),
        pps_s=t_fix[fix & (np.abs(t_fix - np.rint(t_fix)) < 1e-9)],
        p_ant_n=p_ant,
        v_ant_n=v_ant,
        err_n_m=err_enu,
        outages=tuple(outages),
        model=model,
    )
    try:
        epochs, _damaged = nmea.stream(gnss)  # nothing damaged: corrupt_per_sentence 0
    except ValueError as e:
        raise EmulatorError(str(e)) from None
    offs, data = nmea.per_tick(epochs, model.baud, n, TICK_S)
    config = {
        "gyro_range_dps": int(g_range),
        "accel_range_g": int(a_range),
        "gnss_baud": int(model.baud),
        "lever_b_m": [float(x) for x in model.lever_b_m],
        "mount_ypr_deg": [float(x) for x in mount_ypr_deg(dataset.mount_rpy_deg)],
        "gnss_uere_m": float(sigma_h),
        "gnss_hdop_max": float(hdop_max),
    }
    if not opt.sensor_defaults:  # else the firmware's BMI055 defaults, for comparison
        config.update(dataset.board_config)
    config.update(dict(opt.config))
    head = {
        "source": "replay",
        "dataset": dataset.name,
        "tick_us": TICK_US,
        "config": config,
        "outages": [[float(s), float(length)] for s, length in outages],
        "utc_start": model.utc_start,
        "gnss_rate_hz": float(opt.gnss_rate_hz),
        "t_start_gpst": t_start,
        "t0_s": t0,
        "replay": {
            "gnss_noise_m": opt.gnss_noise_m,
            "outages_after_t0": [list(x) for x in opt.outages],
            "skip_s": opt.skip_s,
            "seed": opt.seed,
            "gnss_velocity_sigma": opt.gnss_velocity_sigma,
        },
    }
    stim = stim_mod.from_arrays(
        head,
        gyro_counts,
        accel_counts,
        np.zeros(n, np.int8),
        board_input.pps_per_tick(gnss.pps_s, n),
        (offs, data),
    )
    ranges = {"gyro_range_dps": g_range, "gyro_peak_dps": g_peak, "accel_range_g": a_range,
              "accel_peak_g": a_peak}  # fmt: skip
    return Replay(
        dataset.name, stim, truth, gnss, t_start, t0, t0 + opt.skip_s, outages, opt, ranges
    )
