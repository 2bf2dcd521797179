"""A recorded drive (`dataset.Dataset`) as the board's input: a `host_emulator.stimulus`.

    rep = convert(dataset, ReplayOptions())
    rep.stimulus   # per 5 ms tick: BMI055 registers, PPS, GNSS UART bytes
    rep.truth      # the reference on the run's clock, in the firmware's ENU frame
    rep.gnss       # the fixes sent (after noise and outages), for the report

Time: tick k's state time is T_k = t_start + k * 5 ms (GPST), t_start the first whole GPST
second of the IMU that the reference covers (so the NMEA times and PPS edges fall on whole
seconds of the run's clock). The IMU sample of tick k is the mean rate over [T_k, T_k + 5 ms]
(the firmware integrates tick k's sample up to tick k + 1), cut from the recording's samples
by their cumulative integral, so nothing is lost or counted twice when 100 Hz becomes 200 Hz.

Registers: each axis is quantised to BMI055 counts at the smallest range that keeps the drive
at most 90 % of full scale (or at the range the board settings give, clipped beyond it),
carrying the rounding remainder to the next sample (the sum of the counts stays within one
count of the sum of the values: increments are kept, as an analogue sensor's noise would
dither them). The sensor keeps its own axes: the firmware's `mount_ypr_deg` setting rotates
them into its body frame, as on a board bolted in at an angle. The temperature register reads
23 degC (the recording has none).

GNSS (`_plan_gnss`): at most `gnss_rate_hz` epochs a second, from the recorded GNSS file or
else from the reference: the epochs on that rate's grid when at least half its slots have one
(the RTK solution's .999 s epochs are "whole seconds": the fix is sent as measured at the whole
second, 1 ms late, <2 cm at drive_0708's speeds), else a GNSS file's epochs at their own times.
White noise (north, east, down) from numpy.random.default_rng(seed) drawn for every epoch in
order, no fix during outages (an empty GGA and RMC V, as receivers print). Sent as GGA, GSA and
RMC with 0.1 +- 0.03 s latency at 9600 baud (faster when the epochs need it: `_nmea`), HDOP 1.00
and the firmware's `gnss_uere_m` set to the noise's sigma (so the filter is told sigma_h, and
twice that vertically; a GNSS file's own sigmas set HDOP and gnss_uere_m, `_gnss_sigmas`). A PPS
edge at each fix when every epoch is on a whole second; otherwise none, and `gnss_latency_s`
set to the epochs' measured completion latency (`_latency_s`), so the board times them by their
arrival as it would with such a receiver. No velocity by default (RMC speed and course empty:
the firmware takes its heading from the track); `gnss_velocity_sigma` adds the source's
velocity with that noise, as a receiver's Doppler speed.

Board settings: the ones derived here, then the dataset's (`Dataset.board_config`), then
`ReplayOptions.config` (--set), checked by the firmware's validation (replay/run_config.py).
`Replay.notes` says what was done with the data (anything left out is counted there).
"""

import dataclasses
import datetime
import math
from dataclasses import dataclass, field

import numpy as np
import pymap3d

from common.errors import EmulatorError
from common.proto import stimulus as stim_mod
from host_emulator.replay import carrier, run_config
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
PROTOCOL_SKIP_S = 30.0  # metrics from t0 + this (the protocol)
GNSS_RATES_HZ = (1.0, 2.0, 4.0, 5.0, 10.0)  # --gnss-rate: grids that divide the 5 ms tick
GRID_TOL_S = 0.002  # an epoch this close to the rate's grid is on it (RTK .999 s epochs)
# GNSS UART speeds a replay picks from: at 115200 a 5 ms tick gets 58 bytes, well inside the
# 232 the app reads per tick (app.py _RX_LEN)
GNSS_BAUDS = (9600, 19200, 38400, 57600, 115200)
P_FRD_RFU = ds.SWAP_FRD_RFU  # FRD body -> the firmware's RFU body (and NED -> ENU)


@dataclass(frozen=True)
class ReplayOptions:
    """How the recording is turned into the board's input (defaults: the protocol of
    docs/requirements.md, reference figures, the one other filters were measured with)."""

    gnss_rate_hz: float = 1.0  # epochs per second at most (GNSS_RATES_HZ; see _plan_gnss)
    gnss_noise_m: float | None = 1.5  # per horizontal axis; vertical twice that; None: as given
    outages: tuple = PROTOCOL_OUTAGES  # (start after t0, length) s
    skip_s: float = PROTOCOL_SKIP_S  # metrics from t0 + skip_s (--score-from)
    seed: int = 1
    duration_s: float | None = None  # replay only the first seconds
    gnss_velocity_sigma: float | None = None  # m/s per axis: send velocity (None: positions)
    latency_s: float = 0.1
    latency_jitter_s: float = 0.03
    sensor_defaults: bool = False  # ignore the dataset's board settings (BMI055 defaults)
    config: tuple = ()  # (name, value) board settings applied last (--set, experiments)


