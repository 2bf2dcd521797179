"""The receiver's state as gpsmon shows it (fix type, satellites, HDOP, UTC of the last fix),
read from the NMEA-0183 bytes the raw-input records carry (raw_record = 1: the bytes each tick
fed to the board's GNSS parser).

Only GGA and RMC are read, each checked as the firmware's driver checks it
(firmware/drivers/gnss.py): '$' to CR/LF, printable ASCII, '*' and two hex digits that equal
the XOR of the characters between; a sentence with a field that does not parse is not used.
The firmware's driver itself is not imported: on CPython it needs the firmware environment
(its kernels, NumPy's error mode), which a monitor has no use for; tests/tools/test_monitor.py
checks that both read the same values.
"""

import datetime
from typing import NamedTuple

MAX_LINE = 100  # characters between '$' and CR, as the firmware's driver allows (NMEA: 79)

# GGA quality (NMEA-0183 4.x): what gpsmon calls the fix type
FIX_TYPES = {
    0: "no fix",
    1: "GPS",
    2: "DGPS",
    3: "PPS",
    4: "RTK fixed",
    5: "RTK float",
    6: "dead reckoning",
    7: "manual",
    8: "simulation",
}


class Gga(NamedTuple):
    utc_ms: int | None  # ms of the UTC day; None: empty
    quality: int | None
    n_sats: int | None
    hdop: float | None


class Rmc(NamedTuple):
    utc_ms: int | None
    status: str  # "A" valid, "V" warning, "" empty
    date_iso: str | None  # "2026-11-22"


def fix_type(quality):
    """The GGA quality's name ("-" when unknown)."""
    if quality is None:
        return "-"
    return FIX_TYPES.get(quality, f"quality {quality}")


def checked_body(line):
    """The text between '$' and '*' of a whole sentence (bytes, without CR/LF) whose checksum
    holds; None otherwise."""
    if len(line) < 4 or line[0] != 0x24 or line[-3] != 0x2A:  # '$' ... '*hh'
        return None
    body = line[1:-3]
    if any(b < 0x20 or b > 0x7E for b in body):
        return None
    try:
        want = int(line[-2:].decode("ascii"), 16)
    except ValueError:
        return None
    got = 0
    for b in body:
        got ^= b
    return body.decode("ascii") if got == want else None


def _int(text):
    return int(text) if text else None


def _utc_ms(text):
    """hhmmss[.sss] -> ms of the day (None: empty); ValueError for anything else."""
    if not text:
        return None
    if len(text) < 6 or not text[:6].isdigit() or (len(text) > 6 and text[6] != "."):
        raise ValueError(f"not a time: {text!r}")
    h, m, s = int(text[0:2]), int(text[2:4]), int(text[4:6])
    frac = text[7:10].ljust(3, "0") if len(text) > 7 else "000"
    if h > 23 or m > 59 or s > 60 or not frac.isdigit():
        raise ValueError(f"not a time: {text!r}")
    return ((h * 60 + m) * 60 + s) * 1000 + int(frac)


def _date_iso(text):
    """ddmmyy -> "20yy-mm-dd" (yy from 80: 19yy, as receivers' week rollovers go); None."""
    if not text:
        return None
    if len(text) != 6 or not text.isdigit():
        raise ValueError(f"not a date: {text!r}")
    d, m, y = int(text[0:2]), int(text[2:4]), int(text[4:6])
    return datetime.date(y + (1900 if y >= 80 else 2000), m, d).isoformat()


def parse_gga(fields):
    """Gga of a GGA sentence's fields (the address first); ValueError for a bad field."""
    if len(fields) < 10:
        raise ValueError("GGA with too few fields")
    hdop = float(fields[8]) if fields[8] else None
    return Gga(_utc_ms(fields[1]), _int(fields[6]), _int(fields[7]), hdop)


def parse_rmc(fields):
    """Rmc of an RMC sentence's fields; ValueError for a bad field."""
    if len(fields) < 10:
        raise ValueError("RMC with too few fields")
    return Rmc(_utc_ms(fields[1]), fields[2], _date_iso(fields[9]))


class Receiver:
    """feed(bytes) in any chunks: the latest GGA (`gga`), the latest GGA with a fix
    (`last_fix`, quality > 0) and the latest RMC (`rmc`); counts what was not used."""

    def __init__(self):
        self.gga = None
        self.last_fix = None
        self.rmc = None
        self.n_gga = 0
        self.bad_checksums = 0  # also: no '*', a byte that is not printable ASCII
        self.bad_fields = 0
        self._line = None  # bytes since '$'; None outside a sentence

    def feed(self, data):
        for b in data:
            if b == 0x24:  # '$' starts a sentence, even inside one (collided: dropped)
                self._line = bytearray(b"$")
            elif self._line is None:
                continue
            elif b in (0x0D, 0x0A):
                self._end(bytes(self._line))
                self._line = None
            elif len(self._line) > MAX_LINE:
                self._line = None
            else:
                self._line.append(b)

    def _end(self, line):
        body = checked_body(line)
        if body is None:
            self.bad_checksums += 1
            return
        fields = body.split(",")
        kind = fields[0][2:] if len(fields[0]) == 5 else ""
        try:
            if kind == "GGA":
                self._take_gga(parse_gga(fields))
            elif kind == "RMC":
                self.rmc = parse_rmc(fields)
        except ValueError:
            self.bad_fields += 1

    def _take_gga(self, gga):
        self.gga = gga
        self.n_gga += 1
        if gga.quality:
            self.last_fix = gga

    def fix_date(self):
        """The date of the last fix: the latest RMC's when the two times are within a minute
        (two times of different days, across midnight, are hours apart), else None."""
        fx, r = self.last_fix, self.rmc
        if fx is None or r is None or fx.utc_ms is None or r.utc_ms is None:
            return None
        return r.date_iso if abs(fx.utc_ms - r.utc_ms) < 60_000 else None
