"""Integer latitude/longitude (1e-7 deg) <-> local East-North-Up metres about an integer origin.

Why integers: a float32 latitude in radians resolves only ~0.6 m, so absolute positions never
live in floats. GNSS gives lat/lon as exact decimal digits; we keep them as ints in units of
1e-7 deg ("e7"), subtract the integer origin exactly, and only the small difference becomes
float32 metres.

The approximation: a second-order expansion of WGS-84 geodetic -> ECEF -> ENU (the tangent
plane at the origin, exactly what pymap3d.geodetic2enu computes) in the offsets dphi, dlambda,
dh. With n1 = dphi (M0 + h0) and e1 = dlambda (N0 + h0) cos(phi0), the first-order metres:
    E = e1 + e1 (dh / (N0+h0) - n1 M0 tan(phi0) / ((M0+h0)(N0+h0)))
    N = n1 + n1 (n1 M0' / (2 (M0+h0)^2) + dh / (M0+h0)) + e1^2 tan(phi0) / (2 (N0+h0))
    U = dh - (n1^2 / (2 (M0+h0)) + e1^2 / (2 (N0+h0)))
where M0, N0 are the meridian and prime-vertical radii at the origin and M0' = dM/dphi.
The neglected third-order terms stay below 0.25 d^3 / (R^2 cos^2 phi0) (measured against
pymap3d): 0.1 mm at 2 km, 2 cm at 10 km, 7 cm at 20 km at 34 deg latitude. float32 rounding
adds about 2e-7 d. The navigator re-anchors the origin long before either matters; origins
beyond +-89 deg latitude are refused (the series degrades as 1/cos^2).

Allocation: a longitude beyond +-107.37 deg in 1e-7 deg is a long int on the board
(MicroPython's small ints are 31-bit), so longitudes travel as (whole degrees, fraction in
1e-7 deg with the degrees' sign), as the NMEA parser delivers them (`split_e7`/`join_e7`
convert on a host); every difference formed here is a small int. `to_enu` is one native
kernel call (`geo_enu`) and allocates nothing; `set_origin`'s coefficients are one kernel
(`geo_coef`); `to_e7` (re-anchoring, not per fix) computes in Python.
"""

from array import array

from micropython import const

import f32
import kern
from fmath import cos, sin, sqrt

# WGS-84: a = 6378137 m (exact in float32), e^2 = f (2 - f) with 1/f = 298.257223563.
A_M = f32.f32(6378137)
E2 = f32.from_bits(0x3BDB5C88)  # 0.0066943799901413165
RAD_PER_E7 = f32.from_bits(0x30EFE050)  # pi / 1.8e9 = 1.7453292519943295e-09 rad per 1e-7 deg
MAX_LAT_E7 = 890000000
_E7 = const(10000000)

# Float32 coefficient buffer layout (`LocalFrame.coef`, set by set_origin); H0, INV_RN,
# INV_RM, SIN_LAT and COS_LAT also give the navigator its Earth model.
H0 = 0  # origin height, m
KE = 1  # east metres per 1e-7 deg of longitude
KN = 2  # north metres per 1e-7 deg of latitude
GE_N = 3  # M0 tan(phi0) / ((M0+h0)(N0+h0)), 1/m
INV_RN = 4  # 1/(N0+h0), 1/m
GN_N = 5  # M0' / (2 (M0+h0)^2)
INV_RM = 6  # 1/(M0+h0), 1/m
GN_E = 7  # tan(phi0) / (2 (N0+h0))
GU_N = 8  # 1 / (2 (M0+h0))
GU_E = 9  # 1 / (2 (N0+h0))
SIN_LAT = 10  # sin(phi0)
COS_LAT = 11  # cos(phi0)
NCOEF = 12


def split_into(out, i, x_e7):
    """out[i], out[i + 1] = whole degrees, 1e-7 deg fraction with the same sign, of an angle
    in 1e-7 deg (a small int: a latitude, or a longitude on a host)."""
    d = x_e7 // _E7 if x_e7 >= 0 else -((-x_e7) // _E7)
    out[i] = d
    out[i + 1] = x_e7 - d * _E7


def split_e7(x_e7):
    """(whole degrees, 1e-7 deg fraction with the same sign) of an angle in 1e-7 deg (hosts)."""
    out = [0, 0]
    split_into(out, 0, x_e7)
    return out[0], out[1]


def join_e7(deg, frac_e7):
    """The angle in 1e-7 deg (a long int on the board beyond +-107.37 deg: hosts only)."""
    return deg * _E7 + frac_e7


def _normalize(out, i, deg, frac):
    """out[i], out[i + 1] = the (degrees, fraction) form of deg + frac * 1e-7 (small ints):
    fraction in (-1e7, 1e7) with the degrees' sign, longitude in [-180, 180) deg."""
    while frac >= _E7:
        deg += 1
        frac -= _E7
    while frac <= -_E7:
        deg -= 1
        frac += _E7
    if deg > 0 and frac < 0:
        deg -= 1
        frac += _E7
    elif deg < 0 and frac > 0:
        deg += 1
        frac -= _E7
    if deg >= 180:
        deg -= 360
        if frac > 0:
            deg += 1
            frac -= _E7
    elif deg < -180 or (deg == -180 and frac < 0):
        deg += 360
        if frac < 0:
            deg -= 1
            frac += _E7
    out[i] = deg
    out[i + 1] = frac


