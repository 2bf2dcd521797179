"""The CRC-32 protected records the board sends besides the 52-byte frame (firmware/lib/
records.py packs them): the extended frame (type 0x91) and the raw-input record (0x92).

Common layout: 0xEB, type, length n (u8), counter (u8), n - 1 payload bytes (the counter counts
in n), then the CRC-32 (u32 LE, proto/crc.py) of everything before it. Little-endian; floats
are the navigator's float32 bits, copied.

The extended frame's payload is the table `EXT_FIELDS` (name, struct code, count; a count > 1
decodes as a list); the raw-input record holds a fixed part (`RAW_FIELDS`) and then the GNSS
bytes the tick fed to the parser. `decode_*` give dicts of the fields with the counter;
`encode_*` build the records bit for bit (the model sends them); offsets are in `EXT_OFFSETS`
and `RAW_OFFSETS` (from the start of the record).
"""

import struct

import numpy as np

from common.proto.crc import crc32
from common.proto.frame import HEADER

EXT_TYPE = 0x91
RAW_TYPE = 0x92
HEAD_LEN = 4  # 0xEB, type, length, counter
CRC_LEN = 4

EXT_FIELDS = (
    ("health", "B", 1),  # 0 normal, 1 warning, 2 fault (a configuration fallback counts as 1)
    ("nav_state", "B", 1),  # 1 aligning, 2 navigating
    ("config_status", "B", 1),  # config.OK / MISSING / CORRUPT / INVALID
    ("flags", "B", 1),  # bit 0 GNSS valid, bit 1 standstill, bit 2 IMU saturated
    ("worst_tick_us", "H", 1),  # the board's run time (0 on an emulator)
    ("mean_tick_us", "H", 1),
    ("overruns", "H", 1),  # wrapping
    ("gc_runs", "H", 1),
    ("p_diag", "f", 15),  # covariance diagonal, the error-state order of docs/requirements.md
    ("gyro_bias_rad_s", "f", 3),
    ("accel_bias_m_s2", "f", 3),
    ("pos_enu_m", "f", 3),  # from the origin
    ("origin_lat_e7", "i", 1),  # 1e-7 deg
    ("origin_lon_e7", "i", 1),
    ("tick", "I", 1),  # navigator ticks, wrapping at 2**30
    ("origin_h_m", "f", 1),  # ellipsoidal; the position's U is relative to it
    ("causes", "I", 1),  # why health is not 0: CAUSES bits (docs/health.md)
)
# The bits of "causes": firmware/lib/nav.py CAUSE_* (the navigator's) and firmware/app.py's
# (tests/proto checks that they agree), by name, in bit order
CAUSES = (
    (0x1, "imu_saturated"),
    (0x2, "imu_sample_held"),
    (0x4, "imu_dead"),
    (0x8, "numeric_fault"),
    (0x10, "gnss_lost"),
    (0x20, "gnss_gated"),
    (0x40, "gnss_rejects"),
    (0x80, "gnss_bad_data"),
    (0x100, "reset_to_gnss"),
    (0x200, "uncertain"),
    (0x400, "drift"),
    (0x800, "gnss_late"),
    (0x1000, "nmea_errors"),
    (0x2000, "pps_irregular"),
    (0x4000, "config_defaults"),
    (0x8000, "overrun"),
    (0x10000, "gnss_clock"),
    (0x20000, "gnss_implausible"),
    (0x40000, "display_unanswered"),
    (0x80000, "not_navigating"),
)
CAUSE_BITS = {name: bit for bit, name in CAUSES}  # a cause's bit by its name
CAUSE_OVERRUN = 0x8000  # run time on a board (an injected stall on the emulator): a warning
EXT_TIMING_FIELDS = ("worst_tick_us", "mean_tick_us", "overruns", "gc_runs")  # run time
assert all(code == "H" for name, code, _ in EXT_FIELDS if name in EXT_TIMING_FIELDS)
EXT_FLOAT_FIELDS = tuple(n for n, code, _ in EXT_FIELDS if code == "f")
_EXT = struct.Struct("<" + "".join(f"{count}{code}" for _, code, count in EXT_FIELDS))
EXT_PAYLOAD = _EXT.size  # bytes after the counter
EXT_LEN = HEAD_LEN + EXT_PAYLOAD + CRC_LEN
# before "causes" (an older firmware's recordings): decoded with causes None
_EXT_V1 = struct.Struct("<" + "".join(f"{count}{code}" for _, code, count in EXT_FIELDS[:-1]))
EXT_LEN_V1 = EXT_LEN - 4

