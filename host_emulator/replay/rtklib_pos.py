"""RTKLIB `.pos` solution files (latitude/longitude/height form): read, write, export a track.

What is read (RTKLIB `outsol` with `posf = llh`, decimal degrees; what rtkpost, rnx2rtkp and
rtkplot exchange). Header lines start with `%`; the column header names the time system
(`GPST`, `UTC` or `JST`; none: GPST). Each row is

    time  lat(deg) lon(deg) height(m)  Q ns  sdn sde sdu sdne sdeu sdun(m)  age(s) ratio
          [vn ve vu(m/s)  sdvn sdve sdvu sdvne sdveu sdvun]

time either `yyyy/mm/dd hh:mm:ss.sss` or `week sow` (GPS week and seconds of week); fields
separated by spaces (or commas). So a row has 13 or 22 fields after the time. Height is the
ellipsoidal height; sdne/sdeu/sdun are RTKLIB's signed square roots of the covariances.

`read(path)` returns a `PosFile`: `.positions` a `Positions` (times in GPST seconds since the
GPS epoch whatever the file's time system; sigma_ned_m = (sdn, sde, sdu); v_ned_m_s =
(vn, ve, -vu) when the file has velocities) plus the per-epoch columns a Positions has no room
for: `.q` (RTKLIB's solution quality), `.ns`, `.age_s`, `.ratio`, `.sd_cross_m` and
`.sigma_v_ned_m_s`. Select with `pf.positions.select(pf.q == Q_FIX)`.

`write(path, positions, q, ns, ...)` writes the same layout, always GPST calendar time, with
RTKLIB's fixed-width columns and header, which rtkplot opens. Attitude is not part of the
format (RTKLIB has no INS solution in outsol), so `rpy_deg` is not written.

Quality of an INS solution in RTKLIB's terms (`from_track`): RTKLIB's codes are 1 fix, 2 float,
3 SBAS, 4 DGPS, 5 single, 6 PPP and 7 dead reckoning (SOLQ_DR in rtklib.h; rtkplot has a colour
for it). A GNSS-aided INS output built on a single-point receiver is written as 5 (single);
epochs the navigator coasted through without GNSS (an outage) as 7 (dead reckoning).
"""

import datetime
from dataclasses import dataclass

import numpy as np

from .dataset import GPS_EPOCH, WEEK_S, Positions
from .formats import FormatError, calendar_s, check_increasing, gpst_of_utc_s, read_lines

__all__ = ["FormatError", "PosFile", "read", "write", "from_track", "Q_SINGLE", "Q_DR"]

Q_NONE, Q_FIX, Q_FLOAT, Q_SBAS, Q_DGPS, Q_SINGLE, Q_PPP, Q_DR = range(8)
PROGRAM = "mpy-ins host_emulator.replay.rtklib_pos"

_FIELDS_BASE = 13  # lat lon h Q ns sdn sde sdu sdne sdeu sdun age ratio
_FIELDS_VEL = 22  # ... vn ve vu sdvn sdve sdvu sdvne sdveu sdvun
_JST_S = 9 * 3600.0


@dataclass(eq=False)
class PosFile:
    """An RTKLIB solution file's rows (module docstring)."""

    positions: Positions
    q: np.ndarray  # (M,) int: 1 fix, 2 float, 3 SBAS, 4 DGPS, 5 single, 6 PPP, 7 DR
    ns: np.ndarray  # (M,) int: satellites
    age_s: np.ndarray  # (M,) age of differential, s
    ratio: np.ndarray  # (M,) ambiguity ratio
    sd_cross_m: np.ndarray  # (M, 3) sdne, sdeu, sdun as in the file (signed sqrt of covariance)
    sigma_v_ned_m_s: np.ndarray | None  # (M, 3) sdvn, sdve, sdvu (None without velocities)
    time_system: str  # the file's: GPST, UTC or JST (times in .positions are GPST)

    def __len__(self):
        return len(self.positions)


# --- reading ---


