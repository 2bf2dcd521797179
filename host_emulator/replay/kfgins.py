"""KF-GINS text files plus our `dataset.yaml`: a recorded (or simulated) drive on disk.

KF-GINS (i2Nav, Wuhan University; open-source loosely coupled INS/GNSS) and its public datasets
keep a drive as three whitespace-separated text files, no header:

    IMU   sow  dtheta_x dtheta_y dtheta_z  dv_x dv_y dv_z      (7 columns; an 8th, odometer
          speed in KF-GINS's imudatalen 8 variant, is accepted and ignored)
          increments (rad, m/s) over the interval ending at sow, IMU axes forward-right-down.
          As KF-GINS's loader: the interval is sow[i] - sow[i-1], except for the first row and
          after a gap of GAP_S or more, where it is 1 / imudatarate.
    GNSS  sow lat lon h sd_n sd_e sd_d                         (7 columns; deg, deg, m, m)
          sow lat lon h vn ve vd sd_n sd_e sd_d sd_vn sd_ve sd_vd   (13 columns: the order
          KF-GINS's GnssFileLoader reads, standard deviations at columns 8-10)
    .nav  week sow lat lon h vn ve vd roll pitch yaw           (11 columns; deg, m, m/s, deg)
          the IMU's trajectory, NED velocity, FRD/NED Euler angles (ZYX). KF-GINS datasets put
          week 0 there: a week of 0 means `gpsweek` of the description.

`sow` is GPS seconds of week `gpsweek`; it may run past 604800 s across a week rollover
(written so, read so). The description `dataset.yaml`, ours, sits in the same directory; a tiny
YAML subset (`key: value` lines, `#` comments, numbers, strings, `[a, b, c]` lists):

    name          str                          (default: the directory's name)
    description   str                          (optional)
    imufile       path relative to the directory
    gnssfile      path (optional: without it the dataset has no recorded GNSS input)
    truthfile     path of the .nav reference trajectory
    truthpoint    imu | antenna: which point the .nav describes (ours; default imu, KF-GINS's)
    waypointfile  path (ours, optional; default: `waypoints.csv` when the directory has one):
                  surveyed points passed at known instants, a CSV with a header naming at
                  least gpst_sow, lat_deg, lon_deg; with it the reference is only true there
                  (the .nav joins them) and the replay scores the output at these instants
    imudatarate   Hz
    gpsweek       the GPS week the sow columns count from
    starttime, endtime   optional sow limits applied to all three files (endtime -1: none)
    antlever      [forward, right, down] m, IMU to antenna (KF-GINS's name and meaning)
    installangle  [roll, pitch, yaw] deg, sensor axes -> body FRD as `Dataset.mount_rpy_deg`
                  (ours; default [0, 0, 0]: KF-GINS's IMU axes already are the body's)
    gravity       m/s^2 (optional, information)
    board         (optional) an indented block of the board's ins.cfg settings, one
                  `name: value` per line as `config set NAME=VALUE` takes them (firmware/lib/
                  config.py: noise, profile, thresholds, ...; a list for a vector); the
                  replay runs the firmware with them, after the settings it derives itself

`read` returns a `Dataset` in `dataset.py`'s conventions (GPST seconds, mean rates in sensor
axes); `write` writes the four files from one (body-FRD IMU file, installangle [0, 0, 0]);
`from_simulation` turns a `host_emulator.sim` Simulation into a Dataset. Any problem with a
file raises `FormatError` ("path:line: what"), never a traceback.
"""

import datetime
import math
import re
from pathlib import Path

import numpy as np
import pymap3d

from common.errors import EmulatorError
from host_emulator.sim.trajectory import euler_to_dcm

from .dataset import SWAP_FRD_RFU, WEEK_S, Dataset, Imu, Positions, mount_matrix
from .formats import FormatError, check_increasing, gpst_of_utc, parse_table, read_lines

__all__ = [
    "FormatError",
    "read",
    "write",
    "from_simulation",
    "intervals",
    "parse_description",
    "rpy_ned_deg",
]

DESCRIPTION = "dataset.yaml"
IMU_FILE = "imu.txt"
GNSS_FILE = "gnss.txt"
TRUTH_FILE = "truth.nav"
WAYPOINT_FILE = "waypoints.csv"
WAYPOINT_COLUMNS = ("gpst_sow", "lat_deg", "lon_deg")
GAP_S = 0.1  # KF-GINS ImuFileLoader: a longer interval is a gap, the row covers 1/rate