RAW_FIELDS = (
    ("t0_us", "I"),  # the tick's start, time.ticks_us
    ("pps_us", "I"),  # the parser's PPS edge time
    ("gyro_regs", "6s"),  # BMI055 data registers as read
    ("accel_regs", "6s"),
    ("flags", "B"),  # bit 0: saturated
    ("n_gnss", "B"),  # GNSS bytes that follow
)
_RAW = struct.Struct("<" + "".join(code for _, code in RAW_FIELDS))
RAW_FIXED_LEN = HEAD_LEN + _RAW.size  # 26
RAW_MIN_LEN = RAW_FIXED_LEN + CRC_LEN  # no GNSS bytes
RAW_MAX_GNSS = 255 - (RAW_FIXED_LEN - 3)  # the length byte counts 23 + n <= 255


def _offsets(fields, start):
    out = {}
    at = start
    for name, code, *count in fields:
        out[name] = at
        at += struct.calcsize(f"<{count[0] if count else ''}{code}")
    return out


EXT_OFFSETS = _offsets(EXT_FIELDS, HEAD_LEN)
RAW_OFFSETS = _offsets(RAW_FIELDS, HEAD_LEN)
assert EXT_LEN == 136 and RAW_FIXED_LEN == 26 and RAW_MAX_GNSS == 232


def length_ok(r):
    """Whether a record's length is its type's (extended frame: fixed; raw: its GNSS count)."""
    if r[1] == EXT_TYPE:
        return len(r) in (EXT_LEN, EXT_LEN_V1)
    return len(r) >= RAW_MIN_LEN and r[2] == RAW_FIXED_LEN - 3 + r[RAW_FIXED_LEN - 1]


def crc_ok(r):
    return struct.unpack_from("<I", r, len(r) - CRC_LEN)[0] == crc32(r[:-CRC_LEN])


def seal(body):
    """body + its CRC-32."""
    return bytes(body) + struct.pack("<I", crc32(body))


def decode_ext(r):
    """The extended frame's fields: counter, then EXT_FIELDS (floats as Python floats;
    causes None in an older firmware's shorter frame)."""
    if len(r) == EXT_LEN_V1:
        values = (*_EXT_V1.unpack_from(r, HEAD_LEN), None)
    else:
        values = _EXT.unpack_from(r, HEAD_LEN)
    out = {"counter": r[3]}
    i = 0
    for name, _, count in EXT_FIELDS:
        out[name] = values[i] if count == 1 else list(values[i : i + count])
        i += count
    return out


def cause_names(causes):
    """The names of the bits set in an extended frame's "causes" (CAUSES; unknown bits as
    hex), or [] for None (an older firmware's frame)."""
    if not causes:
        return []
    names = [name for bit, name in CAUSES if causes & bit]
    rest = causes & ~sum(bit for bit, _ in CAUSES)
    if rest:
        names.append(f"0x{rest:x}")
    return names


def encode_ext(counter, fields):
    """The extended frame of `fields` (every name of EXT_FIELDS); float fields are packed
    from their float32 bits (NaN payloads included), exactly as the board copies them."""
    parts = [bytes((HEADER, EXT_TYPE, EXT_PAYLOAD + 1, counter & 0xFF))]
    for name, code, count in EXT_FIELDS:
        v = fields[name]
        if code == "f":
            parts.append(np.asarray(v, "<f4").reshape(count).tobytes())
        else:
            parts.append(struct.pack(f"<{count}{code}", *(v if count > 1 else (v,))))
    return seal(b"".join(parts))


def decode_raw(r):
    """The raw-input record's fields: counter, t0_us, pps_us, gyro_regs, accel_regs,
    saturated and gnss_bytes."""
    t0, pps, g, a, flags, n = _RAW.unpack_from(r, HEAD_LEN)
    return {
        "counter": r[3],
        "t0_us": t0,
        "pps_us": pps,
        "gyro_regs": g,
        "accel_regs": a,
        "saturated": flags & 1,
        "gnss_bytes": bytes(r[RAW_FIXED_LEN : RAW_FIXED_LEN + n]),
    }


def encode_raw(counter, t0_us, pps_us, gyro_regs, accel_regs, saturated, gnss_bytes):
    """The raw-input record of one tick (times as ticks_us values, taken modulo 2**32)."""
    n = len(gnss_bytes)
    if n > RAW_MAX_GNSS:
        raise ValueError(f"a raw-input record holds at most {RAW_MAX_GNSS} GNSS bytes, got {n}")
    body = bytes((HEADER, RAW_TYPE, RAW_FIXED_LEN - 3 + n, counter & 0xFF))
    body += _RAW.pack(
        t0_us & 0xFFFFFFFF, pps_us & 0xFFFFFFFF, bytes(gyro_regs), bytes(accel_regs),
        1 if saturated else 0, n,
    )  # fmt: skip
    return seal(body + bytes(gnss_bytes))
