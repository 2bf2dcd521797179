"""GNSS receiver model: fixes of the antenna (position, speed, course) with realistic errors.

Epochs fall on whole multiples of 1/rate_hz of truth time (t = 0 is the top of a GPS second),
each exactly at a truth sample. The antenna sits at `lever_b_m` from the IMU in body axes
(default 0.5 m forward, 1 m up), so its position is p_n + C_bn l and its velocity
v_n + C_bn (w_nb_b x l).

Errors, per epoch k, scaled by s_k = hdop_k / hdop_nominal:
    position  s_k sigma (sqrt(w) white_k + sqrt(1 - w) gm_k), per axis E, N (sigma_h_m)
              and U (sigma_v_m); w = white_fraction (default 0.5: half the variance white,
              half a first-order Gauss-Markov process with 60 s correlation, the slowly
              wandering multipath/atmosphere part that a filter cannot average away)
    velocity  s_k sigma_vel_m_s white noise per axis (default 0.05 m/s)
    sigma_h_m / sigma_v_m / sigma_vel_m_s report s_k sigma, the 1-sigma per axis actually used.
Speed is the horizontal speed over ground, course the track angle in degrees clockwise from
north in [0, 360); like RMC/VTG, course is NaN below course_min_speed_m_s (0.5 m/s).
HDOP wanders in nominal +- hdop_wander (Gauss-Markov, 120 s) and jumps to 2-4 during random
excursions (one per 300 s on average, 5-20 s long), with fewer satellites: both drawn on a
1 Hz grid whatever the rate (the sky's, so receivers at 1-10 Hz of a seed meet the same).
During an outage, or before ttff_s, the receiver still reports each epoch but with quality 0,
lat/lon 0 and NaN floats (an empty GGA). The sentence becomes available latency_s +-
latency_jitter_s after the epoch (default 100 +- 30 ms, DESIGN 8: 50-150 ms). PPS edges are at
whole seconds while the receiver has a fix (always, if pps_without_fix).
Fix quality is 1 (GPS), or 2 (DGPS) during segments of dgps_length_s starting on average
every dgps_every_s (a label only: the errors are the same).
The byte stream the receiver sends (NMEA sentences, baud rate, corrupted sentences) is made by
`sim/nmea.py` from the fields below the line in GnssModel.
Defaults: 1 Hz, sigma 2/2/4 m E/N/U (the KF-GINS benchmark set-up, DESIGN 10).
"""

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .noise import gauss_markov
from .trajectory import RATE_HZ, body_to_nav, euler_to_dcm

_STREAM_GNSS = 0x474E5353  # seeds the receiver's random stream apart from the others


@dataclass(frozen=True)
class GnssModel:
    """Receiver parameters (see the module docstring)."""

    rate_hz: float = 1.0  # must divide 200 Hz: 1, 2, 4, 5, 10
    sigma_h_m: float = 2.0  # per horizontal axis at nominal HDOP
    sigma_v_m: float = 4.0
    white_fraction: float = 0.5  # share of the position variance that is white
    error_tau_s: float = 60.0  # correlation time of the rest
    sigma_vel_m_s: float = 0.05  # per axis
    course_min_speed_m_s: float = 0.5
    hdop_nominal: float = 1.0
    hdop_wander: float = 0.2
    hdop_tau_s: float = 120.0
    excursion_every_s: float = 300.0  # mean interval between HDOP excursions
    excursion_length_s: tuple = (5.0, 20.0)
    excursion_hdop: tuple = (2.0, 4.0)
    latency_s: float = 0.1
    latency_jitter_s: float = 0.03
    # the solution is this much older than its stamp (a receiver whose fixes are late against
    # their epoch and PPS: position and velocity of t - stamp_lag_s reported as t's)
    stamp_lag_s: float = 0.0
    # IMU -> antenna, body axes (right, forward, up); None: the scenario's (Truth.antenna_b_m)
    lever_b_m: tuple | None = None
    ttff_s: float = 0.0  # no fix before this time
    pps_without_fix: bool = False
    dgps_every_s: float = 240.0
    dgps_length_s: tuple = (30.0, 90.0)
    # ---- the byte stream (sim/nmea.py) ----
    baud: int = 9600
    talker: str = "GN"
    sentences: tuple = ("GGA", "GSA", "RMC")  # per epoch, in this order (MTK-like)
    geoid_sep_m: float = -28.0  # GGA separation: MSL altitude = ellipsoidal height - this
    corrupt_per_sentence: float = 0.002  # chance a sentence arrives damaged (a flipped byte)
    utc_start: str = "2026-11-22T02:00:00"  # UTC at t = 0 (a whole second)


class GnssFix(NamedTuple):
    """One epoch as a receiver would report it (quality 0: no fix, other fields empty)."""

    t_fix_s: float
    t_avail_s: float
    lat_e7: int
    lon_e7: int
    h_m: float
    speed_m_s: float
    course_deg: float
    hdop: float
    quality: int
    nsat: int
    sigma_h_m: float
    sigma_v_m: float
    sigma_vel_m_s: float


