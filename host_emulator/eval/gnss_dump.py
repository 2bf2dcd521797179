"""`python -m host_emulator gnss-dump FILE [--json]`: run a recorded NMEA stream through the
firmware's GNSS driver (firmware/drivers/gnss.py) and print what it accepted.

One line per accepted GGA/RMC/VTG/GSA sentence, in stream order, with the columns
    type utc_s lat_e7 lon_e7 alt_m quality nsat hdop speed_m_s course_deg valid
("-" where the sentence type has no such field or the field was empty). With --json, one
object per line: numbers as numbers, null for "-", and lat_deg/lon_deg (degrees) beside the
1e-7 integers. `valid` is: GGA position present and quality > 0; RMC status A with a position;
VTG mode not N and a speed; GSA fix type 2 or 3. At the end, a summary of the driver's
counters goes to stderr. Lines starting with '#' are comments in gpsd-style logs and are
skipped unless --raw is given (then every byte goes to the driver, as from a UART).

Exit status 0; 1 when the file cannot be read, is empty, or holds no sentence the driver
accepts (a binary log, another file: it says so).
"""

import argparse
import json
import sys

from common import firmware_env
from common.errors import quiet_broken_pipe

firmware_env.install()

from drivers import gnss  # noqa: E402

COLUMNS = (
    "type",
    "utc_s",
    "lat_e7",
    "lon_e7",
    "alt_m",
    "quality",
    "nsat",
    "hdop",
    "speed_m_s",
    "course_deg",
    "valid",
)
NAMES = {gnss.GGA: "GGA", gnss.RMC: "RMC", gnss.VTG: "VTG", gnss.GSA: "GSA"}


def _fixed(v, decimals):
    """An int in units of 10**-decimals as an exact decimal string."""
    s = "-" if v < 0 else ""
    q, r = divmod(abs(v), 10**decimals)
    return f"{s}{q}.{r:0{decimals}d}"


def _opt(v, decimals=0):
    """Non-negative values with -1 for "empty"."""
    if v < 0:
        return None
    return v if decimals == 0 else _fixed(v, decimals)


def record(p):
    """The row (dict of COLUMNS) of the sentence the driver `p` accepted last."""
    row = dict.fromkeys(COLUMNS)
    kind = p.last
    row["type"] = NAMES[kind]
    if kind == gnss.GGA:
        row["utc_s"] = _opt(p.gga_utc_ms, 3)
        if p.gga_pos_ok:
            row["lat_e7"] = p.gga_lat_e7
            row["lon_e7"] = p.gga_lon_e7()
        if p.gga_alt_ok:
            row["alt_m"] = _fixed(p.gga_alt_mm, 3)
        row["quality"] = _opt(p.gga_quality)
        row["nsat"] = _opt(p.gga_nsat)
        row["hdop"] = _opt(p.gga_hdop_x100, 2)
        row["valid"] = int(bool(p.gga_pos_ok and p.gga_quality > 0))
    elif kind == gnss.RMC:
        row["utc_s"] = _opt(p.rmc_utc_ms, 3)
        if p.rmc_pos_ok:
            row["lat_e7"] = p.rmc_lat_e7
            row["lon_e7"] = p.rmc_lon_e7()
        row["speed_m_s"] = _opt(p.rmc_speed_mm_s, 3)
        row["course_deg"] = _opt(p.rmc_course_cdeg, 2)
        row["valid"] = int(p.rmc_status == ord("A") and bool(p.rmc_pos_ok))
    elif kind == gnss.VTG:
        row["speed_m_s"] = _opt(p.vtg_speed_mm_s, 3)
        row["course_deg"] = _opt(p.vtg_course_cdeg, 2)
        row["valid"] = int(p.vtg_mode != ord("N") and p.vtg_speed_mm_s >= 0)
    else:
        row["nsat"] = p.gsa_nsv
        row["hdop"] = _opt(p.gsa_hdop_x100, 2)
        row["valid"] = int(p.gsa_fix >= 2)
    return row


def summary(p):
    return (
        f"accepted GGA {p.n_gga} RMC {p.n_rmc} VTG {p.n_vtg} GSA {p.n_gsa}, "
        f"ignored {p.n_ignored}, rejected {p.rejected()} (bad checksum {p.n_bad_csum}, "
        f"no checksum {p.n_no_csum}, malformed {p.n_malformed}, overlong {p.n_overlong}, "
        f"collided {p.n_collided}, bad field {p.n_bad_field}), "
        f"epochs {p.n_epochs} (dropped {p.n_epochs_dropped})"
    )


def strip_comments(data):
    """Drop lines that start with '#' (gpsd regression-log comments)."""
    return b"".join(x for x in data.splitlines(keepends=True) if not x.startswith(b"#"))


def dump(data):
    """Feed `data` to a fresh driver byte by byte (so each accepted sentence is seen after its
    CR/LF); return the rows and the driver."""
    p = gnss.Nmea()
    out = []
    one = bytearray(1)
    seq = p.seq
    for b in data:
        one[0] = b
        p.feed(one, 1)
        if p.seq != seq:
            seq = p.seq
            out.append(record(p))
    return out, p


def _text(row):
    return " ".join("-" if row[c] is None else str(row[c]) for c in COLUMNS)


def _json(row):
    """The row with its exact decimals as numbers, and lat/lon in degrees too."""
    out = {k: float(v) if isinstance(v, str) and k != "type" else v for k, v in row.items()}
    for k in ("lat", "lon"):
        e7 = row[k + "_e7"]
        out[k + "_deg"] = None if e7 is None else e7 / 1e7
    return out


def _not_nmea(name, data, p):
    """Why `data` gave no accepted sentence, in one line."""
    if not data:
        return f"gnss-dump: {name} is empty" + (" once its '#' comment lines are skipped"
                                                if p is not None else "")  # fmt: skip
    printable = sum(32 <= b < 127 or b in (10, 13) for b in data[:4096]) / min(len(data), 4096)
    what = "binary data (a UBX, RTCM or SBF log? this reads NMEA-0183 text)"
    if printable > 0.9:
        what = "text, but no NMEA sentence the driver accepts ($..GGA/RMC/VTG/GSA with *hh)"
    return (
        f"gnss-dump: {name} is not an NMEA log: {len(data)} bytes of {what}; "
        f"rejected {p.rejected()}, ignored {p.n_ignored}"
    )


def main(argv=None):
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator gnss-dump",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("file", help="NMEA log (raw UART bytes; gpsd .log files work)")
    ap.add_argument("--json", action="store_true", help="one JSON object per sentence")
    ap.add_argument("--raw", action="store_true", help="do not skip '#' comment lines")
    args = ap.parse_args(argv)
    try:
        with open(args.file, "rb") as f:
            data = f.read()
    except OSError as e:
        print(f"gnss-dump: cannot read {args.file}: {e.strerror or e}", file=sys.stderr)
        return 1
    if not data:
        print(_not_nmea(args.file, data, None), file=sys.stderr)
        return 1
    if not args.raw:
        data = strip_comments(data)
    out, p = dump(data)
    if not out:
        print(_not_nmea(args.file, data, p), file=sys.stderr)
        return 1
    try:
        if not args.json:
            print("# " + " ".join(COLUMNS))
        for row in out:
            print(json.dumps(_json(row)) if args.json else _text(row))
        sys.stdout.flush()
    except BrokenPipeError:  # e.g. piped into `head`
        return quiet_broken_pipe()
    print("gnss-dump: " + summary(p), file=sys.stderr)
    return 0