@dataclass(eq=False)
class RunTruth:
    """The reference on the run's clock (t = 0 at tick 0), ENU from `origin`, sampled every
    tick (evaluate.errors looks it up by index); ypr NaN where the reference has no
    attitude. `covered`: per tick, whether the reference exists there (between two of its
    epochs at most `max_gap_s` apart, or at a waypoint): only those ticks are scored, never a
    straight line across a gap. `waypoints`: (t_s run clock, (K, 2) east, north m) of a
    reference that is only true at its waypoints, else None."""

    t_s: np.ndarray
    p_n: np.ndarray
    v_n: np.ndarray
    ypr: np.ndarray
    origin: trajectory.Origin
    has_attitude: bool
    covered: np.ndarray | None = None
    max_gap_s: float | None = None
    waypoints: tuple | None = None

    @property
    def kind(self):
        """The reference's kind: waypoints, gaps (some ticks not covered) or continuous."""
        if self.waypoints is not None:
            return "waypoints"
        return "continuous" if self.covered is None or self.covered.all() else "gaps"


# a reference epoch may be this much later than the one before (times their median interval)
# and still be joined to it by a line for scoring; a longer gap is not scored
GAP_FACTOR = 1.5
# a waypoint is scored at the output samples within this of its instant (10 Hz samples: one)
WAYPOINT_TOL_S = 0.05


def max_gap_s(epochs_t_s, factor=GAP_FACTOR):
    """The longest interval between two epochs still joined by a line for scoring: `factor` x
    their median interval (None for fewer than two epochs)."""
    d = np.diff(np.asarray(epochs_t_s, float))
    return factor * float(np.median(d)) if d.size else None


def reference_covered(ref_t_s, t_s, factor=GAP_FACTOR):
    """(per time of t_s: inside the reference, max gap s): a time is covered at an epoch, or
    between two epochs at most max_gap_s apart."""
    ref = np.asarray(ref_t_s, float)
    t = np.asarray(t_s, float)
    max_gap = max_gap_s(ref, factor)
    if max_gap is None:
        return np.abs(t - ref[0]) <= 1e-6 if ref.size else np.zeros(t.size, bool), None
    j = np.clip(np.searchsorted(ref, t), 1, ref.size - 1)
    inside = (t >= ref[0] - 1e-6) & (t <= ref[-1] + 1e-6)
    at_epoch = (np.abs(ref[j] - t) <= 1e-6) | (np.abs(ref[j - 1] - t) <= 1e-6)
    return inside & ((ref[j] - ref[j - 1] <= max_gap + 1e-9) | at_epoch), max_gap


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
    notes: list = field(default_factory=list)  # what was done with the data, for the console
    # board setting -> run_config.DATASET / COMMAND_LINE
    sources: dict = field(default_factory=dict)
    pps: bool = True  # a PPS edge at each epoch (else timed by gnss_latency_s)
    latency_s: float | None = None  # measured completion latency of the epochs (no PPS)
    gnss_recorded: bool = False  # the GNSS input is the dataset's GNSS file (else the reference)


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
    largest = max(lsb_by_range)
    unit = "deg/s" if what == "gyro" else "g"
    raise EmulatorError(
        f"the recording's {what} peaks at {peak:.1f} {unit}, beyond the BMI055's largest range "
        f"(+-{largest} {unit}): are its rates in the right units (rad/s and m/s^2 in a "
        "Dataset; angle and velocity increments, rad and m/s, in a KF-GINS IMU file)?"
    )


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
    wp = dataset.waypoints
    if wp is not None:  # only the waypoint instants are true: scored there alone
        we, wn, _ = pymap3d.geodetic2enu(wp.lat_deg, wp.lon_deg, np.full(len(wp), h0), lat0,
                                         lon0, h0)  # fmt: skip
        t_wp = wp.t_s - t_start
        covered = np.zeros(t_run.size, bool)
        tol = WAYPOINT_TOL_S + 1e-9
        lo, hi = np.searchsorted(t_run, t_wp - tol), np.searchsorted(t_run, t_wp + tol)
        for a, b in zip(lo, hi, strict=True):
            covered[a:b] = True
        max_gap, waypoints = None, (t_wp, np.stack([we, wn], -1))
    else:
        (covered, max_gap), waypoints = reference_covered(tr.t_s, t_abs), None
    return RunTruth(t_run, p, v, ypr, origin, tr.rpy_deg is not None, covered, max_gap,
                    waypoints)  # fmt: skip


