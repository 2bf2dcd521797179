"""firmware/lib/config.py: round trip, corrupt, truncated, missing and invalid files fall back
to defaults with the reason, unknown records are skipped, the navigator configuration follows,
and the board (MicroPython VM) reads a file written on the desktop to the same values."""

import json
import struct
from binascii import crc32

import numpy as np
import pytest

import config
import navcfg
from host_emulator.runtimes.mpy_unix import vm as mpvm


def custom():
    c = config.BoardConfig()
    c.set("profile", 1)
    c.gyro_range_dps = 500
    c.accel_range_g = 4
    c.output_baud = 921600
    c.ext_every_ticks = 0
    c.raw_record = 1
    c.lever_b_m = [0.1, 0.5, 1.25]
    c.gyro_bias0 = [0.001, -0.002, 0.0005]
    c.gyro_matrix = [1.003, 0.001, 0.0, -0.001, 0.998, 0.0005, 0.0, 0.0, 1.0]
    c.gnss_latency_s = 0.08
    c.gnss_hdop_max = 2.5
    return c


def f32list(x):
    return list(np.asarray(x, np.float32))


def test_round_trip_keeps_every_value_as_float32(tmp_path):
    path = tmp_path / "ins.cfg"
    config.save(str(path), custom())
    cfg, status, msg = config.load(str(path))
    assert status == config.OK and "loaded" in msg
    assert (cfg.profile, cfg.gyro_range_dps, cfg.accel_range_g) == (1, 500, 4)
    assert (cfg.output_baud, cfg.ext_every_ticks, cfg.raw_record) == (921600, 0, 1)
    assert cfg.lever_b_m == f32list([0.1, 0.5, 1.25])
    assert cfg.gyro_matrix == f32list(custom().gyro_matrix)
    assert cfg.accel_matrix is None  # identity stays identity
    assert cfg.gnss_latency_s == np.float32(0.08)


def test_navigator_configuration_follows(tmp_path):
    nav = custom().nav_config()
    assert nav.profile == "handheld" and nav.zupt and not nav.nhc
    hand = navcfg.NavConfig("handheld")
    assert (nav.still_gyro, nav.still_accel) == (hand.still_gyro, hand.still_accel)
    assert list(nav.lever_b_m) == f32list([0.1, 0.5, 1.25])
    assert nav.gnss_hdop_max == np.float32(2.5)
    # +-500 deg/s: 65.6 LSB per deg/s; +-4 g: 512 LSB per g
    assert abs(float(nav.gyro_counts_per_rad_s) - 65.6 * 180 / np.pi) < 1e-3
    assert abs(float(nav.accel_counts_per_m_s2) - 512 / 9.80665) < 1e-4


def test_the_profile_brings_its_own_defaults_and_keeps_what_the_user_chose():
    """A hand is never as still as a parked car: the handheld profile's standstill thresholds
    are its own. Switching the profile moves the settings still at the old profile's default
    (a file written for the car keeps the car's thresholds explicitly) and keeps the others,
    in any order of the changes; a file without those records takes its profile's."""
    car, hand = navcfg.NavConfig("car"), navcfg.NavConfig("handheld")
    assert hand.still_gyro > 5 * car.still_gyro and hand.still_accel > 5 * car.still_accel
    c = config.BoardConfig()
    assert (c.still_gyro, c.still_accel) == (car.still_gyro, car.still_accel)
    c.apply([("still_accel", 0.25), ("profile", 1)])
    assert c.profile == 1 and c.still_gyro == hand.still_gyro and c.still_accel == 0.25
    c.apply([("profile", 0)])
    assert c.still_gyro == car.still_gyro and c.still_accel == 0.25
    assert config.BoardConfig(1).still_gyro == hand.still_gyro
    # a file whose standstill records are missing (an older firmware's): the profile's
    data = config.encode(custom())
    body = bytearray(data[:-4])
    rid = next(r[0] for r in config._SCHEMA if r[1] == "still_gyro")
    at = 6
    while body[at] != rid:
        at += 3 + 4 * body[at + 2]
    del body[at : at + 7]
    body[5] -= 1
    body = bytes(body)
    cfg = config.decode(body + struct.pack("<I", crc32(body) & 0xFFFFFFFF))
    assert cfg.profile == 1 and cfg.still_gyro == hand.still_gyro


@pytest.mark.parametrize("damage", ["flip", "truncate", "magic", "empty"])
def test_damaged_files_fall_back_to_defaults(tmp_path, damage):
    path = tmp_path / "ins.cfg"
    data = bytearray(config.encode(custom()))
    if damage == "flip":
        data[20] ^= 0x04
    elif damage == "truncate":
        data = data[:-7]
    elif damage == "magic":
        data[:4] = b"XXXX"
    else:
        data = bytearray()
    path.write_bytes(bytes(data))
    cfg, status, msg = config.load(str(path))
    assert status == config.CORRUPT and "using defaults" in msg
    assert cfg.profile == 0 and cfg.gyro_range_dps == 250 and cfg.lever_b_m == [0, 0, 0]


def test_missing_file_is_reported_not_raised(tmp_path):
    cfg, status, msg = config.load(str(tmp_path / "nothing.cfg"))
    assert status == config.MISSING and "no configuration file" in msg
    assert cfg.gyro_range_dps == 250


