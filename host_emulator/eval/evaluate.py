"""Score what the firmware sent against truth: the errors of its output frames.

Only the output is used, as for a board on a test drive: the 52-byte frames (position, velocity,
attitude at their resolution: 1 cm, 1 cm/s, 0.01 deg; 10 cm vertically) and the extended frames
(origin of the local frame, covariance diagonal, biases), decoded by proto/stream.py. The track
is sampled where an extended frame follows its 52-byte frame (every `ext_every_ticks`, 10 Hz by
default), because only there is the origin of the frame's local position known for certain
(the navigator moves its origin when it has gone far).

Time: the extended frame's navigator tick T holds the state at T * tick_s (tick k's IMU
sample, taken at k * tick_s, is integrated by tick k + 1). Truth is looked up at that time.
Positions are compared in the truth's ENU frame: the frame's local ENU position -> geodetic
(about the origin it was sent with) -> the truth's ENU (pymap3d, WGS-84).

Errors count from the first frame in the navigating state ("the navigation phase"); angles are
wrapped to +-180 deg. Figures `*_gnss` leave out the GNSS outage windows.
"""

from dataclasses import dataclass

import numpy as np
import pymap3d

from host_emulator.sim.trajectory import wrap_pi

NAVIGATING = 2


@dataclass(eq=False)
class Track:
    """The firmware's output at the extended frames (one row each)."""

    t_s: np.ndarray  # (M,) state time
    state: np.ndarray  # (M,) 1 aligning, 2 navigating
    p_n: np.ndarray  # (M, 3) position in the truth's ENU frame, m
    v_n: np.ndarray  # (M, 3) ENU velocity, m/s
    ypr: np.ndarray  # (M, 3) yaw, pitch, roll, rad (yaw counter-clockwise from north)
    sigma: np.ndarray  # (M, 15) sqrt of the covariance diagonal (dp dv phi dbg dba)
    bg: np.ndarray  # (M, 3) gyro bias estimate, rad/s
    ba: np.ndarray  # (M, 3) accel bias estimate, m/s^2
    health: np.ndarray  # (M,)
    causes: np.ndarray  # (M,) the health's cause bits (proto/records.py CAUSES; 0 if absent)
    gnss_valid: np.ndarray  # (M,) bool
    align_time_s: float | None  # first navigating state time


def track(decoded, tick_s, origin):
    """Track from decoded output; origin: the truth frame's (lat_e7, lon_e7, h_m)."""
    fr = decoded.frames
    align = None
    for i, f in enumerate(fr):
        if f["nav_state"] == NAVIGATING:
            align = (i + 1) * tick_s
            break
    rows = [(e, fr[e["frame_index"]]) for e in decoded.ext if e["frame_index"] >= 0]
    m = len(rows)
    t = np.array([e["tick"] * tick_s for e, _ in rows], float)
    pos = np.array([f["pos_enu_m"] for _, f in rows], float).reshape(m, 3)
    o = np.array([(e["origin_lat_e7"], e["origin_lon_e7"], e["origin_h_m"]) for e, _ in rows])
    o = o.reshape(m, 3)
    if m:
        lat, lon, h = pymap3d.enu2geodetic(
            pos[:, 0], pos[:, 1], pos[:, 2], o[:, 0] * 1e-7, o[:, 1] * 1e-7, o[:, 2]
        )
        e_, n_, u_ = pymap3d.geodetic2enu(
            lat, lon, h, origin[0] * 1e-7, origin[1] * 1e-7, origin[2]
        )
        p_n = np.stack([e_, n_, u_], axis=-1)
    else:
        p_n = np.zeros((0, 3))
    deg = np.pi / 180.0
    return Track(
        t_s=t,
        state=np.array([f["nav_state"] for _, f in rows], int),
        p_n=p_n,
        v_n=np.array([f["vel_enu_m_s"] for _, f in rows], float).reshape(m, 3),
        ypr=np.array(
            [(f["yaw_deg"], f["pitch_deg"], f["roll_deg"]) for _, f in rows], float
        ).reshape(m, 3)
        * deg,
        sigma=np.sqrt(np.maximum(np.array([e["p_diag"] for e, _ in rows], float), 0)).reshape(
            m, 15
        ),
        bg=np.array([e["gyro_bias_rad_s"] for e, _ in rows], float).reshape(m, 3),
        ba=np.array([e["accel_bias_m_s2"] for e, _ in rows], float).reshape(m, 3),
        health=np.array([e["health"] for e, _ in rows], int),
        causes=np.array([e["causes"] or 0 for e, _ in rows], int),
        gnss_valid=np.array([f["gnss_valid"] for _, f in rows], bool),
        align_time_s=align,
    )


@dataclass(eq=False)
class TrackErrors:
    """Track minus truth over the navigation phase."""

    t_s: np.ndarray
    dp: np.ndarray  # (K, 3) m
    dv: np.ndarray  # (K, 3) m/s
    da: np.ndarray  # (K, 3) yaw, pitch, roll, rad, wrapped
    sigma: np.ndarray  # (K, 15)
    in_outage: np.ndarray  # (K,) bool


