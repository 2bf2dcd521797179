"""firmware/lib/frame.py: the 52-byte frame byte for byte against hand-built examples (the
expected bytes are the field table's encoding of values worked out by hand), the integer
conversions, and allocation-freedom of the integer paths in the MicroPython VM."""

import json
import struct

import numpy as np
import pytest

import f32
import frame
from common.proto import frame as frame_schema
from host_emulator.runtimes.mpy_unix import vm as mpvm

F32 = np.float32
CDEG_PER_RAD = F32(18000.0 / np.pi)


def buf(values):
    b = f32.zeros(len(values))
    b[:] = np.asarray(values, F32)
    return b


def expected_frame(counter, gyro, accel, flags, lat_e7, lon_e7, h_dm, state, ypr, vel, pos):
    """The frame of docs/requirements.md, output frame with these integer field values, built from
    the one field table (common/proto/frame.py, itself checked against docs/requirements.md)."""
    names = (
        *frame_schema.SENSOR_FIELDS, "pps", "gga", "gnss_valid", "lat_e7", "lon_e7",
        "height_dm", "nav_state", *frame_schema.NAV_FLOAT_FIELDS,
    )  # fmt: skip
    values = (*gyro, *accel, *flags, lat_e7, lon_e7, h_dm, state, *ypr, *vel, *pos)
    return frame_schema.encode(counter, **dict(zip(names, values, strict=True)))


def packed(
    counter=7,
    gyro=(1312, -1312, 0),
    accel=(0, 512, 1024),
    pps=True,
    gga=False,
    valid=True,
    lat=(34, 2600000),
    lon=(108, 9400000),
    h_dm=4005,
    state=2,
    ypr_deg=(30.0, -5.0, 1.25),
    v=(1.234, -0.006, 0.0),
    p=(1234.567, -0.004, 12.34),
    gyro_lsb_x10=1312,
    accel_lsb=1024,
):
    out = bytearray(frame.FRAME_LEN)
    frame.pack(
        out,
        counter,
        list(gyro),
        list(accel),
        gyro_lsb_x10,
        accel_lsb,
        pps,
        gga,
        valid,
        list(lat),
        list(lon),
        h_dm,
        state,
        CDEG_PER_RAD,
        buf(np.radians(ypr_deg)),
        buf(v),
        buf(p),
    )
    return bytes(out)


def test_hand_built_example():
    # gyro: 1312 counts at 131.2 LSB/(deg/s) = 10 deg/s -> 1310.7 -> 1311 at 131.07
    # accel: 512 counts at 1024 LSB/g = 0.5 g -> 8191.5 -> 8192 (half away); 1 g -> 16383
    # lat 34.26 deg, lon 108.94 deg (a long int on the board, packed from its parts)
    # yaw/pitch/roll 30, -5, 1.25 deg -> 3000, -500, 125
    # v 1.234, -0.006, 0 m/s -> 123, -1, 0
    # p 1234.567, -0.004 m -> 123457, 0 (cm) ; 12.34 m -> 123 (dm)
    want = expected_frame(
        7,
        (1311, -1311, 0),
        (0, 8192, 16383),
        (1, 0, 1),
        342600000,
        1089400000,
        4005,
        2,
        (3000, -500, 125),
        (123, -1, 0),
        (123457, 0, 123),
    )
    got = packed()
    assert len(got) == 52 and got[:2] == b"\xeb\x90"
    assert got == want


def test_southern_western_fix_and_negative_values():
    got = packed(
        counter=300,
        gyro=(-32768, 32767, -1),
        accel=(-2048, 2047, -1),
        pps=False,
        gga=True,
        valid=False,
        lat=(-33, -8688000),
        lon=(-151, -2093000),
        h_dm=-120,
        state=1,
        ypr_deg=(-179.99, 89.5, -0.004),
        v=(-300.0, 327.66, -0.0049),
        p=(-21474.8, 5.0e6, -3276.7),
    )
    # gyro -32768 counts at 131.2 = -249.76 deg/s -> -32735.53 -> -32736 at 131.07;
    #   32767 -> 32734.53 -> 32735; -1 -> -0.999 -> -1
    # accel -2048 at 1024/g = -2 g -> -32766 fits: -2048 * 16383 / 1024 = -32766;
    #   2047 -> 32750.0009 -> 32750 ; -1 -> -15.999 -> -16
    # p N 5e6 m = 5e8 cm fits int32 ; U -3276.7 m -> -32767 dm
    want = expected_frame(
        300 & 0xFF,
        (-32736, 32735, -1),
        (-32766, 32750, -16),
        (0, 1, 0),
        -338688000,
        -1512093000,
        -120,
        1,
        (-17999, 8950, 0),
        (-30000, 32766, 0),
        (-2147480, 500000000, -32767),
    )
    assert got == want


def test_counter_wraps_and_checksum_is_the_byte_sum():
    for c in (0, 255, 256, 511):
        f = packed(counter=c)
        assert f[2] == c & 0xFF
        assert f[51] == sum(f[2:51]) & 0xFF


