"""Bringing one's own recording to `replay --kf-gins`: the defaults (no
outages, scored from t0), --score-from, board settings (--set and dataset.yaml's board:),
GNSS epochs at any time (no PPS, decimation, nothing dropped silently), the messages for the
usual mistakes (units, separator, header, week), why a run never navigated, and the console's
wording. Datasets are made in tmp_path from a simulated drive (urban_drive: 60 s at rest,
then city driving)."""

import dataclasses
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pymap3d
import pytest

from common.errors import EmulatorError
from common.proto import config as board_config
from common.proto import stimulus as stim_mod
from host_emulator.__main__ import main
from host_emulator.replay import dataset as dsm
from host_emulator.replay import kfgins, replay_run, run_config
from host_emulator.replay import to_stimulus as ts
from host_emulator.replay.formats import FormatError
from host_emulator.sim import board_input
from host_emulator.sim import gnss as gnss_mod
from host_emulator.sim import imu as imu_mod
from host_emulator.sim import trajectory as tr

REPO = Path(__file__).resolve().parents[2]


def _quiet(*_a):
    pass


@pytest.fixture(scope="module")
def drive():
    """urban_drive's first 120 s as a Dataset (navigation starts at ~64 s)."""
    return kfgins.from_simulation(board_input.simulate("urban_drive", 120.0, 0))


@pytest.fixture(scope="module")
def written(drive, tmp_path_factory):
    return kfgins.write(tmp_path_factory.mktemp("own") / "drive", drive)


def _gnss_at(ds, t_s, sigma_m=1.5, seed=3, velocity=False):
    """GNSS fixes of the reference (the IMU's point: use with lever 0) at times t_s, white
    noise sigma_m per horizontal axis and twice that vertically; with its velocity if asked."""
    tr = ds.truth
    lat, lon, h = (np.interp(t_s, tr.t_s, x) for x in (tr.lat_deg, tr.lon_deg, tr.h_m))
    n = np.random.default_rng(seed).standard_normal((t_s.size, 3)) * [sigma_m, sigma_m, 2 * sigma_m]
    lat, lon, h = pymap3d.ned2geodetic(n[:, 0], n[:, 1], n[:, 2], lat, lon, h)
    sig = np.tile([sigma_m, sigma_m, 2 * sigma_m], (t_s.size, 1))
    v = None
    if velocity:
        v = np.stack([np.interp(t_s, tr.t_s, tr.v_ned_m_s[:, j]) for j in range(3)], axis=-1)
    return dsm.Positions(t_s, np.asarray(lat), np.asarray(lon), np.asarray(h), sig, v)


def _with_gnss(ds, t_s, **kw):
    return dataclasses.replace(ds, gnss=_gnss_at(ds, t_s, **kw), lever_frd_m=(0.0, 0.0, 0.0))


def _first_second(ds):
    return math.ceil(ds.imu.t_s[0])


def _replay(ds, tmp_path, **opts):
    opt = replay_run.kfgins_options(ds, **opts)
    return replay_run.replay(ds, opt, out_dir=tmp_path, show_progress=False, log=_quiet)


# --- defaults, --score-from, the console ---


def test_kf_gins_runs_as_it_is_and_says_recording(written, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["replay", "--kf-gins", str(written), "--out", str(out), "--quiet"]) == 0
    said = capsys.readouterr().out
    m = json.loads((out / "metrics.json").read_text())
    assert m["outages"] == [] and m["metrics_from_s"] == m["t0_s"]  # no outage, from t0
    assert m["align_time_s"] is not None and m["horiz_rms_m"] is not None
    assert "recording urban_drive: 119.0 s, firmware on cpython" in said
    assert "simulated drive" not in said and "seed" not in said  # no noise was added
    assert "GNSS: 118 epochs at up to 1 Hz, NMEA at 9600 baud, a PPS edge at each" in said
    # nothing left out silently: of the 121 epochs (sim time 0 to 120 s) the two before the
    # run's first whole second + 0.5 s and the last (after the end - 0.5 s) are counted
    assert "3 epochs of the GNSS file (gnss.txt) fall outside the replayed span" in said
    assert m["notes"] and m["board_config_sources"]["gyro_range_dps"] == "replay"