def _span(t_s):
    """'GPS week W sow A to B' of a time range (GPST s)."""
    week = math.floor(t_s[0] / ds.WEEK_S)
    a, b = t_s[0] - week * ds.WEEK_S, t_s[-1] - week * ds.WEEK_S
    return f"GPS week {week} sow {a:.3f} to {b:.3f}"


def _part(dataset, role, what):
    name = dataset.files.get(role)
    return f"the {what} ({name})" if name else f"the {what}"


def _no_overlap(dataset, role_a, what_a, t_a, t_b):
    """The message for parts that share no time: each one's span, and the likely cause."""
    a = _part(dataset, role_a, what_a)
    b = _part(dataset, "imu", "IMU")
    weeks = round((t_a[0] - t_b[0]) / ds.WEEK_S)
    shifted = t_a - weeks * ds.WEEK_S
    if weeks and shifted[0] <= t_b[-1] and shifted[-1] >= t_b[0]:
        if dataset.gpsweek is not None:
            column = (
                f"the .nav's week column ({math.floor(t_a[0] / ds.WEEK_S)})"
                if role_a == "truth"
                else "the files' sow columns"
            )
            why = (
                f"they are {abs(weeks)} GPS week(s) apart: {column} and dataset.yaml's gpsweek "
                f"({dataset.gpsweek}) may disagree"
            )
        else:
            why = f"they are {abs(weeks)} GPS week(s) apart: their times count from different weeks"
    else:
        why = (
            "are their times in the same scale (GPS seconds of week; GPST = UTC + 18 s)? Or "
            "are they of different drives?"
        )
    return f"{a} covers {_span(t_a)}, {b} {_span(t_b)}: they do not overlap; {why}"


def _check_spans(dataset):
    """EmulatorError when the reference or the GNSS file shares no time with the IMU (a
    replay of that would fail later with a less telling message)."""
    t_imu = dataset.imu.t_s
    t_ref = dataset.truth.t_s
    if t_ref[-1] <= t_imu[0] or t_ref[0] >= t_imu[-1]:
        raise EmulatorError(_no_overlap(dataset, "truth", "reference", t_ref, t_imu))
    g = dataset.gnss
    if g is not None and len(g) and (g.t_s[-1] <= t_imu[0] or g.t_s[0] >= t_imu[-1]):
        raise EmulatorError(_no_overlap(dataset, "gnss", "GNSS file", g.t_s, t_imu))


@dataclass(eq=False)
class GnssPlan:
    """Which epochs of the GNSS source are sent, when, and whether with PPS."""

    pos: ds.Positions  # the epochs sent, in order
    t_fix_s: np.ndarray  # their measurement times on the run clock
    rate_hz: float  # the grid's rate, or epochs per second at their closest
    pps: bool  # every epoch on a whole second: a PPS edge marks each
    notes: list


def _interpolate(src, t_s):
    """Positions of a reference trajectory at times t_s (linear; sigmas none)."""
    cols = [np.interp(t_s, src.t_s, x) for x in (src.lat_deg, src.lon_deg, src.h_m)]
    v = None
    if src.v_ned_m_s is not None:
        v = np.stack([np.interp(t_s, src.t_s, src.v_ned_m_s[:, j]) for j in range(3)], -1)
    return ds.Positions(t_s, *cols, None, v)


