"""The replay command end to end: drive_0708's first 120 s through the firmware (with bounds
that a broken mounting or time alignment exceeds, shown here too), the outputs, the exchange
formats, and the command line's errors."""

import copy
import dataclasses
import json
import pathlib

import numpy as np
import pytest

from host_emulator.__main__ import main
from host_emulator.replay import drive_0708, kfgins, replay_run, rtklib_pos
from host_emulator.replay import to_stimulus as ts
from host_emulator.runtimes import cpython

needs_drive = pytest.mark.skipif(
    not drive_0708.DEFAULT_DIR.is_dir(), reason="../shared/data/drive_0708 is not present"
)


@pytest.fixture(scope="module")
def replay_120(tmp_path_factory):
    out = tmp_path_factory.mktemp("replay")
    ds = drive_0708.load()
    m = replay_run.replay(
        ds, ts.ReplayOptions(duration_s=120.0), out_dir=out, show_progress=False,
        log=lambda *a: None,
    )  # fmt: skip
    return m, out


def _within_bounds(m):
    """The 120 s replay's bounds (measured on the correct conversion: 1.61 m with GNSS, 0.60
    m/s, outage 1 ends at 6.0 m)."""
    return (
        m["horiz_rms_gnss_m"] < 2.0
        and m["vel_rms_m_s"] < 0.8
        and m["outages"][0]["horiz_err_end_m"] < 8.0
    )


@needs_drive
def test_first_120_s_of_drive_0708(replay_120):
    m, out = replay_120
    assert 38.0 < m["align_time_s"] < 50.0  # measured 41.3 s
    assert _within_bounds(m)
    assert m["gnss_horiz_rms_m"] > 1.8  # the input really is the noisy one
    assert m["frame_errors"] == 0 and m["yaw_rms_deg"] is None  # no attitude reference
    for name in replay_run.OUTPUTS:
        assert (out / name).stat().st_size > 0, name
    assert json.loads((out / "metrics.json").read_text())["dataset"] == "drive_0708"
    sol = rtklib_pos.read(out / "solution.pos")
    assert len(sol.positions) > 700  # 10 Hz from 41 s
    assert set(np.unique(sol.q)) <= {rtklib_pos.Q_SINGLE, rtklib_pos.Q_DR}
    assert (sol.q == rtklib_pos.Q_DR).any()  # the outage


@needs_drive
@pytest.mark.parametrize("broken", ["mounting pitch left out", "IMU 0.5 s late"])
def test_bounds_catch_a_broken_conversion(broken, tmp_path):
    # measured: pitch left out 3.6 m / 1.7 m/s / 11 m; IMU 0.5 s late 2.6 m / 0.9 m/s / 8.2 m
    ds = copy.copy(drive_0708.load())
    if broken == "IMU 0.5 s late":
        ds.imu = dataclasses.replace(ds.imu, t_s=ds.imu.t_s + 0.5)
    else:
        ds.mount_rpy_deg = (180.0, 0.0, 185.35)
    rep = ts.convert(ds, ts.ReplayOptions(duration_s=120.0))
    fw = cpython.run(rep.stimulus, pathlib.Path(tmp_path))
    m, _tr, _err = replay_run.evaluate_replay(rep, fw, "cpython")
    assert not _within_bounds(m)


def test_export_a_scenario_and_replay_it_as_kf_gins(tmp_path, capsys):
    assert main(["export", "--scenario", "urban_drive", "--duration", "150", "--out",
                 str(tmp_path / "kf")]) == 0  # fmt: skip
    ds = kfgins.read(tmp_path / "kf")
    assert ds.gnss is not None and ds.truth.rpy_deg is not None
    assert rtklib_pos.read(tmp_path / "kf" / "gnss.pos").positions.t_s.size == len(ds.gnss)
    out = tmp_path / "run"
    rc = main(["replay", "--kf-gins", str(tmp_path / "kf"), "--outages", "none", "--out",
               str(out), "--quiet"])  # fmt: skip
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    # measured: 2.93 m horizontal against the simulated fixes' 2.94 m (a short window right
    # after a position-only start), yaw 2.5 deg RMS
    assert m["align_time_s"] is not None and m["horiz_rms_gnss_m"] < 4.5
    assert 2.0 < m["gnss_horiz_rms_m"] < 4.0
    assert m["yaw_rms_deg"] < 6.0
    assert m["yaw_rms_deg"] is not None  # the .nav has attitude


@needs_drive
def test_export_the_replay_input(tmp_path):
    assert main(["export", "--dataset", "drive_0708", "--duration", "60", "--out",
                 str(tmp_path)]) == 0  # fmt: skip
    ds = kfgins.read(tmp_path)
    assert 55 <= len(ds.gnss) <= 60
    np.testing.assert_allclose(ds.gnss.sigma_ned_m[0], [1.5, 1.5, 3.0])
    assert abs(ds.imu.t_s.size - 6000) < 20  # the recording's 100 Hz, rotated to FRD


@pytest.mark.parametrize(
    "argv, says",
    [
        (["replay", "--dataset", "drive_0709", "--out", "x"], "unknown dataset"),
        (["replay", "--dataset", "drive_0708", "--outages", "60-15", "--out", "x"], "START+LENGTH"),
        (["replay", "--dataset", "drive_0708", "--gnss-rate", "3", "--out", "x"], "gnss-rate"),
        (["replay", "--kf-gins", "/nonexistent", "--out", "x"], "nonexistent"),
    ],
)
def test_bad_input_is_one_line(argv, says, capsys, tmp_path):
    argv = [a if a != "x" else str(tmp_path / "o") for a in argv]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert says in err and "Traceback" not in err