# key -> (kind, required)
_KEYS = {
    "name": ("str", False),
    "description": ("str", False),
    "imufile": ("path", True),
    "gnssfile": ("path", False),
    "truthfile": ("path", True),
    "truthpoint": ("str", False),
    "waypointfile": ("path", False),
    "imudatarate": ("number", True),
    "gpsweek": ("int", True),
    "starttime": ("number", False),
    "endtime": ("number", False),
    "antlever": ("vec3", True),
    "installangle": ("vec3", False),
    "gravity": ("number", False),
    "board": ("board", False),
}

# Formats of the written columns (the time columns are written as "%.6f": 1 us).
_SOW = "%.6f"
_INC = "%.10e"
_LATLON = "%.10f"  # 1e-10 deg ~ 0.01 mm
_H = "%.4f"
_SD = "%.4f"
_VEL = "%.6f"
_ANG = "%.8f"

# --- the description file: a tiny YAML subset ---

_KEY_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_INT_RE = re.compile(r"^[+-]?\d+$")


def _strip_comment(line):
    """The line without a `#` comment (a # at the start or after a space, outside quotes)."""
    quote = None
    escaped = False
    for i, ch in enumerate(line):
        if quote:
            if escaped:
                escaped = False
            elif ch == "\\" and quote == '"':
                escaped = True
            elif ch == quote:
                quote = None
        elif ch in "\"'":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1] in " \t"):
            return line[:i]
    return line


def _scalar(text, where):
    if text.startswith('"'):
        if len(text) < 2 or not text.endswith('"'):
            raise FormatError(f"{where}: unterminated string {text}")
        body = text[1:-1]
        out = []
        i = 0
        while i < len(body):
            ch = body[i]
            if ch == "\\" and i + 1 < len(body):
                i += 1
                ch = {"n": "\n", "t": "\t"}.get(body[i], body[i])
            elif ch == '"':
                raise FormatError(f"{where}: stray quote in {text}")
            out.append(ch)
            i += 1
        return "".join(out)
    if text.startswith("'"):
        if len(text) < 2 or not text.endswith("'"):
            raise FormatError(f"{where}: unterminated string {text}")
        return text[1:-1].replace("''", "'")
    if _INT_RE.match(text):
        return int(text)
    try:
        return float(text)
    except ValueError:
        return text


def _value(text, where):
    text = text.strip()
    if not text:
        return None
    if text.startswith("["):
        if not text.endswith("]"):
            raise FormatError(f"{where}: a list must close on its line: {text}")
        inner = text[1:-1].strip()
        if not inner:
            return []
        items = [item.strip() for item in inner.split(",")]
        if any(not item for item in items):
            raise FormatError(f"{where}: empty item in {text}")
        if any(item.startswith(("[", "{")) for item in items):
            raise FormatError(f"{where}: nested lists are not supported: {text}")
        return [_scalar(item, where) for item in items]
    if text.startswith("{"):
        raise FormatError(f"{where}: mappings are not supported: {text}")
    return _scalar(text, where)


def parse_description(path):
    """{key: (value, line number)} of a description file (the YAML subset of the module doc:
    `key: value` lines, `#` comments, numbers, quoted or bare strings, one-line lists, and a
    key with no value followed by indented `name: value` lines, whose value is then
    {name: (text as written, line number)})."""
    path = Path(path)
    out = {}
    block = None  # the key whose indented lines follow
    for i, raw in enumerate(read_lines(path, "dataset description"), 1):
        line = _strip_comment(raw).rstrip()
        if not line.strip():
            continue
        where = f"{path}:{i}"
        indented = line[0] in " \t"
        if line.lstrip().startswith("- ") or (indented and block is None):
            raise FormatError(
                f"{where}: indented or block lines are not supported (only under board:): "
                f"{raw.strip()}"
            )
        key, sep, rest = line.strip().partition(":")
        key = key.strip()
        if not sep or not _KEY_RE.match(key):
            raise FormatError(f"{where}: expected 'key: value', got {raw.strip()!r}")
        if indented:
            entries = out[block][0] if out[block][0] is not None else {}
            if key in entries:
                raise FormatError(
                    f"{where}: {block}: {key} given twice (first on line {entries[key][1]})"
                )
            entries[key] = (rest.strip(), i)
            out[block] = (entries, out[block][1])
            continue
        if key in out:
            raise FormatError(f"{where}: {key} given twice (first on line {out[key][1]})")
        out[key] = (_value(rest, where), i)
        block = key if out[key][0] is None else None
    return out


