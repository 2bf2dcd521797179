"""NMEA-0183 byte stream -> GGA/RMC/VTG/GSA fields as small integers, without allocating.

Use (the app's 5 ms loop; `buf = bytearray(64)` made once at start-up):

    gps = Nmea()
    pps_pin.irq(trigger=Pin.IRQ_RISING, handler=gps.pps_isr, hard=True)   # optional
    ...
    n = uart.readinto(buf)          # any chunk size; None or 0 when nothing arrived
    if n:
        gps.feed(buf, n)
    if gps.epoch_take():
        ... hand epoch_* to the navigator (see "Epochs")

`feed(buf, n)` consumes `n` bytes of a byte buffer (bytearray, bytes, memoryview).
A sentence may be split over any number of calls; every finished sentence is parsed inside the
call that delivers its CR or LF. Nothing in `feed`, the parsers or `pps_isr` allocates: bytes
are collected into a preallocated 100-byte line buffer, fields are located by a preallocated
table of comma positions, and numbers are built digit by digit into small ints. All values
stay within +-2**30, so they are small ints on the board (31-bit) too.

Framing. A sentence starts at '$' and ends at CR or LF. Bytes outside a sentence (binary
protocols such as UBX, NUL fill, line noise) are skipped silently. A line is rejected when:
- a new '$' arrives before its end ("collided": the truncated one is dropped, the new one
  starts; this includes a complete sentence followed directly by '$' without CR/LF),
- it grows beyond MAXLEN = 100 characters between '$' and CR (NMEA allows 79) ("overlong"),
- it contains a byte outside printable ASCII 0x20..0x7E ("malformed"),
- it has no '*' ("no checksum"; NMEA-0183 made it optional once, we do not),
- '*' is not followed by exactly two hex digits (either case) and the end ("malformed"),
- the XOR of the characters between '$' and '*' differs ("bad checksum").
A sentence with a good checksum is parsed if its address is GGA, RMC, VTG or GSA from any
talker of two capital letters but P (GP, GN, GL, GA, GB, BD, GQ, QZ, GI, IN, ...); any other
sentence (GSV, GLL, ZDA, TXT, $P... proprietary) is "ignored", which is not an error. A
parsed sentence whose fields break the syntax below (a letter in a number, a time without
six digits, too few fields) is rejected ("bad field") and leaves every attribute unchanged.
Needed fields: GGA up to the altitude (the geoid separation only if present), RMC up to the
date, VTG the eight of NMEA 2.x, GSA the seventeen; more fields (mode, system id, ...) are
fine.

Field syntax and units (empty fields are legal everywhere and mark the value unknown):
- numbers: optional sign, digits, optional '.' and digits; scaled to an integer unit with
  rounding half away from zero; more than 9 significant digits in the unit is a bad field.
- time hhmmss[.sss...]: ms of the UTC day, 0 .. 86 400 999 (second 60 allowed for a leap
  second, at 23:59 only); decimals beyond the third are truncated; out of range values (hour
  24, 12:34:60) -> -1.
- lat ddmm.mmmm / lon dddmm.mmmm (1 to 3 degree digits, exactly 2 minute digits, any number
  of decimals, or none): 1e-7 deg, round half away from zero of deg + min / 60, exact. Only
  the first 7 minute decimals can matter: with A = floor(min * 1e7) and the rest r in [0, 1),
  floor((A + r) / 60 + 1/2) = floor((A + 30 + r) / 60) = (A + 30) // 60, because the integer
  A + 30 + r can only cross a multiple of 60 if r >= 1. Minutes of exactly 60 are accepted
  (8960.0000 = 90 deg, as some MTK chips print at cold start); a position beyond 90 / 180 deg,
  or with a hemisphere letter other than N/S, E/W, is marked invalid (pos_ok = 0).
- LONGITUDE IS TWO INTS: whole degrees `*_lon_deg` and the rest `*_lon_frac_e7` (1e-7 deg,
  same sign, |frac| < 1e7), because lon_e7 itself exceeds 2**30 beyond 107.37 deg (e.g. Xi'an,
  108.94 E = 1 089 400 000) and would be a heap-allocated long int on the board. `lon_e7(deg,
  frac)` and the `*_lon_e7()` methods return the combined int for callers that accept that
  allocation (once per fix). Latitude (|lat| <= 9e8) is a single int `*_lat_e7`.

Attributes (ints; -1 = empty/unknown for values that cannot be negative; `*_ok` flags for
signed values; characters as their byte code, 0 when absent):
  GGA (latest accepted): gga_utc_ms, gga_lat_e7, gga_lon_deg, gga_lon_frac_e7, gga_pos_ok,
    gga_quality (0 none, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, 6 dead reckoning, 8 sim),
    gga_nsat, gga_hdop_x100, gga_alt_mm (above mean sea level) + gga_alt_ok, gga_sep_mm
    (geoid separation: ellipsoid height = alt + sep) + gga_sep_ok; gga_seen is set to 1 by
    every accepted GGA (`gga_flag_take()` clears it: the frame's "GGA this tick" bit).
  RMC: rmc_utc_ms, rmc_status (ord 'A' valid, ord 'V' warning, 0), rmc_lat_e7, rmc_lon_deg,
    rmc_lon_frac_e7, rmc_pos_ok, rmc_speed_mm_s (from knots), rmc_course_cdeg (centidegrees
    true, 0..36000, -1 empty), rmc_date (yymmdd as an int: ddmmyy 250910 -> 100925; -1
    empty or invalid), rmc_mode (NMEA 2.3 mode letter: A, D, E, N, ..., 0 if absent).
  VTG: vtg_course_cdeg, vtg_speed_mm_s (from the km/h field, else from knots), vtg_mode.
  GSA: gsa_mode (ord 'A'/'M'), gsa_fix (1 none, 2 2D, 3 3D, -1), gsa_nsv (satellite ids
    listed), gsa_pdop_x100, gsa_hdop_x100, gsa_vdop_x100.
  Every accepted sentence: seq += 1 (wraps at 2**30), last = GGA/RMC/VTG/GSA (1..4),
    talker = the two letters as one int (e.g. 0x474E for GN).
  Counters (wrap at 2**30): n_gga, n_rmc, n_vtg, n_gsa accepted; n_ignored; rejected:
    n_bad_csum, n_no_csum, n_malformed, n_overlong, n_collided, n_bad_field; `rejected()`
    sums the six. Speeds: knots * 1852/3600 and km/h / 3.6 to mm/s, rounded half up, exact
    for up to 4 decimals in the sentence.

Epochs. A receiver prints one group of sentences per fix, in a chip-specific order (u-blox
RMC VTG GGA, MTK/SiRF GGA ... RMC VTG, Quectel GGA VTG RMC), and not every receiver prints
the same ones: GGA+RMC(+VTG), RMC only, GGA only, GGA+VTG, GGA every second with RMC every
tenth, GGA and RMC in alternate seconds. An epoch is keyed by the UTC time of GGA and RMC;
VTG has no time and belongs to the epoch of the latest GGA/RMC before it if it comes within
3/4 of the output period (learned from the UTC steps, 750 ms at 1 Hz) of that epoch's first
sentence, else (a receiver printing VTG first and no RMC) to the next epoch, if that starts
within the same window after it. The parser learns what the receiver sends from the last
four epochs that had a time: a GGA, and a speed sentence (RMC or VTG), are expected when at
most one of those four lacked it. An epoch is complete, and released at once, as soon as it
has its GGA (or, GGA not expected, an RMC) and, if expected, its speed sentence: at the
receiver's last expected sentence of the second, never later. So
- GGA+RMC(+VTG) and GGA+VTG receivers complete at the later of GGA and the first speed
  sentence, as `Nmea(need_speed=1)` always does (one lost sentence does not change that);
- RMC only: at the RMC (its position; no height, satellites or HDOP: epoch_alt_ok 0,
  epoch_nsat and epoch_hdop_x100 -1, quality from status and mode: _rmc_quality);
- GGA only, and GGA with RMC every n-th second: at the GGA (speed only where the RMC of the
  second came before the GGA);
- GGA and RMC in alternate seconds: at each (GGA: no speed; RMC: no height).
Learning costs a receiver that is not GGA+speed its first two epochs (four for alternate
seconds), dropped as below; a receiver that changes what it sends is followed within four.
`Nmea(need_speed=1)` and `Nmea(need_speed=0)` (board setting gnss_need_speed 1, 0) override
the learning: always a GGA and a speed sentence, or a GGA alone (the behaviours before
learning). Figures per receiver kind on the gpsd logs: tests/drivers/test_receivers.py,
docs/gnss.md. On completion the epoch is copied, so later sentences cannot tear it, into
  epoch_utc_ms, epoch_lat_e7, epoch_lon_deg, epoch_lon_frac_e7, epoch_pos_ok, epoch_alt_mm,
  epoch_alt_ok, epoch_sep_mm, epoch_sep_ok, epoch_quality, epoch_nsat, epoch_hdop_x100,
  epoch_speed_mm_s, epoch_course_cdeg (-1: unknown; taken from the latest RMC with status A
  or VTG with mode other than N of the epoch), epoch_pps_us (pps_us when the epoch's first
  sentence was parsed: the PPS edge of that second if one arrived in between), epoch_bad
  (BAD_* bits: a fix with a physically impossible field, quality 6 or above, a time that did not
  move forward, counted in n_epochs_bad; the app does not use it),
and epoch_ready = 1, n_epochs += 1 (`epoch_take()` returns and clears epoch_ready). A speed
sentence that arrives damaged (rejected for its checksum, its address still RMC or VTG, within
the VTG window of the epoch's first sentence, an RMC's time the epoch's where it still reads)
counts as sent: the epoch completes at it without speed (epoch_speed_mm_s -1) rather than
waiting for one that will not come; a receiver that prints RMC before GGA and no VTG still
loses such an epoch. An epoch that had a GGA or RMC but
never got what was expected is dropped when the next one starts (n_epochs_dropped += 1), never
released late: a one-second-old position handed over as new would hurt the filter (the
navigator's delay ring reaches back 0.64 s).

PPS: `pps_isr(pin)` only stores time.ticks_us() in pps_us and sets pps_flag = 1 (hard IRQ
safe: no allocation, no float). `pps_flag_take()`, `gga_flag_take()` and `epoch_take()` return
a flag (0 or 1) and clear it; the app reads and clears pps_flag, gga_seen and epoch_ready
itself, a method call less per tick.

Cost: the byte loop, the line checks and the field parsing are one native kernel
(`nmea_scan`, firmware/native/nmea.c; gnss_kern.py's `scan` is its reference, bit for bit on every
log and on damaged input: tests/drivers/test_gnss.py) that returns at each line end; Python
then only books the result into the attributes and the epoch (what a tick costs the board:
docs/benchmarks/board.md).
"""