def _plan_gnss(dataset, opt, t_start, t_end):
    """GnssPlan: the source's epochs inside the run (0.5 s from either end), at most
    opt.gnss_rate_hz of them a second.

    When at least half the slots of the rate's grid have an epoch on them (within GRID_TOL_S;
    RTK .999 s epochs count as the next whole second), those are sent at the grid times and
    the others left out. Else a recorded GNSS file's epochs go at their own times, the first
    in each 1 / rate interval of the run clock (1 Hz at x.5 s: all of them); a reference
    without samples on the grid is interpolated at the grid times. PPS only when every epoch
    is on a whole second: the firmware times an epoch by the PPS edge of its second whatever
    its fraction (app.py `_fix_tick`), so a receiver with PPS and epochs between the whole
    seconds would be mistimed; without PPS it times them by arrival - gnss_latency_s."""
    recorded = dataset.gnss is not None
    src = dataset.gnss if recorded else dataset.truth
    what = _part(dataset, "gnss", "GNSS file") if recorded else "the reference"
    notes = []
    inside = (src.t_s > t_start + 0.5) & (src.t_s < t_end - 0.5)
    finite = np.isfinite(src.lat_deg) & np.isfinite(src.lon_deg) & np.isfinite(src.h_m)
    idx = np.flatnonzero(inside & finite)
    if recorded and (~inside).any():
        week_s = ds.WEEK_S * math.floor(t_start / ds.WEEK_S)
        notes.append(
            f"{int((~inside).sum())} epochs of {what} fall outside the replayed span "
            f"({t_start + 0.5 - week_s:.1f} to {t_end - 0.5 - week_s:.1f} s of week): not sent"
        )
    if (inside & ~finite).any():
        notes.append(f"{int((inside & ~finite).sum())} epochs of {what} without a finite "
                     "position: not sent")  # fmt: skip
    rate = opt.gnss_rate_hz
    period = 1.0 / rate
    t = src.t_s[idx]
    if t.size:
        phase = np.abs((t + 0.0015) % period - 0.0015)
        on = phase < GRID_TOL_S
        slots = int(np.floor((t[-1] - t[0]) * rate + 1e-6)) + 1
        if on.sum() >= 0.5 * slots:
            pos = src.select(idx[on])
            t_fix = np.round((pos.t_s - t_start) * rate) / rate
            left = int((~on).sum())
            if recorded and left:
                notes.append(
                    f"{left} epochs of {what} off the {rate:g} Hz grid (--gnss-rate): not sent"
                )
            return GnssPlan(pos, t_fix, rate, _whole(t_fix), notes)
    if not recorded:
        k0 = math.ceil((t_start + 0.5) * rate + 1e-9)
        k1 = math.floor((t_end - 0.5) * rate - 1e-9)
        t_grid = np.arange(k0, k1 + 1) / rate
        notes.append(
            f"the reference has no samples on the {rate:g} Hz grid: the GNSS input is "
            "interpolated from it at the grid's times"
        )
        pos = _interpolate(src, t_grid)
        return GnssPlan(pos, t_grid - t_start, rate, _whole(t_grid - t_start), notes)
    slot = np.floor((t - t_start) * rate + 1e-9)
    first = np.concatenate([[True], slot[1:] != slot[:-1]]) if t.size else np.zeros(0, bool)
    pos = src.select(idx[first])
    t_fix = pos.t_s - t_start
    if not first.all():
        notes.append(
            f"{int((~first).sum())} epochs of {what} after the first in their {period:g} s "
            f"interval: not sent (at most {rate:g} Hz, --gnss-rate)"
        )
    if t_fix.size and not _whole(t_fix):
        notes.append(f"the epochs of {what} are sent at their own times")
    return GnssPlan(pos, t_fix, rate, _whole(t_fix), notes)


def _whole(t_fix):
    """True when every epoch is on a whole second of the run clock."""
    return bool(t_fix.size) and bool((np.abs(t_fix - np.rint(t_fix)) < 1e-9).all())


def _noise(opt, m):
    """(M, 3) NED noise of the GNSS input: numpy default_rng(seed), one draw per epoch."""
    rng = np.random.default_rng(opt.seed)
    noise = np.zeros((m, 3))
    if opt.gnss_noise_m:
        s = opt.gnss_noise_m
        noise = rng.standard_normal((m, 3)) * np.array([s, s, 2.0 * s])
    return noise


def _gnss_sigmas(dataset, pos, opt, notes):
    """(sigma_h told per unit HDOP = the firmware's gnss_uere_m, HDOP per epoch, the HDOP
    gate). With added noise (or no sigmas in the source) every fix says HDOP 1.00 and
    gnss_uere_m is the noise's sigma (the source's own error, centimetres for RTK, is left
    out). A GNSS file given with its sigmas keeps them: HDOP = sigma / median sigma, so the
    firmware's HDOP gate (2) drops fixes more than twice as uncertain as usual; an epoch
    without a usable sigma (NaN, 0) says HDOP 1.00, and is counted in `notes`."""
    if opt.gnss_noise_m or pos.sigma_ned_m is None or dataset.gnss is None:
        s = opt.gnss_noise_m or 1.5
        return s, np.ones(len(pos)), 2.0
    sig = np.sqrt(0.5 * (pos.sigma_ned_m[:, 0] ** 2 + pos.sigma_ned_m[:, 1] ** 2))
    ok = np.isfinite(sig) & (sig > 0.0)
    if not ok.any():
        raise EmulatorError(
            f"{_part(dataset, 'gnss', 'GNSS file')} has no usable sd_n/sd_e (all zero or "
            "missing): give the fixes' standard deviations, or --gnss-noise to add noise"
        )
    uere = float(np.median(sig[ok]))
    if not ok.all():
        notes.append(
            f"{int((~ok).sum())} epochs of {_part(dataset, 'gnss', 'GNSS file')} without a "
            f"usable sd_n/sd_e: sent with HDOP 1.00 (sigma {uere:.3g} m, the median)"
        )
    hdop = np.where(ok, np.maximum(np.round(np.where(ok, sig, uere) / uere, 2), 0.01), 1.0)
    return uere, hdop, 2.0  # the firmware's gate: fixes twice as bad as usual are dropped


