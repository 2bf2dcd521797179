"""KF-GINS files + dataset.yaml: conversion of a simulation, write/read round trip, hand-made
KF-GINS files, and one clear FormatError per kind of bad input."""

import datetime
import math

import numpy as np
import pytest

from common.errors import EmulatorError
from host_emulator.replay import kfgins
from host_emulator.replay.dataset import WEEK_S, Dataset, Positions, gpst, mount_matrix
from host_emulator.replay.kfgins import FormatError
from host_emulator.sim import gnss as gnss_mod
from host_emulator.sim import imu as imu_mod
from host_emulator.sim import trajectory as tr
from host_emulator.sim.board_input import Simulation

DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def sim():
    """25 s: 5 s at rest, up to 10 m/s, a 90-degree left turn; ideal IMU (quantisation only)."""
    script = tr.DriveScript(yaw0_rad=0.3)
    script.hold(5.0)
    script.speed_to(10.0, 1.5)
    script.turn(0.5 * math.pi, 0.3, ramp_s=2.0)
    truth = tr.truth_from_script(script, 25.0, name="turn", description="a left turn")
    imu = imu_mod.simulate(truth, imu_mod.ImuModel.ideal(), seed=0)
    gnss = gnss_mod.simulate(truth, None, seed=0)
    return Simulation("turn", 0, truth, imu, gnss, None, 0)


@pytest.fixture(scope="module")
def ds(sim):
    return kfgins.from_simulation(sim)


@pytest.fixture(scope="module")
def written(ds, tmp_path_factory):
    out = tmp_path_factory.mktemp("kfgins") / "turn"
    kfgins.write(out, ds)
    return out


# --- from_simulation: our conventions ---


def test_simulation_time_base_is_gpst_of_utc_start(sim, ds):
    t0 = gpst(datetime.datetime(2026, 11, 22, 2, 0, 0)) + 18.0  # GnssModel.utc_start, 18 leap s
    assert sim.gnss.model.utc_start == "2026-11-22T02:00:00"
    assert ds.truth.t_s[0] == t0
    np.testing.assert_allclose(ds.truth.t_s - t0, sim.truth.t_s, atol=1e-6)
    # IMU sample k (instantaneous at k dt) = mean over (k dt - dt/2, k dt + dt/2]
    np.testing.assert_allclose(ds.imu.t_s - t0, sim.imu.t_s + 0.0025, atol=1e-6)
    fixes = sim.gnss.quality > 0
    np.testing.assert_allclose(ds.gnss.t_s - t0, sim.gnss.t_fix_s[fixes], atol=1e-6)


def test_simulation_truth_in_ned_and_frd(sim, ds):
    truth = sim.truth
    np.testing.assert_allclose(ds.truth.lat_deg, truth.lat_e7 * 1e-7, atol=0.51e-7)
    np.testing.assert_allclose(ds.truth.lon_deg, truth.lon_e7 * 1e-7, atol=0.51e-7)
    np.testing.assert_allclose(ds.truth.h_m, truth.h_m, atol=1e-9)
    v = truth.v_n
    np.testing.assert_array_equal(ds.truth.v_ned_m_s, np.column_stack([v[:, 1], v[:, 0], -v[:, 2]]))
    # Firmware ypr (yaw ccw from north, RFU/ENU) -> roll, pitch, yaw (clockwise, FRD/NED).
    yaw, pitch, roll = (truth.ypr[:, i] / DEG for i in range(3))
    np.testing.assert_allclose(ds.truth.rpy_deg[:, 0], roll, atol=1e-9)
    np.testing.assert_allclose(ds.truth.rpy_deg[:, 1], pitch, atol=1e-9)
    dyaw = (ds.truth.rpy_deg[:, 2] + yaw + 180.0) % 360.0 - 180.0
    np.testing.assert_allclose(dyaw, 0.0, atol=1e-9)
    assert ds.truth_point == "imu"
    assert ds.lever_frd_m == (0.5, 0.0, -1.0)  # GnssModel lever (0, 0.5, 1) right-forward-up
    assert ds.gnss.sigma_ned_m[0, 0] == ds.gnss.sigma_ned_m[0, 1] == sim.gnss.sigma_h_m[0]
    assert ds.gnss.sigma_ned_m[0, 2] == sim.gnss.sigma_v_m[0]