import time
from array import array

from micropython import const

import kern

try:
    from time import ticks_diff as _ticks_diff
    from time import ticks_us as _ticks_us
except ImportError:  # CPython: the emulator may add them (its virtual clock) later, or never

    def _ticks_us():
        import time

        return time.ticks_us() if hasattr(time, "ticks_us") else 0

    def _ticks_diff(a, b):
        import time

        return time.ticks_diff(a, b) if hasattr(time, "ticks_diff") else a - b


MAXLEN = const(100)  # characters between '$' and CR; NMEA-0183 allows 79 (82 with $ CR LF)
_MAXF = const(40)  # comma positions kept; the parsed types use at most 21 fields

GGA = const(1)
RMC = const(2)
VTG = const(3)
GSA = const(4)
AUTO = const(2)  # Nmea(need_speed=AUTO): the receiver's sentences decide (Epochs)
_JOIN_US_PER_MS = const(750)  # a VTG joins an epoch within 3/4 of the output period

# epoch_bad: the fields that make a completed epoch's fix physically impossible (the app does
# not use such a fix); checked only for an epoch with a position and a fix quality above 0
BAD_QUALITY = const(1)  # GGA quality 6 (estimated), 7 (manual input), 8 (simulation), or
# above 8 (no NMEA quality is)
BAD_HEIGHT = const(2)  # altitude outside -1 km .. 20 km above mean sea level
BAD_SPEED = const(4)  # speed above 515 m/s (1,000 knots, the export-control limit)
BAD_COURSE = const(8)  # course above 360 deg
BAD_HDOP = const(16)  # HDOP 0: no satellite geometry gives it
BAD_TIME = const(32)  # UTC not after the previous epoch's (a midnight rollover excepted)
BAD_GEOID = const(64)  # geoid separation beyond +-200 m (the geoid lies within -107..+86 m)
BAD_NSAT = const(128)  # more than 99 satellites in use (GGA's field has two digits)
_ALT_MIN_MM = const(-1000000)
_ALT_MAX_MM = const(20000000)
_SPEED_MAX_MM_S = const(515000)
_SEP_MAX_MM = const(200000)
_NSAT_MAX = const(99)
_HALF_DAY_MS = const(43200000)