def _board_settings(path, entries):
    """{name: value} of a board: block, each line parsed as `config set NAME=VALUE` parses it
    and checked by the firmware's own validation (FormatError naming the line)."""
    from host_emulator.replay import run_config

    out = {}
    for name, (text, line) in entries.items():
        value = text[1:-1] if text.startswith("[") and text.endswith("]") else text
        try:
            key, parsed = run_config.parse(f"{name}={value}", where="board:")
        except EmulatorError as e:
            raise FormatError(f"{path}:{line}: {e}") from None
        out[key] = parsed
    return out


def _number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _typed(path, raw):
    """Check keys and types; {key: value} with defaults for the optional keys."""
    for key, (_, line) in raw.items():
        if key not in _KEYS:
            known = ", ".join(_KEYS)
            raise FormatError(f"{path}:{line}: unknown key {key!r} (known: {known})")
    out = {}
    for key, (kind, required) in _KEYS.items():
        value, line = raw.get(key, (None, None))
        if isinstance(value, dict) and kind != "board":
            raise FormatError(f"{path}:{line}: {key} takes its value on its line, not a block")
        if kind == "board":
            if value is not None and not isinstance(value, dict):
                raise FormatError(
                    f"{path}:{line}: board takes indented 'name: value' lines below it"
                )
            out[key] = _board_settings(path, value or {})
            continue
        if value is None:
            if required:
                raise FormatError(f"{path}: missing key {key!r}")
            out[key] = None
            continue
        where = f"{path}:{line}"
        if kind in ("str", "path"):
            if isinstance(value, list):
                raise FormatError(f"{where}: {key} must be a string, got a list")
            value = str(value)
        elif kind == "number":
            if not _number(value):
                raise FormatError(f"{where}: {key} must be a number, got {value!r}")
            value = float(value)
        elif kind == "int":
            if not _number(value) or value != int(value):
                raise FormatError(f"{where}: {key} must be a whole number, got {value!r}")
            value = int(value)
        elif kind == "vec3":
            if not isinstance(value, list) or len(value) != 3 or not all(map(_number, value)):
                raise FormatError(f"{where}: {key} must be a list of 3 numbers, got {value!r}")
            value = tuple(float(x) for x in value)
        out[key] = value
    lines = {key: line for key, (_, line) in raw.items()}
    if out["imudatarate"] <= 0.0:
        raise FormatError(f"{path}:{lines['imudatarate']}: imudatarate must be positive")
    if out["gpsweek"] < 0:
        raise FormatError(f"{path}:{lines['gpsweek']}: gpsweek must not be negative")
    if out["truthpoint"] is None:
        out["truthpoint"] = "imu"
    elif out["truthpoint"] not in ("imu", "antenna"):
        raise FormatError(f"{path}:{lines['truthpoint']}: truthpoint must be imu or antenna")
    if out["installangle"] is None:
        out["installangle"] = (0.0, 0.0, 0.0)
    if out["endtime"] is not None and out["endtime"] < 0:
        out["endtime"] = None  # KF-GINS: -1 = to the end of the files
    if out["starttime"] is not None and out["endtime"] is not None:
        if out["endtime"] < out["starttime"]:
            raise FormatError(f"{path}:{lines['endtime']}: endtime is before starttime")
    out["_lines"] = lines
    return out


def _description_path(path):
    path = Path(path)
    if path.is_dir():
        return path / DESCRIPTION
    return path


# --- reading ---


def intervals(sow, rate_hz):
    """(N,) interval of each IMU row, s, as KF-GINS's loader takes it: sow[i] - sow[i-1], or
    1 / rate_hz for the first row and after a gap of GAP_S or more."""
    sow = np.asarray(sow, dtype=np.float64)
    dt = np.empty_like(sow)
    if sow.size:
        dt[0] = 1.0 / rate_hz
        dt[1:] = np.diff(sow)
        dt[1:][dt[1:] >= GAP_S] = 1.0 / rate_hz
    return dt