def test_drive_0708_keeps_its_protocol():
    """--dataset drive_0708 without options is the published protocol; --kf-gins is not."""
    opt = ts.ReplayOptions()
    assert opt.outages == ((60.0, 15.0), (200.0, 15.0), (400.0, 15.0)) and opt.skip_s == 30.0
    assert opt.gnss_rate_hz == 1.0 and opt.gnss_noise_m == 1.5 and opt.seed == 1
    own = replay_run.kfgins_options()
    assert own.outages == () and own.skip_s == 0.0
    assert dataclasses.replace(own, outages=opt.outages, skip_s=30.0) == opt


def test_help_states_the_defaults(capsys):
    with pytest.raises(SystemExit):
        main(["replay", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "default: drive_0708 60+15,200+15,400+15, its protocol; --kf-gins none" in text
    assert "--score-from S score from S seconds after t0 (default: drive_0708 30" in text
    assert "--kf-gins 0)" in text and "--set NAME=VALUE" in text


def test_score_from(written, tmp_path):
    m = _replay(kfgins.read(written), tmp_path, skip_s=80.0)
    assert m["metrics_from_s"] == m["t0_s"] + 80.0
    m0 = json.loads((tmp_path / "metrics.json").read_text())
    assert m0["metrics_from_s"] == m["metrics_from_s"]
    with pytest.raises(EmulatorError, match=r"--score-from 200: scoring would start 201.0 s"):
        _replay(kfgins.read(written), tmp_path, skip_s=200.0)


def test_outages_after_the_end_are_said_not_applied(written, tmp_path):
    m = _replay(kfgins.read(written), tmp_path, outages=((70.0, 10.0), (500.0, 15.0)))
    assert [o["start_s"] for o in m["outages"]] == [m["t0_s"] + 70.0]
    assert "outage 500+15 s begins after the replay's end: not applied" in m["notes"]


# --- board settings ---


def test_set_reaches_the_firmware(written, tmp_path, capsys):
    """--set goes into the ins.cfg the emulated board loads: it changes what the firmware
    does, and the run records the settings it used."""
    out = tmp_path / "a"
    argv = ["replay", "--kf-gins", str(written), "--out", str(out), "--quiet"]
    assert main([*argv, "--set", "profile=1", "--set", "gnss_uere_m=3.5"]) == 0
    said = capsys.readouterr().out
    m = json.loads((out / "metrics.json").read_text())
    assert m["board_config"]["profile"] == 1 and m["board_config"]["gnss_uere_m"] == 3.5
    assert m["board_config_sources"]["profile"] == "--set"
    assert "profile=1 (--set)" in said and "gnss_uere_m=3.5 (--set)" in said
    stim = stim_mod.read(out / "stimulus.bin")  # the run's input carries them to ins.cfg
    cfg = board_config.decode(board_config.to_bytes(stim.config))
    assert cfg.profile == 1 and float(cfg.gnss_uere_m) == 3.5
    # the same run without them navigates differently (handheld: no ZUPT/NHC, another R)
    assert main([*argv[:-3], "--out", str(tmp_path / "b"), "--quiet"]) == 0
    assert (out / "frames.bin").read_bytes() != (tmp_path / "b" / "frames.bin").read_bytes()


def test_an_hdop_gate_below_the_fixes_never_navigates_and_says_why(drive, tmp_path, capsys):
    """--set gnss_hdop_max reaches the firmware's HDOP gate: fixes whose sd columns make every
    third one's HDOP 10 (sigma / their median) against a gate of 1.5 never give 5 usable fixes
    in a row, and the replay says why. (A gate below the fixes' usual HDOP 1 itself, 0.5, is
    refused: docs/benchmarks/settings.md.)"""
    gnss = _gnss_at(drive, np.arange(_first_second(drive) + 1.0, drive.truth.t_s[-1] - 1, 1.0))
    gnss.sigma_ned_m[::3] *= 10.0
    ds = dataclasses.replace(drive, gnss=gnss, lever_frd_m=(0.0, 0.0, 0.0))
    path = kfgins.write(tmp_path / "ds", ds)
    argv = ["replay", "--kf-gins", str(path), "--out", str(tmp_path / "out"), "--quiet"]
    assert main([*argv, "--set", "gnss_hdop_max=1.5"]) == 1
    err = capsys.readouterr().err
    assert "never 5 usable GNSS fixes in a row" in err and "gnss_hdop_max 1.5 (--set" in err


@pytest.mark.parametrize(
    ("setting", "says"),
    [
        (
            "gyro_arw=5",
            "--set gyro_arw=5: the firmware refuses it: gyro_arw must be within 0.00001..0.003",
        ),
        ("gyro_ar=5", "--set gyro_ar=5: unknown setting 'gyro_ar'; the settings are: profile"),
        ("lever_b_m=1,2", "lever_b_m takes 3 comma-separated numbers, got 2"),
        ("profile=car", "profile must be an integer, got 'car'"),
        ("output_every_ticks=2", "a replay runs with output_every_ticks=1"),
        ("ext_every_ticks=0", "ext_every_ticks=0 (--set): the score reads the extended frames"),
    ],
)
def test_bad_set_is_one_line(written, tmp_path, capsys, setting, says):
    argv = ["replay", "--kf-gins", str(written), "--out", str(tmp_path), "--set", setting]
    assert main([*argv, "--quiet"]) == 1
    err = capsys.readouterr().err
    assert says in err and err.count("\n") == 1 and "Traceback" not in err


def test_set_help_lists_the_settings(capsys):
    assert main(["replay", "--kf-gins", "x", "--set", "help"]) == 0
    out = capsys.readouterr().out
    assert "gyro_arw = 0.000488692   (0.00001..0.003 rad/s/sqrt(Hz))" in out
    assert "gyro_range_dps = 250   (one of 125, 250, 500, 1000, 2000)" in out


BOARD = """\
board:   # this sensor's settings
  gyro_arw: 0.0017
  still_gyro: 0.0524   # rad/s
  gyro_bias0: [0.001, -0.002, 0.0005]
  profile: 1
"""


def test_board_section_of_dataset_yaml(written, tmp_path):
    d = tmp_path / "ds"
    d.mkdir()
    for f in written.iterdir():
        (d / f.name).write_bytes(f.read_bytes())
    (d / "dataset.yaml").write_text((written / "dataset.yaml").read_text() + BOARD)
    ds = kfgins.read(d)
    assert ds.board_config == {
        "gyro_arw": 0.0017, "still_gyro": 0.0524, "gyro_bias0": [0.001, -0.002, 0.0005],
        "profile": 1,
    }  # fmt: skip
    # the dataset's settings reach the run; --set overrides them
    rep = ts.convert(ds, replay_run.kfgins_options(ds, config=(("profile", 0),)))
    cfg = rep.stimulus.config
    assert cfg["gyro_arw"] == 0.0017 and cfg["gyro_bias0"] == [0.001, -0.002, 0.0005]
    assert cfg["profile"] == 0 and rep.sources["profile"] == "--set"
    assert rep.sources["gyro_arw"] == "dataset"
    assert "gyro_arw=0.0017 (dataset)" in run_config.describe(cfg, rep.sources)
    # written back as a board: block (export keeps them)
    kfgins.write(tmp_path / "again", ds)
    assert kfgins.read(tmp_path / "again").board_config == ds.board_config


@pytest.mark.parametrize(
    ("block", "says"),
    [
        ("board:\n  gyro_arw: 5\n", ":14: board: gyro_arw=5: the firmware refuses it: gyro_arw"),
        ("board:\n  no_such: 1\n", ":14: board: no_such=1: unknown setting 'no_such'"),
        ("board:\n  lever_b_m: [1, 2]\n", ":14: board: lever_b_m=1, 2: lever_b_m takes 3"),
        ("board: 3\n", ":13: board takes indented 'name: value' lines below it"),
        ("gnssfile:\n  x: 1\n", "gnssfile given twice"),
        (
            "board:\n  profile: 1\n  profile: 0\n",
            ":15: board: profile given twice (first on line 14)",
        ),
    ],
)
def test_bad_board_section(written, tmp_path, block, says):
    for f in written.iterdir():
        (tmp_path / f.name).write_bytes(f.read_bytes())
    (tmp_path / "dataset.yaml").write_text((written / "dataset.yaml").read_text() + block)
    with pytest.raises(FormatError) as e:
        kfgins.read(tmp_path)
    assert says in str(e.value) and "\n" not in str(e.value)


# --- GNSS epochs at any time ---


def test_epochs_between_the_seconds_go_without_pps_and_keep_their_accuracy(drive, tmp_path):
    """1 Hz at x.5 s: sent at their own times without PPS (the firmware would stamp them by
    the edge of their second, 0.5 s off), gnss_latency_s set to their measured completion
    latency; as accurate as the same receiver at whole seconds with PPS, and clearly better
    than with the default latency of 0.1 s. The receiver's velocity is sent too, so that the
    heading at the start comes from its course, the same in all three runs (from the track
    it varies by up to 20 deg with the fixes' noise and would hide the timing). The wrong
    latency is judged with the lag search off (gnss_lag_learn 0); with it on, the search
    finds most of the ~0.2 s the wrong latency leaves. Measured (horizontal RMS with GNSS,
    whole / x.5 / x.5 at 0.1 s without / with the search): 0.81 / 0.85 / 2.89 / 1.39 m (56 s
    scored)."""
    t1 = _first_second(drive) + 1.0
    whole = _with_gnss(drive, np.arange(t1, drive.truth.t_s[-1] - 1.0, 1.0), velocity=True)
    half = _with_gnss(drive, np.arange(t1 + 0.5, drive.truth.t_s[-1] - 1.0, 1.0), velocity=True)
    rep = ts.convert(half, replay_run.kfgins_options(half))
    assert not rep.pps and (rep.stimulus.pps_before_us == -1).all()
    assert np.allclose(rep.gnss.t_fix_s % 1.0, 0.5)
    # 9600 baud: GGA GSA RMC, ~230 bytes, complete ~0.32 s after the epoch (0.1 s latency)
    assert 0.25 <= rep.stimulus.config["gnss_latency_s"] <= 0.4
    assert rep.stimulus.config["gnss_latency_s"] == rep.latency_s
    assert any("no PPS" in n for n in rep.notes)
    speed = {"gnss_velocity_sigma": 0.05}
    m_whole = _replay(whole, tmp_path / "w", **speed)
    m_half = _replay(half, tmp_path / "h", **speed)
    off = ("gnss_lag_learn", 0)  # the lag search would find most of a wrong latency
    m_late = _replay(half, tmp_path / "l", config=(("gnss_latency_s", 0.1), off), **speed)
    m_found = _replay(half, tmp_path / "f", config=(("gnss_latency_s", 0.1),), **speed)
    assert m_whole["gnss_pps"] and not m_half["gnss_pps"]
    assert abs(m_half["horiz_rms_gnss_m"] - m_whole["horiz_rms_gnss_m"]) < 0.4
    assert m_late["horiz_rms_gnss_m"] > 2.0 * max(
        m_half["horiz_rms_gnss_m"], m_whole["horiz_rms_gnss_m"]
    )
    assert any("gnss_latency_s = 0.1 s (--set; the epochs complete" in n for n in m_late["notes"])
    # with the search on, the ~0.2 s the wrong latency leaves is found: most of the loss back
    assert m_found["horiz_rms_gnss_m"] < 0.6 * m_late["horiz_rms_gnss_m"], (m_found, m_late)


def test_faster_receivers_are_decimated_and_counted(drive):
    t1 = _first_second(drive) + 1.0
    t_end = drive.truth.t_s[-1] - 1.0
    on_grid = _with_gnss(drive, t1 + np.arange(int((t_end - t1) * 10)) / 10.0)
    rep = ts.convert(on_grid, replay_run.kfgins_options(on_grid))  # default: 1 Hz, whole seconds
    n = len(on_grid.gnss)
    sent = rep.gnss.t_fix_s.size
    assert rep.pps and np.allclose(rep.gnss.t_fix_s % 1.0, 0.0)
    assert (
        f"{n - sent} epochs of the GNSS file off the 1 Hz grid (--gnss-rate): not sent" in rep.notes
    )
    fast = ts.convert(on_grid, replay_run.kfgins_options(on_grid, gnss_rate_hz=10.0))
    assert fast.gnss.t_fix_s.size == n and not fast.pps
    assert fast.stimulus.config["gnss_baud"] == 57600  # 230 bytes in half of 0.1 s
    # 10 Hz off the grid (x.05): the first epoch of each second, at its own time
    off = _with_gnss(drive, t1 + 0.05 + np.arange(int((t_end - t1) * 10)) / 10.0)
    rep = ts.convert(off, replay_run.kfgins_options(off))
    assert np.allclose(rep.gnss.t_fix_s % 1.0, 0.05) and not rep.pps
    kept = rep.gnss.t_fix_s.size
    assert (
        f"{len(off.gnss) - kept} epochs of the GNSS file after the first in their 1 s"
        in " ".join(rep.notes)
    )


def test_gnss_baud_set_by_hand_is_used_or_refused(drive):
    t1 = _first_second(drive) + 1.0
    ds = _with_gnss(drive, t1 + np.arange(int((drive.truth.t_s[-1] - 1 - t1) * 10)) / 10.0)
    opt = replay_run.kfgins_options(ds, gnss_rate_hz=10.0, config=(("gnss_baud", 115200),))
    assert ts.convert(ds, opt).stimulus.config["gnss_baud"] == 115200
    opt = replay_run.kfgins_options(ds, gnss_rate_hz=10.0, config=(("gnss_baud", 9600),))
    with pytest.raises(EmulatorError, match=r"gnss_baud 9600 \(--set\)"):
        ts.convert(ds, opt)


def test_a_reference_off_the_grid_is_interpolated(drive):
    """Without a GNSS file the input is made from the reference; one without samples on the
    whole seconds (200 Hz, 2.5 ms off them) is interpolated there, with PPS."""
    truth = dataclasses.replace(drive.truth, t_s=drive.truth.t_s + 0.0025)
    rep = ts.convert(
        dataclasses.replace(drive, gnss=None, truth=truth), replay_run.kfgins_options()
    )
    assert rep.pps and np.allclose(rep.gnss.t_fix_s % 1.0, 0.0)
    assert (
        "the reference has no samples on the 1 Hz grid: the GNSS input is interpolated"
        in (rep.notes[0])
    )


def test_a_range_set_by_hand_clips_and_says_so(drive):
    imu = dataclasses.replace(drive.imu, gyro_rad_s=drive.imu.gyro_rad_s * 10.0)  # up to ~200 deg/s
    ds = dataclasses.replace(drive, imu=imu)
    assert ts.convert(ds, replay_run.kfgins_options(ds)).stimulus.config["gyro_range_dps"] >= 250
    rep = ts.convert(ds, replay_run.kfgins_options(ds, config=(("gyro_range_dps", 125),)))
    counts = stim_mod.gyro_counts(rep.stimulus.gyro_regs)
    clipped = int((np.abs(counts) >= 32767).any(axis=1).sum())
    assert clipped > 100 and rep.stimulus.config["gyro_range_dps"] == 125
    assert (
        f"{clipped} gyro samples beyond +-125 (gyro_range_dps from --set) clipped" in rep.notes[0]
    )


def test_bad_epochs_are_counted(drive):
    ds = _with_gnss(drive, np.arange(_first_second(drive) + 1.0, drive.truth.t_s[-1] - 1, 1.0))
    ds.gnss.lat_deg[[10, 11, 30]] = np.nan
    ds.gnss.sigma_ned_m[[40, 41], :2] = [np.nan, 0.0]
    rep = ts.convert(ds, replay_run.kfgins_options(ds))
    assert "3 epochs of the GNSS file without a finite position: not sent" in rep.notes
    assert rep.gnss.t_fix_s.size == len(ds.gnss) - 3
    assert "2 epochs of the GNSS file without a usable sd_n/sd_e: sent with HDOP 1.00" in (
        " ".join(rep.notes)
    )
    assert np.all(rep.gnss.hdop == 1.0)  # every other sigma is the median one


# --- the mistakes a user makes with the files ---


def _files(written, tmp_path, imu=None, yaml=None, nav=None, gnss=None):
    for f in written.iterdir():
        (tmp_path / f.name).write_bytes(f.read_bytes())
    for name, fn in (("imu.txt", imu), ("dataset.yaml", yaml), ("truth.nav", nav),
                     ("gnss.txt", gnss)):  # fmt: skip
        if fn is not None:
            p = tmp_path / name
            p.write_text(fn(p.read_text()))
    return tmp_path


def _columns(f):
    """A function rewriting every row of a whitespace table with f(list of floats)."""

    def rewrite(text):
        rows = (line.split() for line in text.splitlines() if line.strip())
        return "".join(" ".join(f"{x:.10g}" for x in f([float(v) for v in r])) + "\n" for r in rows)

    return rewrite


def _read_error(path):
    with pytest.raises(EmulatorError) as e:
        kfgins.read(path)
    msg = str(e.value)
    assert "\n" not in msg
    return msg


RATE = 200.0  # the simulation's IMU rate: intervals of 1/200 s


@pytest.mark.parametrize(
    ("f", "says"),
    [
        (lambda r: [r[0], *(x * RATE for x in r[1:])],
         "the dv columns look like accelerations in m/s^2 rather than velocity increments"),
        (lambda r: [r[0], *(x * RATE for x in r[1:4]), *(x * RATE / 9.80665 for x in r[4:])],
         "the dv columns look like accelerations in g"),
        (lambda r: [r[0], *(x / 9.80665 for x in r[1:])],
         "the dv columns look like increments in g s: multiply them by 9.80665"),
        (lambda r: [r[0], *(x * RATE for x in r[1:4]), *r[4:]],
         "the gyro columns look like rates (in rad/s, by their size)"),
        (lambda r: [r[0], *(math.degrees(x * RATE) for x in r[1:4]), *r[4:]],
         "the gyro columns look like rates (in deg/s, by their size) rather than angle"),
        (lambda r: [r[0] * 1000.0, *r[1:]], "is sow in milliseconds?"),
    ],
)  # fmt: skip
def test_units_mistakes_say_what_to_do(written, tmp_path, f, says):
    msg = _read_error(_files(written, tmp_path, imu=_columns(f)))
    assert "imu.txt: " in msg and says in msg


def test_wrong_imudatarate(written, tmp_path):
    msg = _read_error(
        _files(written, tmp_path, yaml=lambda t: t.replace("imudatarate: 200", "imudatarate: 100"))
    )
    assert "the rows are 0.005 s apart (median), imudatarate 100 Hz says 0.01 s" in msg
    assert "set imudatarate to 200" in msg


@pytest.mark.parametrize(
    ("rewrite", "says"),
    [
        (lambda t: t.replace(" ", ","),
         "imu.txt:1: 1 columns, IMU rows have 7 or 8: the line holds commas"),
        (lambda t: t.replace(" ", ";"), "the line holds semicolons"),
        (lambda t: "sow gx gy gz ax ay az\n" + t,
         "imu.txt:1: column 1 is 'sow', not a number: a header line?"),
    ],
)  # fmt: skip
def test_separator_and_header(written, tmp_path, rewrite, says):
    assert says in _read_error(_files(written, tmp_path, imu=rewrite))


def test_week_mismatch_names_files_and_weeks(written, tmp_path):
    week = kfgins.read(written).gpsweek
    d = _files(
        written, tmp_path, yaml=lambda t: t.replace(f"gpsweek: {week}", f"gpsweek: {week - 1}")
    )
    with pytest.raises(EmulatorError) as e:
        ts.convert(kfgins.read(d), replay_run.kfgins_options())
    msg = str(e.value)
    assert f"the reference (truth.nav) covers GPS week {week} sow" in msg
    assert f"the IMU (imu.txt) GPS week {week - 1} sow" in msg
    assert (
        f"1 GPS week(s) apart: the .nav's week column ({week}) and dataset.yaml's gpsweek "
        f"({week - 1}) may disagree"
    ) in msg


def test_gnss_file_of_another_week(written, tmp_path):
    d = _files(written, tmp_path, gnss=_columns(lambda r: [r[0] + 604800.0, *r[1:]]))
    with pytest.raises(EmulatorError) as e:
        ts.convert(kfgins.read(d), replay_run.kfgins_options())
    assert re.search(r"the GNSS file \(gnss.txt\) covers GPS week \d+ ", str(e.value))
    assert "1 GPS week(s) apart: the files' sow columns" in str(e.value)


def test_too_short_overlap_says_both_spans(written, tmp_path):
    def cut(text):
        rows = text.splitlines()
        return "\n".join(rows[: int(len(rows) * 0.1)]) + "\n"

    d = _files(written, tmp_path, nav=cut)
    with pytest.raises(EmulatorError) as e:
        ts.convert(kfgins.read(d), replay_run.kfgins_options())
    assert re.match(r"only 1\d\.\d s to replay: the IMU \(imu.txt\) covers GPS week ", str(e.value))
    assert "the reference (truth.nav) GPS week" in str(e.value)
    assert str(e.value).endswith("a replay needs 20 s of both")


def test_a_dataset_beyond_every_range_asks_about_units(drive):
    imu = dataclasses.replace(drive.imu, gyro_rad_s=drive.imu.gyro_rad_s * 1000)
    with pytest.raises(EmulatorError) as e:
        ts.convert(dataclasses.replace(drive, imu=imu), replay_run.kfgins_options())
    assert "beyond the BMI055's largest range (+-2000 deg/s): are its rates in the right" in str(
        e.value
    )


# --- why the firmware never navigated ---


def _heading_speed_m_s():
    """The firmware's default heading_speed_m_s (navcfg), as the diagnosis reads it."""
    return float(run_config.nav_config(run_config.defaults()).heading_speed_m_s)


def test_never_navigated_standing_still(tmp_path, capsys):
    kf = tmp_path / "kf"
    assert main(["export", "--scenario", "urban_drive", "--duration", "50", "--out", str(kf)]) == 0
    capsys.readouterr()
    assert main(["replay", "--kf-gins", str(kf), "--out", str(tmp_path / "o"), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(
        "error: the firmware never navigated on urban_drive: no course in the fixes (RMC speed "
        "and course empty), and their track never "
    )
    cfg = run_config.nav_config(
        run_config.defaults()
    )  # the firmware's track: a chord of track_min_m
    assert f"never covered track_min_m {float(cfg.track_min_m):g} m in track_s to" in err
    assert "the reference moves at most 0.00 m/s" in err and err.count("\n") == 1


def _slow_drive():
    """60 s: 20 s at rest, then 0.7 m/s (a course: over RMC's 0.5 m/s, below the heading
    speed); ideal IMU, 1 Hz fixes of 1.5 m."""
    script = tr.DriveScript(yaw0_rad=0.3)
    script.hold(20.0)
    script.speed_to(0.7, 0.5)
    truth = tr.truth_from_script(script, 60.0, name="slow", description="a slow walk")
    imu = imu_mod.simulate(truth, imu_mod.ImuModel.ideal(), seed=0)
    gnss = gnss_mod.simulate(truth, None, seed=0)
    return kfgins.from_simulation(board_input.Simulation("slow", 0, truth, imu, gnss, None, 0))


def test_never_navigated_below_the_heading_speed(tmp_path):
    """With the receiver's speed and course sent (made from the reference): the speed
    against heading_speed_m_s of the configuration the run used."""
    hs = _heading_speed_m_s()
    assert hs > 0.75  # the drive's 0.7 m/s stays below it
    ds = dataclasses.replace(_slow_drive(), gnss=None)
    with pytest.raises(EmulatorError) as e:
        _replay(ds, tmp_path, gnss_velocity_sigma=0.02)
    msg = str(e.value)
    assert f"the GNSS speed never reached heading_speed_m_s {hs:g} m/s (at most 0.7" in msg
    assert "replay a part of the recording where it drives" in msg


def test_never_navigated_all_in_outages(written, tmp_path):
    with pytest.raises(EmulatorError) as e:
        _replay(kfgins.read(written), tmp_path, outages=((0.0, 1000.0),))
    assert "no GNSS fix was sent (118 epochs: every epoch falls in an outage" in str(e.value)


def test_never_navigated_never_levelled(drive, tmp_path):
    imu = dataclasses.replace(drive.imu, accel_m_s2=drive.imu.accel_m_s2 / 9.80665)  # in g
    with pytest.raises(EmulatorError) as e:
        _replay(dataclasses.replace(drive, imu=imu), tmp_path)
    assert re.search(
        r"it never levelled: the accelerometer's mean specific force over 2 s is at most 1\.0\d "
        r"m/s\^2, where gravity gives 9\.8",
        str(e.value),
    )


# --- the worked example of docs/formats.md ---


def test_worked_example_in_formats_md(tmp_path):
    """The doc's commands and conversion script, run as written (in tmp_path): the foreign
    CSVs are made from an exported simulation, converted, replayed."""
    doc = (REPO / "docs" / "formats.md").read_text()
    blocks = re.findall(r"<!-- example:(\w+) -->\n```\w*\n(.*?)```", doc, re.S)
    assert [name for name, _ in blocks] == ["make_foreign", "convert", "commands"]
    code = dict(blocks)
    (tmp_path / "make_foreign.py").write_text(code["make_foreign"])
    (tmp_path / "convert.py").write_text(code["convert"])
    env = {"PYTHONPATH": str(REPO), "PATH": str(Path(sys.executable).parent) + ":/usr/bin:/bin"}
    out = []
    for line in code["commands"].splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        cmd = line.replace("python ", f"{sys.executable} ", 1).replace("$REPO", str(REPO))
        r = subprocess.run(cmd, shell=True, cwd=tmp_path, env=env, capture_output=True, text=True)
        assert r.returncode == 0, (cmd, r.stderr)
        out.append(r.stdout)
    m = json.loads((tmp_path / "out" / "metrics.json").read_text())
    said = "".join(out)
    assert "recording my_drive" in said and m["board_config"]["gyro_arw"] == 0.001
    assert m["board_config_sources"]["gyro_arw"] == "dataset"
    assert not m["gnss_pps"] and m["align_time_s"] is not None
    assert m["horiz_rms_m"] < 5.0