# self._s, the parser's int buffer (firmware/native/layout.h NS_*, generated from it): the framing
# state between feeds, then the fields of the sentence that ended last
_NS_I = const(0)  # next byte of the input
_NS_K = const(1)  # characters in the line; -1 outside a sentence
_NS_X = const(2)  # running XOR checksum
_NS_STAR = const(3)  # index of '*' in the line; -1 before it
_NS_NF = const(4)  # fields found so far
_NS_LEN = const(5)  # length of the line that ended last
_NS_TALKER = const(6)
_NS_UTC = const(7)  # GGA, RMC: ms of day
_NS_POS = const(8)  # GGA, RMC: _pos's 1 / 0 and its lat, lon degrees and fraction
_NS_LAT = const(9)
_NS_DEG = const(10)
_NS_FRAC = const(11)
_NS_A = const(12)  # GGA quality, RMC status, GSA fix
_NS_B = const(13)  # GGA satellites, RMC and VTG speed (mm/s), GSA satellites listed
_NS_C = const(14)  # GGA HDOP, RMC and VTG course, GSA HDOP
_NS_D = const(15)  # GGA altitude, RMC date, GSA PDOP
_NS_E = const(16)  # GGA separation, RMC and VTG mode, GSA mode
_NS_F = const(17)  # GSA VDOP
_NS_N = const(18)
_FS = const(MAXLEN)  # where the comma table starts in the line buffer
# What a scan reports (GGA..GSA: that sentence, parsed into self._s)
_NR_GGA = const(1)
_NR_RMC = const(2)
_NR_VTG = const(3)
_NR_GSA = const(4)
_NR_IGNORED = const(5)
_NR_BAD_FIELD = const(6)
_NR_NO_CSUM = const(7)
_NR_MALFORMED = const(8)
_NR_BAD_CSUM = const(9)
_NR_OVERLONG = const(10)
_NR_COLLIDED = const(11)

