"""firmware/lib/geo.py: integer lat/lon <-> local ENU against pymap3d over 0-20 km, exact
integer round trips, the float32 model bit for bit, and the MicroPython VM."""

import array
import json

import numpy as np
import pymap3d
import pytest

import f32
import geo
from host_emulator.model import geo as model
from host_emulator.runtimes.mpy_unix import vm as mpvm

F32 = np.float32
R_EARTH_M = 6.371e6
RNG = np.random.default_rng(7)


def series_tolerance_m(d_m, lat0_deg):
    """What the second-order series implies: third-order terms below 0.25 d^3/(R^2 cos^2 lat0)
    (bounded here with a factor 2), plus float32 rounding of ~2e-7 d, plus 2 mm of rounding in
    the coefficients and the height."""
    c = np.cos(np.radians(lat0_deg))
    return 0.5 * d_m**3 / (R_EARTH_M**2 * c * c) + 3e-7 * d_m + 2e-3


def random_points(lat0_e7, lon0_e7, h0, n, max_d_m):
    """Integer points up to max_d_m from the origin in random directions, heights +-300 m."""
    d = RNG.uniform(0, max_d_m, n)
    az = RNG.uniform(0, 2 * np.pi, n)
    dh = RNG.uniform(-300, 300, n)
    lat, lon, h = pymap3d.enu2geodetic(
        d * np.sin(az), d * np.cos(az), h0 + dh, lat0_e7 / 1e7, lon0_e7 / 1e7, h0
    )
    return np.rint(lat * 1e7).astype(np.int64), np.rint(lon * 1e7).astype(np.int64), h


# (lat0_e7, lon0_e7, h0_m): equator, Xi'an (near the original board's test drives,
# docs/requirements.md), 60 N, 80 S
ORIGINS = [
    (0, 0, 0.0),
    (342600000, 1089400000, 400.0),
    (600000000, -1500000000, 50.0),
    (-800000000, 1200000000, 2500.0),
]


def frame(lat0_e7, lon0_e7, h0):
    f = geo.LocalFrame()
    assert f.set_origin(lat0_e7, *geo.split_e7(lon0_e7), F32(h0)) is True
    return f


def to_enu(f, enu, lat_e7, lon_e7, h):
    """LocalFrame.to_enu with the longitude in 1e-7 deg and the height a float."""
    hb = f32.zeros(1)
    hb[0] = h
    f.to_enu(enu, lat_e7, *geo.split_e7(lon_e7), hb)


def to_e7(f, enu):
    """LocalFrame.to_e7 as (lat_e7, lon_e7, h)."""
    out = array.array("i", bytes(12))
    h = f.to_e7(out, enu)
    return out[0], geo.join_e7(out[1], out[2]), h


@pytest.mark.parametrize("origin", ORIGINS, ids=lambda o: f"lat{o[0] // 10**7}")
def test_to_enu_matches_pymap3d_over_20_km(origin):
    lat0, lon0, h0 = origin
    f = frame(*origin)
    lat, lon, h = random_points(lat0, lon0, h0, 400, 20000.0)
    enu = f32.zeros(3)
    worst_ratio = 0.0
    for i in range(len(lat)):
        to_enu(f, enu, int(lat[i]), int(lon[i]), F32(h[i]))
        truth = np.array(
            pymap3d.geodetic2enu(
                lat[i] / 1e7, lon[i] / 1e7, float(F32(h[i])), lat0 / 1e7, lon0 / 1e7, float(F32(h0))
            )
        )
        err = np.linalg.norm(np.asarray(enu, float) - truth)
        tol = series_tolerance_m(np.linalg.norm(truth), lat0 / 1e7)
        worst_ratio = max(worst_ratio, err / tol)
    assert worst_ratio <= 1.0