def _ranges(gyro, accel, user, sources, notes):
    """(gyro counts, accel counts, ranges dict): the BMI055 ranges the user set (samples beyond
    full scale clipped, as the sensor saturates, and counted) or the smallest that hold the
    recording."""
    g_peak = float(np.degrees(np.abs(gyro).max()))
    a_peak = float(np.abs(accel).max() / G0)
    out = []
    for key, x, peak, lsb_by, full, what in (
        ("gyro_range_dps", np.degrees(gyro), g_peak, imu_mod.GYRO_LSB_PER_DPS_BY_RANGE, 32767,
         "gyro"),
        ("accel_range_g", accel / G0, a_peak, imu_mod.ACCEL_LSB_PER_G_BY_RANGE, 2047,
         "accelerometer"),
    ):  # fmt: skip
        if key in user:
            rng = int(user[key])
            counts = quantise(x, 1.0 / lsb_by[rng])
            clipped = int((np.abs(counts) > full).any(axis=1).sum())
            if clipped:
                notes.append(
                    f"{clipped} {what} samples beyond +-{rng} ({key} from "
                    f"{sources[key]}) clipped at full scale, as the sensor saturates"
                )
            counts = np.clip(counts, -full - 1, full)
        else:
            rng = pick_range(peak, lsb_by, full, what)
            counts = quantise(x, 1.0 / lsb_by[rng])
        out.append((rng, counts))
    (g_range, gyro_counts), (a_range, accel_counts) = out
    ranges = {"gyro_range_dps": g_range, "gyro_peak_dps": g_peak, "accel_range_g": a_range,
              "accel_peak_g": a_peak}  # fmt: skip
    return gyro_counts, accel_counts, ranges


def _with_baud(gnss, baud):
    return dataclasses.replace(gnss, model=dataclasses.replace(gnss.model, baud=baud))


def _nmea(gnss, user_baud, source):
    """(epochs as nmea.stream gives them, baud): the user's gnss_baud, or the slowest of
    GNSS_BAUDS on which each epoch's sentences take at most half the shortest interval
    between epochs (9600 at 1 Hz, as receivers ship)."""
    trial = _with_baud(gnss, baud=user_baud or GNSS_BAUDS[-1])
    try:
        epochs, _damaged = nmea.stream(trial)  # nothing damaged: corrupt_per_sentence 0
    except ValueError as e:
        raise EmulatorError(f"gnss_baud {user_baud} ({source}): {e}") from None
    longest = max((len(d) for _, d in epochs), default=0)
    t = gnss.t_fix_s
    shortest = float(np.min(np.diff(t))) if t.size > 1 else 1.0
    if user_baud:
        if longest * 10.0 / user_baud > shortest:
            raise EmulatorError(
                f"gnss_baud {user_baud} ({source}) cannot carry the GNSS epochs: {longest} "
                f"bytes of NMEA each, {shortest:.3g} s apart at the closest; set a faster "
                "gnss_baud or a lower --gnss-rate"
            )
        return epochs, user_baud
    baud = next((b for b in GNSS_BAUDS if longest * 10.0 / b <= 0.5 * shortest), GNSS_BAUDS[-1])
    if baud == trial.model.baud:
        return epochs, baud
    return nmea.stream(_with_baud(gnss, baud=baud))[0], baud


def _latency_s(epochs, gnss, baud):
    """How long after its measurement time the firmware completes an epoch (GGA and RMC in):
    the tick that receives the RMC's CR, median over the fixes, to the tick."""
    byte_s = 10.0 / baud
    ends = np.array([t0 + (len(d) - 1) * byte_s for t0, d in epochs])
    ticks = np.ceil(ends / TICK_S - 1e-9)
    fix = gnss.quality > 0
    lag = ticks[fix] * TICK_S - gnss.t_fix_s[fix]
    return float(np.round(np.median(lag) / TICK_S) * TICK_S)


