"""The status page on the UsartGPU serial screen (docs/display.md), in integers only.

The screen takes ASCII commands, each ending in `;`, and draws a batch when `\\r\\n` comes;
it then answers `OK\\r\\n`. At start (`start`, before the loop's timer: the screen starts a
demo loop if nothing comes within ~10 s of power-up) the page is cleared and its labels drawn.
Then one field's turn comes every _PAGE_SLOT ticks (`turn`, called by the loop when ticks is
_PAGE_PHASE mod _PAGE_SLOT, with the navigator's state): the field's text is made and, only if
it or its colour differs from what the screen shows, sent as one `DSn(x,y,'text',c);` command.
After the last field, a batch that sent anything is ended with `\\r\\n`. A round of _TURNS
turns is 0.64 s.

What a turn costs the loop: one field's formatting, skipped when the inputs of a field that
changes seldom are those of its last text (_unchanged), and one write of at most _CMD_MAX
bytes to the screen's transmitter: on the board the UART's DMA (drivers/uart_dma.py), so no
tick waits for the line; at 38400 baud or more a turn's bytes have left before the next turn.
The digits and the comparison with the shown text are navk's integer kernels (text_num,
text_diff; their Python references are here). Nothing allocates: texts are made in
preallocated bytearrays from small ints (the transmitter without DMA writes byte by byte:
board._Chars), and every function keeps its frame within the VM's 11 words
(tests/runtimes/test_frames.py), hence the module-level buffers and the few arguments.

The values are what the board's records say: attitude, velocity and position from the last
52-byte frame sent (its bytes); health, causes and, while navigating, the horizontal 1-sigma
from the last extended frame (its int fields, and the float32 bits of P's east and north
variances decoded here in integers; with the extended frame off, the navigator's health and
causes and no 1-sigma); the fix's latitude, longitude and height (above mean sea level) from
the frame's int fields; the fix's quality, satellites and HDOP from the NMEA parser; the state
from the loop.

The `OK`s are read when they are there, never waited for: at each batch's end the bytes that
came are counted. A screen that has never answered is taken as absent (a board may have
none). Once one has answered, a batch still unanswered when the next one ends (0.64 s later;
the screen answers within ~0.2 s) counts in `missed` and raises the app's display cause for a
second (`bad_until`).
"""

from array import array

from micropython import const

import kern
from frame import bytes_copy

