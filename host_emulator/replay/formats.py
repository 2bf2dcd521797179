"""What the exchange-format readers share: the error they raise, GPST/UTC, table reading.

Every reader in `host_emulator.replay` reports a bad file as one `FormatError` whose message
names the file and, where there is one, the line ("path:line: what is wrong"), never as a
traceback. Time conventions are `dataset.py`'s (GPST seconds since the GPS epoch).
"""

import datetime
from pathlib import Path

import numpy as np

from common.errors import EmulatorError

from .dataset import GPS_EPOCH


class FormatError(EmulatorError):
    """A data or description file is missing or does not follow its format."""


# GPST - UTC (s) from each date on (the leap seconds since the GPS epoch; IERS Bulletin C).
# No leap second has been announced after 2017-01-01; update this table when one is.
_GPS_UTC_STEPS = (
    (datetime.datetime(1981, 7, 1), 1),
    (datetime.datetime(1982, 7, 1), 2),
    (datetime.datetime(1983, 7, 1), 3),
    (datetime.datetime(1985, 7, 1), 4),
    (datetime.datetime(1988, 1, 1), 5),
    (datetime.datetime(1990, 1, 1), 6),
    (datetime.datetime(1991, 1, 1), 7),
    (datetime.datetime(1992, 7, 1), 8),
    (datetime.datetime(1993, 7, 1), 9),
    (datetime.datetime(1994, 7, 1), 10),
    (datetime.datetime(1996, 1, 1), 11),
    (datetime.datetime(1997, 7, 1), 12),
    (datetime.datetime(1999, 1, 1), 13),
    (datetime.datetime(2006, 1, 1), 14),
    (datetime.datetime(2009, 1, 1), 15),
    (datetime.datetime(2012, 7, 1), 16),
    (datetime.datetime(2015, 7, 1), 17),
    (datetime.datetime(2017, 1, 1), 18),
)


def gps_utc_offset_s(utc):
    """GPST - UTC in whole seconds at a naive UTC datetime (18 s since 2017-01-01)."""
    offset = 0
    for when, value in _GPS_UTC_STEPS:
        if utc >= when:
            offset = value
    return offset


def gpst_of_utc(utc):
    """GPST seconds since the GPS epoch of a naive (or aware) UTC datetime."""
    if utc.tzinfo is not None:
        utc = utc.astimezone(datetime.UTC).replace(tzinfo=None)
    return (utc - GPS_EPOCH).total_seconds() + gps_utc_offset_s(utc)


def gpst_of_utc_s(t_utc_s):
    """GPST seconds of UTC times given as seconds since 1980-01-06 00:00 UTC (array)."""
    t = np.asarray(t_utc_s, np.float64)
    steps = np.array([(when - GPS_EPOCH).total_seconds() for when, _ in _GPS_UTC_STEPS])
    offsets = np.array([0.0] + [float(v) for _, v in _GPS_UTC_STEPS])
    return t + offsets[np.searchsorted(steps, t, side="right")]


def calendar_s(year, month, day, hour, minute, second):
    """Seconds since the GPS epoch of a calendar date and time in the same time system
    (GPST gives GPST seconds); `second` may carry a fraction."""
    days = (datetime.date(year, month, day) - GPS_EPOCH.date()).days
    return days * 86400.0 + (hour * 3600 + minute * 60) + second


def read_lines(path, what):
    """The text lines of `path`, or FormatError naming `what` the file was meant to be."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8", errors="replace").splitlines()
    except FileNotFoundError:
        raise FormatError(f"{path}: no such file ({what})") from None
    except IsADirectoryError:
        raise FormatError(f"{path}: is a directory, expected a file ({what})") from None
    except OSError as e:
        raise FormatError(f"{path}: cannot read ({what}): {e.strerror}") from None


def _separator_hint(line):
    """What to say about a row whose columns did not split on whitespace."""
    for sep, name in ((",", "commas"), (";", "semicolons"), ("|", "bars")):
        if sep in line:
            return (
                f": the line holds {name}, the columns must be separated by spaces or tabs "
                f"(e.g. tr '{sep}' ' ' < in.csv > out.txt)"
            )
    return ""


def parse_table(path, lines, counts, what, comment="#"):
    """Whitespace-separated numeric rows -> ((N, cols) float64 array, (N,) 1-based line
    numbers). Blank lines and lines starting with a `comment` character are skipped; every
    other row must have the same number of columns, one of `counts`. The messages say when a
    line holds another separator (commas: a CSV) or the first row is a header."""
    rows = []
    line_no = []
    cols = None
    for i, line in enumerate(lines, 1):
        parts = line.split()
        if not parts or parts[0][0] in comment:
            continue
        n = len(parts)
        if cols is None:
            if n not in counts:
                raise FormatError(
                    f"{path}:{i}: {n} columns, {what} rows have {_counts(counts)}"
                    + _separator_hint(line)
                )
            cols = n
        elif n != cols:
            raise FormatError(
                f"{path}:{i}: {n} columns, the rows before have {cols}" + _separator_hint(line)
            )
        rows.append(parts)
        line_no.append(i)
    if not rows:
        raise FormatError(f"{path}: no data rows ({what})")
    try:
        table = np.array(rows, dtype=np.float64)
    except ValueError:
        for r, (parts, i) in enumerate(zip(rows, line_no, strict=True)):
            for col, token in enumerate(parts, 1):
                try:
                    float(token)
                except ValueError:
                    hint = ""
                    if r == 0 and any(ch.isalpha() for ch in token):
                        hint = (
                            ": a header line? The files have none (delete it, or start it with #)"
                        )
                    elif "," in token:
                        hint = ": a decimal comma? Numbers take a point"
                    raise FormatError(
                        f"{path}:{i}: column {col} is {token!r}, not a number{hint}"
                    ) from None
        raise
    return table, np.asarray(line_no)


def check_increasing(path, t, line_no, what="time", text=None):
    """FormatError at the first row whose time is not after the previous row's (`text`: the
    times as the file writes them, for the message; default the numbers)."""

    def shown(k):
        return text[k] if text is not None else repr(float(t[k]))

    finite = np.isfinite(t)
    if not finite.all():
        k = int(np.flatnonzero(~finite)[0])
        raise FormatError(f"{path}:{line_no[k]}: {what} is {shown(k)}")
    bad = np.flatnonzero(~(np.diff(t) > 0.0))
    if bad.size:
        k = int(bad[0]) + 1
        raise FormatError(
            f"{path}:{line_no[k]}: {what} {shown(k)} is not after the previous row's "
            f"{shown(k - 1)} (line {line_no[k - 1]})"
        )


def _counts(counts):
    counts = sorted(counts)
    if len(counts) == 1:
        return str(counts[0])
    return ", ".join(str(c) for c in counts[:-1]) + f" or {counts[-1]}"