def test_simulation_imu_axes_through_the_mounting(sim, ds):
    c_sb = mount_matrix(ds.mount_rpy_deg)  # board right-forward-up -> body forward-right-down
    np.testing.assert_allclose(c_sb, [[0, 1, 0], [1, 0, 0], [0, 0, -1]], atol=1e-15)
    f_b = ds.imu.accel_m_s2 @ c_sb.T
    w_b = ds.imu.gyro_rad_s @ c_sb.T
    # At rest the body specific force is gravity's reaction: up, i.e. -g along body down.
    r, p, _ = ds.truth.rpy_deg[0] * DEG
    g = ds.gravity_m_s2
    expect = g * np.array([math.sin(p), -math.sin(r) * math.cos(p), -math.cos(r) * math.cos(p)])
    np.testing.assert_allclose(f_b[:800].mean(axis=0), expect, atol=0.01)  # 1 count = 0.0096
    # The FRD z gyro integrates to the change of the clockwise yaw (Earth rate removed).
    lat = ds.truth.lat_deg[0] * DEG
    psi_dot = w_b[:, 2] + tr.OMEGA_IE_RAD_S * math.sin(lat)
    turned = np.sum(psi_dot[1:] * np.diff(ds.imu.t_s)) / DEG
    yaw = np.unwrap(ds.truth.rpy_deg[:, 2] * DEG) / DEG
    assert abs(yaw[-1] - yaw[0] - (-90.0)) < 0.5  # a left turn: clockwise yaw goes down
    assert turned == pytest.approx(yaw[-1] - yaw[0], abs=0.15)  # 0.06 here: quantisation, roll


# --- write -> read ---


def test_round_trip(ds, written):
    back = kfgins.read(written)
    c_sb = mount_matrix(ds.mount_rpy_deg)
    c_sb[np.abs(c_sb) < 1e-12] = 0.0
    assert back.name == "turn"
    assert back.description == ds.description
    assert back.mount_rpy_deg == (0.0, 0.0, 0.0)  # the IMU file is body FRD
    assert back.lever_frd_m == ds.lever_frd_m
    assert back.gravity_m_s2 == ds.gravity_m_s2
    assert back.truth_point == "imu"
    assert len(back.imu) == len(ds.imu) and len(back.truth) == len(ds.truth)
    np.testing.assert_allclose(back.imu.t_s, ds.imu.t_s, atol=1e-6)
    np.testing.assert_allclose(
        back.imu.gyro_rad_s, ds.imu.gyro_rad_s @ c_sb.T, rtol=1e-9, atol=1e-12
    )
    np.testing.assert_allclose(
        back.imu.accel_m_s2, ds.imu.accel_m_s2 @ c_sb.T, rtol=1e-9, atol=1e-12
    )
    for a, b in ((back.truth, ds.truth), (back.gnss, ds.gnss)):
        np.testing.assert_allclose(a.t_s, b.t_s, atol=1e-6)
        np.testing.assert_allclose(a.lat_deg, b.lat_deg, atol=1e-10)
        np.testing.assert_allclose(a.lon_deg, b.lon_deg, atol=1e-10)
        np.testing.assert_allclose(a.h_m, b.h_m, atol=1e-4)
    np.testing.assert_allclose(back.truth.v_ned_m_s, ds.truth.v_ned_m_s, atol=1e-6)
    np.testing.assert_allclose(back.truth.rpy_deg, ds.truth.rpy_deg, atol=1e-8)
    np.testing.assert_allclose(back.gnss.sigma_ned_m, ds.gnss.sigma_ned_m, atol=1e-4)
    assert back.gnss.v_ned_m_s is None and back.truth.sigma_ned_m is None


def test_written_files_are_kfgins_layout(ds, written):
    desc = {k: v for k, (v, _) in kfgins.parse_description(written / "dataset.yaml").items()}
    week = int(ds.truth.t_s[0] // WEEK_S)
    assert desc["gpsweek"] == week and desc["imudatarate"] == 200
    assert desc["installangle"] == [0.0, 0.0, 0.0]
    assert desc["antlever"] == [0.5, 0.0, -1.0]
    imu = np.loadtxt(written / desc["imufile"])
    assert imu.shape == (len(ds.imu), 7)
    np.testing.assert_allclose(imu[:, 0], ds.imu.t_s - week * WEEK_S, atol=1e-6)
    c_sb = np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1.0]])
    # increments = rate x interval; the first row's interval is 1 / imudatarate
    np.testing.assert_allclose(imu[:, 1:4], ds.imu.gyro_rad_s @ c_sb.T * 0.005, atol=1e-14)
    np.testing.assert_allclose(imu[:, 4:7], ds.imu.accel_m_s2 @ c_sb.T * 0.005, atol=1e-13)
    assert np.loadtxt(written / desc["gnssfile"]).shape == (len(ds.gnss), 7)
    nav = np.loadtxt(written / desc["truthfile"])
    assert nav.shape == (len(ds.truth), 11) and (nav[:, 0] == week).all()


