"""The screen's byte stream as firmware/lib/status_page.py sends it, computed independently:
Python's string formatting where the firmware writes digits into buffers, NumPy's float32
where it decodes a variance's bits. The parity oracle of the display UART.

    page = Page(cfg)             # the board's settings (BoardConfig)
    page.start()                 # the cleared page and its labels
    page.turn(ticks, view)       # at every tick the loop gives the page a turn
    page.out                     # bytes so far

`View` is what the firmware reads at a turn: the navigator's state, the app's fix fields, the
parser's quality, satellites and HDOP, the last 52-byte frame sent and the last extended
frame sent (None before one, or with the extended frame off: then the navigator's health and
causes). The screen is taken to answer every batch (the emulated UsartGPU does), so the
display cause never rises here.
"""

import math
from dataclasses import dataclass

import numpy as np

from common.proto import records

SLOT = 8  # ticks between turns
PHASE = 3  # the loop's tick count mod SLOT at a turn
TURNS = 16  # turns in a round
FIELDS = 13  # fields, one a row; turn 13 ends the batch
COL = 7  # the values' text column
LABELS = ("UP", "STATE", "FIX", "LAT", "LON", "HEIGHT", "POS", "SPEED", "HEAD", "ATT", "SIGMA",
          "HEALTH", "CAUSE")  # fmt: skip
STATES = {-1: "no IMU", 0: "starting", 1: "aligning", 2: "navigating"}
QUALITY = ("none", "GPS", "DGPS", "PPS", "RTK", "float", "DR", "manual", "sim")
HEALTHS = ("0 ok", "1 warning", "2 FAULT")
# the words of records.CAUSES' bits, and the display's own (app.CAUSE_DISPLAY)
CAUSE_WORDS = ("IMU range", "IMU held", "IMU dead", "numeric", "GNSS lost", "fix gated",
               "fix rejects", "GNSS data", "reset", "uncertain", "drift", "GNSS late",
               "NMEA error", "PPS", "config", "overrun", "GNSS clock", "implausible",
               "display", "aligning")  # fmt: skip
FAULTS = 0x2074C  # the causes of health 2 (nav.CAUSE_FAULTS): named first
VAR_MAX = 0x1FFFFFFF  # cm^2
V_MAX = 23170  # cm/s
POS_MAX = 99999999  # cm


def font_for(w, h):
    """The text height whose 13 rows of 35 cells fit w x h (12, 16, 24), else 0."""
    for font in (24, 16, 12):
        if w >= 3 + 35 * font // 2 and h >= 13 * font:
            return font
    return 0


@dataclass
class View:
    state: int
    fix_valid: int
    lat_e7: int
    lon_e7: int
    height_dm: int
    quality: int
    nsat: int
    hdop_x100: int
    frame: bytes  # the last 52-byte frame sent (zeros before one)
    ext: bytes | None  # the last extended frame sent
    health: int  # the navigator's (read when the extended frame is off)
    causes: int


def _fixed(value, scale_digits, width, signed=False):
    """|value| / 10**scale_digits with that many decimals, right-aligned in width; signed: a
    + or - before it."""
    a = abs(value)
    if scale_digits:
        text = f"{a // 10**scale_digits}.{a % 10**scale_digits:0{scale_digits}d}"
    else:
        text = str(a)
    if signed:
        text = ("-" if value < 0 else "+") + text
    return text.rjust(width)


def _i16(b, o):
    return int(np.frombuffer(b, "<i2", 1, o)[0])


def _i32(b, o):
    return int(np.frombuffer(b, "<i4", 1, o)[0])


def _clamp(v, m):
    return max(-m, min(m, v))


def variance_cm2(bits):
    """A float32 variance (m^2, its 4 bytes) in cm^2 as the firmware rounds it: the mantissa
    cut to its top 14 bits, times 1e4, times the power of two, floored; VAR_MAX above 2**29
    ish; None if negative, infinite or NaN."""
    v = np.frombuffer(bits, "<f4")[0]
    if not np.isfinite(v) or v < 0 or (v == 0 and np.signbit(v)):
        return None
    if v == 0 or int.from_bytes(bits, "little") >> 23 == 0:
        return 0  # zero and the subnormals
    m, e = math.frexp(float(v))  # v = m * 2**e, 0.5 <= m < 1: the 24-bit mantissa is m * 2**24
    q = (int(m * 2**24) >> 10) * 10000
    shift = e - 24 + 10  # q * 2**shift = (mantissa >> 10) * 1e4 * 2**(exp - 23 + 10)
    if shift > 1:
        return VAR_MAX
    return q << shift if shift >= 0 else q >> -shift