_FIX_FIELDS = GnssFix._fields


@dataclass(frozen=True, eq=False)
class GnssData:
    """All epochs of a run as arrays (M epochs), the PPS edges, and the truth behind them."""

    t_fix_s: np.ndarray  # (M,) epoch (measurement) time, s, on truth samples
    t_avail_s: np.ndarray  # (M,) when the sentence is available, s
    lat_e7: np.ndarray  # (M,) int64, 1e-7 deg (0 without fix)
    lon_e7: np.ndarray  # (M,) int64
    h_m: np.ndarray  # (M,) ellipsoidal height, m
    speed_m_s: np.ndarray  # (M,) horizontal speed over ground
    course_deg: np.ndarray  # (M,) clockwise from north, [0, 360), NaN when slow or no fix
    hdop: np.ndarray  # (M,)
    quality: np.ndarray  # (M,) int8: 1 GPS fix, 2 DGPS, 0 none
    nsat: np.ndarray  # (M,) int8
    sigma_h_m: np.ndarray  # (M,) 1-sigma per horizontal axis used for this epoch
    sigma_v_m: np.ndarray  # (M,)
    sigma_vel_m_s: np.ndarray  # (M,)
    pps_s: np.ndarray  # (P,) PPS rising edges, s
    # Truth, for evaluation only:
    p_ant_n: np.ndarray  # (M, 3) true antenna ENU position, m
    v_ant_n: np.ndarray  # (M, 3) true antenna ENU velocity, m/s
    err_n_m: np.ndarray  # (M, 3) position error against the antenna at the stamp (ENU), m
    outages: tuple
    model: GnssModel

    def __len__(self):
        return self.t_fix_s.size

    @property
    def valid(self):
        return self.quality > 0

    def __iter__(self):
        for k in range(len(self)):
            yield self[k]

    def __getitem__(self, k):
        return GnssFix(*(getattr(self, name)[k].item() for name in _FIX_FIELDS))


def _hdop(rng, model, t, t_truth):
    """HDOP at the epochs t. The sky's: its wander and excursions are drawn on the 1 Hz grid of
    the truth's times whatever the receiver's rate and read at the epochs (the wander
    interpolated), so that receivers at different rates meet the same excursions (a 5 Hz
    receiver whose excursion followed the outage where the 1 Hz one's did not made rates look
    better or worse than they are). At 1 Hz the epochs are the grid."""
    grid = t_truth[:: int(RATE_HZ)]
    lim = model.hdop_wander
    wander = np.clip(gauss_markov(rng, grid.size, 1.0, model.hdop_tau_s, 0.5 * lim), -lim, lim)
    hdop = model.hdop_nominal + np.interp(t, grid, wander)
    duration = grid[-1] - grid[0]
    count = rng.poisson(duration / model.excursion_every_s)
    starts = rng.uniform(grid[0], grid[0] + duration, count)
    lengths = rng.uniform(*model.excursion_length_s, count)
    peaks = rng.uniform(*model.excursion_hdop, count)
    for start, length, peak in zip(starts, lengths, peaks, strict=True):
        inside = (t >= start) & (t < start + length)
        hdop[inside] = np.maximum(hdop[inside], peak)
    return hdop