def _header(path, lines):
    """Time system named by the column header line ('GPST' if there is none)."""
    system = "GPST"
    for i, line in enumerate(lines, 1):
        if not line.startswith("%"):
            continue
        for other in ("x-ecef(m)", "e-baseline(m)", "latitude(d'\")"):
            if other in line:
                raise FormatError(
                    f"{path}:{i}: {other} solution form is not supported: export "
                    "latitude/longitude/height in decimal degrees"
                )
        if "latitude(deg)" in line:
            tokens = line[1:].split()
            if tokens and tokens[0] in ("GPST", "UTC", "JST"):
                system = tokens[0]
    return system


def _time(path, i, a, b):
    """Seconds since 1980-01-06 in the file's time system of the two time tokens."""
    try:
        if "/" in a:
            y, mo, d = (int(x) for x in a.split("/"))
            hh, mm, ss = b.split(":")
            return calendar_s(y, mo, d, int(hh), int(mm), float(ss))
        return int(a) * WEEK_S + float(b)
    except ValueError:
        raise FormatError(
            f"{path}:{i}: time {a} {b!s} is neither yyyy/mm/dd hh:mm:ss nor week sow"
        ) from None


def _to_gpst(t, system):
    if system == "JST":
        return gpst_of_utc_s(t - _JST_S)
    if system == "UTC":
        return gpst_of_utc_s(t)
    return t


def read(path):
    """PosFile of an RTKLIB .pos file (lat/lon/height form); FormatError if it is not one."""
    lines = read_lines(path, "RTKLIB solution")
    system = _header(path, lines)
    t = []
    t_text = []
    values = []
    line_no = []
    cols = None
    for i, line in enumerate(lines, 1):
        if line.startswith("%") or not line.strip():
            continue
        parts = line.replace(",", " ").split()
        n = len(parts) - 2
        if cols is None:
            if n not in (_FIELDS_BASE, _FIELDS_VEL):
                raise FormatError(
                    f"{path}:{i}: {n} fields after the time, an RTKLIB lat/lon/height row has "
                    f"{_FIELDS_BASE} (or {_FIELDS_VEL} with velocities)"
                )
            cols = n
        elif n != cols:
            raise FormatError(f"{path}:{i}: {n} fields after the time, the rows before have {cols}")
        t.append(_time(path, i, parts[0], parts[1]))
        t_text.append(f"{parts[0]} {parts[1]}")
        values.append(parts[2:])
        line_no.append(i)
    if not values:
        raise FormatError(f"{path}: no solution rows")
    line_no = np.asarray(line_no)
    try:
        v = np.array(values, dtype=np.float64)
    except ValueError:
        for row, i in zip(values, line_no, strict=True):
            for col, token in enumerate(row, 3):
                try:
                    float(token)
                except ValueError:
                    raise FormatError(
                        f"{path}:{i}: field {col} is {token!r}, not a number"
                    ) from None
        raise
    t = _to_gpst(np.asarray(t, np.float64), system)
    check_increasing(path, t, line_no, "time", t_text)
    bad = np.flatnonzero(~np.isfinite(v[:, 3:5]).all(axis=1))
    if bad.size:
        raise FormatError(f"{path}:{line_no[bad[0]]}: Q or ns is not a number")
    vel = sd_v = None
    if cols == _FIELDS_VEL:
        vel = np.column_stack([v[:, 13], v[:, 14], -v[:, 15]])
        sd_v = v[:, 16:19].copy()
    positions = Positions(t, v[:, 0], v[:, 1], v[:, 2], v[:, 5:8].copy(), vel)
    return PosFile(
        positions=positions,
        q=np.rint(v[:, 3]).astype(np.int64),
        ns=np.rint(v[:, 4]).astype(np.int64),
        age_s=v[:, 11].copy(),
        ratio=v[:, 12].copy(),
        sd_cross_m=v[:, 8:11].copy(),
        sigma_v_ned_m_s=sd_v,
        time_system=system,
    )


# --- writing ---