_PAGE_SLOT = const(8)  # ticks between two turns: the loop calls `turn` when ticks % _PAGE_SLOT
_PAGE_PHASE = const(3)  # is this, odd, so a turn never shares its tick with an extended frame's
# (every 20 ticks)
_TURNS = const(16)  # turns in a round: the 13 fields, the batch's end, two idle
_END = const(13)  # the turn that ends the batch
_NFIELD = const(13)
_CMD_MAX = const(64)  # bytes of one field's command at most
_COL = const(7)  # the values' column, in text cells (the labels take 6)
_ROWS = const(13)
_TICKS_S = const(200)
_WMAX = const(25)
# the fields, one per row, in turn order
_P_UP = const(0)
_P_STATE = const(1)
_P_FIX = const(2)
_P_LAT = const(3)
_P_LON = const(4)
_P_HEIGHT = const(5)
_P_POS = const(6)
_P_SPEED = const(7)
_P_HEAD = const(8)
_P_ATT = const(9)
_P_SIGMA = const(10)
_P_HEALTH = const(11)
_P_CAUSE = const(12)
WIDTH = b"\x0a\x0a\x16\x10\x10\x0b\x19\x16\x0a\x16\x09\x09\x0f"  # each value's characters
LABELS = b"UP    STATE FIX   LAT   LON   HEIGHTPOS   SPEED HEAD  ATT   SIGMA HEALTHCAUSE "
_X_PEE = const(16)  # the extended frame's P[0][0] + cv, f32 (records.py); P[1][1] + cv next
_V_MAX = const(23170)  # |velocity| clamp, cm/s: the sum of two squares stays a small int
_VAR_MAX = const(0x1FFFFFFF)  # a variance's clamp, cm^2: the sum of two stays a small int
_POS_MAX = const(99999999)  # cm
_NONE = const(-0x40000000)  # _same's inputs before the first
TN_WIDTH = const(0xFF)  # text_num's form: width | decimals << TN_DEC_SHIFT | ...
TN_DEC_SHIFT = const(8)
TN_DEC = const(0xF)
TN_SIGNED = const(0x1000)  # ... the sign before the digits
TN_ZEROS = const(0x2000)  # ... zeros before them, not spaces
_D1 = const(1 << 8)  # text_num's form: 1 decimal, 2 decimals
_D2 = const(2 << 8)
# The frame's, the extended frame's and the navigator's indices read here
# ---- frame.py's consts used here: `python -m common.native.layout` writes them ----
_FB_YAW = const(29)
_FB_PITCH = const(31)
_FB_ROLL = const(33)
_FB_VE = const(35)
_FB_VN = const(37)
_FB_PE = const(41)
_FB_PN = const(45)
_F_VALID = const(5)
_F_HEIGHT_DM = const(6)
_F_LAT_DEG = const(8)
_F_LAT_FRAC = const(9)
_F_LON_DEG = const(10)
_F_LON_FRAC = const(11)
# ---- end of frame.py's consts ----
# ---- records.py's consts used here: `python -m common.native.layout` writes them ----
_EF_HEALTH = const(1)
_EF_CAUSES = const(13)
# ---- end of records.py's consts ----
# ---- nav.py's consts used here: `python -m common.native.layout` writes them ----
_NAVIGATING = const(2)
_CAUSE_FAULTS = const(0x2074C)
_C_HEALTH = const(2)
_C_CAUSES = const(48)
# ---- end of nav.py's consts ----
STATES = b"no IMU    starting  aligning  navigating"  # state -1 .. 2, 10 characters each
QUALITY = b"none  GPS   DGPS  PPS   RTK   float DR    manualsim   "  # GGA quality, 6 each
HEALTHS = b"0 ok     1 warning2 FAULT  "  # 9 each
# each cause bit's word (nav.CAUSE_* and app.CAUSE_*, bit 0 first), 12 characters each
CAUSES = (
    b"IMU range   IMU held    IMU dead    numeric     GNSS lost   fix gated   "
    b"fix rejects GNSS data   reset       uncertain   drift       GNSS late   "
    b"NMEA error  PPS         config      overrun     GNSS clock  implausible "
    b"display     aligning    "
)
NCAUSE = const(20)

_T = bytearray(_WMAX)  # the text being made (one page per board: module-level buffers)
_C = bytearray(_CMD_MAX)  # the command being made
_K = array("i", (0,))  # a field's third input (_same: a fourth argument would cost a word)


def font_for(w, h):
    """The text height (12, 16 or 24 px; cells half as wide) whose 13 rows of 35 cells fit a
    w x h screen; 0 if none does (below 213 x 156)."""
    if w >= 3 + 35 * 12 and h >= _ROWS * 24:
        return 24
    if w >= 3 + 35 * 8 and h >= _ROWS * 16:
        return 16
    if w >= 3 + 35 * 6 and h >= _ROWS * 12:
        return 12
    return 0


def _text_num_py(t, p, v, form):
    """The int v over 10**dec into t[p:p+w], right-aligned, spaces before (form: w | dec << 8,
    | TN_ZEROS for zeros instead, | TN_SIGNED for its sign, + or -, just before the first digit,
    |v| then: a space must be left for it); p + w. The reference of the native `text_num`."""
    w = form & TN_WIDTH
    dec = form >> TN_DEC_SHIFT & TN_DEC
    u = -v if v < 0 else v
    i = p + w
    while dec:
        i -= 1
        t[i] = 48 + u % 10
        u //= 10
        dec -= 1
        if not dec:
            i -= 1
            t[i] = 46  # the point
    i -= 1
    t[i] = 48 + u % 10
    u //= 10
    while i > p:
        i -= 1
        if u:
            t[i] = 48 + u % 10
            u //= 10
        else:
            t[i] = 48 if form & TN_ZEROS else 32
    if form & TN_SIGNED:
        i = p
        while t[i] == 32:
            i += 1
        t[i - 1] = 45 if v < 0 else 43
    return p + w


