"""RTKLIB .pos files: the real drive_0708 solution, write/read round trips, the INS export,
time systems, and one clear FormatError per kind of bad input."""

import datetime
from pathlib import Path

import numpy as np
import pytest

from common.errors import EmulatorError
from host_emulator.replay import rtklib_pos
from host_emulator.replay.dataset import WEEK_S, Positions, gpst
from host_emulator.replay.rtklib_pos import FormatError

DRIVE_POS = Path(__file__).resolve().parents[3] / "shared/data/drive_0708/gnss_1934_sf.pos"

needs_drive = pytest.mark.skipif(not DRIVE_POS.is_file(), reason="drive_0708 data not present")


@pytest.fixture(scope="module")
def drive():
    return rtklib_pos.read(DRIVE_POS)


@needs_drive
def test_read_drive_0708(drive):
    p = drive.positions
    assert len(drive) == len(p) == 2197
    assert drive.time_system == "GPST"
    # first epoch 2025/07/08 19:34:18.499 GPST = GPS week 2374, 243258.499 s of week
    assert p.t_s[0] == gpst(datetime.datetime(2025, 7, 8, 19, 34, 18, 499000))
    assert p.t_s[0] == pytest.approx(2374 * WEEK_S + 243258.499, abs=1e-6)
    assert p.t_s[-1] == gpst(datetime.datetime(2025, 7, 8, 19, 43, 27, 499000))
    np.testing.assert_allclose(np.diff(p.t_s), 0.25, atol=1e-6)  # 4 Hz
    assert (drive.q == 2).sum() == 8 and (drive.q == 1).sum() == 2189
    np.testing.assert_array_equal(np.flatnonzero(drive.q == 2), np.arange(170, 178))
    assert drive.ns[0] == 21 and drive.ns.min() == 19
    assert (p.lat_deg[0], p.lon_deg[0], p.h_m[0]) == (40.0966268, -105.1474483, 1601.474)
    np.testing.assert_array_equal(p.sigma_ned_m[0], [0.0098995, 0.0098995, 0.01])
    # velocities vn ve vu -> v_ned (vd = -vu): first row 0.010 -0.002 0.009
    np.testing.assert_array_equal(p.v_ned_m_s[0], [0.01, -0.002, -0.009])
    np.testing.assert_array_equal(drive.sigma_v_ned_m_s[0], [0.0586899] * 3)
    assert (drive.age_s == 0).all() and (drive.ratio == 0).all()
    assert p.rpy_deg is None


@needs_drive
def test_round_trip_of_drive_0708(drive, tmp_path):
    out = tmp_path / "again.pos"
    p = drive.positions
    rtklib_pos.write(
        out, p, drive.q, drive.ns, sigma_v_ned_m_s=drive.sigma_v_ned_m_s, comment="copy\nof it"
    )
    back = rtklib_pos.read(out)
    b = back.positions
    np.testing.assert_allclose(b.t_s, p.t_s, atol=1e-6)
    np.testing.assert_allclose(b.lat_deg, p.lat_deg, atol=5e-10)
    np.testing.assert_allclose(b.lon_deg, p.lon_deg, atol=5e-10)
    np.testing.assert_allclose(b.h_m, p.h_m, atol=5e-5)
    np.testing.assert_allclose(b.sigma_ned_m, p.sigma_ned_m, atol=5e-5)  # %8.4f
    np.testing.assert_allclose(b.v_ned_m_s, p.v_ned_m_s, atol=5e-6)
    np.testing.assert_allclose(back.sigma_v_ned_m_s, drive.sigma_v_ned_m_s, atol=5e-6)
    np.testing.assert_array_equal(back.q, drive.q)
    np.testing.assert_array_equal(back.ns, drive.ns)
    text = out.read_text().splitlines()
    assert text[1:3] == ["% copy", "% of it"]