_EMPTY = const(-0x3FFFFFFE)  # _num(): empty field
_BAD = const(-0x3FFFFFFF)  # _num(): syntax error (both below any value, inside small ints)
_CAP = const(100000000)  # digit accumulator limit: v * 10 + 9 < 1e9 < 2**30
_WRAP = const(0x3FFFFFFF)  # counters wrap here and stay small ints

# Sentence formatters as (c1 << 16) | (c2 << 8) | c3.
_FMT_GGA = const(0x474741)
_FMT_RMC = const(0x524D43)
_FMT_VTG = const(0x565447)
_FMT_GSA = const(0x475341)


def lon_e7(deg, frac_e7):
    """Combined longitude in 1e-7 deg. ALLOCATES on the board beyond +-107.37 deg (long int)."""
    return deg * 10000000 + frac_e7


class Nmea:
    def __init__(self, need_speed=AUTO):
        """Every attribute the parser keeps (the module docstring's list), made once here so
        that nothing in feed() allocates: a flat list on purpose, about 100 lines."""
        self.need_speed = need_speed  # AUTO, or 1 / 0: always / never wait for the speed
        # the line and, after its MAXLEN bytes, the comma table: fs[i] = lb[_FS + i] is the
        # start of field i in the line, fs[nf] = '*' + 1
        self._line = bytearray(_FS + _MAXF + 1)
        self._s = array("i", bytes(4 * _NS_N))  # framing state and a sentence's fields (_NS_*)
        self._s[_NS_K] = -1  # outside a sentence
        # counters
        self.n_gga = 0
        self.n_rmc = 0
        self.n_vtg = 0
        self.n_gsa = 0
        self.n_ignored = 0
        self.n_bad_csum = 0
        self.n_no_csum = 0
        self.n_malformed = 0
        self.n_overlong = 0
        self.n_collided = 0
        self.n_bad_field = 0
        self.seq = 0
        self.last = 0
        self.talker = 0
        # GGA
        self.gga_seen = 0
        self.gga_utc_ms = -1
        self.gga_lat_e7 = 0
        self.gga_lon_deg = 0
        self.gga_lon_frac_e7 = 0
        self.gga_pos_ok = 0
        self.gga_quality = -1
        self.gga_nsat = -1
        self.gga_hdop_x100 = -1
        self.gga_alt_mm = 0
        self.gga_alt_ok = 0
        self.gga_sep_mm = 0
        self.gga_sep_ok = 0
        # RMC
        self.rmc_utc_ms = -1
        self.rmc_status = 0
        self.rmc_lat_e7 = 0
        self.rmc_lon_deg = 0
        self.rmc_lon_frac_e7 = 0
        self.rmc_pos_ok = 0
        self.rmc_speed_mm_s = -1
        self.rmc_course_cdeg = -1
        self.rmc_date = -1
        self.rmc_mode = 0
        # VTG
        self.vtg_course_cdeg = -1
        self.vtg_speed_mm_s = -1
        self.vtg_mode = 0
        # GSA
        self.gsa_mode = 0
        self.gsa_fix = -1
        self.gsa_nsv = 0
        self.gsa_pdop_x100 = -1
        self.gsa_hdop_x100 = -1
        self.gsa_vdop_x100 = -1
        # epoch in progress
        self._ep_utc = -2  # no epoch yet (-1: the last GGA/RMC had no time)
        self._ep_gga = 0
        self._ep_rmc = 0
        self._ep_spd = 0
        self._ep_done = 0
        self._ep_pps = 0
        self._ep_us = 0  # ticks_us at its first sentence
        self._ep_speed = -1
        self._ep_course = -1
        self._prev_utc = -1  # the last completed epoch's time
        # what the receiver sends: bit i set if the epoch i + 1 back had no GGA / no speed
        # sentence (need_speed AUTO learns it; 1 and 0 fix it: always, never wait for speed)
        self._miss_gga = 0
        self._miss_spd = 0 if need_speed else 15
        self._join_us = 1000 * _JOIN_US_PER_MS  # a VTG's window after its epoch's start
        self._vtg_pend = 0  # a VTG that came after its window: the next epoch's
        self._vtg_us = 0
        self._vtg_speed = -1
        self._vtg_course = -1
        # completed epoch
        self.epoch_ready = 0
        self.n_epochs = 0
        self.n_epochs_dropped = 0
        self.n_epochs_bad = 0
        self.epoch_bad = 0
        self.epoch_utc_ms = -1
        self.epoch_lat_e7 = 0
        self.epoch_lon_deg = 0
        self.epoch_lon_frac_e7 = 0
        self.epoch_pos_ok = 0
        self.epoch_alt_mm = 0
        self.epoch_alt_ok = 0
        self.epoch_sep_mm = 0
        self.epoch_sep_ok = 0
        self.epoch_quality = -1
        self.epoch_nsat = -1
        self.epoch_hdop_x100 = -1
        self.epoch_speed_mm_s = -1
        self.epoch_course_cdeg = -1
        self.epoch_pps_us = 0
        # PPS
        self.pps_us = 0
        self.pps_flag = 0

    # ---- interrupt ---------------------------------------------------------------------

    def pps_isr(self, pin):
        """PPS rising edge (hard IRQ): time stamp and flag only."""
        self.pps_us = time.ticks_us()
        self.pps_flag = 1

    # ---- flags for the app (no allocation) ----------------------------------------------

    def pps_flag_take(self):
        """1 if a PPS edge came since the last call, else 0; clears the flag."""
        f = self.pps_flag
        self.pps_flag = 0
        return f

    def gga_flag_take(self):
        """1 if a GGA was accepted since the last call, else 0; clears gga_seen."""
        f = self.gga_seen
        self.gga_seen = 0
        return f

    def epoch_take(self):
        """1 if an epoch completed since the last call (epoch_* hold it), else 0; clears
        epoch_ready."""
        f = self.epoch_ready
        self.epoch_ready = 0
        return f

    # ---- conveniences (may allocate: not for the tick loop unless noted) -----------------

    def rejected(self):
        """Sentences rejected so far (the sum of the six counters)."""
        return (
            self.n_bad_csum
            + self.n_no_csum
            + self.n_malformed
            + self.n_overlong
            + self.n_collided
            + self.n_bad_field
        )

    def gga_lon_e7(self):
        """Combined GGA longitude (1e-7 deg); a long int (allocation) beyond 107.37 deg."""
        return lon_e7(self.gga_lon_deg, self.gga_lon_frac_e7)

    def rmc_lon_e7(self):
        return lon_e7(self.rmc_lon_deg, self.rmc_lon_frac_e7)

    def epoch_lon_e7(self):
        return lon_e7(self.epoch_lon_deg, self.epoch_lon_frac_e7)

    # ---- byte stream -------------------------------------------------------------------

    def feed(self, buf, n):
        """Consume buf[0:n] (bytes from the UART, any chunking). The byte loop, the line
        checks and the field parsing are one kernel (`nmea_scan`, reference `_scan_py`) that
        returns at each line end or rejection; `_end` books it."""
        if n <= 0:
            return
        if n > len(buf):
            raise ValueError("feed: n is beyond the buffer")
        s = self._s
        s[_NS_I] = 0
        r = _scan(s, self._line, buf, n)
        while r:
            self._end(r)
            r = _scan(s, self._line, buf, n)

    def _end(self, r):
        """What the scan reported (_NR_*): a parsed sentence, an ignored one, or a rejection."""
        if r <= GSA:
            if r == GGA:
                self._gga()
            elif r == RMC:
                self._rmc()
            elif r == VTG:
                self._vtg()
            else:
                self._gsa()
            self.seq = (self.seq + 1) & _WRAP
            self.last = r
            self.talker = self._s[_NS_TALKER]
        elif r == _NR_IGNORED:
            self.n_ignored = (self.n_ignored + 1) & _WRAP
        elif r == _NR_BAD_FIELD:
            self.n_bad_field = (self.n_bad_field + 1) & _WRAP
        elif r == _NR_NO_CSUM:
            self.n_no_csum = (self.n_no_csum + 1) & _WRAP
        elif r == _NR_MALFORMED:
            self.n_malformed = (self.n_malformed + 1) & _WRAP
        elif r == _NR_BAD_CSUM:
            self.n_bad_csum = (self.n_bad_csum + 1) & _WRAP
            self._speed_damaged()
        elif r == _NR_OVERLONG:
            self.n_overlong = (self.n_overlong + 1) & _WRAP
        else:
            self.n_collided = (self.n_collided + 1) & _WRAP

    def line_length(self):
        """Characters of the line that ended last (self._line[0:n], between '$' and CR)."""
        return self._s[_NS_LEN]

    # ---- accepted sentences: the scan's fields (self._s) into the attributes ---------------

    def _gga(self):
        s = self._s
        utc = s[_NS_UTC]
        self._epoch_time(utc)  # first: a new epoch learns from the one it ends
        self.gga_utc_ms = utc
        self.gga_pos_ok = s[_NS_POS]
        if s[_NS_POS]:
            self.gga_lat_e7 = s[_NS_LAT]
            self.gga_lon_deg = s[_NS_DEG]
            self.gga_lon_frac_e7 = s[_NS_FRAC]
        self.gga_quality = s[_NS_A]
        self.gga_nsat = s[_NS_B]
        self.gga_hdop_x100 = s[_NS_C]
        self.gga_alt_ok = 0
        if s[_NS_D] != _EMPTY:
            self.gga_alt_mm = s[_NS_D]
            self.gga_alt_ok = 1
        self.gga_sep_ok = 0
        if s[_NS_E] != _EMPTY:
            self.gga_sep_mm = s[_NS_E]
            self.gga_sep_ok = 1
        self.gga_seen = 1
        self.n_gga = (self.n_gga + 1) & _WRAP
        if utc >= 0:
            self._ep_gga = 1
            self._check()

    def _rmc(self):
        s = self._s
        utc = s[_NS_UTC]
        self._epoch_time(utc)
        self.rmc_utc_ms = utc
        a = s[_NS_A]
        self.rmc_status = a
        self.rmc_pos_ok = s[_NS_POS]
        if s[_NS_POS]:
            self.rmc_lat_e7 = s[_NS_LAT]
            self.rmc_lon_deg = s[_NS_DEG]
            self.rmc_lon_frac_e7 = s[_NS_FRAC]
        self.rmc_speed_mm_s = s[_NS_B]
        self.rmc_course_cdeg = s[_NS_C]
        self.rmc_date = s[_NS_D]
        self.rmc_mode = s[_NS_E]
        self.n_rmc = (self.n_rmc + 1) & _WRAP
        if utc >= 0:
            self._ep_rmc = 1
        if a == 65:  # 'A'
            self._speed(s[_NS_B], s[_NS_C])
        else:
            self._speed(-1, -1)

    def _vtg(self):
        s = self._s
        self.vtg_course_cdeg = s[_NS_C]
        self.vtg_speed_mm_s = s[_NS_B]
        self.vtg_mode = s[_NS_E]
        self.n_vtg = (self.n_vtg + 1) & _WRAP
        spd = s[_NS_B]
        crs = s[_NS_C]
        if s[_NS_E] == 78:  # 'N': data not valid
            spd = -1
            crs = -1
        if self._ep_utc >= 0:
            t = _ticks_us()
            if _ticks_diff(t, self._ep_us) > self._join_us:
                # too long after its epoch's first sentence: the first of the next group
                # (a receiver that prints VTG before GGA/RMC and no RMC): for the next epoch
                self._vtg_pend = 1
                self._vtg_us = t
                self._vtg_speed = spd
                self._vtg_course = crs
                return
        self._speed(spd, crs)

    def _gsa(self):
        s = self._s
        self.gsa_mode = s[_NS_E]
        self.gsa_fix = s[_NS_A]
        self.gsa_nsv = s[_NS_B]
        self.gsa_pdop_x100 = s[_NS_D]
        self.gsa_hdop_x100 = s[_NS_C]
        self.gsa_vdop_x100 = s[_NS_F]
        self.n_gsa = (self.n_gsa + 1) & _WRAP

    # ---- epochs ------------------------------------------------------------------------

    def _epoch_time(self, utc):
        """A GGA or RMC of time utc: start a new epoch if the time changed, after learning
        from the one it ends. Without a time (utc -1) the "epoch" is a gap that nothing
        completes, no VTG joins and nothing learns from."""
        if utc == self._ep_utc:
            return
        old = self._ep_utc
        if old >= 0:
            if (self._ep_gga or self._ep_rmc) and not self._ep_done:
                self.n_epochs_dropped = (self.n_epochs_dropped + 1) & _WRAP
            if self.need_speed == AUTO:
                self._miss_gga = ((self._miss_gga << 1) | (1 - self._ep_gga)) & 15
                self._miss_spd = ((self._miss_spd << 1) | (1 - self._ep_spd)) & 15
            d = utc - old
            if 0 < d <= 1000:  # the output period (1 Hz .. 10 Hz): a VTG's window
                self._join_us = d * _JOIN_US_PER_MS
        self._ep_utc = utc
        self._ep_gga = 0
        self._ep_rmc = 0
        self._ep_spd = 0
        self._ep_done = 0
        self._ep_pps = self.pps_us
        self._ep_speed = -1
        self._ep_course = -1
        if utc < 0:
            return
        t = _ticks_us()
        self._ep_us = t
        if self._vtg_pend:  # a VTG that came first in this group
            self._vtg_pend = 0
            if _ticks_diff(t, self._vtg_us) <= self._join_us:
                self._speed(self._vtg_speed, self._vtg_course)

    def _speed(self, spd, crs):
        """Speed and course of the current epoch (from RMC, or VTG)."""
        if self._ep_utc < 0:
            return  # VTG before any timed sentence, or after one without time
        self._ep_speed = spd
        self._ep_course = crs
        self._ep_spd = 1
        self._check()

    def _speed_damaged(self):
        """A line rejected for its checksum whose address still reads RMC or VTG (a talker of
        two capitals, not P, as the scan's rule): the epoch's speed sentence, damaged on the
        line. It counts as sent, so an epoch that has its position and waits only for the
        speed completes now, without one, instead of being dropped at the next epoch; only
        within the VTG window of the epoch's first sentence and, for an RMC whose time still
        reads as one, at the epoch's time (else it is the next group's)."""
        if self._ep_utc < 0 or self._ep_done or self._s[_NS_NF] < 2 or self._s[_NS_LEN] < 6:
            return
        lb = self._line
        if lb[_FS + 1] != 6 or lb[0] == 80 or not (65 <= lb[0] <= 90 and 65 <= lb[1] <= 90):
            return
        f = (lb[2] << 16) | (lb[3] << 8) | lb[4]
        if f != _FMT_RMC and f != _FMT_VTG:
            return
        if f == _FMT_RMC and self._s[_NS_NF] > 2:  # its time, where still readable, decides
            utc = _utc_ms(lb, 6, lb[_FS + 2] - 1)
            if utc >= 0 and utc != self._ep_utc:
                return
        if _ticks_diff(_ticks_us(), self._ep_us) > self._join_us:
            return
        self._ep_spd = 1
        self._check()

    def _check(self):
        """Complete the epoch when it has what the receiver sends each epoch: a GGA (or an
        RMC's position, from a receiver not sending GGA every epoch) and a speed sentence
        (unless the receiver does not send one every epoch). x & (x - 1) is 0 when at most
        one of the last four epochs missed it."""
        if self._ep_done:
            return
        m = self._miss_gga
        if not (self._ep_gga or self._ep_rmc and m & (m - 1)):
            return
        m = self._miss_spd
        if self._ep_spd or m & (m - 1):
            self._complete()

    def _complete(self):
        self._ep_done = 1
        if self._ep_gga:
            self.epoch_utc_ms = self.gga_utc_ms
            self.epoch_lat_e7 = self.gga_lat_e7
            self.epoch_lon_deg = self.gga_lon_deg
            self.epoch_lon_frac_e7 = self.gga_lon_frac_e7
            self.epoch_pos_ok = self.gga_pos_ok
            self.epoch_alt_mm = self.gga_alt_mm
            self.epoch_alt_ok = self.gga_alt_ok
            self.epoch_sep_mm = self.gga_sep_mm
            self.epoch_sep_ok = self.gga_sep_ok
            self.epoch_quality = self.gga_quality
            self.epoch_nsat = self.gga_nsat
            self.epoch_hdop_x100 = self.gga_hdop_x100
        else:  # the RMC's position: no height, satellites or HDOP
            self.epoch_utc_ms = self.rmc_utc_ms
            self.epoch_lat_e7 = self.rmc_lat_e7
            self.epoch_lon_deg = self.rmc_lon_deg
            self.epoch_lon_frac_e7 = self.rmc_lon_frac_e7
            self.epoch_pos_ok = self.rmc_pos_ok
            self.epoch_alt_mm = 0
            self.epoch_alt_ok = 0
            self.epoch_sep_mm = 0
            self.epoch_sep_ok = 0
            self.epoch_quality = _rmc_quality(self.rmc_status, self.rmc_mode)
            self.epoch_nsat = -1
            self.epoch_hdop_x100 = -1
        self.epoch_speed_mm_s = self._ep_speed
        self.epoch_course_cdeg = self._ep_course
        self.epoch_pps_us = self._ep_pps
        self._plausible()
        self.n_epochs = (self.n_epochs + 1) & _WRAP
        self.epoch_ready = 1

    def _plausible(self):
        """epoch_bad (BAD_*) of the epoch just completed; n_epochs_bad counts the fixes it
        makes unusable."""
        bad = 0
        utc = self.epoch_utc_ms
        prev = self._prev_utc
        self._prev_utc = utc  # a receiver's clock that jumped back costs one epoch, not hours
        if self.epoch_pos_ok and self.epoch_quality > 0:
            if self.epoch_quality >= 6:
                bad |= BAD_QUALITY
            a = self.epoch_alt_mm
            if self.epoch_alt_ok and (a < _ALT_MIN_MM or a > _ALT_MAX_MM):
                bad |= BAD_HEIGHT
            if self.epoch_speed_mm_s > _SPEED_MAX_MM_S:
                bad |= BAD_SPEED
            if self.epoch_course_cdeg > 36000:
                bad |= BAD_COURSE
            if self.epoch_hdop_x100 == 0:
                bad |= BAD_HDOP
            if prev >= 0 and utc >= 0 and -_HALF_DAY_MS < utc - prev <= 0:
                bad |= BAD_TIME
            sep = self.epoch_sep_mm
            if self.epoch_sep_ok and (sep > _SEP_MAX_MM or sep < -_SEP_MAX_MM):
                bad |= BAD_GEOID
            if self.epoch_nsat > _NSAT_MAX:
                bad |= BAD_NSAT
            if bad:
                self.n_epochs_bad = (self.n_epochs_bad + 1) & _WRAP
        self.epoch_bad = bad


