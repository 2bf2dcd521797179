"""Decode what a board sends: 52-byte frames (DESIGN.md 6), extended frames and raw-input
records (firmware/lib/records.py), from a byte stream that may hold garbage.

The decoder resynchronises after anything it cannot read: at each 0xEB it tries the record
its type byte announces and accepts it only if its checksum (frames) or CRC-32 (records, via
crcmod, the same CRC as the board's binascii.crc32) is right; otherwise it skips one byte.
"""

import struct
from dataclasses import dataclass, field

import crcmod.predefined

crc32 = crcmod.predefined.mkCrcFun("crc-32")
FRAME_TYPE = 0x90
EXT_TYPE = 0x91
RAW_TYPE = 0x92


@dataclass
class Decoded:
    frames: list = field(default_factory=list)  # dicts of the 52-byte frame's fields
    ext: list = field(default_factory=list)  # dicts of extended frames
    raw: list = field(default_factory=list)  # dicts of raw-input records
    bad_checksum: int = 0  # frames whose checksum failed
    bad_crc: int = 0  # records whose CRC failed
    skipped_bytes: int = 0  # bytes that belonged to nothing decodable


def frame_fields(f):
    """The 52-byte frame's fields in physical units (DESIGN.md section 6)."""
    v = struct.unpack("<2BB3h3h3Bii h B3h3hiih B", f)
    return {
        "counter": v[2],
        "gyro_dps": [x / 131.07 for x in v[3:6]],
        "accel_g": [x / 16383 for x in v[6:9]],
        "pps": v[9],
        "gga": v[10],
        "gnss_valid": v[11],
        "lat_e7": v[12],
        "lon_e7": v[13],
        "height_m": v[14] / 10,
        "nav_state": v[15],
        "yaw_deg": v[16] / 100,
        "pitch_deg": v[17] / 100,
        "roll_deg": v[18] / 100,
        "vel_enu_m_s": [x / 100 for x in v[19:22]],
        "pos_enu_m": [v[22] / 100, v[23] / 100, v[24] / 10],
        "raw": bytes(f),
    }


def ext_fields(r):
    f = struct.unpack_from("<4B4H15f3f3f3fiiIf", r, 4)
    return {
        "counter": r[3],
        "health": f[0],
        "nav_state": f[1],
        "config_status": f[2],
        "flags": f[3],
        "worst_tick_us": f[4],
        "mean_tick_us": f[5],
        "overruns": f[6],
        "gc_runs": f[7],
        "p_diag": list(f[8:23]),
        "gyro_bias_rad_s": list(f[23:26]),
        "accel_bias_m_s2": list(f[26:29]),
        "pos_enu_m": list(f[29:32]),
        "origin_lat_e7": f[32],
        "origin_lon_e7": f[33],
        "tick": f[34],
        "origin_h_m": f[35],
    }


def raw_fields(r):
    n = r[25]
    return {
        "counter": r[3],
        "t0_us": struct.unpack_from("<I", r, 4)[0],
        "pps_us": struct.unpack_from("<I", r, 8)[0],
        "gyro_regs": bytes(r[12:18]),
        "accel_regs": bytes(r[18:24]),
        "saturated": r[24] & 1,
        "gnss_bytes": bytes(r[26 : 26 + n]),
    }


def decode(data):
    """All decodable frames and records in `data`, in order of appearance per kind."""
    out = Decoded()
    i = 0
    n = len(data)
    while i < n:
        if data[i] != 0xEB or i + 1 >= n:
            out.skipped_bytes += 1
            i += 1
            continue
        t = data[i + 1]
        if t == FRAME_TYPE and i + 52 <= n:
            f = data[i : i + 52]
            if f[51] == sum(f[2:51]) & 0xFF:
                out.frames.append(frame_fields(f))
                i += 52
                continue
            out.bad_checksum += 1
        elif t in (EXT_TYPE, RAW_TYPE) and i + 3 <= n:
            end = i + 3 + data[i + 2] + 4  # header, length byte, counter + payload, CRC
            if end <= n:
                r = data[i:end]
                if struct.unpack_from("<I", r, len(r) - 4)[0] == crc32(bytes(r[:-4])):
                    rec = ext_fields(r) if t == EXT_TYPE else raw_fields(r)
                    rec["frame_index"] = len(out.frames) - 1  # the 52-byte frame before it
                    (out.ext if t == EXT_TYPE else out.raw).append(rec)
                    i = end
                    continue
                out.bad_crc += 1
        out.skipped_bytes += 1
        i += 1
    return out