def convert(dataset, opt=None):
    """Replay of a Dataset under the options (EmulatorError when they cannot be met)."""
    opt = opt or ReplayOptions()
    _check_options(opt)
    notes = []
    user, sources = _board_settings(dataset, opt)
    _check_spans(dataset)
    t_start, t_end, n = _replayed_span(dataset, opt, notes)
    imu = dataset.imu
    t_ticks = t_start + np.arange(n) * TICK_S
    gyro = resample(imu.t_s, imu.gyro_rad_s, t_ticks)
    accel = resample(imu.t_s, imu.accel_m_s2, t_ticks)
    gyro_counts, accel_counts, ranges = _ranges(gyro, accel, user, sources, notes)

    truth = _truth_on_ticks(dataset, t_start, n)
    plan = _plan_gnss(dataset, opt, t_start, t_end)
    notes += plan.notes
    if len(plan.pos) < 10:
        raise EmulatorError(
            f"only {len(plan.pos)} GNSS epochs at {opt.gnss_rate_hz:g} Hz in the replayed span "
            f"({t_end - t_start:.1f} s from {_span(np.array([t_start]))}); a replay needs 10"
        )
    noise = _noise(opt, len(plan.pos))
    t0 = float(plan.t_fix_s[0])
    outages = _run_outages(opt.outages, t0, n * TICK_S, notes)
    gnss, sigma_h, hdop_max = _gnss_sent(dataset, opt, plan, truth, noise, outages, t_start, notes)
    epochs, baud = _nmea(gnss, user.get("gnss_baud"), sources.get("gnss_baud"))
    gnss = _with_baud(gnss, baud=baud)
    offs, data = nmea.per_tick(epochs, baud, n, TICK_S)
    config = {
        "gyro_range_dps": int(ranges["gyro_range_dps"]),
        "accel_range_g": int(ranges["accel_range_g"]),
        "gnss_baud": int(baud),
        "lever_b_m": [float(x) for x in gnss.model.lever_b_m],
        "mount_ypr_deg": [float(x) for x in mount_ypr_deg(dataset.mount_rpy_deg)],
        "gnss_uere_m": float(sigma_h),
        "gnss_hdop_max": float(hdop_max),
    }
    latency = None
    if not plan.pps:
        latency = _latency_s(epochs, gnss, baud)
        if "gnss_latency_s" not in user:
            config["gnss_latency_s"] = latency
    notes.append(_gnss_note(plan, len(plan.pos), baud, latency, user, sources))
    notes.append(_profile(gyro_counts, accel_counts, ranges, config, user, sources))
    config.update(user)
    run_config.check_scorable(config, sources)
    refused = run_config.problem(config)
    if refused:
        raise EmulatorError(f"the firmware refuses the replay's board settings: {refused}")
    head = _stimulus_header(dataset, opt, plan, config, outages, gnss.model, t_start, t0)
    stim = stim_mod.from_arrays(
        head,
        gyro_counts,
        accel_counts,
        np.zeros(n, np.int8),
        board_input.pps_per_tick(gnss.pps_s, n),
        (offs, data),
    )
    return Replay(
        dataset.name, stim, truth, gnss, t_start, t0, t0 + opt.skip_s, outages, opt, ranges,
        notes=notes, sources=sources, pps=plan.pps, latency_s=latency,
        gnss_recorded=dataset.gnss is not None,
    )  # fmt: skip


def _check_options(opt):
    """EmulatorError for a GNSS rate, GNSS noise or --score-from out of range."""
    if opt.gnss_rate_hz not in GNSS_RATES_HZ:
        raise EmulatorError("--gnss-rate must be 1, 2, 4, 5 or 10 Hz")
    if opt.gnss_noise_m is not None and not 0.0 <= opt.gnss_noise_m <= 100.0:
        raise EmulatorError("--gnss-noise must be 0 to 100 m")
    if not opt.skip_s >= 0.0:
        raise EmulatorError("--score-from must be 0 or more")


def _board_settings(dataset, opt):
    """(the board settings given, where each came from: run_config.DATASET / COMMAND_LINE)."""
    # board settings: the dataset's, then the options' (--set); the replay's own go first
    ds_cfg = {} if opt.sensor_defaults else dict(dataset.board_config)
    user = {**ds_cfg, **dict(opt.config)}
    sources = {name: run_config.DATASET for name in ds_cfg}
    sources.update((name, run_config.COMMAND_LINE) for name, _ in opt.config)
    return user, sources


def _replayed_span(dataset, opt, notes):
    """(t_start, t_end GPST s, ticks): the whole GPST second where both the IMU and the
    reference have begun, to where either ends (or --duration); IMU data left out is noted.
    EmulatorError under 20 s."""
    imu = dataset.imu
    t_start = float(np.ceil(max(imu.t_s[0], dataset.truth.t_s[0])))
    t_end = min(float(imu.t_s[-1]), float(dataset.truth.t_s[-1]))
    cut = [(t_start - float(imu.t_s[0]), "before the reference starts"),
           (float(imu.t_s[-1]) - t_end, "after the reference ends")]  # fmt: skip
    for span_s, where in cut:
        if span_s > 1.0:
            notes.append(f"{span_s:.1f} s of IMU data {where}: not replayed")
    if opt.duration_s is not None:
        t_end = min(t_end, t_start + opt.duration_s)
    n = int(np.floor((t_end - t_start) / TICK_S + 1e-9)) - 1
    if n < 200 * 20:
        limit = " (--duration)" if opt.duration_s is not None else ""
        imu_part = _part(dataset, "imu", "IMU")
        ref_part = _part(dataset, "truth", "reference")
        raise EmulatorError(
            f"only {max(t_end - t_start, 0.0):.1f} s to replay{limit}: {imu_part} covers "
            f"{_span(imu.t_s)}, {ref_part} {_span(dataset.truth.t_s)}; a replay needs 20 s "
            "of both"
        )
    return t_start, t_end, n