def _text_diff_py(s, o, t, n):
    """Whether t[0:n] differs from s[o:o+n] (1, else 0); s[o:o+n] becomes t[0:n]. The
    reference of the native `text_diff`."""
    d = 0
    for i in range(n):
        if s[o + i] != t[i]:
            s[o + i] = t[i]
            d = 1
    return d


_text_num = kern.pick("text_num", _text_num_py)
_text_diff = kern.pick("text_diff", _text_diff_py)


def _sign(p, neg):
    """'-' (neg) or '+' just before the first non-space from _T[p] (a space is there)."""
    while _T[p] == 32:
        p += 1
    _T[p - 1] = 45 if neg else 43


def _put(p, s, a, n):
    """s[a:a+n] into _T from p; p + n."""
    for i in range(n):
        _T[p + i] = s[a + i]
    return p + n


def _two(p, v):
    """v (0..99) as two digits into _T; p + 2."""
    _T[p] = 48 + v // 10
    _T[p + 1] = 48 + v % 10
    return p + 2


def _dec(b, p, v):
    """v (0..999) in decimal into b from p, no padding; the end."""
    if v >= 100:
        b[p] = 48 + v // 100
        p += 1
    if v >= 10:
        b[p] = 48 + v // 10 % 10
        p += 1
    b[p] = 48 + v % 10
    return p + 1


def _i16(b, o):
    v = b[o] | b[o + 1] << 8
    return v - 65536 if v > 32767 else v


def _i32(b, o):
    """A frame's int32 (within +-2**30, its clamp: a small int)."""
    return b[o] | b[o + 1] << 8 | b[o + 2] << 16 | ((b[o + 3] ^ 0x80) - 0x80) << 24


def _clamp(v, m):
    return m if v > m else (-m if v < -m else v)


def var_cm2(b, o):
    """The float32 at b[o:o+4] (a variance, m^2) in cm^2, from its bits: 14 bits of mantissa
    are kept so that every product stays a small int; clamped to _VAR_MAX; -1 if negative or
    not finite."""
    e = (b[o + 3] & 0x7F) << 1 | b[o + 2] >> 7
    if b[o + 3] & 0x80 or e == 255:
        return -1
    if e == 0:
        return 0
    q = ((b[o + 2] & 0x7F) << 16 | b[o + 1] << 8 | b[o] | 0x800000) >> 10
    q *= 10000  # mantissa x 1e4 x 2^(e - 140): the variance in cm^2
    e -= 140
    if e > 1:
        return _VAR_MAX
    if e >= 0:
        return q << e
    return q >> -e if e > -31 else 0