def _calendar(t_s, decimals):
    """'yyyy/mm/dd hh:mm:ss.sss' (GPST) of GPST seconds, rounded to `decimals`."""
    unit = 10**decimals
    n = round(float(t_s) * unit)
    days, rest = divmod(n, 86400 * unit)
    sec, frac = divmod(rest, unit)
    date = GPS_EPOCH + datetime.timedelta(days=days)
    text = f"{date:%Y/%m/%d} {sec // 3600:02d}:{sec // 60 % 60:02d}:{sec % 60:02d}"
    return text + (f".{frac:0{decimals}d}" if decimals else "")


def _week_sow(t_s):
    week = int(t_s // WEEK_S)
    return week, float(t_s) - week * WEEK_S


def _column(values, n, default=0.0):
    if values is None:
        return np.full((n, 3), default)
    return np.asarray(values, np.float64).reshape(n, 3)


# Column labels and widths of RTKLIB's outsolheads (lat/lon/height in degrees).
_LABELS_BASE = (
    ("latitude(deg)", 14),
    ("longitude(deg)", 14),
    ("height(m)", 10),
    ("Q", 3),
    ("ns", 3),
    ("sdn(m)", 8),
    ("sde(m)", 8),
    ("sdu(m)", 8),
    ("sdne(m)", 8),
    ("sdeu(m)", 8),
    ("sdun(m)", 8),
    ("age(s)", 6),
    ("ratio", 6),
)
_LABELS_VEL = (
    ("vn(m/s)", 10),
    ("ve(m/s)", 10),
    ("vu(m/s)", 10),
    ("sdvn", 9),
    ("sdve", 8),
    ("sdvu", 8),
    ("sdvne", 8),
    ("sdveu", 8),
    ("sdvun", 8),
)


def _labels(pairs):
    return " ".join(f"{label:>{width}}" for label, width in pairs)


def write(
    path,
    positions,
    q=None,
    ns=None,
    *,
    age_s=None,
    ratio=None,
    sigma_v_ned_m_s=None,
    comment=None,
    program=PROGRAM,
    time_decimals=3,
):
    """Write `positions` as an RTKLIB .pos file (GPST calendar time, lat/lon/height).

    q: per-epoch quality (default Q_SINGLE), ns: satellites (default 0), age_s and ratio
    (default 0); sigma_ned_m gives sdn/sde/sdu (0 when None: RTKLIB's "unknown"), the cross
    terms are written as 0. With v_ned_m_s the nine velocity columns follow (vu = -vd;
    sigma_v_ned_m_s or 0). comment: a string (one `%` line per text line). Times are rounded
    to `time_decimals` decimals (RTKLIB's default 3).
    """
    m = len(positions)
    if m == 0:
        raise FormatError(f"{path}: no positions to write")
    q = np.full(m, Q_SINGLE) if q is None else np.broadcast_to(np.asarray(q), (m,))
    ns = np.zeros(m, int) if ns is None else np.broadcast_to(np.asarray(ns), (m,))
    age = np.zeros(m) if age_s is None else np.broadcast_to(np.asarray(age_s, float), (m,))
    rat = np.zeros(m) if ratio is None else np.broadcast_to(np.asarray(ratio, float), (m,))
    sd = _column(positions.sigma_ned_m, m)
    times = _epoch_times(path, positions.t_s, time_decimals)
    vel = positions.v_ned_m_s is not None
    head = _header_lines(positions.t_s, times, comment, program, vel)
    body = _position_lines(positions, times, q, ns, sd, age, rat)
    if vel:
        v = np.asarray(positions.v_ned_m_s, np.float64)
        sdv = _column(sigma_v_ned_m_s, m)
        vfmt = " %10.5f %10.5f %10.5f %9.5f %8.5f %8.5f %8.5f %8.5f %8.5f"
        body = [
            line + vfmt % (vv[0], vv[1], -vv[2], s[0], s[1], s[2], 0.0, 0.0, 0.0)
            for line, vv, s in zip(body, v.tolist(), sdv.tolist(), strict=True)
        ]
    with open(path, "w", encoding="ascii") as f:
        f.write("\n".join(head + body) + "\n")


def _epoch_times(path, t_s, time_decimals):
    """The epochs' GPST calendar times at time_decimals; FormatError if one does not come
    after the one before once rounded."""
    times = [_calendar(t, time_decimals) for t in t_s]
    unit = 10**time_decimals
    ticks = np.array([round(float(t) * unit) for t in t_s])
    if len(t_s) > 1 and not (np.diff(ticks) > 0).all():
        k = int(np.flatnonzero(np.diff(ticks) <= 0)[0]) + 1
        raise FormatError(
            f"{path}: epoch {k} ({times[k]}) is not after the one before at "
            f"time_decimals={time_decimals}"
        )
    return times


def _header_lines(t_s, times, comment, program, vel):
    """The .pos header: program, comment lines, start/end, the legend and column labels
    (with the velocity columns' if vel)."""
    w0, s0 = _week_sow(t_s[0])
    w1, s1 = _week_sow(t_s[-1])
    head = [f"% program   : {program}"]
    for text in (comment or "").splitlines():
        head.append(f"% {text}".rstrip())
    head += [
        f"% obs start : {times[0]} GPST (week{w0:04d} {s0:10.3f}s)",
        f"% obs end   : {times[-1]} GPST (week{w1:04d} {s1:10.3f}s)",
        "% (lat/lon/height=WGS84/ellipsoidal,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,"
        "7:dr,ns=# of satellites)",
    ]
    labels = _labels(_LABELS_BASE)
    if vel:
        labels += " " + _labels(_LABELS_VEL)
    head.append("%  " + "GPST".ljust(len(times[0]) - 3) + " " + labels)
    return head


def _position_lines(positions, times, q, ns, sd, age, rat):
    """One line per epoch: time, lat/lon/height, Q, ns, sdn/sde/sdu, cross terms 0, age,
    ratio."""
    fmt = "%s %14.9f %14.9f %10.4f %3d %3d %8.4f %8.4f %8.4f %8.4f %8.4f %8.4f %6.2f %6.1f"
    rows = zip(
        times,
        positions.lat_deg.tolist(),
        positions.lon_deg.tolist(),
        positions.h_m.tolist(),
        q.tolist(),
        ns.tolist(),
        sd.tolist(),
        age.tolist(),
        rat.tolist(),
        strict=True,
    )
    return [
        fmt % (tm, la, lo, h, qq, nn, s[0], s[1], s[2], 0.0, 0.0, 0.0, a, r)
        for tm, la, lo, h, qq, nn, s, a, r in rows
    ]


def from_track(
    t_gpst_s, lat_deg, lon_deg, h_m, sigma_enu_m=None, v_enu_m_s=None, dead_reckoning=None
):
    """(Positions, q) of a navigator's track in the firmware's ENU terms, for `write`:

        write(path, *from_track(t, lat, lon, h, sigma_enu, v_enu, outage), comment="...")

    sigma_enu_m (M, 3) 1-sigma E, N, U and v_enu_m_s (M, 3) become NED; q is Q_SINGLE, or
    Q_DR where `dead_reckoning` (M,) bool is set (no GNSS aiding, e.g. an outage).
    """
    t = np.asarray(t_gpst_s, np.float64)
    sigma = None if sigma_enu_m is None else np.asarray(sigma_enu_m, np.float64)[:, [1, 0, 2]]
    v_ned = None
    if v_enu_m_s is not None:
        v = np.asarray(v_enu_m_s, np.float64)
        v_ned = np.column_stack([v[:, 1], v[:, 0], -v[:, 2]])
    q = np.full(t.size, Q_SINGLE, np.int64)
    if dead_reckoning is not None:
        q[np.asarray(dead_reckoning, bool)] = Q_DR
    positions = Positions(
        t,
        np.asarray(lat_deg, np.float64),
        np.asarray(lon_deg, np.float64),
        np.asarray(h_m, np.float64),
        sigma,
        v_ned,
    )
    return positions, q
