"""Files written from the decoded stream: CSV (frames, and extended frames in a second file)
and MDF4 (asammdf). The channels and their units are the tables below; docs/monitor.md lists
them too."""

import csv
import math
from pathlib import Path

G = 9.80665  # m/s^2 per g (for accelerometer biases in mg)
RAD_S_TO_DEG_H = 180.0 / math.pi * 3600.0

# (name, unit, decimals in the CSV, MDF dtype); the CSV column is `name`, the MDF channel too.
FRAME_COLUMNS = [
    ("time_s", "s", 3, "f8"),
    ("counter", "", None, "u1"),
    ("nav_state", "", None, "u1"),
    ("gnss_valid", "", None, "u1"),
    ("pps", "", None, "u1"),
    ("gga", "", None, "u1"),
    ("lat_deg", "deg", 7, "f8"),
    ("lon_deg", "deg", 7, "f8"),
    ("height_m", "m", 1, "f4"),
    ("yaw_deg", "deg", 2, "f4"),
    ("pitch_deg", "deg", 2, "f4"),
    ("roll_deg", "deg", 2, "f4"),
    ("vel_e_m_s", "m/s", 2, "f4"),
    ("vel_n_m_s", "m/s", 2, "f4"),
    ("vel_u_m_s", "m/s", 2, "f4"),
    ("pos_e_m", "m", 2, "f8"),
    ("pos_n_m", "m", 2, "f8"),
    ("pos_u_m", "m", 1, "f4"),
    ("gyro_x_dps", "deg/s", 4, "f4"),
    ("gyro_y_dps", "deg/s", 4, "f4"),
    ("gyro_z_dps", "deg/s", 4, "f4"),
    ("accel_x_g", "g", 6, "f4"),
    ("accel_y_g", "g", 6, "f4"),
    ("accel_z_g", "g", 6, "f4"),
]

_XYZ = ("x", "y", "z")
_ENU = ("e", "n", "u")
EXT_COLUMNS = (
    [
        ("time_s", "s", 3, "f8"),
        ("tick", "", None, "u4"),
        ("counter", "", None, "u1"),
        ("health", "", None, "u1"),
        ("causes", "", None, "u4"),
        ("nav_state", "", None, "u1"),
        ("config_status", "", None, "u1"),
        ("gnss_valid", "", None, "u1"),
        ("standstill", "", None, "u1"),
        ("imu_saturated", "", None, "u1"),
        ("worst_tick_us", "us", None, "u2"),
        ("mean_tick_us", "us", None, "u2"),
        ("overruns", "", None, "u2"),
        ("gc_runs", "", None, "u2"),
    ]
    + [(f"sigma_pos_{a}_m", "m", 4, "f4") for a in _ENU]
    + [(f"sigma_vel_{a}_m_s", "m/s", 4, "f4") for a in _ENU]
    + [(f"sigma_att_{a}_deg", "deg", 4, "f4") for a in _ENU]
    + [(f"sigma_gyro_bias_{a}_deg_h", "deg/h", 3, "f4") for a in _XYZ]
    + [(f"sigma_accel_bias_{a}_mg", "mg", 4, "f4") for a in _XYZ]
    + [(f"gyro_bias_{a}_deg_h", "deg/h", 3, "f4") for a in _XYZ]
    + [(f"accel_bias_{a}_mg", "mg", 4, "f4") for a in _XYZ]
    + [(f"pos_{a}_m", "m", 3, "f8") for a in _ENU]
    + [
        ("origin_lat_deg", "deg", 7, "f8"),
        ("origin_lon_deg", "deg", 7, "f8"),
        ("origin_h_m", "m", 3, "f4"),
    ]
)

# MDF4 channel names: the CSV names; the extended frames' ones that a frame channel also has
# get an "ext_" prefix, so every channel name is unique in the file.
MDF_FRAME_NAMES = [c[0] for c in FRAME_COLUMNS]
MDF_EXT_NAMES = ["ext_" + c[0] if c[0] in MDF_FRAME_NAMES[1:] else c[0] for c in EXT_COLUMNS]


def frame_values(t, f):
    """The FRAME_COLUMNS values of frame fields `f` (frames.frame_fields) at board time t."""
    return [
        t,
        f["counter"],
        f["nav_state"],
        f["gnss_valid"],
        f["pps"],
        f["gga"],
        f["lat_e7"] / 1e7,
        f["lon_e7"] / 1e7,
        f["height_m"],
        f["yaw_deg"],
        f["pitch_deg"],
        f["roll_deg"],
        *f["vel_enu_m_s"],
        *f["pos_enu_m"],
        *f["gyro_dps"],
        *f["accel_g"],
    ]


def sigma(p):
    """1-sigma from a variance (NaN for a negative or non-finite one: a fault)."""
    return math.sqrt(p) if p >= 0.0 and math.isfinite(p) else float("nan")


def sigmas(e):
    """{pos, vel, att_deg, gyro_bias_deg_h, accel_bias_mg}: 3 values each, from p_diag
    (the error-state order of docs/requirements.md: position, velocity, attitude error, gyro bias,
    accel bias)."""
    s = [sigma(p) for p in e["p_diag"]]
    return {
        "pos": s[0:3],
        "vel": s[3:6],
        "att_deg": [math.degrees(x) for x in s[6:9]],
        "gyro_bias_deg_h": [x * RAD_S_TO_DEG_H for x in s[9:12]],
        "accel_bias_mg": [x / G * 1000.0 for x in s[12:15]],
    }


