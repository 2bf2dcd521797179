"""A replay scores the output only where its reference exists: not across a gap between the
reference's epochs, and at the waypoints alone when the reference is a line between surveyed
points (replay/to_stimulus.py RunTruth.covered, eval/evaluate.py, replay/kfgins.py
waypointfile)."""

import dataclasses
import json

import numpy as np
import pymap3d
import pytest

from host_emulator.__main__ import main
from host_emulator.eval import evaluate
from host_emulator.replay import kfgins, replay_run
from host_emulator.replay import to_stimulus as ts
from host_emulator.replay.formats import FormatError
from host_emulator.sim import board_input


@pytest.fixture(scope="module")
def drive():
    """urban_drive's first 120 s as a Dataset (navigation starts at ~64 s)."""
    return kfgins.from_simulation(board_input.simulate("urban_drive", 120.0, 0))


def test_a_time_is_covered_at_an_epoch_or_between_close_ones():
    ref = 1.3e9 + np.array([0.0, 0.2, 0.4, 1.4, 1.6])  # GPST-sized times: no relative slack
    t = 1.3e9 + np.array([0.0, 0.1, 0.4, 0.5, 1.3, 1.4, 1.5, 1.7])
    covered, max_gap = ts.reference_covered(ref, t)
    assert max_gap == pytest.approx(0.3)  # 1.5 x the median interval, 0.2 s
    assert covered.tolist() == [True, True, True, False, False, True, True, False]


def test_positions_are_interpolated_at_waypoints_but_never_across_a_gap():
    t = np.array([0.0, 1.0, 2.0, 5.0])
    p = np.array([[0.0, 0.0], [1.0, 2.0], [2.0, 4.0], [5.0, 10.0]])
    got = evaluate.at_times(t, p, np.array([0.5, 1.5, 3.0, 6.0]), max_gap_s=1.5)
    assert got[:2].tolist() == [[0.5, 1.0], [1.5, 3.0]]
    assert np.isnan(got[2:]).all()  # inside the 3 s gap, and after the end
    err = evaluate.waypoint_errors(t, p, (np.array([0.5, 3.0]), np.array([[3.5, 5.0]] * 2)), 1.5)
    assert err[0] == pytest.approx(5.0) and np.isnan(err[1])
    assert evaluate.spread([3.0, 1.0, np.nan, 2.0]) == {"n": 3, "median": 2.0, "p75": 2.5,
                                                        "max": 3.0}  # fmt: skip


def test_a_gap_in_the_reference_is_left_out_of_the_scores(drive, tmp_path):
    tr = drive.truth
    t_rel = tr.t_s - tr.t_s[0]
    gap = (t_rel > 80.0) & (t_rel < 90.0)
    ds = dataclasses.replace(drive, truth=tr.select(~gap))
    m = replay_run.replay(ds, replay_run.kfgins_options(ds), out_dir=tmp_path,
                          show_progress=False, log=lambda *_: None)  # fmt: skip
    ref = m["reference"]
    assert ref["kind"] == "gaps"
    assert ref["unscored_s"] == pytest.approx(10.0, abs=0.05)
    report = (tmp_path / "report.md").read_text()
    assert "are not scored (no straight line is drawn across a gap)" in report
    whole = replay_run.replay(drive, replay_run.kfgins_options(drive), out_dir=tmp_path / "w",
                              show_progress=False, log=lambda *_: None)  # fmt: skip
    assert whole["reference"]["kind"] == "continuous" and whole["reference"]["unscored_s"] == 0


def _written(drive, tmp_path):
    """The directory of the drive written as KF-GINS files."""
    p = kfgins.write(tmp_path / "walk", drive)
    return p if p.is_dir() else p.parent