def isqrt(v):
    """floor(sqrt(v)) of an int v >= 0 (Newton's iteration in ints)."""
    x = v
    y = (x + 1) >> 1
    while y < x:
        x = y
        y = (x + v // x) >> 1
    return x


def first_cause(c):
    """The lowest set bit among the NCAUSE causes, faults first; -1 if none."""
    if not c:
        return -1
    for k in range(NCAUSE):
        if (c & _CAUSE_FAULTS) >> k & 1:
            return k
    for k in range(NCAUSE):
        if c >> k & 1:
            return k
    return -1


def _bits(c):
    """The causes set among the NCAUSE."""
    c &= (1 << NCAUSE) - 1
    n = 0
    while c:
        n += c & 1
        c >>= 1
    return n


class StatusPage:
    """The page on one screen. `tx`: the screen UART's transmitter (write_n), `uart`: the
    UART (any, readinto: the OKs); `cfg`: the settings (display_w/h and the colours); `app`:
    the loop whose records are shown (its out, _fields, ext, nav.ctl and gnss)."""

    def __init__(self, tx, uart, cfg, app):
        self._tx = tx
        self._uart = uart
        self._font = font_for(cfg.display_w, cfg.display_h)
        self._pitch = cfg.display_h // _ROWS
        self._y0 = (cfg.display_h - _ROWS * self._pitch) // 2
        self._cw = self._font // 2
        self._fg = cfg.display_fg
        self._bg = cfg.display_bg
        self._warn = cfg.display_warn
        self._fault = cfg.display_fault
        self._out = app.out
        self._ff = app._fields
        self._ext = app.ext.data if cfg.ext_every_ticks else None
        self._ef = app.ext.fields
        self._ctl = app.nav.ctl
        self._gnss = app.gnss
        self._shown = bytearray(_NFIELD * _WMAX)  # what the screen shows, per field
        self._col = bytearray(_NFIELD)  # and in which colour
        self._keys = array("i", (_NONE,) * (3 * _NFIELD))  # _same's: each field's inputs
        # each field's command head, made once
        self._heads = tuple(self._head(_COL, f).encode() for f in range(_NFIELD))
        self._rx = bytearray(8)
        self.state = -1  # the loop's at the last turn: -1 no IMU, else the navigator's
        self._batch = 0  # bytes sent in this round's batch
        self.batches = 0  # batches ended with \r\n
        self.oks = 0  # OKs the screen answered
        self.missed = 0  # batches it left unanswered (once it has answered one)
        self.bad_until = 0  # the app's display cause until this tick

    # ---- start: the cleared page and its labels ----------------------------------------

    def start(self):
        """`SBC(bg);CLS(bg);`, the labels, `\\r\\n`: one batch, before the loop starts (it
        allocates: start-up only)."""
        cmd = f"SBC({self._bg});CLS({self._bg});"
        for f in range(_NFIELD):
            label = LABELS[6 * f : 6 * f + 6].decode().rstrip()
            cmd += f"{self._head(0, f)}{label}',{self._fg});"
        self._tx.write((cmd + "\r\n").encode())
        self.batches += 1

    def _head(self, col, row):
        """`DSf(x,y,'` of the text at cell col of row."""
        return f"DS{self._font}({3 + col * self._cw},{self._y0 + row * self._pitch},'"

    def _send(self, f, n, colour):
        """`DSf(x,y,'_T[0:n]',colour);` at field f's place, written; counted in the batch."""
        h = self._heads[f]
        p = len(h)
        _C[0:p] = h
        bytes_copy(_C, p, _T, n)
        p += n
        _C[p] = 39  # '
        _C[p + 1] = 44  # ,
        p = _dec(_C, p + 2, colour)
        _C[p] = 41  # )
        _C[p + 1] = 59  # ;
        self._tx.write_n(_C, p + 2)
        self._batch += p + 2

    # ---- per turn ------------------------------------------------------------------------

    def turn(self, ticks, state):
        """The turn of tick `ticks` (_PAGE_PHASE mod _PAGE_SLOT): one field, or the batch's end.
        state: the navigator's, or -1 without an IMU."""
        self.state = state
        k = (ticks // _PAGE_SLOT) % _TURNS
        if k < _NFIELD:
            c = self._make(k, ticks)
            if c >= 0:
                self._draw(k, c)
        elif k == _END:
            self._end(ticks)

    def _same(self, f, a, b):
        """Whether field f's inputs a, b and _K are those of its last text; they become so."""
        k = self._keys
        f *= 3
        if k[f] == a and k[f + 1] == b and k[f + 2] == _K[0]:
            return True
        k[f] = a
        k[f + 1] = b
        k[f + 2] = _K[0]
        return False

    def _unchanged(self, f):
        """Whether the inputs of field f, one that changes seldom, are those its text was last
        made from (the text is then the same: not made again)."""
        _K[0] = 0
        if f == _P_STATE:
            return self._same(f, self.state, 0)
        if f == _P_FIX:
            g = self._gnss
            _K[0] = g.epoch_hdop_x100
            return self._same(f, g.epoch_quality if self._ff[_F_VALID] else 0, g.epoch_nsat)
        if f == _P_LAT or f == _P_LON:
            g = _F_LAT_DEG if f == _P_LAT else _F_LON_DEG
            return self._same(f, self._ff[g], self._ff[g + 1])
        if f == _P_HEIGHT:
            return self._same(f, self._ff[_F_HEIGHT_DM], 0)
        if f < _P_HEALTH:
            return False
        if self._ext is not None:
            _K[0] = self._ef[_EF_CAUSES] if f == _P_CAUSE else 0
            return self._same(f, self._ef[_EF_HEALTH], 0)
        _K[0] = self._ctl[_C_CAUSES] if f == _P_CAUSE else 0
        return self._same(f, self._ctl[_C_HEALTH], 0)

    def _make(self, f, ticks):
        """Field f's text into _T (WIDTH[f] characters) and its colour; -1 if the field's
        inputs are those of its last text (_unchanged)."""
        if self._unchanged(f):
            return -1
        if f == _P_UP:
            ticks //= _TICKS_S
            p = _text_num(_T, 0, ticks // 3600, 4)
            _T[p] = 58  # :
            p = _two(p + 1, ticks // 60 % 60)
            _T[p] = 58
            _two(p + 1, ticks % 60)
            return self._fg
        if f == _P_STATE:
            _put(0, STATES, 10 * (self.state + 1), 10)
            return self._fg
        if f == _P_FIX:
            return self._fix()
        if f == _P_LAT or f == _P_LON:
            return self._angle(f)
        if f == _P_SPEED:
            return self._speed()
        if f <= _P_ATT:
            return self._motion(f)
        return self._health(f)

    def _fix(self):
        """Quality (of a valid fix, else none), satellites, HDOP."""
        g = self._gnss
        q = g.epoch_quality if self._ff[_F_VALID] else 0
        p = _put(0, QUALITY, 6 * (q if 0 <= q <= 8 else 0), 6)
        q = g.epoch_nsat
        if q >= 0:
            p = _text_num(_T, p, q if q < 99 else 99, 3)
        else:
            p = _put(p, b" --", 0, 3)
        p = _put(p, b" sat HDOP", 0, 9)
        q = g.epoch_hdop_x100
        if q >= 0:
            _text_num(_T, p, (q + 5) // 10 if q < 9995 else 999, 4 | _D1)
        else:
            _put(p, b"  --", 0, 4)
        return self._fg

    def _angle(self, f):
        """The fix's latitude or longitude: sign, degrees, 7 decimals, " deg"."""
        d = self._ff[_F_LAT_DEG if f == _P_LAT else _F_LON_DEG]
        r = self._ff[_F_LAT_FRAC if f == _P_LAT else _F_LON_FRAC]
        p = _text_num(_T, 0, abs(d), 4)
        _T[p] = 46
        _text_num(_T, p + 1, abs(r), 7 | TN_ZEROS)
        _sign(0, d < 0 or r < 0)
        _put(p + 8, b" deg", 0, 4)
        return self._fg

    def _speed(self):
        """Horizontal speed in m/s and km/h."""
        b = self._out
        e = _clamp(_i16(b, _FB_VE), _V_MAX)
        b = _clamp(_i16(b, _FB_VN), _V_MAX)
        e = isqrt(e * e + b * b)
        p = _text_num(_T, 0, e, 6 | _D2)
        p = _put(p, b" m/s", 0, 4)
        p = _text_num(_T, p, (e * 36 + 50) // 100, 7 | _D1)
        _put(p, b" km/h", 0, 5)
        return self._fg

    def _motion(self, f):
        """Height (the fix's), position from the origin, heading, attitude (the frame's)."""
        b = self._out
        if f == _P_HEIGHT:
            p = _text_num(_T, 0, self._ff[_F_HEIGHT_DM], 9 | _D1 | TN_SIGNED)
            _put(p, b" m", 0, 2)
        elif f == _P_POS:
            _T[0] = 69  # E
            p = _text_num(_T, 1, _clamp(_i32(b, _FB_PE), _POS_MAX), 10 | _D2 | TN_SIGNED)
            _T[p] = 32
            _T[p + 1] = 78  # N
            p = _text_num(_T, p + 2, _clamp(_i32(b, _FB_PN), _POS_MAX), 10 | _D2 | TN_SIGNED)
            _put(p, b" m", 0, 2)
        elif f == _P_HEAD:
            f = _i16(b, _FB_YAW)
            p = _text_num(_T, 0, f + 36000 if f < 0 else f, 6 | _D2)
            _put(p, b" deg", 0, 4)
        else:
            _T[0] = 82  # R
            p = _text_num(_T, 1, _i16(b, _FB_ROLL), 8 | _D2 | TN_SIGNED)
            _T[p] = 32
            _T[p + 1] = 80  # P
            p = _text_num(_T, p + 2, _i16(b, _FB_PITCH), 7 | _D2 | TN_SIGNED)
            _put(p, b" deg", 0, 4)
        return self._fg

    def _health(self, f):
        """The horizontal 1-sigma; the health; its first cause and how many more. The colour
        of the health for these two."""
        x = self._ext
        if f == _P_SIGMA:
            # only while navigating: P is 0 before
            if x is not None and x[0] == 0xEB and self.state == _NAVIGATING:
                f = var_cm2(x, _X_PEE)
                x = var_cm2(x, _X_PEE + 4)
                if f >= 0 and x >= 0:
                    _put(_text_num(_T, 0, isqrt(f + x), 7 | _D2), b" m", 0, 2)
                    return self._fg
            _put(0, b"     --  ", 0, 9)
            return self._fg
        h = self._ef[_EF_HEALTH] if x is not None else self._ctl[_C_HEALTH]
        if f == _P_HEALTH:
            _put(0, HEALTHS, 9 * (h if 0 <= h <= 2 else 2), 9)
        else:
            self._cause(self._ef[_EF_CAUSES] if x is not None else self._ctl[_C_CAUSES])
        return self._fg if h == 0 else (self._warn if h == 1 else self._fault)

    def _cause(self, c):
        k = first_cause(c)
        if k < 0:
            _put(0, b"none        ", 0, 12)
        else:
            _put(0, CAUSES, 12 * k, 12)
        k = _bits(c) - 1
        if k > 0:
            _text_num(_T, 12, k if k < 9 else 9, 3)
            _T[13] = 43  # " +n"
        else:
            _put(12, b"   ", 0, 3)

    def _draw(self, f, colour):
        """Field f's command if its text or colour changed since it was drawn."""
        if _text_diff(self._shown, f * _WMAX, _T, WIDTH[f]) or self._col[f] != colour:
            self._col[f] = colour
            self._send(f, WIDTH[f], colour)

    def _end(self, ticks):
        """The batch's end (if it sent anything), after counting the OKs that came."""
        u = self._uart
        n = u.any()
        while n:
            # only what is there: readinto(buf) would wait timeout_char for the rest of buf
            n = u.readinto(self._rx, n if n < 8 else 8) or 0
            for i in range(n):
                if self._rx[i] == 75:  # the K of OK
                    self.oks += 1
            n = u.any()
        if self.oks > self.batches:
            self.oks = self.batches
        if self.oks and self.batches > self.oks:  # it has answered before, not this time
            self.missed += self.batches - self.oks
            self.oks = self.batches
            self.bad_until = ticks + _TICKS_S
        if self._batch:
            _C[0] = 13
            _C[1] = 10
            self._tx.write_n(_C, 2)
            self.batches += 1
            self._batch = 0