def _track(n=40):
    t0 = gpst(datetime.datetime(2025, 7, 8, 19, 34, 20))
    t = t0 + 0.005 * np.arange(n)  # 200 Hz
    lat = 40.0966268 + 1e-6 * np.arange(n)
    lon = -105.1474483 - 2e-6 * np.arange(n)
    h = 1601.5 + 0.01 * np.arange(n)
    sigma_enu = np.tile([1.0, 2.0, 3.0], (n, 1))
    v_enu = np.tile([4.0, 5.0, 0.5], (n, 1))
    outage = np.arange(n) >= n // 2
    return t, lat, lon, h, sigma_enu, v_enu, outage


def test_from_track_maps_enu_to_ned_and_marks_dead_reckoning():
    t, lat, lon, h, sigma_enu, v_enu, outage = _track()
    positions, q = rtklib_pos.from_track(t, lat, lon, h, sigma_enu, v_enu, outage)
    np.testing.assert_array_equal(positions.sigma_ned_m[0], [2.0, 1.0, 3.0])
    np.testing.assert_array_equal(positions.v_ned_m_s[0], [5.0, 4.0, -0.5])
    assert (q[~outage] == rtklib_pos.Q_SINGLE).all() and (q[outage] == rtklib_pos.Q_DR).all()
    assert (rtklib_pos.Q_SINGLE, rtklib_pos.Q_DR) == (5, 7)


def test_written_file_is_rtklib_fixed_width(tmp_path):
    out = tmp_path / "ins.pos"
    t, lat, lon, h, sigma_enu, v_enu, outage = _track()
    rtklib_pos.write(out, *rtklib_pos.from_track(t, lat, lon, h, sigma_enu, v_enu, outage))
    lines = out.read_text().splitlines()
    head = [x for x in lines if x.startswith("%")]
    rows = [x for x in lines if not x.startswith("%")]
    assert head[0].startswith("% program   : ")
    assert head[1] == "% obs start : 2025/07/08 19:34:20.000 GPST (week2374 243260.000s)"
    labels = head[-1]
    assert labels.startswith("%  GPST ")
    for name in ("latitude(deg)", "height(m)", "sdun(m)", "ratio", "vu(m/s)", "sdvun"):
        assert name in labels
    assert len(rows) == 40 and len({len(r) for r in rows}) == 1
    assert len(labels) == len(rows[0])  # labels right-aligned over their columns
    first = rows[0].split()
    assert first[:2] == ["2025/07/08", "19:34:20.000"]
    assert first[5:7] == ["5", "0"]  # Q single, ns 0
    assert rows[-1].split()[5] == "7"  # dead reckoning
    assert first[7:10] == ["2.0000", "1.0000", "3.0000"]  # sdn sde sdu
    assert first[15:18] == ["5.00000", "4.00000", "0.50000"]  # vn ve vu
    back = rtklib_pos.read(out)
    np.testing.assert_allclose(back.positions.t_s, t, atol=1e-6)
    np.testing.assert_allclose(back.positions.lat_deg, lat, atol=5e-10)
    np.testing.assert_array_equal(back.q, np.where(outage, 7, 5))


def test_write_without_sigma_or_velocity(tmp_path):
    t, lat, lon, h, *_ = _track(3)
    out = tmp_path / "bare.pos"
    with pytest.raises(FormatError, match=r"epoch 1 \(2025/07/08 19:34:20.0\) is not after"):
        rtklib_pos.write(out, Positions(t, lat, lon, h), time_decimals=1)  # 200 Hz in 0.1 s
    t = t[0] + 0.5 * np.arange(3)
    rtklib_pos.write(out, Positions(t, lat, lon, h), q=1, ns=12, time_decimals=1)
    rows = [x.split() for x in out.read_text().splitlines() if not x.startswith("%")]
    assert [len(r) for r in rows] == [15, 15, 15]
    assert rows[1][1] == "19:34:20.5" and rows[1][5:7] == ["1", "12"]
    back = rtklib_pos.read(out)
    assert back.positions.v_ned_m_s is None and back.sigma_v_ned_m_s is None
    np.testing.assert_array_equal(back.positions.sigma_ned_m, 0.0)


