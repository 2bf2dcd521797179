"""The NMEA scan in Python: the reference of navk's `nmea_scan` (firmware/native/nmea.c).

`scan(s, lb, buf, n)` consumes the bytes buf[s[NS_I]:n] into the line buffer lb (the line at
lb[0:MAXLEN], then the table of where each field starts, field i at lb[_FS + i]) and stops at
the first thing to report (gnss.py's _NR_*): a line's end, with its checks (printable ASCII,
the '*' and two hex digits, the XOR checksum) and, for GGA, RMC, VTG and GSA, its fields
parsed into the int buffer s (_NS_*: gnss.py lays it out, as its docstring describes the
syntax and units); a collision, a malformed or overlong line; 0 once all n bytes are
consumed. The framing state stays in s between calls. Module functions over the buffers
only, with the same operation order as nmea.c, so that both give the same result on every
log and on damaged input (tests/drivers/test_gnss.py). gnss.py picks the native kernel where
navk is loaded (kern.py) and this otherwise.
"""

from micropython import const

from drivers.gnss import _utc_ms  # the time field's syntax, which gnss.py needs on its own too

# ---- gnss.py's consts used here: `python -m common.native.layout` writes them ----
_MAXLEN = const(100)
_MAXF = const(40)
_GGA = const(1)
_RMC = const(2)
_VTG = const(3)
_GSA = const(4)
_NS_I = const(0)
_NS_K = const(1)
_NS_X = const(2)
_NS_STAR = const(3)
_NS_NF = const(4)
_NS_LEN = const(5)
_NS_TALKER = const(6)
_NS_UTC = const(7)
_NS_POS = const(8)
_NS_LAT = const(9)
_NS_DEG = const(10)
_NS_FRAC = const(11)
_NS_A = const(12)
_NS_B = const(13)
_NS_C = const(14)
_NS_D = const(15)
_NS_E = const(16)
_NS_F = const(17)
_FS = const(100)
_NR_IGNORED = const(5)
_NR_BAD_FIELD = const(6)
_NR_NO_CSUM = const(7)
_NR_MALFORMED = const(8)
_NR_BAD_CSUM = const(9)
_NR_OVERLONG = const(10)
_NR_COLLIDED = const(11)
_EMPTY = const(-0x3FFFFFFE)
_BAD = const(-0x3FFFFFFF)
_CAP = const(100000000)
_FMT_GGA = const(0x474741)
_FMT_RMC = const(0x524D43)
_FMT_VTG = const(0x565447)
_FMT_GSA = const(0x475341)
# ---- end of gnss.py's consts ----


def _num(line, a, b, k):
    """line[a:b] as a decimal number times 10**k, rounded half away from zero (only the first
    dropped digit decides: a tie has only zeros after it); _EMPTY if a == b; _BAD on a syntax
    error or a magnitude of 1e9 units or more."""
    if a >= b:
        return _EMPTY
    c = line[a]
    neg = c == 45  # '-'
    if neg or c == 43:  # '+'
        a += 1
    v = 0
    nd = 0  # digits seen
    dec = -1  # decimals taken into v; -1 before the point
    up = 0
    while a < b:
        c = line[a] - 48
        a += 1
        if 0 <= c <= 9:
            nd += 1
            if dec < k:
                if v >= _CAP:
                    return _BAD
                v = v * 10 + c
                if dec >= 0:
                    dec += 1
            elif dec == k:
                up = c >= 5
                dec += 1
        elif c == -2 and dec < 0:  # '.'
            dec = 0
        else:
            return _BAD
    if nd == 0:
        return _BAD
    if dec < 0:
        dec = 0
    while dec < k:
        if v >= _CAP:
            return _BAD
        v *= 10
        dec += 1
    if up:
        v += 1
    return -v if neg else v


def _nn(v):
    """A _num() result that may not be negative: -1 if empty, _BAD if negative."""
    if v == _EMPTY:
        return -1
    if v < 0:
        return _BAD
    return v


