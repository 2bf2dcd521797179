"""What the MDF4 file says about itself: each channel's comment (what it is and the frame
field it comes from, by the tables of common/proto/frame.py and records.py), value names for
the state channels, and the header comment (source, baud, the board's configuration, the
start time, the tool and its version)."""

import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

from common.proto import frame, records

TOOL = "python -m tools.monitor"
PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"

_ENU = ("e", "n", "u")
_XYZ = ("x", "y", "z")

# what each channel of the stamps (not in a frame) is
STAMP_TEXT = {
    "board_time_s": "board time in its run: tick x 0.005 s (goes back at a restart)",
    "restart": "1 on the first frame after a board restart",
    "utc": "host UTC, seconds since 1970-01-01: the recording's start plus time_s",
}

# 52-byte frame channel -> (description, frame field)
FRAME_TEXT = {
    "counter": ("frame counter 0..255", "counter"),
    "nav_state": ("navigation state: 1 aligning, 2 navigating", "nav_state"),
    "gnss_valid": ("1: the GNSS fix is valid", "gnss_valid"),
    "pps": ("1 on the tick a PPS edge was seen", "pps"),
    "gga": ("1 on the tick a GGA sentence completed", "gga"),
    "lat_deg": ("GNSS fix latitude; NaN while gnss_valid is 0", "lat_e7"),
    "lon_deg": ("GNSS fix longitude; NaN while gnss_valid is 0", "lon_e7"),
    "height_m": ("GNSS fix height above mean sea level; NaN while gnss_valid is 0", "height_dm"),
    "yaw_deg": ("attitude: yaw", "yaw_cdeg"),
    "pitch_deg": ("attitude: pitch", "pitch_cdeg"),
    "roll_deg": ("attitude: roll", "roll_cdeg"),
    **{f"vel_{a}_m_s": (f"velocity {a.upper()} (ENU)", f"vel_{a}_cm_s") for a in _ENU},
    "pos_e_m": ("position E from the origin (ENU)", "pos_e_cm"),
    "pos_n_m": ("position N from the origin (ENU)", "pos_n_cm"),
    "pos_u_m": ("position U from the origin (ENU)", "pos_u_dm"),
    **{f"gyro_{a}_dps": (f"raw gyro {a}", f"gyro_{a}") for a in _XYZ},
    **{f"accel_{a}_g": (f"raw accelerometer {a}", f"accel_{a}") for a in _XYZ},
}

# extended frame channel -> (description, field, index in a list field or None)
EXT_TEXT = {
    "tick": ("board tick (x 0.005 s)", "tick", None),
    "health": ("health: 0 ok, 1 warning, 2 fault (docs/health.md)", "health", None),
    "causes": ("why health is not 0: bits of docs/health.md", "causes", None),
    "nav_state": ("navigation state: 1 aligning, 2 navigating", "nav_state", None),
    "config_status": ("configuration: 0 ok, 1 missing, 2 corrupt, 3 invalid", "config_status",
                      None),  # fmt: skip
    "gnss_valid": ("flags bit 0: GNSS valid", "flags", None),
    "standstill": ("flags bit 1: standstill", "flags", None),
    "imu_saturated": ("flags bit 2: IMU saturated", "flags", None),
    "worst_tick_us": ("worst tick run time", "worst_tick_us", None),
    "mean_tick_us": ("mean tick run time", "mean_tick_us", None),
    "overruns": ("tick overruns (wrapping u16)", "overruns", None),
    "gc_runs": ("garbage collections (wrapping u16)", "gc_runs", None),
    **{f"sigma_pos_{a}_m": (f"1-sigma position {a.upper()}", "p_diag", i)
       for i, a in enumerate(_ENU)},
    **{f"sigma_vel_{a}_m_s": (f"1-sigma velocity {a.upper()}", "p_diag", 3 + i)
       for i, a in enumerate(_ENU)},
    **{f"sigma_att_{a}_deg": (f"1-sigma attitude error {a.upper()}", "p_diag", 6 + i)
       for i, a in enumerate(_ENU)},
    **{f"sigma_gyro_bias_{a}_deg_h": (f"1-sigma gyro bias {a}", "p_diag", 9 + i)
       for i, a in enumerate(_XYZ)},
    **{f"sigma_accel_bias_{a}_mg": (f"1-sigma accel bias {a}", "p_diag", 12 + i)
       for i, a in enumerate(_XYZ)},
    **{f"gyro_bias_{a}_deg_h": (f"estimated gyro bias {a}", "gyro_bias_rad_s", i)
       for i, a in enumerate(_XYZ)},
    **{f"accel_bias_{a}_mg": (f"estimated accel bias {a}", "accel_bias_m_s2", i)
       for i, a in enumerate(_XYZ)},
    **{f"pos_{a}_m": (f"float32 position {a.upper()} from the origin", "pos_enu_m", i)
       for i, a in enumerate(_ENU)},
    "origin_lat_deg": ("local frame origin latitude", "origin_lat_e7", None),
    "origin_lon_deg": ("local frame origin longitude", "origin_lon_e7", None),
    "origin_h_m": ("local frame origin height (ellipsoidal)", "origin_h_m", None),
}  # fmt: skip