def test_truth_without_velocity_or_attitude_is_written_as_nan(ds, tmp_path):
    bare = Positions(
        ds.truth.t_s[:50], ds.truth.lat_deg[:50], ds.truth.lon_deg[:50], ds.truth.h_m[:50]
    )
    kfgins.write(tmp_path, ds, truth=bare)
    assert "nan nan nan nan nan nan" in (tmp_path / "truth.nav").read_text().splitlines()[0]
    back = kfgins.read(tmp_path / "dataset.yaml")
    assert back.truth.v_ned_m_s is None and back.truth.rpy_deg is None
    assert len(back.truth) == 50


def test_gnss_with_velocity_uses_the_13_column_form(ds, tmp_path):
    g = ds.gnss
    with_v = Positions(g.t_s, g.lat_deg, g.lon_deg, g.h_m, g.sigma_ned_m, np.ones((len(g), 3)))
    kfgins.write(tmp_path, ds, gnss=with_v)
    row = (tmp_path / "gnss.txt").read_text().split("\n")[0].split()
    assert len(row) == 13 and row[4:7] == ["1.000000"] * 3 and row[10:] == ["nan"] * 3
    back = kfgins.read(tmp_path)
    np.testing.assert_array_equal(back.gnss.v_ned_m_s, 1.0)
    np.testing.assert_allclose(back.gnss.sigma_ned_m, g.sigma_ned_m, atol=1e-4)


def test_dataset_without_gnss(ds, tmp_path):
    no_gnss = Dataset("x", ds.imu, ds.truth, "antenna", None, (1.0, 2.0, 3.0), (0.0, 0.05, 0.0))
    kfgins.write(tmp_path, no_gnss)
    assert not (tmp_path / "gnss.txt").exists()
    back = kfgins.read(tmp_path)
    assert back.gnss is None and back.truth_point == "antenna" and back.gravity_m_s2 is None
    # written in body axes: the sensor-axes data went through the mounting (1, 2, 3) deg
    c_sb = mount_matrix((1.0, 2.0, 3.0))
    np.testing.assert_allclose(
        back.imu.gyro_rad_s, ds.imu.gyro_rad_s @ c_sb.T, rtol=1e-9, atol=1e-12
    )


# --- hand-made KF-GINS files ---

YAML = """\
# a KF-GINS drive
name: 'hand # made'   # a comment after a quoted '#'
imufile: imu.txt
gnssfile: "gnss.txt"
truthfile: truth.nav
imudatarate: 200
gpsweek: 2200
starttime: 456300.005
endtime: -1          # KF-GINS: to the end
antlever: [ 0.136, -0.301, -0.184 ]
installangle: [0, 0, 90]
gravity: 9.7936
"""

IMU = """\
456300.000 1e-4 0 0 0 0 -0.049
456300.005 2e-4 0 0 0 0 -0.049
456300.010 3e-4 0 0 0 0 -0.049
456300.210 4e-4 0 0 0 0 -0.049
456300.215 5e-4 0 0 0 0 -0.098
"""

GNSS13 = """\
456300.000 30.4447858174 114.4718660799 21.102 0.1 0.2 0.3 0.010 0.009 0.019 0.05 0.05 0.05
456301.000 30.4447858449 114.4718661417 21.093 0.1 0.2 0.3 0.011 0.009 0.019 0.05 0.05 0.05
"""

NAV = """\
0 456300.000 30.4447873701 114.4718632047 20.899 0.0 0.0 0.0 0.854 -2.034 185.702
0 456300.005 30.4447873701 114.4718632047 20.899 0.0 0.0 0.0 0.854 -2.034 185.702
"""


def _make(tmp_path, yaml=YAML, imu=IMU, gnss=GNSS13, nav=NAV):
    for name, text in (("dataset.yaml", yaml), ("imu.txt", imu), ("gnss.txt", gnss)):
        (tmp_path / name).write_text(text)
    (tmp_path / "truth.nav").write_text(nav)
    return tmp_path


def test_read_handmade_kfgins_files(tmp_path):
    d = kfgins.read(_make(tmp_path))
    t_week = 2200 * WEEK_S
    assert d.name == "hand # made"
    assert d.mount_rpy_deg == (0.0, 0.0, 90.0) and d.lever_frd_m == (0.136, -0.301, -0.184)
    assert d.gravity_m_s2 == 9.7936
    # starttime drops the first row; its interval still comes from the row before it
    np.testing.assert_allclose(d.imu.t_s - t_week, [456300.005, 456300.010, 456300.210, 456300.215])
    # intervals: 0.005, 0.005, 0.2 >= 0.1 s -> a gap, the row covers 1/200 s, 0.005
    np.testing.assert_allclose(d.imu.gyro_rad_s[:, 0], [0.04, 0.06, 0.08, 0.1], rtol=1e-9)
    np.testing.assert_allclose(d.imu.accel_m_s2[:, 2], [-9.8, -9.8, -9.8, -19.6], rtol=1e-9)
    # 13-column GNSS: velocity in columns 5-7, standard deviations in 8-10 (KF-GINS's loader)
    assert len(d.gnss) == 1  # the 456300.000 epoch is before starttime
    np.testing.assert_allclose(d.gnss.v_ned_m_s, [[0.1, 0.2, 0.3]])
    np.testing.assert_allclose(d.gnss.sigma_ned_m, [[0.011, 0.009, 0.019]])
    # .nav week 0 -> gpsweek
    np.testing.assert_allclose(d.truth.t_s, [t_week + 456300.005])
    np.testing.assert_allclose(d.truth.rpy_deg, [[0.854, -2.034, 185.702]])