@pytest.mark.parametrize(
    "lsb_x10, dps", [(2624, 125), (1312, 250), (656, 500), (328, 1000), (164, 2000)]
)
def test_gyro_scale_for_every_range(lsb_x10, dps):
    """Counts at any range become 131.07 per deg/s; beyond 250 deg/s the frame clamps."""
    for counts in (-32768, -12345, -1, 0, 1, 999, 32767):
        rate = counts / (lsb_x10 / 10)
        want = int(np.clip(np.sign(rate) * np.floor(abs(rate) * 131.07 + 0.5), -32768, 32767))
        assert frame.gyro_to_frame(counts, lsb_x10) == want, (counts, lsb_x10)


@pytest.mark.parametrize("lsb, g", [(1024, 2), (512, 4), (256, 8), (128, 16)])
def test_accel_scale_for_every_range(lsb, g):
    for counts in (-2048, -1000, -1, 0, 1, 777, 2047):
        acc = counts / lsb
        want = int(np.clip(np.sign(acc) * np.floor(abs(acc) * 16383 + 0.5), -32768, 32767))
        assert frame.accel_to_frame(counts, lsb) == want


def test_angles_from_parts_equal_the_int32():
    rng = np.random.default_rng(5)
    cases = [
        (180, 0),
        (-180, 0),
        (179, 9999999),
        (-179, -9999999),
        (0, 0),
        (0, -1),
        (0, 1),
        (107, 3741823),
        (107, 3741824),
        (-90, 0),
        (90, 0),
    ]
    cases += [
        (int(d), int(np.sign(d) or 1) * int(f))
        for d, f in zip(rng.integers(-179, 180, 500), rng.integers(0, 10**7, 500), strict=True)
    ]
    out = bytearray(4)
    for deg, frac in cases:
        frame.put_e7(out, 0, deg, frac)
        assert bytes(out) == struct.pack("<i", deg * 10**7 + frac), (deg, frac)


def test_integer_paths_allocate_nothing_on_micropython():
    """Gyro/accel conversion, angle and int16/int32 packing, header and checksum run under
    heap_lock with a longitude beyond 107.37 deg (a long int if it were ever formed)."""
    out = json.loads(
        mpvm.run("""
import json, frame
b = bytearray(52)
def ints():
    frame.put_i16(b, 3, frame.gyro_to_frame(32767, 1312))
    frame.put_i16(b, 9, frame.accel_to_frame(-2048, 1024))
    frame.put_e7(b, 18, 34, 2600000)
    frame.put_e7(b, 22, 108, 9400000)
    frame.put_e7(b, 22, -179, -9999999)
    frame.put_i32(b, 41, -1073741823)
    frame.finish(b, 300)
print(json.dumps([_locked(ints), list(b)]))
""")
        .strip()
        .splitlines()[-1]
    )
    assert out[0] is True
    assert bytes(out[1][22:26]) == struct.pack("<i", -1799999999)
    assert out[1][2] == 300 & 0xFF and out[1][51] == sum(out[1][2:51]) & 0xFF


def test_the_vm_packs_the_same_frame():
    f_desk = packed()
    got = mpvm.run_json(f"""
import json, frame, f32
def buf(v):
    b = f32.zeros(len(v))
    for i in range(len(v)):
        b[i] = v[i]
    return b
out = bytearray(52)
frame.pack(out, 7, [1312, -1312, 0], [0, 512, 1024], 1312, 1024, True, False, True,
           [34, 2600000], [108, 9400000], 4005, 2, {float(CDEG_PER_RAD)!r},
           _buf({mpvm.hex_of(np.radians([30.0, -5.0, 1.25]))!r}),
           _buf({mpvm.hex_of([1.234, -0.006, 0.0])!r}),
           _buf({mpvm.hex_of([1234.567, -0.004, 12.34])!r}))
print(json.dumps(list(out)))
""")
    assert bytes(got) == f_desk


def test_the_byte_offsets_are_the_contract_tables():
    """frame.py's _FB_* (which frame.c, the app and the status page take, generated) start
    the fields of the host's own table of the frame (common/proto/frame.py)."""
    first = {
        "_FB_COUNTER": "counter",
        "_FB_GYRO": "gyro_x",
        "_FB_ACCEL": "accel_x",
        "_FB_PPS": "pps",
        "_FB_GGA": "gga",
        "_FB_VALID": "gnss_valid",
        "_FB_LAT": "lat_e7",
        "_FB_LON": "lon_e7",
        "_FB_HEIGHT": "height_dm",
        "_FB_STATE": "nav_state",
        "_FB_YAW": "yaw_cdeg",
        "_FB_PITCH": "pitch_cdeg",
        "_FB_ROLL": "roll_cdeg",
        "_FB_VE": "vel_e_cm_s",
        "_FB_VN": "vel_n_cm_s",
        "_FB_VU": "vel_u_cm_s",
        "_FB_PE": "pos_e_cm",
        "_FB_PN": "pos_n_cm",
        "_FB_PU": "pos_u_dm",
        "_FB_SUM": "checksum",
    }
    assert {n for n in vars(frame) if n.startswith("_FB_")} == set(first)
    for name, field in first.items():
        assert getattr(frame, name) == frame_schema.OFFSETS[field], name
    assert frame.FRAME_LEN == frame_schema.FRAME_LEN