def errors(tr, truth_t_s, truth_p_n, truth_v_n, truth_ypr, outages=(), covered=None):
    """Errors at the track's navigating samples; truth arrays sampled at truth_t_s (uniform).
    covered: per truth sample, whether the reference exists there (None: everywhere); the
    track is scored only there."""
    dt = float(truth_t_s[1] - truth_t_s[0])
    nav = (tr.state == NAVIGATING) & (tr.t_s <= truth_t_s[-1] + 1e-9)
    k = np.clip(np.rint((tr.t_s - truth_t_s[0]) / dt).astype(int), 0, truth_t_s.size - 1)
    if covered is not None:
        nav &= covered[k]
    idx = k[nav]
    t = tr.t_s[nav]
    out = np.zeros(t.size, bool)
    for start, length in outages:
        out |= (t >= start) & (t < start + length)
    return TrackErrors(
        t_s=t,
        dp=tr.p_n[nav] - truth_p_n[idx],
        dv=tr.v_n[nav] - truth_v_n[idx],
        da=wrap_pi(tr.ypr[nav] - truth_ypr[idx]),
        sigma=tr.sigma[nav],
        in_outage=out,
    )


def at_times(t_s, p, t_query, max_gap_s):
    """p (N, D) sampled at t_s, linearly interpolated at each t_query; NaN where no two
    samples at most max_gap_s apart bracket it."""
    t_s, t_query = np.asarray(t_s, float), np.asarray(t_query, float)
    out = np.full((t_query.size, p.shape[1]), np.nan)
    if t_s.size < 2:
        return out
    j = np.clip(np.searchsorted(t_s, t_query), 1, t_s.size - 1)
    ok = (t_query >= t_s[0]) & (t_query <= t_s[-1]) & (t_s[j] - t_s[j - 1] <= max_gap_s)
    w = (t_query - t_s[j - 1]) / np.where(t_s[j] > t_s[j - 1], t_s[j] - t_s[j - 1], 1.0)
    out[ok] = p[j - 1][ok] + w[ok, None] * (p[j][ok] - p[j - 1][ok])
    return out


def waypoint_errors(t_s, p_en, waypoints, max_gap_s):
    """Horizontal errors (K,) of positions p_en (N, 2) at times t_s against waypoints
    (t_s (K,), (K, 2) east, north): the positions interpolated at each waypoint's instant
    between samples at most max_gap_s apart; NaN where none bracket it."""
    t_wp, p_wp = waypoints
    p = at_times(t_s, np.asarray(p_en, float), t_wp, max_gap_s)
    return np.hypot(*(p - p_wp).T)


def spread(x):
    """{"n", "median", "p75", "max"} of the finite values of x (None where there are none)."""
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    if not x.size:
        return {"n": 0, "median": None, "p75": None, "max": None}
    return {"n": int(x.size), "median": float(np.median(x)),
            "p75": float(np.percentile(x, 75)), "max": float(x.max())}  # fmt: skip


def rms(x):
    return float(np.sqrt(np.mean(np.square(x)))) if np.size(x) else None


def accuracy(err, outages=(), skip_s=0.0, from_s=None):
    """The accuracy figures of metrics.json from Errors (after skip_s more seconds, or from
    the time from_s). Attitude figures are None where the truth has no attitude (NaN)."""
    start = err.t_s[0] + skip_s if err.t_s.size else 0.0
    keep = err.t_s >= (start if from_s is None else from_s)
    dp, dv, da = err.dp[keep], err.dv[keep], err.da[keep]
    if np.isnan(da).any():
        da = np.zeros((0, 3))
    ok = ~err.in_outage[keep]
    horiz = np.hypot(dp[:, 0], dp[:, 1])
    deg = 180.0 / np.pi
    sig = err.sigma[keep]
    inside = np.abs(dp[:, :2]) <= 3 * sig[:, :2]
    with np.errstate(divide="ignore", invalid="ignore"):
        nees = np.square(dp[:, :2] / sig[:, :2])  # 1 on average when the sigma is right
    res = {
        "horiz_rms_m": rms(horiz),
        "horiz_rms_gnss_m": rms(horiz[ok]),
        "horiz_max_m": float(horiz.max()) if horiz.size else None,
        "vert_rms_m": rms(dp[:, 2]),
        "vel_rms_m_s": rms(np.linalg.norm(dv, axis=1)),
        "vel_rms_gnss_m_s": rms(np.linalg.norm(dv[ok], axis=1)),
        "yaw_rms_deg": None if not da.size else rms(da[:, 0]) * deg,
        "pitch_rms_deg": None if not da.size else rms(da[:, 1]) * deg,
        "roll_rms_deg": None if not da.size else rms(da[:, 2]) * deg,
        "pos_3sigma_coverage": float(inside.mean()) if inside.size else None,
        "pos_nees_h": float(np.mean(nees[np.isfinite(nees)])) if np.isfinite(nees).any() else None,
        "outages": [],
    }
    for start, length in outages:
        end = start + length
        j = np.searchsorted(err.t_s, end - 1e-9)
        if j < err.t_s.size and err.t_s[j] - end < 0.5:
            res["outages"].append(
                {
                    "start_s": float(start),
                    "length_s": float(length),
                    "horiz_err_end_m": float(np.hypot(*err.dp[j, :2])),
                }
            )
        else:  # the run ended first, or the navigator was not navigating then
            res["outages"].append(
                {"start_s": float(start), "length_s": float(length), "horiz_err_end_m": None}
            )
    return res


def frame_errors(decoded):
    """Checksum and CRC failures, undecodable bytes and gaps in the frame counter."""
    c = np.array([f["counter"] for f in decoded.frames], int)
    gaps = int(np.count_nonzero((np.diff(c) % 256) != 1)) if c.size > 1 else 0
    return {
        "bad_checksum": decoded.bad_checksum,
        "bad_crc": decoded.bad_crc,
        "skipped_bytes": decoded.skipped_bytes,
        "counter_gaps": gaps,
        "total": decoded.bad_checksum + decoded.bad_crc + decoded.skipped_bytes + gaps,
    }