def _data_file(desc_path, desc, key):
    path = desc_path.parent / desc[key]
    if not path.is_file():
        raise FormatError(
            f"{desc_path}:{desc['_lines'][key]}: {key} {desc[key]!r}: no such file ({path})"
        )
    return path


def _window(desc, sow):
    keep = np.ones(sow.size, bool)
    if desc["starttime"] is not None:
        keep &= sow >= desc["starttime"]
    if desc["endtime"] is not None:
        keep &= sow <= desc["endtime"]
    return keep


def _triple_or_none(a):
    return None if np.isnan(a).all() else a


# What a vehicle's IMU shows (the checks that catch rates written instead of increments)
_GRAVITY_BAND = (4.9, 20.0)  # m/s^2: the median specific force of a drive is about g
_GYRO_MAX_RAD_S = math.radians(2000.0)  # the BMI055's largest range


def _check_imu_rows(path, desc, sow, tab, dt, keep):
    """FormatError naming the likely mistake when the IMU rows cannot be a vehicle's
    increments: rows spaced unlike imudatarate (sow in ms?), velocity increments whose
    specific force is not about g (accelerations written instead of increments, or g
    units), gyro increments beyond any gyro range (rates written instead)."""
    rate = desc["imudatarate"]
    if sow.size > 1:
        step = float(np.median(np.diff(sow)))
        if not 1.0 / 1.5 <= step * rate <= 1.5:
            hint = (
                ": is sow in milliseconds? It counts seconds of the GPS week"
                if 500.0 < step * rate < 2000.0
                else f": set imudatarate to {1.0 / step:.6g}"
            )
            raise FormatError(
                f"{path}: the rows are {step:.6g} s apart (median), imudatarate {rate:g} Hz "
                f"says {1.0 / rate:.6g} s{hint}"
            )
    dv, dth, dt = tab[keep, 4:7], tab[keep, 1:4], dt[keep, None]
    f_m_s2 = float(np.median(np.linalg.norm(dv / dt, axis=1)))
    lo, hi = _GRAVITY_BAND
    if not lo <= f_m_s2 <= hi:
        raw = float(np.median(np.linalg.norm(dv, axis=1)))
        interval = f"1/imudatarate = {1.0 / rate:.6g} s"
        if lo <= raw <= hi:
            cause = (
                "the dv columns look like accelerations in m/s^2 rather than velocity "
                f"increments (m/s) over the row's interval ({interval}): multiply them by the "
                "interval (dv = f dt), and the gyro columns too (dtheta = w dt, rad)"
            )
        elif 0.5 <= raw <= 2.0:
            cause = (
                "the dv columns look like accelerations in g rather than velocity increments "
                f"(m/s) over the row's interval ({interval}): multiply them by 9.80665 and by "
                "the interval, and the gyro columns by the interval (dtheta = w dt, rad)"
            )
        elif 0.5 <= f_m_s2 <= 2.0:
            cause = "the dv columns look like increments in g s: multiply them by 9.80665"
        else:
            cause = "the dv columns must be velocity increments in m/s over each row's interval"
        raise FormatError(
            f"{path}: the velocity increments give a median specific force of {f_m_s2:.4g} "
            f"m/s^2, where gravity alone is about 9.8: {cause}"
        )
    w = np.linalg.norm(dth / dt, axis=1)
    if w.size and float(w.max()) > _GYRO_MAX_RAD_S:
        k = int(np.argmax(w))
        raw = float(np.linalg.norm(dth[k]))
        # a vehicle turns at up to ~1 rad/s: values of a few units are rad/s, tens deg/s
        unit = "rad/s" if raw < 3.0 else "deg/s" if raw <= 2000.0 else None
        cause = (
            f"the gyro columns look like rates (in {unit}, by their size) rather than angle "
            f"increments (rad) over the row's interval: "
            f"{'' if unit == 'rad/s' else 'convert them to rad/s and '}multiply them by the "
            "interval (dtheta = w dt)"
            if unit
            else "the gyro columns must be angle increments in rad over each row's interval"
        )
        raise FormatError(
            f"{path}: a gyro increment of {raw:.4g} over {float(dt[k, 0]):.4g} s is "
            f"{math.degrees(float(w[k])):.4g} deg/s, beyond any gyro range (the BMI055's "
            f"largest is 2000 deg/s): {cause}"
        )