def test_intervals_follow_kfgins_loader():
    dt = kfgins.intervals([10.0, 10.01, 10.02, 10.5, 10.51], 100.0)
    np.testing.assert_allclose(dt, [0.01, 0.01, 0.01, 0.01, 0.01], atol=1e-12)


# --- bad input: one FormatError line naming file and line ---


def _error(tmp_path, **files):
    with pytest.raises(FormatError) as err:
        kfgins.read(_make(tmp_path, **files))
    msg = str(err.value)
    assert "\n" not in msg and isinstance(err.value, EmulatorError)
    return msg


def test_unknown_key(tmp_path):
    msg = _error(tmp_path, yaml=YAML + "imupath: x.txt\n")
    assert "dataset.yaml:13: unknown key 'imupath'" in msg


def test_missing_key(tmp_path):
    msg = _error(tmp_path, yaml=YAML.replace("antlever", "# antlever"))
    assert "dataset.yaml: missing key 'antlever'" in msg


@pytest.mark.parametrize(
    ("line", "expect"),
    [
        ("imudatarate: fast", "imudatarate must be a number, got 'fast'"),
        ("imudatarate: 0", "imudatarate must be positive"),
        ("gpsweek: 2200.5", "gpsweek must be a whole number"),
        ("antlever: [1, 2]", "antlever must be a list of 3 numbers"),
        ("antlever: [1, 2, 3", "a list must close on its line"),
        ("truthpoint: gps", "truthpoint must be imu or antenna"),
        ("  indented: 1", "indented or block lines are not supported"),
        ("name: x", "name given twice (first on line 2)"),
        ("just words", "expected 'key: value'"),
    ],
)
def test_bad_description(tmp_path, line, expect):
    """The bad line replaces the line of its key (or is appended); the message names it."""
    lines = YAML.splitlines()
    key = line.split(":")[0]
    at = [i for i, x in enumerate(lines) if x.startswith(key + ":")]
    if at and key != "name":
        lines[at[0]] = line
    else:
        lines.append(line)
    msg = _error(tmp_path, yaml="\n".join(lines) + "\n")
    assert f"dataset.yaml:{lines.index(line) + 1}: {expect}" in msg


def test_missing_data_file(tmp_path):
    _make(tmp_path)
    (tmp_path / "gnss.txt").unlink()
    with pytest.raises(FormatError, match=r"dataset.yaml:4: gnssfile 'gnss.txt': no such file"):
        kfgins.read(tmp_path)


def test_missing_description(tmp_path):
    with pytest.raises(FormatError, match=r"dataset.yaml: no such file \(dataset description\)"):
        kfgins.read(tmp_path)


def test_wrong_column_count(tmp_path):
    msg = _error(tmp_path, imu=IMU + "456300.220 1 2 3 4 5\n")
    assert msg.endswith("imu.txt:6: 6 columns, the rows before have 7")
    msg = _error(tmp_path, gnss="456300.0 30 114 21 0.1 0.1\n")
    assert msg.endswith("gnss.txt:1: 6 columns, GNSS rows have 7 or 13")


def test_non_increasing_time(tmp_path):
    msg = _error(tmp_path, imu=IMU + "456300.215 0 0 0 0 0 0\n")
    assert "imu.txt:6: sow 456300.215 is not after the previous row's 456300.215 (line 5)" in msg
    nav = NAV + "0 456300.001 30.4 114.4 20.9 0 0 0 0 0 0\n"
    assert "truth.nav:3: GPST (week, sow)" in _error(tmp_path, nav=nav)


def test_not_a_number(tmp_path):
    msg = _error(tmp_path, nav=NAV.replace("20.899", "20,899", 1))
    assert msg.endswith(
        "truth.nav:1: column 5 is '20,899', not a number: a decimal comma? Numbers take a point"
    )


def test_window_without_imu_rows(tmp_path):
    msg = _error(tmp_path, yaml=YAML.replace("starttime: 456300.005", "starttime: 500000"))
    assert "no IMU rows between starttime and endtime" in msg