def _run_outages(outages_after_t0, t0, duration_s, notes):
    """The outages (start, length) on the run clock; those beginning after the end noted."""
    outages = []
    for s, length in outages_after_t0:
        if t0 + s < duration_s:
            outages.append((t0 + s, length))
        else:
            notes.append(f"outage {s:g}+{length:g} s begins after the replay's end: not applied")
    return outages


def _gnss_sent(dataset, opt, plan, truth, noise, outages, t_start, notes):
    """(GnssData of the epochs sent, sigma_h = gnss_uere_m, the HDOP gate): the planned epochs
    with the noise added, no fix inside the outages, and the source's velocity with
    --gnss-velocity's noise if asked."""
    pos, t_fix = plan.pos, plan.t_fix_s
    in_out = np.zeros(t_fix.size, bool)
    for s, length in outages:
        in_out |= (t_fix >= s) & (t_fix < s + length)
    lat, lon, h = pymap3d.ned2geodetic(
        noise[:, 0], noise[:, 1], noise[:, 2], pos.lat_deg, pos.lon_deg, pos.h_m
    )
    fix = ~in_out
    m = t_fix.size
    lat_e7 = np.where(fix, np.rint(np.asarray(lat) * 1e7), 0).astype(np.int64)
    lon_e7 = np.where(fix, np.rint(np.asarray(lon) * 1e7), 0).astype(np.int64)
    p_ant, err_enu = _antenna_and_error_enu(dataset, pos, t_fix, noise, truth)
    sigma_h, hdop, hdop_max = _gnss_sigmas(dataset, pos, opt, notes)
    speed_m_s, course_deg, v_ant = _gnss_velocity(dataset, pos, opt)
    lat_rng = np.random.default_rng([opt.seed, 0x4C4154])
    t_avail = t_fix + opt.latency_s + opt.latency_jitter_s * lat_rng.uniform(-1, 1, m)
    utc = ds.gpst_datetime(t_start) - datetime.timedelta(seconds=LEAP_S)
    model = gnss_mod.GnssModel(
        rate_hz=plan.rate_hz,
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
        speed_m_s=np.where(fix, speed_m_s, np.nan),
        course_deg=np.where(fix, course_deg, np.nan),
        hdop=np.where(fix, hdop, np.nan),
        quality=np.where(fix, 1, 0).astype(np.int8),
        nsat=np.where(fix, 12, 0).astype(np.int8),
        sigma_h_m=np.where(fix, sigma_h * hdop, np.nan),
        sigma_v_m=np.where(fix, 2.0 * sigma_h * hdop, np.nan),
        sigma_vel_m_s=np.where(fix, opt.gnss_velocity_sigma or np.nan, np.nan),
        pps_s=t_fix[fix] if plan.pps else np.zeros(0),
        p_ant_n=p_ant,
        v_ant_n=v_ant,
        err_n_m=err_enu,
        outages=tuple(outages),
        model=model,
    )
    return gnss, sigma_h, hdop_max


def _antenna_and_error_enu(dataset, pos, t_fix, noise, truth):
    """(antenna positions ENU from the truth's origin, the fixes' errors ENU): the source's
    positions and the added noise; for a recorded GNSS input, the reference at each epoch and
    the fix's whole error against it."""
    o = truth.origin
    e, nn, u = pymap3d.geodetic2enu(
        pos.lat_deg, pos.lon_deg, pos.h_m, o.lat_e7 * 1e-7, o.lon_e7 * 1e-7, o.h_m
    )
    p_ant = np.stack([e, nn, u], axis=-1)
    err_enu = noise @ P_FRD_RFU.T
    if dataset.gnss is not None:  # a recorded GNSS input: its error against the reference
        k = np.clip(np.rint(t_fix / TICK_S).astype(np.int64), 0, len(truth.p_n) - 1)
        err_enu = p_ant + err_enu - truth.p_n[k]  # (includes the lever arm, if any)
        p_ant = truth.p_n[k]
    return p_ant, err_enu