def test_close_range_is_millimetre_exact():
    """Within the 2 km re-anchoring radius the conversion is as good as float32 allows."""
    lat0, lon0, h0 = ORIGINS[1]
    f = frame(*ORIGINS[1])
    lat, lon, h = random_points(lat0, lon0, h0, 300, 2000.0)
    enu = f32.zeros(3)
    for i in range(len(lat)):
        to_enu(f, enu, int(lat[i]), int(lon[i]), F32(h[i]))
        truth = pymap3d.geodetic2enu(
            lat[i] / 1e7, lon[i] / 1e7, float(F32(h[i])), lat0 / 1e7, lon0 / 1e7, h0
        )
        assert np.abs(np.asarray(enu, float) - truth).max() < 1e-3


@pytest.mark.parametrize("origin", ORIGINS, ids=lambda o: f"lat{o[0] // 10**7}")
def test_to_e7_inverts_to_enu(origin):
    f = frame(*origin)
    lat, lon, h = random_points(*origin, 300, 20000.0)
    enu = f32.zeros(3)
    for i in range(len(lat)):
        h32 = F32(h[i])
        to_enu(f, enu, int(lat[i]), int(lon[i]), h32)
        lat_back, lon_back, h_back = to_e7(f, enu)
        # One 1e-7 deg step is 1.1 cm: float32 metres at 20 km resolve 2 mm, so the integers
        # come back exactly or, at a rounding tie, one step off.
        assert abs(lat_back - lat[i]) <= 1 and abs(lon_back - lon[i]) <= 1
        assert abs(float(h_back) - float(h32)) < 0.01


def test_longitude_wraps_at_the_antimeridian():
    f = frame(-170000000, 1799990000, 0.0)  # 17 S, 179.999 E
    enu = f32.zeros(3)
    to_enu(f, enu, -170000000, -1799990000, F32(0.0))  # 179.999 W: 0.002 deg further east
    truth = pymap3d.geodetic2enu(-17.0, -179.999, 0.0, -17.0, 179.999, 0.0)
    assert np.abs(np.asarray(enu, float) - truth).max() < 1e-3
    assert to_e7(f, enu)[:2] == (-170000000, -1799990000)
    out = array.array("i", bytes(12))
    f.to_e7(out, enu)
    assert list(out) == [-170000000, -179, -9990000]  # (degrees, fraction) of the longitude


def test_longitude_pairs_normalise_like_the_integers():
    """to_e7's (degrees, fraction) longitude equals split_e7 of the integer sum, wrap included,
    for origins all round the globe and offsets up to the series' 2**24 limit."""
    rng = np.random.default_rng(3)
    out = array.array("i", bytes(12))
    edges = [-1800000000, 1799999999, 0, 1, -1, 1790000000, -1790000000]
    lon0s = np.concatenate([rng.integers(-1800000000, 1800000000, 20000), edges])
    for lon0 in lon0s.tolist():
        d, fr = geo.split_e7(lon0)
        assert (
            geo.join_e7(d, fr) == lon0 and abs(fr) < 10**7 and (fr == 0 or (fr > 0) == (lon0 > 0))
        )
        r = int(rng.integers(-(2**24), 2**24))
        geo._normalize(out, 1, d, fr + r)
        lon = lon0 + r
        lon = (
            lon - 3600000000
            if lon >= 1800000000
            else lon + 3600000000
            if lon < -1800000000
            else lon
        )
        assert (out[1], out[2]) == geo.split_e7(lon), (lon0, r)


def test_origin_beyond_89_degrees_is_refused():
    f = frame(*ORIGINS[1])
    assert f.set_origin(895000000, 0, 0, F32(0.0)) is False
    assert f.lat0_e7 == ORIGINS[1][0]  # unchanged
    assert f.set_origin(-890000000, 0, 0, F32(0.0)) is True


