"""`bench-real` (host_emulator/bench/realdata.py): which replays a folder of recordings gives,
one replay's figures and verdicts, the report; on a simulated drive written as a recording
(the real ones are minutes: make bench-real)."""

import numpy as np
import pytest

from host_emulator.__main__ import main
from host_emulator.bench import realdata
from host_emulator.replay import kfgins
from host_emulator.sim import board_input


def test_the_cases_of_a_folder_of_recordings(tmp_path):
    seg = tmp_path / "tokyo_1105" / "seg01"
    seg.mkdir(parents=True)
    (tmp_path / "ipin_handheld" / "T01_R01").mkdir(parents=True)
    (tmp_path / "ipin_handheld" / "README.md").write_text("not a walk")
    got = realdata.cases(tmp_path)
    assert [c["id"] for c in got] == [
        "tokyo_seg01_1hz_pos", "tokyo_seg01_1hz_pos_noise", "tokyo_seg01_1hz_vel",
        "tokyo_seg01_1hz_vel_noise", "tokyo_seg01_5hz_pos", "tokyo_seg01_5hz_pos_noise",
        "tokyo_seg01_5hz_vel", "tokyo_seg01_5hz_vel_noise", "ipin_T01_R01_pos", "ipin_T01_R01_vel",
    ]  # fmt: skip
    vel5 = got[7]
    assert vel5["kf_gins"].endswith("seg01/dataset_5hz_vel.yaml")
    assert vel5["options"] == {"gnss_rate_hz": 5.0, "gnss_noise_m": realdata.NOISE_M,
                               "gnss_velocity_sigma": 0.0}  # fmt: skip
    assert got[8]["group"] == "walk" and got[8]["kf_gins"].endswith("T01_R01/dataset.yaml")
    # RTK-grade fixes as recorded are reported, the RMS target judged with noise added
    assert [c["rms_target"] for c in got[:2]] == [False, True]
    row = {"group": "drive", "rms_target": False, "horiz_rms_m": 0.5, "fixes_horiz_rms_m": 0.02,
           "nav_after_motion_s": 3.0, "coverage": 1.0, "waypoints": None}  # fmt: skip
    assert realdata.verdicts(row)["rms"] is None


def test_no_recording_is_one_line(tmp_path, capsys):
    assert main(["bench-real", "--data", str(tmp_path), "--out", str(tmp_path / "r.md")]) != 0
    err = capsys.readouterr().err
    assert "no recording there" in err and "Traceback" not in err


@pytest.fixture(scope="module")
def row(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec") / "drive"
    sim = board_input.simulate("urban_drive", 120.0, 0)
    written = kfgins.write(d, kfgins.from_simulation(sim))
    case = {"id": "sim", "group": "drive", "recording": "urban_drive", "variant": "1 Hz",
            "kf_gins": str(written), "options": {"gnss_velocity_sigma": None}}  # fmt: skip
    return realdata.run_case(case)


def test_one_replay_gives_its_figures_and_verdicts(row):
    assert "error" not in row and row["reference"] == "continuous"
    assert 0 < row["horiz_rms_m"] < 5 and 0 < row["fixes_horiz_rms_m"] < 10
    # urban_drive stands for 60 s, then drives: navigating some seconds after that
    assert row["first_motion_s"] == pytest.approx(60.0, abs=2.0)
    assert row["nav_after_motion_s"] == pytest.approx(row["align_time_s"] - row["first_motion_s"])
    v = realdata.verdicts(row)
    assert v["navigates"] is True
    assert v["rms"] == (row["horiz_rms_m"] <= 0.8 * row["fixes_horiz_rms_m"])
    assert v["nav_within"] == (row["nav_after_motion_s"] <= 10.0)
    text = realdata.markdown([row, {**row, "id": "x", "error": "never navigated: why"}], "cmd")
    assert f"| urban_drive | 1 Hz | {row['horiz_rms_m']:.2f} | " in text
    assert "never navigates: never navigated: why" in text
    assert "| navigates at all | 1 | 1 | 0 |" in text
    # what the firmware said of itself: its health 2 share and resets, in the row's last columns
    assert 0.0 <= row["health2_share"] <= 1.0 and row["gnss_resets"] >= 0
    said = f"| {100 * row['health2_share']:.1f} | {row['gnss_resets']} |"
    lines = text.split("\n")
    assert any(ln.startswith("| urban_drive | 1 Hz |") and ln.endswith(said) for ln in lines)


def test_a_walk_is_judged_at_its_waypoints():
    wp = {"n": 3, "firmware": {"n": 3, "median": 2.0, "p75": 2.5, "max": 3.0},
          "fixes": {"n": 3, "median": 2.5, "p75": 3.0, "max": 4.0}}  # fmt: skip
    row = {"group": "walk", "waypoints": wp, "nav_after_motion_s": 12.0, "coverage": 0.97,
           "horiz_rms_m": None, "fixes_horiz_rms_m": None}  # fmt: skip
    assert realdata.verdicts(row) == {"navigates": True, "nav_within": False, "coverage": True,
                                      "waypoints": True}  # fmt: skip
    worse = {**wp, "firmware": {**wp["firmware"], "max": np.float64(5.0)}}
    assert realdata.verdicts({**row, "waypoints": worse})["waypoints"] is False