def _utc_ms(line, a, b):
    """hhmmss[.sss] -> ms of day; -1 if empty or out of range; _BAD on a syntax error."""
    if a >= b:
        return -1
    if b - a < 6:
        return _BAD
    v = 0
    for i in range(a, a + 6):
        c = line[i] - 48
        if c < 0 or c > 9:
            return _BAD
        v = v * 10 + c
    ms = 0
    n = 0
    i = a + 6
    if i < b:
        if line[i] != 46:
            return _BAD
        i += 1
        while i < b:
            c = line[i] - 48
            if c < 0 or c > 9:
                return _BAD
            if n < 3:
                ms = ms * 10 + c
                n += 1
            i += 1
    while n < 3:
        ms *= 10
        n += 1
    h = v // 10000
    m = v // 100 % 100
    s = v % 100
    if h > 23 or m > 59 or s > 60 or (s == 60 and h * 100 + m != 2359):
        return -1  # a leap second is 23:59:60, never another minute's 60th second
    return ((h * 60 + m) * 60 + s) * 1000 + ms


def _rmc_quality(status, mode):
    """GGA's fix quality of an RMC: 0 unless status A; then from the NMEA 2.3 mode letter
    (D differential 2, R RTK fixed 4, F RTK float 5, E estimated 6, M manual 7, S simulator
    8, N 0; A, P or none 1)."""
    if status != 65:  # 'A'
        return 0
    if mode == 68:  # 'D'
        return 2
    if mode == 82:  # 'R'
        return 4
    if mode == 70:  # 'F'
        return 5
    if mode == 69:  # 'E'
        return 6
    if mode == 77:  # 'M'
        return 7
    if mode == 83:  # 'S'
        return 8
    if mode == 78:  # 'N'
        return 0
    return 1


# The Python scan, gnss_kern.py: loaded where navk is not, and on CPython (the reference its
# tests compare with); a board with navk runs nmea.c and keeps the heap its functions would take.
# A board image does not freeze it; beside a frozen drivers package it can only be a top-level
# module (/flash/lib/gnss_kern.mpy: a /flash/drivers directory would hide the frozen package)
gnss_kern = None
if not kern.NATIVE or kern.HOST:
    try:
        from drivers import gnss_kern  # here, after _utc_ms, which it takes from this module
    except ImportError:
        try:
            import gnss_kern
        except ImportError as e:  # kern.Missing: main.py says so
            raise kern.missing(e) from None
_scan = kern.navk.nmea_scan if kern.NATIVE else gnss_kern.scan