def _read_imu(desc_path, desc):
    path = _data_file(desc_path, desc, "imufile")
    tab, line_no = parse_table(path, read_lines(path, "KF-GINS IMU file"), (7, 8), "IMU")
    sow = tab[:, 0]
    check_increasing(path, sow, line_no, "sow")
    dt = intervals(sow, desc["imudatarate"])
    keep = _window(desc, sow)
    if not keep.any():
        raise FormatError(f"{desc_path}: no IMU rows between starttime and endtime ({path})")
    _check_imu_rows(path, desc, sow, tab, dt, keep)
    t = desc["gpsweek"] * WEEK_S + sow
    dt = dt[:, None]
    return Imu(t[keep], (tab[:, 1:4] / dt)[keep], (tab[:, 4:7] / dt)[keep])


def _read_gnss(desc_path, desc):
    if desc["gnssfile"] is None:
        return None
    path = _data_file(desc_path, desc, "gnssfile")
    tab, line_no = parse_table(path, read_lines(path, "KF-GINS GNSS file"), (7, 13), "GNSS")
    sow = tab[:, 0]
    check_increasing(path, sow, line_no, "sow")
    if tab.shape[1] == 7:
        v, sd = None, tab[:, 4:7]
    else:
        v, sd = tab[:, 4:7], tab[:, 7:10]
    pos = Positions(desc["gpsweek"] * WEEK_S + sow, tab[:, 1], tab[:, 2], tab[:, 3], sd, v)
    return pos.select(_window(desc, sow))


def _read_truth(desc_path, desc):
    path = _data_file(desc_path, desc, "truthfile")
    tab, line_no = parse_table(path, read_lines(path, "KF-GINS .nav file"), (11,), ".nav")
    week = tab[:, 0]
    bad = np.flatnonzero((week != np.floor(week)) | (week < 0))
    if bad.size:
        k = bad[0]
        raise FormatError(f"{path}:{line_no[k]}: week {float(week[k])!r} is not a GPS week")
    week = np.where(week > 0, week, desc["gpsweek"])
    t = week * WEEK_S + tab[:, 1]
    check_increasing(path, t, line_no, "GPST (week, sow)")
    pos = Positions(
        t,
        tab[:, 2],
        tab[:, 3],
        tab[:, 4],
        None,
        _triple_or_none(tab[:, 5:8]),
        _triple_or_none(tab[:, 8:11]),
    )
    return pos.select(_window(desc, t - desc["gpsweek"] * WEEK_S))


def _read_waypoints(desc_path, desc):
    if desc["waypointfile"] is not None:
        path = _data_file(desc_path, desc, "waypointfile")
    else:
        path = desc_path.parent / WAYPOINT_FILE
        if not path.is_file():
            return None
    lines = read_lines(path, "waypoint file")
    rows = [(i + 1, ln.strip()) for i, ln in enumerate(lines) if ln.strip()]
    if not rows:
        raise FormatError(f"{path}: no header line (it needs {', '.join(WAYPOINT_COLUMNS)})")
    header = [h.strip() for h in rows[0][1].split(",")]
    missing = [c for c in WAYPOINT_COLUMNS if c not in header]
    if missing:
        raise FormatError(f"{path}:{rows[0][0]}: the header has no column {', '.join(missing)}")
    cols = [header.index(c) for c in WAYPOINT_COLUMNS]
    vals = []
    for line_no, text in rows[1:]:
        cells = text.split(",")
        try:
            v = [float(cells[c]) for c in cols]
        except (IndexError, ValueError):
            need = ", ".join(WAYPOINT_COLUMNS)
            raise FormatError(
                f"{path}:{line_no}: not {len(header)} comma-separated values with numbers in {need}"
            ) from None
        if not all(math.isfinite(x) for x in v):
            raise FormatError(f"{path}:{line_no}: {text!r}: not finite")
        vals.append(v)
    if not vals:
        raise FormatError(f"{path}: no waypoints after the header")
    tab = np.array(vals)
    check_increasing(path, tab[:, 0], [n for n, _ in rows[1:]], "gpst_sow")
    t = desc["gpsweek"] * WEEK_S + tab[:, 0]
    wp = Positions(t, tab[:, 1], tab[:, 2], np.zeros(len(t)))
    keep = _window(desc, tab[:, 0])
    if not keep.any():
        raise FormatError(f"{path}: none of its {len(t)} waypoints lies between starttime and "
                          "endtime")  # fmt: skip
    return wp.select(keep)


