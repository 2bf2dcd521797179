"""bench-nav --trial: one scenario with navigator settings changed, means on stdout, nothing
written; the tuning figures in firmware/lib/navcfg.py come from it."""

import re

import pytest

from host_emulator.bench import navigation


def _trial(capsys, *argv):
    assert navigation.main(["--trial", "walk", "--seeds", "1", "--jobs", "1", *argv]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    return line, float(re.search(r"horiz ([0-9.]+) m", line).group(1))


def test_a_trial_runs_the_setting_it_is_given(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    line, horiz_10 = _trial(capsys)
    assert line.startswith("walk (handheld), GGA + RMC at 1 Hz white, seeds 0-0:")
    line, horiz_2 = _trial(capsys, "--nav", "level_s=2")
    assert "level_s=2" in line and horiz_2 != horiz_10  # the setting reached the navigator
    # the simulated sensors' fields and the GNSS error model reach the simulation
    line, horiz_imu = _trial(capsys, "--imu", "gyro_noise_dps_rt_hz=0.1")
    assert "gyro_noise_dps_rt_hz=0.1" in line and horiz_imu != horiz_10
    line, horiz_real = _trial(capsys, "--realistic", "--gnss", "sigma_h_m=3")
    assert "1 Hz realistic" in line and "sigma_h_m=3" in line and horiz_real != horiz_10
    assert not any(tmp_path.iterdir())  # nothing written


@pytest.mark.parametrize(
    "argv, says",
    [
        (["--trial", "walk", "--nav", "no_such=1"], "not a setting of firmware/lib/navcfg.py"),
        (["--trial", "walk", "--nav", "level_s=x"], "is not a number"),
        (["--trial", "jog"], "unknown scenario 'jog'"),
        (["--trial", "walk", "--rate", "3"], "--rate must be 1, 2, 4, 5 or 10 Hz"),
        (["--nav", "level_s=5"], "go with --trial"),
        (["--realistic"], "go with --trial"),
        (["--trial", "walk", "--imu", "no_such=1"], "not a number field of ImuModel"),
        (["--trial", "walk", "--gnss", "baud=fast"], "is not a number"),
    ],
)
def test_a_bad_trial_is_a_usage_error(argv, says, capsys):
    with pytest.raises(SystemExit) as e:
        navigation.main(argv)
    assert e.value.code == 2 and says in capsys.readouterr().err


def test_the_velocity_noise_rows_reach_the_receiver_and_the_report():
    """Each velocity noise is a walk_real run per seed; its row sets the runs' means beside
    the 0.05 m/s of the walk's own runs."""
    tasks = [t for t in navigation._tasks(2) if t[3].startswith("velocity noise")]
    assert tasks == [("walk_real", s, True, f"velocity noise: {v:g} m/s")
                     for v in navigation.VEL_NOISE_M_S for s in (0, 1)]  # fmt: skip

    def run(h, nees):
        return {"horiz_rms_m": h, "gnss_horiz_rms_m": 3.0, "vel_rms_m_s": 1.0,
                "yaw_rms_deg": 20.0, "resets": 2.0, "pos_3sigma_cover": 0.9,
                "pos_nees_h": nees}  # fmt: skip

    results = {
        ("walk_real", 0, True, "handheld"): run(2.0, 1.0),
        ("walk_real", 1, True, "handheld"): run(3.0, 2.0),
        ("walk_real", 0, True, "velocity noise: 0.3 m/s"): run(6.0, 7.0),
        ("walk_real", 1, True, "velocity noise: 0.3 m/s"): run(8.0, 9.0),
    }
    text = "\n".join(navigation._vel_noise_lines(results))
    row = "| walk_real (handheld) | {} | 3.00 | 1.000 | 20.0 | 2.0 | 90 % | {} |"
    assert row.format("0.05 | 2.50", "1.50") in text
    assert row.format("0.3 | 7.00", "8.00") in text
    assert "| 0.5 |" not in text  # no runs, no row