# value -> name of the state channels (both groups), shown by asammdf and MDF viewers
VALUE_NAMES = {
    "nav_state": {1: "aligning", 2: "navigating"},
    "health": {0: "ok", 1: "warning", 2: "fault"},
    "config_status": {0: "ok", 1: "missing", 2: "corrupt", 3: "invalid"},
}


def frame_comment(name):
    """A 52-byte frame channel's comment: what it is, its field, byte offset and scale."""
    if name == "time_s":
        return "capture time: 0 at the first frame, monotonic across board restarts"
    if name in STAMP_TEXT:
        return STAMP_TEXT[name]
    text, field = FRAME_TEXT[name]
    f = next(x for x in frame.FIELDS if x.name == field)
    if f.scale:
        scale = f", {f.scale:g} counts per {f.unit}"
    else:
        scale = f", in {f.unit}" if f.unit else ""
    return f"{text}; 52-byte frame field {field} at byte {frame.OFFSETS[field]}{scale}"


def ext_comment(name):
    """An extended frame channel's comment: what it is and its field and byte offset."""
    if name == "time_s":
        return "capture time of the extended frame's tick"
    if name in STAMP_TEXT:
        return STAMP_TEXT[name]
    if name == "counter":
        return "extended frame counter 0..255 (byte 3)"
    text, field, i = EXT_TEXT[name]
    at = records.EXT_OFFSETS[field] + 4 * (i or 0)
    part = field if i is None else f"{field}[{i}]"
    return f"{text}; extended frame field {part} at byte {at}"


def conversion(name):
    """asammdf's value-to-text conversion for a state channel (None for the others)."""
    names = VALUE_NAMES.get(name)
    if names is None:
        return None
    conv = {"default_addr": "unknown"}
    for k, (value, text) in enumerate(names.items()):
        conv[f"val_{k}"] = value
        conv[f"text_{k}"] = text
    return conv


def tool_version():
    """The project's version (pyproject.toml), "unknown" without one."""
    try:
        return tomllib.loads(PYPROJECT.read_text())["project"]["version"]
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        return "unknown"


def _tree(parent, name, values):
    tree = ET.SubElement(parent, "tree", name=name)
    for key, value in values.items():
        ET.SubElement(tree, "e", name=str(key)).text = str(value)


def header_comment(info, start_utc_text):
    """The MDF4 header comment (HDcomment XML): the description, then source, baud, the
    capture file, the start time, the tool and its version, and the board's configuration
    and identity as trees; items not known are left out."""
    root = ET.Element("HDcomment")
    ET.SubElement(root, "TX").text = (
        "INS board output recorded by python -m tools.monitor: 52-byte frames and extended "
        "frames (docs/monitor.md)"
    )
    props = ET.SubElement(root, "common_properties")
    items = {
        "source": info.get("source"),
        "baud": info.get("baud"),
        "capture_file": info.get("capture_file"),
        "config_file": info.get("config_file"),
        "start_utc": start_utc_text,
        "tool": TOOL,
        "tool_version": tool_version(),
    }
    for key, value in items.items():
        if value is not None:
            ET.SubElement(props, "e", name=key).text = str(value)
    for key in ("config", "board"):
        if info.get(key):
            _tree(props, key, info[key])
    return ET.tostring(root, encoding="unicode")