def ext_values(e):
    """The EXT_COLUMNS values of an extended frame's fields (frames.ext_fields)."""
    s = sigmas(e)
    fl = e["flags"]
    return [
        e["tick"] * 0.005,
        e["tick"],
        e["counter"],
        e["health"],
        e["causes"] or 0,
        e["nav_state"],
        e["config_status"],
        fl & 1,
        (fl >> 1) & 1,
        (fl >> 2) & 1,
        e["worst_tick_us"],
        e["mean_tick_us"],
        e["overruns"],
        e["gc_runs"],
        *s["pos"],
        *s["vel"],
        *s["att_deg"],
        *s["gyro_bias_deg_h"],
        *s["accel_bias_mg"],
        *[x * RAD_S_TO_DEG_H for x in e["gyro_bias_rad_s"]],
        *[x / G * 1000.0 for x in e["accel_bias_m_s2"]],
        *e["pos_enu_m"],
        e["origin_lat_e7"] / 1e7,
        e["origin_lon_e7"] / 1e7,
        e["origin_h_m"],
    ]


def ext_csv_path(path):
    """The extended frames' CSV next to the frames' one: out.csv -> out_ext.csv."""
    p = Path(path)
    return p.with_name(p.stem + "_ext" + (p.suffix or ".csv"))


def _fmt(columns):
    out = []
    for _name, _unit, dec, _dt in columns:
        out.append(str if dec is None else (lambda x, d=dec: f"{x:.{d}f}"))
    return out


class CsvExport:
    """One row per 52-byte frame in `path`, one per extended frame in ext_csv_path(path)."""

    def __init__(self, path):
        self.path = Path(path)
        self.ext_path = ext_csv_path(path)
        self.rows = 0
        self.ext_rows = 0
        self._files = []
        try:
            self._f = open(self.path, "w", newline="")  # noqa: SIM115 (closed in close())
            self._files.append(self._f)
            self._fe = open(self.ext_path, "w", newline="")  # noqa: SIM115
            self._files.append(self._fe)
        except OSError as e:
            self.close()
            raise OSError(f"cannot write {e.filename}: {e.strerror}") from None
        self._w = csv.writer(self._f)
        self._we = csv.writer(self._fe)
        self._w.writerow([c[0] for c in FRAME_COLUMNS])
        self._we.writerow([c[0] for c in EXT_COLUMNS])
        self._ff = _fmt(FRAME_COLUMNS)
        self._fx = _fmt(EXT_COLUMNS)

    def frame(self, t, f):
        self._w.writerow([fmt(v) for fmt, v in zip(self._ff, frame_values(t, f), strict=True)])
        self.rows += 1

    def ext(self, e):
        self._we.writerow([fmt(v) for fmt, v in zip(self._fx, ext_values(e), strict=True)])
        self.ext_rows += 1

    def close(self):
        for f in self._files:
            f.close()
        self._files = []


class _MdfGroup:
    def __init__(self, columns, comment, names):
        self.columns = columns
        self.names = names
        self.comment = comment
        self.rows = []
        self.index = None
        self.samples = 0


class MdfExport:
    """MDF4 (asammdf): a channel group for the frames (master: time_s, the board time from
    the tick) and one for the extended frames. Written in blocks of CHUNK samples as they come
    (memory stays bounded), saved at close."""

    CHUNK = 2000

    def __init__(self, path):
        try:
            from asammdf import MDF
        except ImportError:
            raise OSError("writing MDF4 needs asammdf (pip install asammdf==8.8.28)") from None
        self.path = Path(path)
        try:  # fail now, not after the session, if the file cannot be written
            self.path.open("ab").close()
        except OSError as e:
            raise OSError(f"cannot write {self.path}: {e.strerror}") from None
        self.mdf = MDF(version="4.10")
        self.frames = _MdfGroup(FRAME_COLUMNS, "INS 52-byte frames", MDF_FRAME_NAMES)
        self.ext = _MdfGroup(EXT_COLUMNS, "INS extended frames", MDF_EXT_NAMES)

    def frame(self, t, f):
        self._add(self.frames, frame_values(t, f))

    def ext_frame(self, e):
        self._add(self.ext, ext_values(e))

    def _add(self, g, values):
        g.rows.append(values)
        if len(g.rows) >= self.CHUNK:
            self._flush(g)

    def _flush(self, g):
        if not g.rows:
            return
        import numpy as np
        from asammdf import Signal

        cols = list(zip(*g.rows, strict=True))
        g.rows = []
        t = np.asarray(cols[0], dtype="f8")
        arrays = [np.asarray(c, dtype=spec[3]) for c, spec in zip(cols, g.columns, strict=True)]
        if g.index is None:
            sigs = [
                Signal(a, t, name=name, unit=spec[1])
                for a, name, spec in zip(arrays[1:], g.names[1:], g.columns[1:], strict=True)
            ]
            g.index = self.mdf.append(sigs, comment=g.comment)
        else:
            self.mdf.extend(g.index, [(t, None)] + [(a, None) for a in arrays[1:]])
        g.samples += len(t)

    def close(self):
        if self.mdf is None:
            return
        self._flush(self.frames)
        self._flush(self.ext)
        try:
            self.mdf.save(self.path, overwrite=True)
        finally:
            self.mdf.close()
            self.mdf = None