def _mins(line, a, b):
    """Index of the first minute digit of a ddmm.mmm field line[a:b], or -1 if the integer
    part does not have 3 to 5 digits."""
    p = a
    while p < b and line[p] != 46:
        p += 1
    p -= 2
    if p <= a or p - a > 3:
        return -1
    return p


def _uint(line, a, p):
    """The digits line[a:p] as an int (at most 9 of them); -1 on a non-digit."""
    v = 0
    while a < p:
        c = line[a] - 48
        if c < 0 or c > 9:
            return -1
        v = v * 10 + c
        a += 1
    return v


def _min_e7(line, p, b):
    """round(minutes * 1e7 / 60) of the minutes line[p:b] ("mm", "mm." or "mm.ddd..."), i.e.
    1e-7 deg in 0..1e7; -1 on a syntax error. Only 7 decimals can matter (module doc)."""
    v = 0
    i = p
    n = 0  # decimals taken
    while i < b:
        c = line[i] - 48
        if i == p + 2:
            if c != -2:
                return -1
        elif 0 <= c <= 9:
            if i < p + 2:
                v = v * 10 + c
            elif n < 7:
                v = v * 10 + c
                n += 1
        else:
            return -1
        i += 1
    if i < p + 2:
        return -1
    while n < 7:
        v *= 10
        n += 1
    return (v + 30) // 60


def _char(line, a, b):
    """A one-letter field as its byte code, 0 if empty, -1 if longer."""
    if a >= b:
        return 0
    if b - a > 1:
        return -1
    return line[a]


def _hex(c):
    """Value of a hex digit character (either case), -1 otherwise."""
    if 48 <= c <= 57:
        return c - 48
    if 65 <= c <= 70:
        return c - 55
    if 97 <= c <= 102:
        return c - 87
    return -1


def _pos(s, lb, i):
    """Fields i..i+3 (lat, N/S, lon, E/W) into s[_NS_LAT.._NS_FRAC]: 1 valid, 0 empty or
    out of range, -1 syntax error."""
    a = lb[_FS + i]
    b = lb[_FS + i + 1] - 1
    c = lb[_FS + i + 2] - 1
    d = lb[_FS + i + 3] - 1
    e = lb[_FS + i + 4] - 1
    if a == b and c + 1 == d:
        return 0  # both empty (the hemisphere letters may be there or not)
    p = _mins(lb, a, b)
    if p < 0:
        return -1
    deg = _uint(lb, a, p)
    fr = _min_e7(lb, p, b)
    if deg < 0 or fr < 0:
        return -1
    ok = 1
    if deg > 90 or fr > 10000000:
        ok = 0
        deg = 0
    lat = deg * 10000000 + fr  # <= 9.1e8
    p = _mins(lb, c + 1, d)
    if p < 0:
        return -1
    deg = _uint(lb, c + 1, p)
    fr = _min_e7(lb, p, d)
    if deg < 0 or fr < 0:
        return -1
    if fr > 10000000:  # more than 60 minutes
        ok = 0
    elif fr == 10000000:  # 59.99999995.. or 60 minutes round up to the next degree
        deg += 1
        fr = 0
    if lat > 900000000 or deg > 180 or deg == 180 and fr > 0:
        ok = 0
    ns = _char(lb, b + 1, c)
    ew = _char(lb, d + 1, e)
    if ns == 83:  # 'S'
        lat = -lat
    elif ns != 78:  # not 'N'
        ok = 0
    if ew == 87:  # 'W'
        deg = -deg
        fr = -fr
    elif ew != 69:  # not 'E'
        ok = 0
    s[_NS_LAT] = lat
    s[_NS_DEG] = deg
    s[_NS_FRAC] = fr
    return ok


def _field(lb, i, k):
    """Field i as a number times 10**k (_num)."""
    return _num(lb, lb[_FS + i], lb[_FS + i + 1] - 1, k)