def read(path):
    """Dataset of a directory holding `dataset.yaml` (or of the description file itself)."""
    desc_path = _description_path(path)
    desc = _typed(desc_path, parse_description(desc_path))
    name = desc["name"] if desc["name"] is not None else desc_path.parent.resolve().name
    files = {key[:-4]: desc[key] for key in ("imufile", "gnssfile", "truthfile") if desc[key]}
    return Dataset(
        name=name,
        imu=_read_imu(desc_path, desc),
        truth=_read_truth(desc_path, desc),
        truth_point=desc["truthpoint"],
        gnss=_read_gnss(desc_path, desc),
        mount_rpy_deg=desc["installangle"],
        lever_frd_m=desc["antlever"],
        gravity_m_s2=desc["gravity"],
        description=desc["description"] or "",
        board_config=desc["board"],
        files=files,
        gpsweek=desc["gpsweek"],
        waypoints=_read_waypoints(desc_path, desc),
    )


# --- writing ---


def _quoted(s):
    s = " ".join(str(s).splitlines())
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _sow_text(t_s, t_week, path):
    """The sow column as written ("%.6f") and its value as read back."""
    text = [_SOW % x for x in np.asarray(t_s, np.float64) - t_week]
    back = np.array(text, dtype=np.float64)
    if back.size > 1 and not (np.diff(back) > 0.0).all():
        raise FormatError(f"{path}: times closer than 1 us cannot be written")
    return text, back


def _write_rows(path, first, cols, fmt):
    """Rows of `first` (strings) followed by the (N, k) float columns, `fmt` per row."""
    fmt = "%s " + fmt + "\n"
    with open(path, "w", encoding="ascii") as f:
        f.writelines(fmt % (s, *row) for s, row in zip(first, cols.tolist(), strict=True))


def _fmts(*pairs):
    return " ".join(" ".join([f] * n) for f, n in pairs)


def _rate_text(sow):
    step = float(np.median(np.diff(sow)))
    return f"{1.0 / step:.6g}"


def write(path, dataset, gnss=None, truth=None):
    """Write `dataset` as KF-GINS files plus dataset.yaml into directory `path` (created).
    Its board_config becomes the description's `board:` block.

    The IMU file holds body-FRD increments: the sensor-axes rates are rotated with
    mount_matrix(dataset.mount_rpy_deg), multiplied by each row's interval (`intervals` of the
    written times) and installangle is written as [0, 0, 0]. `gnss` defaults to dataset.gnss
    (none: no GNSS file); it needs sigma_ned_m; with v_ned_m_s it is written in the 13-column
    form with NaN velocity standard deviations (a Positions carries none). `truth` defaults to
    dataset.truth; a missing v_ned_m_s or rpy_deg is written as NaN columns, which `read` turns
    back into None. Times are written to 1 us, sow counted from the week of the earliest time.
    """
    out = Path(path)
    out.mkdir(parents=True, exist_ok=True)
    gnss = dataset.gnss if gnss is None else gnss
    truth = dataset.truth if truth is None else truth
    imu = dataset.imu
    if len(imu) < 2:
        raise FormatError(f"{out}: cannot write an IMU of fewer than 2 samples")
    firsts = [imu.t_s[0], truth.t_s[0]] + ([gnss.t_s[0]] if gnss is not None else [])
    week = int(math.floor(min(firsts) / WEEK_S))
    t_week = week * WEEK_S
    rate_txt = _write_imu(out / IMU_FILE, dataset, t_week)
    if gnss is not None:
        _write_gnss(out / GNSS_FILE, gnss, t_week)
    _write_truth(out / TRUTH_FILE, truth, week, t_week)
    text = _description_text(dataset, gnss is not None, rate_txt, week)
    (out / DESCRIPTION).write_text(text, encoding="utf-8")
    return out


