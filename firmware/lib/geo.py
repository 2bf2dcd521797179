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

Allocation: the integer differences are exact small ints; on the board a longitude beyond
+-107.37 deg is a long int (MicroPython's small ints are 31-bit), so the subtraction then
allocates a few words per fix. Conversions are per GNSS fix, not per tick.
"""

import f32
from fmath import cos, sin, sqrt

# WGS-84: a = 6378137 m (exact in float32), e^2 = f (2 - f) with 1/f = 298.257223563.
A_M = f32.f32(6378137)
E2 = f32.from_bits(0x3BDB5C88)  # 0.0066943799901413165
RAD_PER_E7 = f32.from_bits(0x30EFE050)  # pi / 1.8e9 = 1.7453292519943295e-09 rad per 1e-7 deg
MAX_LAT_E7 = 890000000
HALF_TURN_E7 = 1800000000
FULL_TURN_E7 = 3600000000

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


def _round_half_away(x):
    """Nearest int of a float32, halves away from zero."""
    if x >= 0.0:
        return int(x + 0.5)
    return -int(0.5 - x)


class LocalFrame:
    """An integer origin (lat0_e7, lon0_e7, h0) and the ENU conversions about it."""

    def __init__(self):
        self.lat0_e7 = 0
        self.lon0_e7 = 0
        self.lon0_deg = 0
        self.lon0_frac = 0
        self.valid = False
        self.coef = f32.zeros(NCOEF)

    def set_origin(self, lat0_e7, lon0_e7, h0_m):
        """(Re-)anchor the frame; False (and the frame left unchanged) beyond +-89 deg."""
        if lat0_e7 > MAX_LAT_E7 or lat0_e7 < -MAX_LAT_E7:
            return False
        c = self.coef
        phi0 = f32.f32(lat0_e7) * RAD_PER_E7
        s = sin(phi0)
        co = cos(phi0)
        w2 = 1.0 - E2 * s * s
        rn = A_M / sqrt(w2)
        rm = rn * (1.0 - E2) / w2
        drm = f32.f32(3) * rm * E2 * s * co / w2
        h0 = f32.f32(h0_m)
        rn_h = rn + h0
        rm_h = rm + h0
        tan = s / co
        c[H0] = h0
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
        self.lat0_e7 = lat0_e7
        self.lon0_e7 = lon0_e7
        # the longitude as (degrees, 1e-7 deg fraction): small ints for allocation-free packing
        d = lon0_e7 // 10000000 if lon0_e7 >= 0 else -((-lon0_e7) // 10000000)
        self.lon0_deg = d
        self.lon0_frac = lon0_e7 - d * 10000000
        self.valid = True
        return True

    def offset_to_enu(self, enu, dlat_e7, dlon_e7, h_m):
        """enu[0:3] (m) of the point dlat_e7, dlon_e7 (ints, |d| < 2**24) from the origin, at
        height h_m above the ellipsoid."""
        c = self.coef
        dh = h_m - c[H0]
        n1 = f32.f32(dlat_e7) * c[KN]
        e1 = f32.f32(dlon_e7) * c[KE]
        ee = e1 * e1
        nn = n1 * n1
        enu[0] = e1 + e1 * (dh * c[INV_RN] - n1 * c[GE_N])
        enu[1] = n1 + (n1 * (n1 * c[GN_N] + dh * c[INV_RM]) + ee * c[GN_E])
        enu[2] = dh - (nn * c[GU_N] + ee * c[GU_E])

    def to_enu(self, enu, lat_e7, lon_e7, h_m):
        """enu[0:3] (m) of an absolute integer position; longitude wraps across +-180 deg."""
        dlon = lon_e7 - self.lon0_e7
        if dlon > HALF_TURN_E7:
            dlon -= FULL_TURN_E7
        elif dlon < -HALF_TURN_E7:
            dlon += FULL_TURN_E7
        self.offset_to_enu(enu, lat_e7 - self.lat0_e7, dlon, h_m)

    def to_e7(self, out_e7, enu):
        """Inverse of to_enu: out_e7[0], out_e7[1] = lat, lon (ints, 1e-7 deg, longitude in
        [-180, 180) deg); returns the height (m). Three fixed-point passes of the series
        converge to float32 resolution within 20 km (each pass gains a factor ~d/R)."""
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
        out_e7[0] = self.lat0_e7 + _round_half_away(n1 / c[KN])
        lon = self.lon0_e7 + _round_half_away(e1 / c[KE])
        if lon >= HALF_TURN_E7:
            lon -= FULL_TURN_E7
        elif lon < -HALF_TURN_E7:
            lon += FULL_TURN_E7
        out_e7[1] = lon
        return c[H0] + dh