def test_bit_exact_against_the_model():
    for lat0, lon0, h0 in ORIGINS:
        f = frame(lat0, lon0, h0)
        c = model.coefficients(lat0, F32(h0))
        assert np.array_equal(np.asarray(f.coef).view(np.uint32), c.view(np.uint32))
        lat, lon, h = random_points(lat0, lon0, h0, 200, 25000.0)
        dlat, dlon = lat - lat0, lon - lon0
        h32 = h.astype(F32)
        want = model.offset_to_enu(c, dlat, dlon, h32)
        want_lat, want_lon, want_h = model.to_e7(c, lat0, lon0, want)
        enu = f32.zeros(3)
        hbuf = f32.zeros(1)
        for i in range(len(lat)):
            hbuf[0] = h32[i]
            f.offset_to_enu(enu, int(dlat[i]), int(dlon[i]), hbuf)
            assert np.array_equal(np.asarray(enu).view(np.uint32), want[i].view(np.uint32))
            lat_b, lon_b, hb = to_e7(f, enu)
            assert (lat_b, lon_b) == (want_lat[i], want_lon[i])
            assert np.float32(hb).view(np.uint32) == want_h[i].view(np.uint32)


MAX = geo.MAX_LAT_E7


def test_the_native_coefficients_equal_the_python_reference():
    """geo_coef (the origin's coefficients, native) against _coef_py, bit for bit, from pole
    limit to pole limit and from below sea level to aircraft heights."""
    import kern

    assert kern.NATIVE
    rng = np.random.default_rng(11)
    lats = [-MAX, -1, 0, 1, MAX, *rng.integers(-MAX, MAX, 3000).tolist()]
    heights = rng.uniform(-500.0, 12000.0, len(lats)).astype(F32)
    for lat0, h0 in zip(lats, heights, strict=True):
        a = f32.zeros(geo.NCOEF)
        b = f32.zeros(geo.NCOEF)
        a[geo.H0] = b[geo.H0] = h0
        geo._coef_py(a, int(lat0))
        kern.navk.geo_coef(b, int(lat0))
        assert np.array_equal(np.asarray(a).view(np.uint32), np.asarray(b).view(np.uint32)), lat0


@pytest.mark.parametrize("kernels", ["native", "python"])
def test_micropython_vm_agrees_and_allocates_only_float_boxes(kernels):
    """The double-precision VM computes the same series; its metres differ from the float32
    model by float32 rounding only (~2e-7 d: < 1 cm at 20 km). With the native kernels
    (geo_enu in float32) to_enu allocates nothing; the Python reference allocates 34 float
    boxes: 10 buffer reads (9 coefficients and the height), 2 int->float conversions and 22
    operations (dh 1, n1 1, e1 1, squares 2, east 5, north 8, up 4)."""
    lat0, lon0, h0 = ORIGINS[1]
    lat, lon, h = random_points(lat0, lon0, h0, 50, 20000.0)
    h32 = h.astype(F32)
    c = model.coefficients(lat0, F32(h0))
    want = model.offset_to_enu(c, lat - lat0, lon - lon0, h32)
    pairs = [geo.split_e7(int(v)) for v in lon]
    out = json.loads(
        mpvm.run(
            f"""
import json, geo, f32
fr = geo.LocalFrame()
fr.set_origin({lat0}, {geo.split_e7(lon0)[0]}, {geo.split_e7(lon0)[1]}, {float(F32(h0))!r})
lat = {[int(v) for v in lat]!r}
lon = {pairs!r}
hs = _buf({mpvm.hex_of(h32)!r})
hb = f32.zeros(1)
enu = f32.zeros(3)
res = []
for i in range(len(lat)):
    hb[0] = hs[i]
    fr.to_enu(enu, lat[i], lon[i][0], lon[i][1], hb)
    res.append(_hex(enu))
blocks = _blocks(lambda: fr.to_enu(enu, 342612345, 108, 9376544, hb))
print(json.dumps([res, blocks]))
""",
            kernels=kernels,
        )
        .strip()
        .splitlines()[-1]
    )
    got = np.array([mpvm.from_hex(r) for r in out[0]])
    assert np.abs(got - want).max() < 0.01
    assert out[1] == (0 if kernels == "native" else 34)