def _gnss_velocity(dataset, pos, opt):
    """(RMC speed m/s, course deg: NaN unless --gnss-velocity, and the course also below
    0.5 m/s; the source's velocity ENU, zero without one). EmulatorError when
    --gnss-velocity is asked of a source without velocities."""
    m = len(pos)
    nan = np.full(m, np.nan)
    speed, course = nan.copy(), nan.copy()
    v_ant = np.zeros((m, 3))
    if pos.v_ned_m_s is not None:
        v_ant = pos.v_ned_m_s @ P_FRD_RFU.T
    if opt.gnss_velocity_sigma is not None:
        if pos.v_ned_m_s is None:
            raise EmulatorError(
                f"--gnss-velocity: {_part(dataset, 'gnss', 'GNSS file')} has no velocity "
                "columns (the 13-column form has them); leave --gnss-velocity out"
                if dataset.gnss is not None
                else f"--gnss-velocity: {_part(dataset, 'truth', 'reference')} has no "
                "velocities; leave --gnss-velocity out"
            )
        vrng = np.random.default_rng([opt.seed, 0x56454C])
        v_meas = v_ant + opt.gnss_velocity_sigma * vrng.standard_normal((m, 3))
        speed = np.hypot(v_meas[:, 0], v_meas[:, 1])
        course = np.degrees(np.arctan2(v_meas[:, 0], v_meas[:, 1])) % 360.0
        course[speed < 0.5] = np.nan
    return speed, course, v_ant


def _stimulus_header(dataset, opt, plan, config, outages, model, t_start, t0):
    """The stimulus header of the replay (Stimulus.header)."""
    return {
        "source": "replay",
        "dataset": dataset.name,
        "tick_us": TICK_US,
        "config": config,
        "outages": [[float(s), float(length)] for s, length in outages],
        "utc_start": model.utc_start,
        "gnss_rate_hz": float(plan.rate_hz),
        "t_start_gpst": t_start,
        "t0_s": t0,
        "replay": {
            "gnss_noise_m": opt.gnss_noise_m,
            "outages_after_t0": [list(x) for x in opt.outages],
            "skip_s": opt.skip_s,
            "seed": opt.seed,
            "gnss_velocity_sigma": opt.gnss_velocity_sigma,
            "gnss_pps": plan.pps,
        },
    }


def _profile(gyro_counts, accel_counts, ranges, config, user, sources):
    """The board's profile for the replay, and the note that says which and why: the one
    given (dataset or --set), else the one the IMU shows (carrier.py: a walker's steps or a
    hand's tilting, the handheld profile); a car profile given for a walker's data is said
    loudly."""
    lsb = imu_mod.ACCEL_LSB_PER_G_BY_RANGE[int(ranges["accel_range_g"])]
    lsb_g = imu_mod.GYRO_LSB_PER_DPS_BY_RANGE[int(ranges["gyro_range_dps"])]
    gait = carrier.gait(accel_counts / lsb * carrier.G_M_S2, TICK_S,
                        np.radians(gyro_counts / lsb_g))  # fmt: skip
    if "profile" not in user:
        config["profile"] = 1 if gait.walking else 0
        sources["profile"] = run_config.DETECTED
        if gait.walking:
            return (f"profile 1 (handheld), chosen from the data: {gait.describe()}; "
                    "--set profile=0 runs it as a vehicle")  # fmt: skip
        return f"profile 0 (car): {gait.describe()}"
    given = int(user["profile"])
    if given == 0 and gait.walking:
        return (f"WARNING: profile=0 (car; {sources['profile']}), but {gait.describe()}: a "
                "board carried by a person, whom the car's non-holonomic constraint and "
                "standstill thresholds do not fit; --set profile=1 runs it as one")  # fmt: skip
    what = "handheld" if given == 1 else "car"
    return f"profile {given} ({what}; {sources['profile']}): {gait.describe()}"


def _gnss_note(plan, m, baud, latency, user, sources):
    """One line: the epochs sent, their timing (PPS, or latency) and the baud."""
    line = f"GNSS: {m} epochs at up to {plan.rate_hz:g} Hz, NMEA at {baud} baud"
    if plan.pps:
        return line + ", a PPS edge at each (every epoch is on a whole second)"
    line += (
        ", no PPS: not every epoch is on a whole second (the firmware would time each by the "
        "PPS edge of its second); the board times them by arrival - gnss_latency_s"
    )
    if "gnss_latency_s" in user:
        return line + (
            f" = {user['gnss_latency_s']:g} s ({sources['gnss_latency_s']}; the epochs "
            f"complete {latency:.3f} s after their time)"
        )
    return line + f" = {latency:.3f} s (the epochs' completion, measured on the stimulus)"
