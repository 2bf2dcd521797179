"""NumPy float32 model of `firmware/lib/geo.py`: the tangent-plane series about an integer
origin, vectorised over points (one origin per call). Operation order mirrors the firmware."""

import numpy as np

from common import firmware_env
from host_emulator.model import fmath

firmware_env.install()
import geo as fw  # noqa: E402  (constants shared with the firmware, not retyped)

F32 = np.float32
# the longitude's wrap in 1e-7 deg (the firmware carries (degrees, fraction) pairs instead)
HALF_TURN_E7 = 1_800_000_000
FULL_TURN_E7 = 3_600_000_000


def coefficients(lat0_e7, h0_m):
    """The firmware's coefficient buffer for an origin (float32, indexed like `LocalFrame.coef`)."""
    c = np.zeros(fw.NCOEF, dtype=F32)
    phi0 = F32(lat0_e7) * fw.RAD_PER_E7
    s = fmath.sin(np.array([phi0]))[0]
    co = fmath.cos(np.array([phi0]))[0]
    one, half = F32(1.0), F32(0.5)
    w2 = one - fw.E2 * s * s
    rn = fw.A_M / np.sqrt(w2)
    rm = rn * (one - fw.E2) / w2
    drm = F32(3) * rm * fw.E2 * s * co / w2
    h0 = F32(h0_m)
    rn_h, rm_h = rn + h0, rm + h0
    tan = s / co
    c[fw.H0] = h0
    c[fw.KE] = fw.RAD_PER_E7 * rn_h * co
    c[fw.KN] = fw.RAD_PER_E7 * rm_h
    c[fw.GE_N] = rm * tan / (rm_h * rn_h)
    c[fw.INV_RN] = one / rn_h
    c[fw.GN_N] = half * drm / (rm_h * rm_h)
    c[fw.INV_RM] = one / rm_h
    c[fw.GN_E] = half * tan / rn_h
    c[fw.GU_N] = half / rm_h
    c[fw.GU_E] = half / rn_h
    c[fw.SIN_LAT] = s
    c[fw.COS_LAT] = co
    return c


def offset_to_enu(c, dlat_e7, dlon_e7, h_m):
    """ENU (..., 3) of integer offsets (|d| < 2**24) at heights h_m, given `coefficients`."""
    dh = np.asarray(h_m, dtype=F32) - c[fw.H0]
    n1 = np.asarray(dlat_e7).astype(F32) * c[fw.KN]
    e1 = np.asarray(dlon_e7).astype(F32) * c[fw.KE]
    ee, nn = e1 * e1, n1 * n1
    e = e1 + e1 * (dh * c[fw.INV_RN] - n1 * c[fw.GE_N])
    n = n1 + (n1 * (n1 * c[fw.GN_N] + dh * c[fw.INV_RM]) + ee * c[fw.GN_E])
    u = dh - (nn * c[fw.GU_N] + ee * c[fw.GU_E])
    return np.stack(np.broadcast_arrays(e, n, u), axis=-1)


def _round_half_away(x):
    return np.where(x >= 0, np.trunc(x + F32(0.5)), -np.trunc(F32(0.5) - x)).astype(np.int64)


def to_e7(c, lat0_e7, lon0_e7, enu):
    """(lat_e7, lon_e7, h_m) of ENU points: the firmware's three fixed-point passes."""
    enu = np.asarray(enu, dtype=F32)
    e, n, u = enu[..., 0], enu[..., 1], enu[..., 2]
    e1, n1 = e, n
    one = F32(1.0)
    for _ in range(3):
        ee = e1 * e1
        dh = u + (n1 * n1 * c[fw.GU_N] + ee * c[fw.GU_E])
        e1 = e / (one + (dh * c[fw.INV_RN] - n1 * c[fw.GE_N]))
        n1 = (n - ee * c[fw.GN_E]) / (one + (n1 * c[fw.GN_N] + dh * c[fw.INV_RM]))
    lat = lat0_e7 + _round_half_away(n1 / c[fw.KN])
    lon = lon0_e7 + _round_half_away(e1 / c[fw.KE])
    lon = np.where(lon >= HALF_TURN_E7, lon - FULL_TURN_E7, lon)
    lon = np.where(lon < -HALF_TURN_E7, lon + FULL_TURN_E7, lon)
    return lat, lon, c[fw.H0] + dh