def _knots_mm_s(kn):
    """1e-4 kn -> mm/s: * 1852e3 / 3600e4 = * 463 / 9000, in two parts."""
    return kn // 9000 * 463 + (kn % 9000 * 463 + 4500) // 9000


def _gga(s, lb, nf):
    # GGA,time,lat,N,lon,E,quality,nsat,hdop,alt[,M,sep,M,age,station]: up to alt needed
    if nf < 10:
        return False
    utc = _utc_ms(lb, lb[_FS + 1], lb[_FS + 2] - 1)
    pos = _pos(s, lb, 2)
    q = _nn(_field(lb, 6, 0))
    ns = _nn(_field(lb, 7, 0))
    hd = _nn(_field(lb, 8, 2))
    alt = _field(lb, 9, 3)
    sep = _EMPTY
    if nf >= 12:
        sep = _field(lb, 11, 3)
    if utc == _BAD or pos < 0 or q == _BAD or ns == _BAD or hd == _BAD:
        return False
    if alt == _BAD or sep == _BAD:
        return False
    s[_NS_UTC] = utc
    s[_NS_POS] = pos
    s[_NS_A] = q
    s[_NS_B] = ns
    s[_NS_C] = hd
    s[_NS_D] = alt
    s[_NS_E] = sep
    return True


def _rmc(s, lb, nf):
    # RMC,time,status,lat,N,lon,E,knots,course,ddmmyy[,magvar,E[,mode[,navstatus]]]
    if nf < 10:
        return False
    utc = _utc_ms(lb, lb[_FS + 1], lb[_FS + 2] - 1)
    st = _char(lb, lb[_FS + 2], lb[_FS + 3] - 1)
    pos = _pos(s, lb, 3)
    kn = _nn(_field(lb, 7, 4))
    crs = _nn(_field(lb, 8, 2))
    a = lb[_FS + 9]
    b = lb[_FS + 10] - 1
    date = -1
    if b - a == 6:
        date = _uint(lb, a, b)
        if date < 0:
            return False
        d = date // 10000
        m = date // 100 % 100
        date = (date % 100) * 10000 + m * 100 + d
        if d < 1 or d > 31 or m < 1 or m > 12:
            date = -1
    elif a != b:
        return False
    mode = 0
    if nf > 12:
        mode = _char(lb, lb[_FS + 12], lb[_FS + 13] - 1)
    if utc == _BAD or st < 0 or pos < 0 or mode < 0:
        return False
    if kn == _BAD or crs == _BAD:
        return False
    s[_NS_UTC] = utc
    s[_NS_POS] = pos
    s[_NS_A] = st
    s[_NS_B] = _knots_mm_s(kn) if kn >= 0 else -1
    s[_NS_C] = crs
    s[_NS_D] = date
    s[_NS_E] = mode
    return True


def _vtg(s, lb, nf):
    # VTG,course,T,course_mag,M,knots,N,kmh,K[,mode]
    if nf < 9:
        return False
    crs = _nn(_field(lb, 1, 2))
    kn = _nn(_field(lb, 5, 4))
    kmh = _nn(_field(lb, 7, 4))
    mode = 0
    if nf > 9:
        mode = _char(lb, lb[_FS + 9], lb[_FS + 10] - 1)
    if crs == _BAD or kn == _BAD or kmh == _BAD or mode < 0:
        return False
    spd = -1
    if kmh >= 0:  # 1e-4 km/h -> mm/s: / 36
        spd = (kmh + 18) // 36
    elif kn >= 0:
        spd = _knots_mm_s(kn)
    s[_NS_B] = spd
    s[_NS_C] = crs
    s[_NS_E] = mode
    return True