def test_out_of_range_values_are_refused(tmp_path):
    bad = custom()
    bad.gyro_range_dps = 300
    with pytest.raises(ValueError, match="gyro_range_dps"):
        config.save(str(tmp_path / "x.cfg"), bad)
    # a file with a valid CRC but an invalid value (e.g. written by another tool)
    path = tmp_path / "ins.cfg"
    bad.validate = lambda: None
    path.write_bytes(config.encode(bad))
    cfg, status, msg = config.load(str(path))
    assert status == config.INVALID and "gyro_range_dps" in msg and cfg.gyro_range_dps == 250
    nan = custom()
    nan.lever_b_m = [0.0, float("nan"), 0.0]
    assert "lever_b_m" in nan.validate()


@pytest.mark.parametrize(
    "name, value, words",
    [
        ("gyro_bias0", [3e38, 0.0, 0.0], "gyro_bias0 must be within -0.0205..0.0205 rad/s"),
        ("accel_bias0", [0.0, 0.0, -2.5], "accel_bias0 must be within -0.92..0.92 m/s^2"),
        ("lever_b_m", [0.0, 11.0, 0.0], "lever_b_m must be within -3..3 m"),
        ("gyro_matrix", [3.0, 0, 0, 0, 1, 0, 0, 0, 1], "gyro_matrix must be within -1.02..1.02"),
        ("mount_ypr_deg", [0.0, 0.0, 181.0], "mount_ypr_deg must be within -180..180 deg"),
        ("gyro_arw", 0.2, "gyro_arw must be within 0.00001..0.003 rad/s/sqrt(Hz)"),
        ("accel_vrw", 0.0, "accel_vrw must be within 0.0001..0.07 m/s^2/sqrt(Hz)"),
        ("gyro_bias_sigma", 1.0, "gyro_bias_sigma must be within 0.000001..0.005 rad/s"),
        ("accel_bias_sigma", 2.0, "accel_bias_sigma must be within 0.0001..0.24 m/s^2"),
        ("gnss_hdop_max", 60.0, "gnss_hdop_max must be within 1.2..2.7"),
        ("gate_sigma", 0.5, "gate_sigma must be within 3.5..100 sigmas"),
        ("gnss_uere_m", 500.0, "gnss_uere_m must be within 1..7 m"),
        ("still_gyro", 1.0, "still_gyro must be within 0.0087..0.2 rad/s"),
        ("still_accel", 6.0, "still_accel must be within 0.04..5 m/s^2"),
    ],
)
def test_physically_impossible_values_are_refused_with_the_range(name, value, words):
    """Finite but absurd settings (gyro_bias0=3e38 once gave a NaN covariance) are refused
    with the setting's name and its range; the defaults and the range's ends are accepted."""
    cfg = custom()
    setattr(cfg, name, value)
    assert cfg.validate() == words
    assert config.BoardConfig().validate() is None


def test_the_ends_of_each_range_are_accepted():
    for name, lo, hi, den, _unit, open_low in config._RANGES:
        for end in (lo, hi):
            if open_low and end == lo:
                continue  # must be above 0
            cfg = custom()
            v = end / den
            old = getattr(cfg, name)
            n = 9 if name.endswith("_matrix") else 3
            setattr(cfg, name, [v] * n if isinstance(old, list) or old is None else v)
            assert cfg.validate() is None, (name, v)


def test_unknown_records_from_a_newer_firmware_are_skipped(tmp_path):
    data = config.encode(custom())
    body = bytearray(data[:-4])
    body[5] += 1  # one more record
    body += bytes((200, 1, 2)) + struct.pack("<2f", 1.5, 2.5)
    path = tmp_path / "ins.cfg"
    path.write_bytes(bytes(body) + struct.pack("<I", crc32(bytes(body))))
    cfg, status, _ = config.load(str(path))
    assert status == config.OK and cfg.gyro_range_dps == 500


def test_the_board_reads_the_desktop_file(tmp_path):
    path = tmp_path / "ins.cfg"
    config.save(str(path), custom())
    (tmp_path / "bad.cfg").write_bytes(b"INSC\x01\x00garbage")
    out = json.loads(
        mpvm.run(f"""
import json, config
cfg, status, msg = config.load({str(path)!r})
nav = cfg.nav_config()
bad, bad_status, bad_msg = config.load({str(tmp_path / "bad.cfg")!r})
print(json.dumps([status, cfg.gyro_range_dps, list(cfg.lever_b_m), cfg.gnss_latency_s,
                  list(nav.lever_b_m), nav.profile, bad_status, bad.gyro_range_dps]))
""")
        .strip()
        .splitlines()[-1]
    )
    assert out[0] == config.OK and out[1] == 500
    assert out[2] == [float(x) for x in f32list([0.1, 0.5, 1.25])]  # the float32 values, exactly
    assert out[3] == float(np.float32(0.08))
    assert out[4] == out[2] and out[5] == "handheld"
    assert out[6] == config.CORRUPT and out[7] == 250


def test_mounting_rotation_turns_sensor_axes_into_body_axes():
    """A board mounted turned 90 deg about up (sensor x = body forward): a rate about the
    sensor's x axis is a rate about the body's y axis once calibrated."""
    import f32
    import navcfg  # noqa: F401
    from nav import Navigator

    c = config.BoardConfig()
    c.mount_ypr_deg = [90.0, 0.0, 0.0]
    c.gyro_matrix = [1.01, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]  # x scale first, then mount
    nav = Navigator(c.nav_config())
    w = f32.zeros(3)
    w[0] = np.float32(0.1)
    assert nav._calibrate(w, f32.zeros(3) + np.float32(0.0))
    assert np.allclose(np.asarray(nav._w, float), [0.0, 0.101, 0.0], atol=1e-7)
    assert config.decode(config.encode(c)).mount_ypr_deg == [90.0, 0.0, 0.0]