def simulate(truth, model=None, seed=0, outages=None):
    """Receiver output for a Truth (model None: the scenario's receiver, Truth.receiver over
    GnssModel's defaults). outages: ((start_s, length_s), ...), default truth.outages;
    epochs in [start, start + length) have no fix. Same seed -> same data."""
    model = GnssModel(**getattr(truth, "receiver", {})) if model is None else model
    if model.lever_b_m is None:
        model = dataclasses.replace(model, lever_b_m=tuple(truth.antenna_b_m))
    outages = truth.outages if outages is None else tuple(outages)
    step = _step_samples(model)
    rng = np.random.default_rng([seed, _STREAM_GNSS])

    idx = np.arange(0, len(truth.t_s), step)
    t = truth.t_s[idx]
    m = idx.size
    fix = (t >= model.ttff_s) & _outside(t, outages)

    # Truth of the antenna, at the stamps and at the moments the receiver measured.
    p_ant, v_ant = _antenna_n(truth, model, idx)
    lag = int(round(model.stamp_lag_s * RATE_HZ))
    p_meas, v_true_meas = (p_ant, v_ant)
    if lag:  # the receiver measured `lag` truth samples before each stamp (after: negative)
        p_meas, v_true_meas = _antenna_n(truth, model, np.clip(idx - lag, 0, len(truth.t_s) - 1))

    # Errors (drawn for every epoch, fix or not, so outages do not shift the random stream).
    dt = 1.0 / model.rate_hz
    hdop = _hdop(rng, model, t, truth.t_s)
    scale = hdop / model.hdop_nominal
    sigma = np.array([model.sigma_h_m, model.sigma_h_m, model.sigma_v_m])
    wf = model.white_fraction
    unit = np.sqrt(wf) * rng.standard_normal((m, 3)) + np.sqrt(1.0 - wf) * gauss_markov(
        rng, m, dt, model.error_tau_s, 1.0, (3,)
    )
    err = scale[:, None] * sigma * unit
    v_meas = v_true_meas + scale[:, None] * model.sigma_vel_m_s * rng.standard_normal((m, 3))
    nsat = np.clip(np.rint(11.0 / hdop + 0.7 * rng.standard_normal(m)), 4, 20)
    nsat_nofix = rng.integers(0, 4, m)
    latency = model.latency_s + rng.uniform(-1.0, 1.0, m) * model.latency_jitter_s

    # DGPS segments (drawn last, so the streams above do not change with them)
    dgps = _dgps_segments(rng, model, t)

    lat_e7, lon_e7, h_m = truth.origin.to_geodetic(p_meas + err)
    err = err + (p_meas - p_ant)  # as evaluated: against the antenna at the stamp
    speed = np.hypot(v_meas[:, 0], v_meas[:, 1])
    course = _course_deg(v_meas, speed, model.course_min_speed_m_s)
    nan = np.full(m, np.nan)
    pps = _pps_s(truth, model, outages)

    return GnssData(
        t_fix_s=t,
        t_avail_s=t + latency,
        lat_e7=np.where(fix, lat_e7, 0),
        lon_e7=np.where(fix, lon_e7, 0),
        h_m=np.where(fix, h_m, nan),
        speed_m_s=np.where(fix, speed, nan),
        course_deg=np.where(fix, course, nan),
        hdop=np.where(fix, hdop, nan),
        quality=np.where(fix, np.where(dgps, 2, 1), 0).astype(np.int8),
        nsat=np.where(fix, nsat, nsat_nofix).astype(np.int8),
        sigma_h_m=np.where(fix, scale * model.sigma_h_m, nan),
        sigma_v_m=np.where(fix, scale * model.sigma_v_m, nan),
        sigma_vel_m_s=np.where(fix, scale * model.sigma_vel_m_s, nan),
        pps_s=pps,
        p_ant_n=p_ant,
        v_ant_n=v_ant,
        err_n_m=err,
        outages=outages,
        model=model,
    )


def _step_samples(model):
    """Truth samples between epochs (rate_hz must divide RATE_HZ)."""
    step = RATE_HZ / model.rate_hz
    if abs(step - round(step)) > 1e-9 or step < 1:
        raise ValueError(f"rate_hz must divide {RATE_HZ} Hz")
    return int(round(step))


def _outside(t_s, outages):
    """True where t_s lies in none of outages ((start_s, length_s), ...), each [start, end)."""
    keep = np.ones(np.shape(t_s), bool)
    for start, length in outages:
        keep &= ~((t_s >= start) & (t_s < start + length))
    return keep


def _antenna_n(truth, model, i):
    """Position and velocity (n frame) of the antenna at truth samples i, from the lever arm."""
    c_bn = euler_to_dcm(truth.ypr[i])
    lever = np.asarray(model.lever_b_m, dtype=float)
    p = truth.p_n[i] + body_to_nav(c_bn, lever)
    return p, truth.v_n[i] + body_to_nav(c_bn, np.cross(truth.w_nb_b[i], lever))


def _dgps_segments(rng, model, t_s):
    """True at the epochs t_s inside a random DGPS segment (draws: count, starts, lengths)."""
    m = len(t_s)
    dgps = np.zeros(m, bool)
    duration = t_s[-1] - t_s[0] if m else 0.0
    count = rng.poisson(duration / model.dgps_every_s) if model.dgps_every_s > 0 else 0
    starts = rng.uniform(t_s[0], t_s[0] + duration, count) if m else []
    lengths = rng.uniform(*model.dgps_length_s, count)
    for start, length in zip(starts, lengths, strict=True):
        dgps |= (t_s >= start) & (t_s < start + length)
    return dgps


def _course_deg(v_n, speed_m_s, min_speed_m_s):
    """Track angle, degrees clockwise from north in [0, 360); NaN below min_speed_m_s."""
    course = np.degrees(np.arctan2(v_n[:, 0], v_n[:, 1])) % 360.0
    course[course >= 360.0] = 0.0  # -1e-17 % 360 rounds to 360
    course[speed_m_s < min_speed_m_s] = np.nan
    return course


def _pps_s(truth, model, outages):
    """PPS edges: whole seconds of the run while the receiver has a fix (all if pps_without_fix)."""
    pps = np.arange(np.ceil(truth.t_s[0]), truth.t_s[-1] + 1e-9, 1.0)
    if not model.pps_without_fix:
        pps = pps[(pps >= model.ttff_s) & _outside(pps, outages)]
    return pps