def cause_text(causes):
    bits = [k for k in range(len(CAUSE_WORDS)) if causes >> k & 1]
    faults = [k for k in bits if FAULTS >> k & 1]
    text = CAUSE_WORDS[(faults or bits)[0]] if bits else "none"
    more = len(bits) - 1
    return text.ljust(12) + (f" +{min(more, 9)}" if more > 0 else "   ")


class Page:
    def __init__(self, cfg):
        self.font = font_for(cfg.display_w, cfg.display_h)
        self.pitch = cfg.display_h // 13
        self.y0 = (cfg.display_h - 13 * self.pitch) // 2
        self.fg, self.bg = cfg.display_fg, cfg.display_bg
        self.warn, self.fault = cfg.display_warn, cfg.display_fault
        self.ext_on = bool(cfg.ext_every_ticks)
        self.shown = [None] * FIELDS  # (text, colour) on the screen
        self.batch = 0
        self.out = bytearray()

    def _cmd(self, col, row, text, colour):
        x = 3 + col * (self.font // 2)
        return f"DS{self.font}({x},{self.y0 + row * self.pitch},'{text}',{colour});".encode()

    def start(self):
        self.out += f"SBC({self.bg});CLS({self.bg});".encode()
        for row, label in enumerate(LABELS):
            self.out += self._cmd(0, row, label, self.fg)
        self.out += b"\r\n"

    def turn(self, ticks, view):
        k = ticks // SLOT % TURNS
        if k < FIELDS:
            text, colour = self.field(k, ticks, view)
            if self.shown[k] != (text, colour):
                self.shown[k] = (text, colour)
                cmd = self._cmd(COL, k, text, colour)
                self.out += cmd
                self.batch += len(cmd)
        elif k == FIELDS and self.batch:
            self.out += b"\r\n"
            self.batch = 0

    def field(self, k, ticks, v):
        """(text, colour) of field k."""
        fr = v.frame
        ext = v.ext if self.ext_on else None
        health = ext[4] if ext is not None else (0 if self.ext_on else v.health)
        causes = records.decode_ext(ext)["causes"] if ext is not None else (
            0 if self.ext_on else v.causes)  # fmt: skip
        fg = self.fg
        if k == 0:
            s = ticks // 200
            return f"{s // 3600:4d}:{s // 60 % 60:02d}:{s % 60:02d}", fg
        if k == 1:
            return STATES[v.state].ljust(10), fg
        if k == 2:
            q = v.quality if v.fix_valid else 0
            word = QUALITY[q if 0 <= q <= 8 else 0].ljust(6)
            sats = f"{min(v.nsat, 99):3d}" if v.nsat >= 0 else " --"
            hdop = _fixed(min((v.hdop_x100 + 5) // 10, 999), 1, 4) if v.hdop_x100 >= 0 else "  --"
            return f"{word}{sats} sat HDOP{hdop}", fg
        if k in (3, 4):
            e7 = v.lat_e7 if k == 3 else v.lon_e7
            deg, frac = divmod(abs(e7), 10**7)
            whole = ("-" if e7 < 0 else "+") + str(deg)
            return f"{whole.rjust(4)}.{frac:07d} deg", fg
        if k == 5:
            return _fixed(v.height_dm, 1, 9, True) + " m", fg
        if k == 6:
            e = _fixed(_clamp(_i32(fr, 41), POS_MAX), 2, 10, True)
            n = _fixed(_clamp(_i32(fr, 45), POS_MAX), 2, 10, True)
            return f"E{e} N{n} m", fg
        if k == 7:
            s = math.isqrt(_clamp(_i16(fr, 35), V_MAX) ** 2 + _clamp(_i16(fr, 37), V_MAX) ** 2)
            return f"{_fixed(s, 2, 6)} m/s{_fixed((s * 36 + 50) // 100, 1, 7)} km/h", fg
        if k == 8:
            return _fixed(_i16(fr, 29) % 36000, 2, 6) + " deg", fg
        if k == 9:
            r = _fixed(_i16(fr, 33), 2, 8, True)
            p = _fixed(_i16(fr, 31), 2, 7, True)
            return f"R{r} P{p} deg", fg
        if k == 10:
            if ext is not None and v.state == 2:
                a, b = variance_cm2(ext[16:20]), variance_cm2(ext[20:24])
                if a is not None and b is not None:
                    return _fixed(math.isqrt(a + b), 2, 7) + " m", fg
            return "     --  ", fg
        colour = fg if health == 0 else (self.warn if health == 1 else self.fault)
        if k == 11:
            return HEALTHS[health if 0 <= health <= 2 else 2].ljust(9), colour
        return cause_text(causes), colour