def _write_imu(imu_path, dataset, t_week):
    """The IMU file: body FRD increments over the written intervals; the rate as written."""
    imu = dataset.imu
    sow_txt, sow = _sow_text(imu.t_s, t_week, imu_path)
    rate_txt = _rate_text(sow)
    dt = intervals(sow, float(rate_txt))[:, None]
    c_sb = mount_matrix(dataset.mount_rpy_deg)
    c_sb[np.abs(c_sb) < 1e-12] = 0.0  # sin(180 deg) = 1.2e-16: keep exact axis swaps exact
    inc = np.hstack([imu.gyro_rad_s @ c_sb.T * dt, imu.accel_m_s2 @ c_sb.T * dt])
    _write_rows(imu_path, sow_txt, inc, _fmts((_INC, 6)))
    return rate_txt


def _write_gnss(gnss_path, gnss, t_week):
    """The GNSS file: 7 columns, or 13 with the velocities (their sigmas NaN)."""
    if gnss.sigma_ned_m is None:
        raise FormatError(f"{gnss_path}: the GNSS positions have no sigma_ned_m to write")
    sow_txt, _ = _sow_text(gnss.t_s, t_week, gnss_path)
    pos = np.column_stack([gnss.lat_deg, gnss.lon_deg, gnss.h_m])
    if gnss.v_ned_m_s is None:
        cols = np.hstack([pos, gnss.sigma_ned_m])
        fmt = _fmts((_LATLON, 2), (_H, 1), (_SD, 3))
    else:
        nan = np.full((len(gnss), 3), np.nan)
        cols = np.hstack([pos, gnss.v_ned_m_s, gnss.sigma_ned_m, nan])
        fmt = _fmts((_LATLON, 2), (_H, 1), (_VEL, 3), (_SD, 3), (_SD, 3))
    _write_rows(gnss_path, sow_txt, cols, fmt)


def _write_truth(truth_path, truth, week, t_week):
    """The .nav reference: a missing velocity or attitude as NaN columns."""
    sow_txt, _ = _sow_text(truth.t_s, t_week, truth_path)
    nan = np.full((len(truth), 3), np.nan)
    cols = np.column_stack(
        [
            truth.lat_deg,
            truth.lon_deg,
            truth.h_m,
            nan if truth.v_ned_m_s is None else truth.v_ned_m_s,
            nan if truth.rpy_deg is None else truth.rpy_deg,
        ]
    )
    first = [f"{week} {s}" for s in sow_txt]
    _write_rows(truth_path, first, cols, _fmts((_LATLON, 2), (_H, 1), (_VEL, 3), (_ANG, 3)))


def _vec(v):
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def _description_text(dataset, has_gnss, rate_txt, week):
    """The text of dataset.yaml for the files written."""
    lines = [
        "# Drive in KF-GINS text files (host_emulator/replay/kfgins.py, docs/formats.md)",
        f"name: {_quoted(dataset.name)}",
    ]
    if dataset.description:
        lines.append(f"description: {_quoted(dataset.description)}")
    lines += [
        f"imufile: {IMU_FILE}  # sow, gyro (rad) and velocity (m/s) increments, body FRD",
    ]
    if has_gnss:
        lines.append(f"gnssfile: {GNSS_FILE}")
    lines += [
        f"truthfile: {TRUTH_FILE}",
        f"truthpoint: {dataset.truth_point}  # the point the .nav trajectory describes",
        f"imudatarate: {rate_txt}  # Hz",
        f"gpsweek: {week}  # the sow columns count from this GPS week",
        f"antlever: {_vec(dataset.lever_frd_m)}  # m, forward right down, IMU -> antenna",
        "installangle: [0.0, 0.0, 0.0]  # deg; the IMU file is already in body axes",
    ]
    if dataset.gravity_m_s2 is not None:
        lines.append(f"gravity: {float(dataset.gravity_m_s2)!r}  # m/s^2")
    if dataset.board_config:
        lines.append(
            "board:  # the board's ins.cfg settings for this sensor (firmware/lib/config.py)"
        )
        for name, value in dataset.board_config.items():
            if value is None:
                text = "identity"
            elif isinstance(value, (list, tuple)):
                text = _vec(value)
            else:
                text = repr(value)
            lines.append(f"  {name}: {text}")
    return "\n".join(lines) + "\n"