def _enu_py(enu, coef, h, d_e7):
    """enu[0:3] (m) of the point d_e7[0], d_e7[1] (lat and lon offsets in 1e-7 deg, ints,
    |d| < 2**24) from the origin of the coefficients coef, at the height h[0] (m) above the
    ellipsoid; the reference of the native kernel `geo_enu`."""
    c = coef
    dh = h[0] - c[H0]
    n1 = f32.f32(d_e7[0]) * c[KN]
    e1 = f32.f32(d_e7[1]) * c[KE]
    ee = e1 * e1
    nn = n1 * n1
    enu[0] = e1 + e1 * (dh * c[INV_RN] - n1 * c[GE_N])
    enu[1] = n1 + (n1 * (n1 * c[GN_N] + dh * c[INV_RM]) + ee * c[GN_E])
    enu[2] = dh - (nn * c[GU_N] + ee * c[GU_E])


_enu = kern.pick("geo_enu", _enu_py)


def _coef_py(c, lat0_e7):
    """The coefficients of the origin at lat0_e7 (1e-7 deg) and the height c[H0] (m) into
    c (the layout above); the reference of the native kernel `geo_coef`."""
    phi0 = f32.f32(lat0_e7) * RAD_PER_E7
    s = sin(phi0)
    co = cos(phi0)
    w2 = 1.0 - E2 * s * s
    rn = A_M / sqrt(w2)
    rm = rn * (1.0 - E2) / w2
    drm = f32.f32(3) * rm * E2 * s * co / w2
    h0 = c[H0]
    rn_h = rn + h0
    rm_h = rm + h0
    tan = s / co
    c[KE] = RAD_PER_E7 * rn_h * co
    c[KN] = RAD_PER_E7 * rm_h
    c[GE_N] = rm * tan / (rm_h * rn_h)
    c[INV_RN] = 1.0 / rn_h
    c[GN_N] = 0.5 * drm / (rm_h * rm_h)
    c[INV_RM] = 1.0 / rm_h
    c[GN_E] = 0.5 * tan / rn_h
    c[GU_N] = 0.5 / rm_h
    c[GU_E] = 0.5 / rn_h
    c[SIN_LAT] = s
    c[COS_LAT] = co


_coef = kern.pick("geo_coef", _coef_py)


def _round_half_away(x):
    """Nearest int of a float32, halves away from zero."""
    if x >= 0.0:
        return int(x + 0.5)
    return -int(0.5 - x)


class LocalFrame:
    """An integer origin (lat0_e7, lon0_e7, h0) and the ENU conversions about it."""

    def __init__(self):
        self.lat0_e7 = 0
        self.lon0_deg = 0
        self.lon0_frac = 0
        self.valid = False
        self.coef = f32.zeros(NCOEF)
        self._d_e7 = array("i", bytes(8))  # an offset from the origin for the kernel

    def set_origin(self, lat0_e7, lon0_deg, lon0_frac, h0_m):
        """(Re-)anchor the frame at lat0_e7, the longitude lon0_deg + lon0_frac * 1e-7 deg and
        the height h0_m (a float); False (and the frame left unchanged) beyond +-89 deg."""
        if lat0_e7 > MAX_LAT_E7 or lat0_e7 < -MAX_LAT_E7:
            return False
        c = self.coef
        c[H0] = h0_m  # rounded to float32 by the buffer
        _coef(c, lat0_e7)
        self.lat0_e7 = lat0_e7
        self.lon0_deg = lon0_deg
        self.lon0_frac = lon0_frac
        self.valid = True
        return True

    def offset_to_enu(self, enu, dlat_e7, dlon_e7, h):
        """enu[0:3] (m) of the point dlat_e7, dlon_e7 (ints, |d| < 2**24) from the origin, at
        the height h[0] (a float32 buffer: m above the ellipsoid)."""
        self._d_e7[0] = dlat_e7
        self._d_e7[1] = dlon_e7
        _enu(enu, self.coef, h, self._d_e7)

    def to_enu(self, enu, lat_e7, lon_deg, lon_frac, h):
        """enu[0:3] (m) of an absolute integer position at the height h[0] (a float32 buffer);
        longitude wraps across +-180 deg. Allocates nothing."""
        # the arguments are reused as the offsets: this frame stays on the C stack
        lon_deg -= self.lon0_deg
        if lon_deg > 180:
            lon_deg -= 360
        elif lon_deg < -180:
            lon_deg += 360
        self._d_e7[0] = lat_e7 - self.lat0_e7
        self._d_e7[1] = lon_deg * _E7 + (lon_frac - self.lon0_frac)  # small near the origin
        _enu(enu, self.coef, h, self._d_e7)

    def to_e7(self, out, enu):
        """Inverse of to_enu: out[0] = lat (1e-7 deg), out[1], out[2] = the longitude as
        (degrees, 1e-7 deg fraction) in [-180, 180) deg; returns the height (m). Three
        fixed-point passes of the series converge to float32 resolution within 20 km (each
        pass gains a factor ~d/R)."""
        c = self.coef
        e = enu[0]
        n = enu[1]
        u = enu[2]
        e1 = e
        n1 = n
        dh = u
        for _ in range(3):
            ee = e1 * e1
            dh = u + (n1 * n1 * c[GU_N] + ee * c[GU_E])
            e1 = e / (1.0 + (dh * c[INV_RN] - n1 * c[GE_N]))
            n1 = (n - ee * c[GN_E]) / (1.0 + (n1 * c[GN_N] + dh * c[INV_RM]))
        out[0] = self.lat0_e7 + _round_half_away(n1 / c[KN])
        _normalize(out, 1, self.lon0_deg, self.lon0_frac + _round_half_away(e1 / c[KE]))
        return c[H0] + dh
