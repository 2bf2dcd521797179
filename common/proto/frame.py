"""The 52-byte output frame (docs/requirements.md, output frame, a **contract**), written once as a
field table.

`FIELDS` lists the fields in byte order (little-endian, signed unless the code is upper-case):
    name   the integer as the bytes hold it, named with its unit of count ("yaw_cdeg")
    code   its struct code
    scale  counts per physical unit (None: a count, a flag or a byte)
    unit   the physical unit
    key    where `decode` puts the physical value (fields sharing a key form a list, in order)
Everything else here is derived from the table: the layout (`STRUCT`, `OFFSETS`), the decoder,
the encoder and the model's NumPy record type. The board packs the same layout with integer
code at fixed offsets (firmware/lib/frame.py: no struct, nothing allocated);
tests/lib/test_frame.py checks the firmware's bytes against this table.
"""

import struct
from typing import NamedTuple

HEADER = 0xEB
FRAME_TYPE = 0x90  # the second header byte: what 0xEB 0x90 starts (records.py has the others)
FRAME_LEN = 52


class Field(NamedTuple):
    name: str
    code: str
    scale: float | None
    unit: str
    key: str | None


def _xyz(prefix, code, scale, unit, key, axes="xyz", suffix=""):
    return tuple(Field(f"{prefix}_{a}{suffix}", code, scale, unit, key) for a in axes)


FIELDS = (
    Field("header0", "B", None, "", None),  # 0xEB
    Field("header1", "B", None, "", None),  # 0x90
    Field("counter", "B", None, "", "counter"),  # 0..255, one more per frame sent
    *_xyz("gyro", "h", 131.07, "deg/s", "gyro_dps"),  # raw BMI055 counts at +-250 deg/s
    *_xyz("accel", "h", 16383, "g", "accel_g"),  # raw counts at +-2 g, 12-bit left-justified
    Field("pps", "B", None, "", "pps"),  # 1 on the tick a PPS edge was seen
    Field("gga", "B", None, "", "gga"),  # 1 on the tick a GGA sentence completed
    Field("gnss_valid", "B", None, "", "gnss_valid"),
    Field("lat_e7", "i", None, "1e-7 deg", "lat_e7"),  # the GNSS fix
    Field("lon_e7", "i", None, "1e-7 deg", "lon_e7"),
    Field("height_dm", "h", 10, "m", "height_m"),
    Field("nav_state", "B", None, "", "nav_state"),  # 1 aligning, 2 navigating
    Field("yaw_cdeg", "h", 100, "deg", "yaw_deg"),
    Field("pitch_cdeg", "h", 100, "deg", "pitch_deg"),
    Field("roll_cdeg", "h", 100, "deg", "roll_deg"),
    *_xyz("vel", "h", 100, "m/s", "vel_enu_m_s", "enu", "_cm_s"),
    Field("pos_e_cm", "i", 100, "m", "pos_enu_m"),  # local ENU frame of the navigator
    Field("pos_n_cm", "i", 100, "m", "pos_enu_m"),
    Field("pos_u_dm", "h", 10, "m", "pos_enu_m"),
    Field("checksum", "B", None, "", None),  # sum of bytes 2..50, mod 256
)
STRUCT = struct.Struct("<" + "".join(f.code for f in FIELDS))
NAMES = tuple(f.name for f in FIELDS)
OFFSETS = {}
_at = 0
for _f in FIELDS:
    OFFSETS[_f.name] = _at
    _at += struct.calcsize("<" + _f.code)
assert STRUCT.size == FRAME_LEN == _at
# fields the board computes from the navigator's float32 state (the rest are integers it
# copies or converts exactly): where a double-precision VM may differ by a step
NAV_FLOAT_FIELDS = tuple(
    f.name
    for f in FIELDS
    if f.key in ("yaw_deg", "pitch_deg", "roll_deg", "vel_enu_m_s", "pos_enu_m")
)
SENSOR_FIELDS = tuple(f.name for f in FIELDS if f.key in ("gyro_dps", "accel_g"))


def checksum(b):
    """The checksum byte the frame b must end with."""
    return sum(b[2 : FRAME_LEN - 1]) & 0xFF


def is_valid(b):
    return len(b) == FRAME_LEN and b[0] == HEADER and b[1] == FRAME_TYPE and b[-1] == checksum(b)


def decode(b):
    """The frame's fields in physical units (value = counts / scale), keyed by Field.key, plus
    "raw": the 52 bytes."""
    out = {}
    for f, v in zip(FIELDS, STRUCT.unpack(b), strict=True):
        if f.key is None:
            continue
        x = v if f.scale is None else v / f.scale
        if f.key in out:
            prev = out[f.key]
            out[f.key] = [*prev, x] if isinstance(prev, list) else [prev, x]
        else:
            out[f.key] = x
    out["raw"] = bytes(b)
    return out


def encode(counter, **counts):
    """The frame holding these integer field values (names of FIELDS, 0 where not given), with
    its header, counter and checksum."""
    unknown = set(counts) - set(NAMES)
    if unknown:
        raise KeyError(f"not frame fields: {sorted(unknown)}")
    values = [counts.get(n, 0) for n in NAMES]
    values[0], values[1], values[2] = HEADER, FRAME_TYPE, counter & 0xFF
    b = bytearray(STRUCT.pack(*values))
    b[-1] = checksum(b)
    return bytes(b)


_NUMPY = {"B": "u1", "h": "<i2", "i": "<i4"}


def numpy_dtype():
    """The frame as a NumPy record type (one field per table entry), for building many frames
    at once (the model)."""
    import numpy as np

    dt = np.dtype([(f.name, _NUMPY[f.code]) for f in FIELDS])
    assert dt.itemsize == FRAME_LEN
    return dt