def _waypoints_csv(drive, path, t_rel):
    """Waypoints on the reference at t_rel s after its start, as a survey would give them."""
    tr = drive.truth
    t = tr.t_s[0] + np.asarray(t_rel, float)
    lat, lon = (np.interp(t, tr.t_s, x) for x in (tr.lat_deg, tr.lon_deg))
    week = drive.gpsweek or int(tr.t_s[0] // kfgins.WEEK_S)
    rows = ["app_s,gpst_sow,lat_deg,lon_deg,floor"]
    rows += [f"{i},{t_i - week * kfgins.WEEK_S:.4f},{a:.10f},{b:.10f},0"
             for i, (t_i, a, b) in enumerate(zip(t, lat, lon, strict=True))]  # fmt: skip
    path.write_text("\n".join(rows) + "\n")
    return lat, lon


def test_waypoints_are_read_and_the_output_is_scored_there_alone(drive, tmp_path):
    d = _written(drive, tmp_path)
    lat, lon = _waypoints_csv(drive, d / "waypoints.csv", [76.0, 84.0, 92.0, 100.0, 108.0])
    ds = kfgins.read(d)
    assert len(ds.waypoints) == 5 and np.allclose(ds.waypoints.lat_deg, lat)
    out = tmp_path / "run"
    assert main(["replay", "--kf-gins", str(d), "--out", str(out), "--quiet"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    wp = m["reference"]["waypoints"]
    assert m["reference"]["kind"] == "waypoints" and wp["n"] == 5
    assert wp["firmware"]["n"] == 5 and wp["fixes"]["n"] == 5
    # the simulated receiver's fixes (noise and multipath: metres), the firmware near them
    assert 0.5 < wp["fixes"]["median"] < 8.0 and 0.2 < wp["firmware"]["median"] < 6.0
    # the continuous figures are those of the samples at the waypoints: 5 of them, not 500
    # (each waypoint covers the ticks within WAYPOINT_TOL_S of it: 21 ticks of 5 ms)
    assert m["reference"]["scored_s"] == pytest.approx(5 * 21 * 0.005)
    lat0, lon0 = lat[0], lon[0]
    e, n, _ = pymap3d.geodetic2enu(lat, lon, 0.0, lat0, lon0, 0.0)
    assert np.hypot(e[-1], n[-1]) > 50  # the waypoints are spread along the drive
    report = (out / "report.md").read_text()
    assert "| waypoints scored | 5 of 5 | 5 of 5 |" in report
    assert "true only at its 5 waypoints" in report


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("app_s,gpst_sow,lat\n1,2,3\n", r"waypoints.csv:1: the header has no column lat_deg, "
         "lon_deg"),
        ("gpst_sow,lat_deg,lon_deg\n1,x,3\n", r"waypoints.csv:2: not 3 comma-separated values"),
        ("gpst_sow,lat_deg,lon_deg\n", r"waypoints.csv: no waypoints after the header"),
        ("gpst_sow,lat_deg,lon_deg\n2,1,1\n1,1,1\n", r"waypoints.csv:3: gpst_sow"),
    ],
)  # fmt: skip
def test_a_bad_waypoint_file_says_where(drive, tmp_path, text, says):
    d = _written(drive, tmp_path)
    (d / "waypoints.csv").write_text(text)
    with pytest.raises(FormatError, match=says):
        kfgins.read(d)


def test_waypoints_outside_starttime_and_endtime_are_an_error(drive, tmp_path):
    d = _written(drive, tmp_path)
    sow0 = drive.truth.t_s[0] % kfgins.WEEK_S
    yaml = d / "dataset.yaml"
    yaml.write_text(yaml.read_text() + f"starttime: {sow0 + 50.0:.3f}\n")
    _waypoints_csv(drive, d / "waypoints.csv", [10.0, 20.0])  # both before the window
    with pytest.raises(FormatError, match=r"none of its 2 waypoints lies between starttime"):
        kfgins.read(d)
    _waypoints_csv(drive, d / "waypoints.csv", [10.0, 60.0, 70.0])
    assert len(kfgins.read(d).waypoints) == 2