def _gsa(s, lb, nf):
    # GSA,mode,fix,12 x sv,pdop,hdop,vdop[,system]
    if nf < 18:
        return False
    mode = _char(lb, lb[_FS + 1], lb[_FS + 2] - 1)
    fix = _nn(_field(lb, 2, 0))
    pd = _nn(_field(lb, 15, 2))
    hd = _nn(_field(lb, 16, 2))
    vd = _nn(_field(lb, 17, 2))
    if mode < 0 or fix == _BAD or pd == _BAD or hd == _BAD or vd == _BAD:
        return False
    nsv = 0
    for i in range(_FS + 3, _FS + 15):
        if lb[i + 1] - 1 > lb[i]:
            nsv += 1
    s[_NS_A] = fix
    s[_NS_B] = nsv
    s[_NS_C] = hd
    s[_NS_D] = pd
    s[_NS_E] = mode
    s[_NS_F] = vd
    return True


def _line(s, lb, k, x, star, nf):
    """A line lb[0:k] ended by CR/LF: check, classify, parse; what the scan reports."""
    s[_NS_LEN] = k
    if star < 0:
        return _NR_NO_CSUM
    if k != star + 3:
        return _NR_MALFORMED
    h = _hex(lb[star + 1])
    lo = _hex(lb[star + 2])
    if h < 0 or lo < 0:
        return _NR_MALFORMED
    if h * 16 + lo != x:
        return _NR_BAD_CSUM
    lb[_FS + nf] = star + 1
    kind = 0
    if lb[_FS + 1] == 6:  # a five-letter address
        t = (lb[0] << 8) | lb[1]
        # any talker (GP GN GL GA GB BD GQ QZ IN ...): two capitals, P (proprietary) excepted
        if 65 <= lb[0] <= 90 and lb[0] != 80 and 65 <= lb[1] <= 90:
            f = (lb[2] << 16) | (lb[3] << 8) | lb[4]
            if f == _FMT_GGA:
                kind = _GGA
            elif f == _FMT_RMC:
                kind = _RMC
            elif f == _FMT_VTG:
                kind = _VTG
            elif f == _FMT_GSA:
                kind = _GSA
            s[_NS_TALKER] = t
    if kind == 0:
        return _NR_IGNORED
    if nf >= _MAXF:
        ok = False
    elif kind == _GGA:
        ok = _gga(s, lb, nf)
    elif kind == _RMC:
        ok = _rmc(s, lb, nf)
    elif kind == _VTG:
        ok = _vtg(s, lb, nf)
    else:
        ok = _gsa(s, lb, nf)
    return kind if ok else _NR_BAD_FIELD


def scan(s, lb, buf, n):
    """Consume buf[s[_NS_I]:n] up to the first thing to report (a line's end: _line's
    result; a collision, a malformed or overlong line); 0 once all n bytes are consumed. The
    framing state stays in s between calls."""
    k = s[_NS_K]
    x = s[_NS_X]
    star = s[_NS_STAR]
    nf = s[_NS_NF]
    r = 0
    i = s[_NS_I]
    while i < n and r == 0:
        b = buf[i]
        i += 1
        if b == 36:  # '$': a new sentence, whatever came before
            if k >= 0:
                r = _NR_COLLIDED
            k = 0
            x = 0
            star = -1
            nf = 1
            lb[_FS] = 0
        elif k < 0:
            pass  # outside a sentence: skip
        elif b == 13 or b == 10:
            r = _line(s, lb, k, x, star, nf)
            k = -1
        elif b < 32 or b > 126:
            r = _NR_MALFORMED
            k = -1
        elif k >= _MAXLEN:
            r = _NR_OVERLONG
            k = -1
        else:
            lb[k] = b
            if star < 0:
                if b == 42:  # '*'
                    star = k
                else:
                    x ^= b
                    if b == 44 and nf < _MAXF:  # ','
                        lb[_FS + nf] = k + 1
                        nf += 1
            k += 1
    s[_NS_I] = i
    s[_NS_K] = k
    s[_NS_X] = x
    s[_NS_STAR] = star
    s[_NS_NF] = nf
    return r