ROW = "   40.096626800 -105.147448300  1601.4740   1  21   0.0099   0.0099   0.0100   0.0000   0.0000   0.0000   0.00    0.0"  # noqa: E501


def _file(tmp_path, text):
    path = tmp_path / "x.pos"
    path.write_text(text)
    return path


def test_utc_jst_and_week_sow_time_forms(tmp_path):
    gpst_s = gpst(datetime.datetime(2025, 7, 8, 19, 34, 18, 500000))
    utc = _file(tmp_path, "%  UTC    latitude(deg)\n2025/07/08 19:34:00.500" + ROW + "\n")
    assert rtklib_pos.read(utc).positions.t_s[0] == gpst_s  # + 18 leap seconds
    jst = _file(tmp_path, "%  JST    latitude(deg)\n2025/07/09 04:34:00.500" + ROW + "\n")
    assert rtklib_pos.read(jst).positions.t_s[0] == gpst_s
    week = _file(tmp_path, "%  GPST   latitude(deg)\n2374 243258.500" + ROW + "\n")
    assert rtklib_pos.read(week).positions.t_s[0] == pytest.approx(gpst_s, abs=1e-6)
    commas = _file(tmp_path, "2374,243258.500," + ",".join(ROW.split()) + "\n")
    assert rtklib_pos.read(commas).time_system == "GPST"


def _error(tmp_path, text):
    with pytest.raises(FormatError) as err:
        rtklib_pos.read(_file(tmp_path, text))
    msg = str(err.value)
    assert "\n" not in msg and isinstance(err.value, EmulatorError)
    return msg


def test_missing_file(tmp_path):
    with pytest.raises(FormatError, match=r"nope.pos: no such file \(RTKLIB solution\)"):
        rtklib_pos.read(tmp_path / "nope.pos")


def test_unsupported_solution_form(tmp_path):
    msg = _error(tmp_path, "% a\n%  GPST    x-ecef(m)    y-ecef(m)\n")
    assert msg.endswith(
        "x.pos:2: x-ecef(m) solution form is not supported: export latitude/"
        "longitude/height in decimal degrees"
    )


def test_wrong_field_count(tmp_path):
    msg = _error(tmp_path, "% h\n2025/07/08 19:34:18.499 40.1 -105.1 1601.4 1 21\n")
    assert msg.endswith(
        "x.pos:2: 5 fields after the time, an RTKLIB lat/lon/height row has 13 "
        "(or 22 with velocities)"
    )
    msg = _error(tmp_path, "2025/07/08 19:34:18.499" + ROW + "\n2025/07/08 19:34:18.749 1 2\n")
    assert msg.endswith("x.pos:2: 2 fields after the time, the rows before have 13")


def test_non_increasing_time(tmp_path):
    text = "2025/07/08 19:34:18.499" + ROW + "\n" + "2025/07/08 19:34:18.499" + ROW + "\n"
    assert _error(tmp_path, text).endswith(
        "x.pos:2: time 2025/07/08 19:34:18.499 is not after the previous row's "
        "2025/07/08 19:34:18.499 (line 1)"
    )


def test_bad_time_and_bad_number(tmp_path):
    msg = _error(tmp_path, "2025-07-08 19:34:18.499" + ROW + "\n")
    assert msg.endswith(
        "x.pos:1: time 2025-07-08 19:34:18.499 is neither yyyy/mm/dd hh:mm:ss nor week sow"
    )
    msg = _error(tmp_path, "2025/07/08 19:34:18.499" + ROW.replace("1601.4740", "16O1.474") + "\n")
    assert msg.endswith("x.pos:1: field 5 is '16O1.474', not a number")


def test_no_rows(tmp_path):
    assert _error(tmp_path, "% only a header\n").endswith("x.pos: no solution rows")
