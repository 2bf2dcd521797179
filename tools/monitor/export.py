"""Files written from the decoded stream: CSV (frames, and extended frames in a second file)
and MDF4 (asammdf). The channels and their units are the tables below; docs/monitor.md lists
them too."""

import csv
import datetime
import math
import os
from pathlib import Path

from tools.monitor import mdf_meta

G = 9.80665  # m/s^2 per g (for accelerometer biases in mg)
RAD_S_TO_DEG_H = 180.0 / math.pi * 3600.0

# (name, unit, decimals in the CSV (UTC: ISO 8601 text), MDF dtype); the CSV column is
# `name`, the MDF channel too (UTC: utc_unix_s, seconds since 1970 UTC).
UTC = "utc"
# the times of every row (Monitor._stamp): the capture's time, monotonic across board restarts;
# the board's own time in its run; 1 on a restarted run's first frame; the host's UTC
FRAME_COLUMNS = [
    ("time_s", "s", 3, "f8"),
    ("board_time_s", "s", 3, "f8"),
    ("restart", "", None, "u1"),
    ("utc", "", UTC, "f8"),
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
        ("utc", "", UTC, "f8"),
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
def _mdf_name(column):
    name, _unit, dec, _dt = column
    return name + "_unix_s" if dec == UTC else name


MDF_FRAME_NAMES = [_mdf_name(c) for c in FRAME_COLUMNS]
MDF_EXT_NAMES = [
    "ext_" + n if n in MDF_FRAME_NAMES[1:] else n for n in (_mdf_name(c) for c in EXT_COLUMNS)
]


def utc_text(unix_s):
    """ISO 8601 UTC to the millisecond: 2026-05-01T09:30:00.005Z."""
    t = datetime.datetime.fromtimestamp(unix_s, datetime.UTC)
    return t.isoformat(timespec="milliseconds").replace("+00:00", "Z")


# the frame's GNSS fix: no value (an empty CSV cell, NaN in MDF4) while gnss_valid is 0, where
# the board sends 0, 0 before its first fix (a point in the Gulf of Guinea, not a position)
FIX_COLUMNS = ("lat_deg", "lon_deg", "height_m")


def fix_values(f):
    """(lat deg, lon deg, height m) of the frame's GNSS fix; NaN without a valid one."""
    if not f["gnss_valid"]:
        return (math.nan,) * len(FIX_COLUMNS)
    return f["lat_e7"] / 1e7, f["lon_e7"] / 1e7, f["height_m"]


def frame_values(stamp, f):
    """The FRAME_COLUMNS values of frame fields `f` (frames.frame_fields) with its times
    `stamp` (time_s, board_time_s, restart, utc_unix_s)."""
    return [
        stamp["time_s"],
        stamp["board_time_s"],
        stamp["restart"],
        stamp["utc_unix_s"],
        f["counter"],
        f["nav_state"],
        f["gnss_valid"],
        f["pps"],
        f["gga"],
        *fix_values(f),
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


def ext_values(stamp, e):
    """The EXT_COLUMNS values of an extended frame's fields (frames.ext_fields) with its times
    `stamp` (time_s, utc_unix_s)."""
    s = sigmas(e)
    fl = e["flags"]
    return [
        stamp["time_s"],
        stamp["utc_unix_s"],
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


def _fix_cell(decimals):
    """A fix column's formatter: an empty cell for NaN (no valid fix)."""
    return lambda x: "" if math.isnan(x) else f"{x:.{decimals}f}"


def _fmt(columns):
    out = []
    for name, _unit, dec, _dt in columns:
        if dec == UTC:
            out.append(utc_text)
        elif name in FIX_COLUMNS and columns is FRAME_COLUMNS:
            out.append(_fix_cell(dec))
        else:
            out.append(str if dec is None else (lambda x, d=dec: f"{x:.{d}f}"))
    return out


class WriteFailed(Exception):
    """An export could not be written (a full disk, a device that refuses): the message names
    the file and the OS reason; what was written of it is removed."""


def part_path(path):
    """Where an export is written until it is complete: `.NAME.part` beside NAME, renamed to
    NAME once closed whole. A device or a pipe (/dev/stdout) is written to directly."""
    p = Path(path)
    if p.exists() and not p.is_file():
        return p
    return p.with_name(f".{p.name}.part")


def _publish(part, path):
    if part != Path(path):
        os.replace(part, path)


def _discard(f, part, path):
    """Close f without a word and remove the part file (never the device written to)."""
    try:
        f.close()
    except OSError:
        pass
    if part != Path(path):
        part.unlink(missing_ok=True)


def failed_text(path, e):
    why = e.strerror or str(e)
    hint = " (the disk is full)" if e.errno == 28 else ""
    return f"writing {path} failed: {why}{hint}; nothing of it is kept"


def _open_part(part, path, mode, **kw):
    try:
        return open(part, mode, **kw)  # noqa: SIM115 (closed by the export's close)
    except OSError as e:
        raise OSError(f"cannot write {path}: {e.strerror}") from None


class CsvExport:
    """One row per 52-byte frame in `path`, one per extended frame in ext_csv_path(path); both
    written under their part_path names and renamed at close, or removed when a write fails
    (WriteFailed)."""

    def __init__(self, path):
        self.path = Path(path)
        self.ext_path = ext_csv_path(path)
        self.rows = 0
        self.ext_rows = 0
        self.failed = None  # why it was not written (WriteFailed), or None
        self._targets = [self.path, self.ext_path]
        self._parts = [part_path(p) for p in self._targets]
        self._files = []
        try:
            for part, target in zip(self._parts, self._targets, strict=True):
                self._files.append(_open_part(part, target, "w", newline=""))
        except OSError:
            self._discard_all()
            raise
        self._w = csv.writer(self._files[0])
        self._we = csv.writer(self._files[1])
        self._ff = _fmt(FRAME_COLUMNS)
        self._fx = _fmt(EXT_COLUMNS)
        self._write(0, [c[0] for c in FRAME_COLUMNS])
        self._write(1, [c[0] for c in EXT_COLUMNS])

    def frame(self, stamp, f):
        values = frame_values(stamp, f)
        self._write(0, [fmt(v) for fmt, v in zip(self._ff, values, strict=True)])
        self.rows += 1

    def ext(self, stamp, e):
        values = ext_values(stamp, e)
        self._write(1, [fmt(v) for fmt, v in zip(self._fx, values, strict=True)])
        self.ext_rows += 1

    def _write(self, k, row):
        try:
            (self._w if k == 0 else self._we).writerow(row)
        except OSError as e:
            self._fail(k, e)

    def _fail(self, k, e):
        self._discard_all()
        self.failed = failed_text(self._targets[k], e)
        raise WriteFailed(self.failed) from None

    def describe(self):
        return f"{self.path} ({self.rows} rows), {self.ext_path} ({self.ext_rows} rows)"

    def abandon(self):
        """Remove what was written (another output could not be opened)."""
        self._discard_all()

    def _discard_all(self):
        for f, part, target in zip(self._files, self._parts, self._targets, strict=False):
            _discard(f, part, target)
        self._files = []

    def close(self):
        """Both files complete under their names; WriteFailed (and neither kept) otherwise."""
        if not self._files:  # closed, or failed before
            return
        for k, f in enumerate(self._files):  # both whole before either gets its name
            try:
                f.close()
            except OSError as e:
                self._fail(k, e)
        for k, part in enumerate(self._parts):
            try:
                _publish(part, self._targets[k])
            except OSError as e:
                self._fail(k, e)
        self._files = []


class _MdfGroup:
    def __init__(self, columns, comment, names, channel_comment):
        self.columns = columns
        self.names = names
        self.comment = comment
        self.channel_comment = channel_comment  # column name -> the channel's comment
        self.rows = []
        self.index = None
        self.samples = 0


class MdfExport:
    """MDF4 (asammdf): a channel group for the frames (master: time_s, the capture's time)
    and one for the extended frames; the header's start time is the host's UTC at capture
    time 0. Written in blocks of CHUNK samples as they come (memory stays bounded), saved at
    close under part_path(path) and renamed; WriteFailed (and nothing kept) when that fails."""

    CHUNK = 2000

    def __init__(self, path, info=None):
        try:
            from asammdf import MDF
        except ImportError:
            raise OSError("writing MDF4 needs asammdf (pip install asammdf==8.8.28)") from None
        self.path = Path(path)
        self._part = part_path(self.path)
        self._file = _open_part(self._part, self.path, "w+b")  # fails now, not at the end
        self.start_unix_s = None
        self.info = info or {}  # for the header: source, baud, config, ... (mdf_meta)
        self.failed = None  # why it was not written (WriteFailed), or None
        self.mdf = MDF(version="4.10")
        self.frame_group = _MdfGroup(
            FRAME_COLUMNS, "INS 52-byte frames", MDF_FRAME_NAMES, mdf_meta.frame_comment
        )
        self.ext_group = _MdfGroup(
            EXT_COLUMNS, "INS extended frames", MDF_EXT_NAMES, mdf_meta.ext_comment
        )

    def frame(self, stamp, f):
        self._add(self.frame_group, stamp, frame_values(stamp, f))

    def ext(self, stamp, e):
        self._add(self.ext_group, stamp, ext_values(stamp, e))

    def _add(self, g, stamp, values):
        if self.start_unix_s is None:
            self.start_unix_s = stamp["utc_unix_s"] - stamp["time_s"]
        g.rows.append(values)
        if len(g.rows) >= self.CHUNK:
            self._guarded(lambda: self._flush(g))

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
                Signal(
                    a, t, name=name, unit=spec[1], comment=g.channel_comment(spec[0]),
                    conversion=mdf_meta.conversion(spec[0]),
                )
                for a, name, spec in zip(arrays[1:], g.names[1:], g.columns[1:], strict=True)
            ]  # fmt: skip
            g.index = self.mdf.append(sigs, comment=g.comment)
        else:
            self.mdf.extend(g.index, [(t, None)] + [(a, None) for a in arrays[1:]])
        g.samples += len(t)

    def _guarded(self, write):
        """write(); on an OSError the file removed and WriteFailed naming it."""
        try:
            write()
        except OSError as e:
            self.abandon()
            self.failed = failed_text(self.path, e)
            raise WriteFailed(self.failed) from None
        except BaseException:  # Ctrl-C, or asammdf failing: no part file left either
            self.abandon()
            self.failed = f"writing {self.path} was interrupted; nothing of it is kept"
            raise

    def describe(self):
        g, x = self.frame_group, self.ext_group
        return f"{self.path} (MDF4: {g.samples} frames, {x.samples} ext)"

    def abandon(self):
        """Remove what was written (a failed write, or another output not opened)."""
        _discard(self._file, self._part, self.path)
        if self.mdf is not None:
            self.mdf.close()
            self.mdf = None

    def close(self):
        if self.mdf is None:
            return
        self._guarded(self._save)
        self.mdf.close()
        self.mdf = None

    def _save(self):
        self._flush(self.frame_group)
        self._flush(self.ext_group)
        start_text = None
        if self.start_unix_s is not None:
            start = datetime.datetime.fromtimestamp(self.start_unix_s, datetime.UTC)
            self.mdf.header.start_time = start
            start_text = utc_text(self.start_unix_s)
        self.mdf.header.comment = mdf_meta.header_comment(self.info, start_text)
        self.mdf.save(self._file)  # a file object: asammdf keeps its name and raises
        self._file.close()
        _publish(self._part, self.path)