# --- from a simulation ---

# The simulation's board axes are right-forward-up and its navigation frame ENU.
_SWAP = SWAP_FRD_RFU
# Mounting of the simulated board as `Dataset.mount_rpy_deg`: mount_matrix of it is _SWAP.
SIM_MOUNT_RPY_DEG = (180.0, 0.0, 90.0)


def rpy_ned_deg(ypr_rad):
    """(N, 3) roll, pitch, yaw (deg, FRD body in NED, yaw clockwise from north) of firmware
    ypr (N, 3) = [yaw ccw from north, pitch, roll] (rad, RFU body in ENU, firmware/lib/rot.py)."""
    c = _SWAP @ euler_to_dcm(ypr_rad) @ _SWAP  # C_b^n, FRD body -> NED
    roll = np.arctan2(c[..., 2, 1], c[..., 2, 2])
    pitch = np.arcsin(np.clip(-c[..., 2, 0], -1.0, 1.0))
    yaw = np.arctan2(c[..., 1, 0], c[..., 0, 0])
    return np.degrees(np.stack([roll, pitch, yaw], axis=-1))


def from_simulation(sim):
    """Dataset of a `host_emulator.sim.board_input.Simulation` (only .name, .seed, .truth,
    .imu, .gnss are used).

    Time: sim time 0 is UTC `gnss.model.utc_start`, GPST = UTC + the leap seconds then (18 s
    since 2017). IMU: the simulated sample k is the instantaneous rate at k dt in the board's
    right-forward-up axes; it is taken as the mean rate over (k dt - dt/2, k dt + dt/2], so its
    time is k dt + dt/2 (midpoint rule: the error is dt^2/24 times the rate's second
    derivative; sampling the mean rates at interval midpoints gives back sample k at k dt).
    The sensor axes stay the board's (RFU) with mount_rpy_deg SIM_MOUNT_RPY_DEG (RFU -> FRD).
    Truth: every 5 ms sample of the IMU's trajectory, lat/lon/h exact (pymap3d) from the ENU
    position, NED velocity, FRD/NED attitude. GNSS: the epochs with a fix, at their fix time,
    sigma (h, h, v) per epoch, no velocity (the NMEA output has no vertical speed).
    """
    truth, imu, gnss = sim.truth, sim.imu, sim.gnss
    utc = datetime.datetime.fromisoformat(gnss.model.utc_start)
    t0 = gpst_of_utc(utc)
    o = truth.origin
    lat, lon, h = pymap3d.enu2geodetic(
        truth.p_n[:, 0], truth.p_n[:, 1], truth.p_n[:, 2], o.lat_e7 * 1e-7, o.lon_e7 * 1e-7, o.h_m
    )
    v = truth.v_n
    truth_pos = Positions(
        t0 + truth.t_s,
        np.asarray(lat, float),
        np.asarray(lon, float),
        np.asarray(h, float),
        None,
        np.column_stack([v[:, 1], v[:, 0], -v[:, 2]]),
        rpy_ned_deg(truth.ypr),
    )
    fix = np.asarray(gnss.quality) > 0
    sh, sv = gnss.sigma_h_m[fix], gnss.sigma_v_m[fix]
    gnss_pos = Positions(
        t0 + gnss.t_fix_s[fix],
        gnss.lat_e7[fix] * 1e-7,
        gnss.lon_e7[fix] * 1e-7,
        np.asarray(gnss.h_m[fix], float),
        np.column_stack([sh, sh, sv]),
    )
    dt = float(truth.dt_s)
    imu_ds = Imu(
        t0 + np.asarray(imu.t_s, float) + 0.5 * dt,
        np.asarray(imu.w_b_rad_s, float),
        np.asarray(imu.f_b_m_s2, float),
    )
    right, forward, up = (float(x) for x in gnss.model.lever_b_m)
    return Dataset(
        name=sim.name,
        imu=imu_ds,
        truth=truth_pos,
        truth_point="imu",
        gnss=gnss_pos,
        mount_rpy_deg=SIM_MOUNT_RPY_DEG,
        lever_frd_m=(forward, right, -up),
        gravity_m_s2=float(o.gravity_m_s2()),
        description=f"simulation {sim.name!r}, seed {sim.seed}: {truth.description}",
    )
