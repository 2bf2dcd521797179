"""replay/carrier.py: a walker's steps in the accelerometer choose the handheld profile of a
replay that names none, and a car profile given for a walker's data is said loudly."""

import numpy as np
import pytest

from host_emulator.__main__ import main
from host_emulator.replay import carrier, drive_0708, kfgins, to_stimulus
from host_emulator.sim import imu, trajectory


@pytest.mark.parametrize(
    "name, seed, walking",
    [(w, seed, True) for w in ("walk", "walk_ideal") for seed in range(3)]
    + [("bicycle", 2, False), ("urban_drive", 2, False), ("static", 2, False)],
)  # fmt: skip
def test_a_walkers_steps_and_nothing_else(name, seed, walking):
    """Whole scenarios: the walks (300 s, 30 of them standing) step in 71-79 % of their 4 s
    windows (seeds 0-2), the rest in none."""
    truth = trajectory.SCENARIOS[name](seed=seed)
    g = carrier.gait(imu.simulate(truth, seed=seed).f_b_m_s2, truth.dt_s)
    assert g.walking is walking, g.describe()
    if walking:
        # the cadence is the simulated walker's 1.6-2.2 steps/s
        assert 0.7 < g.share < 0.8 and 1.5 <= g.cadence_hz <= 2.3 and g.amplitude_g > 0.15
    else:
        assert g.stepping == 0 and "no walking steps" in g.describe()
        assert g.strongest_g < carrier.MIN_STEP_G


@pytest.mark.skipif(not drive_0708.DEFAULT_DIR.is_dir(), reason="drive_0708 is not present")
def test_a_real_cars_drive_has_no_steps_and_runs_as_a_car():
    """drive_0708 (a real car): no window with a walker's steps, its strongest at a step's
    rate 0.11 g (a bump), below the 0.15 g a step needs; the replay runs the car profile."""
    rep = to_stimulus.convert(drive_0708.load())
    g = carrier.of_stimulus(rep.stimulus)
    assert g.windows > 100 and g.stepping == 0 and 0.05 < g.strongest_g < 0.13, g
    assert rep.stimulus.config["profile"] == 0 and rep.sources["profile"] == "detected"
    assert any(n.startswith("profile 0 (car): no walking steps") for n in rep.notes)


def test_a_sine_at_the_step_rate_is_found_at_its_amplitude():
    """On a 0.25 Hz bin its amplitude exactly; between two bins up to 15 % low."""
    t = np.arange(0, 40.0, 0.005)
    f = np.zeros((t.size, 3))
    f[:, 2] = 9.80665 * (1.0 + 0.3 * np.sin(2 * np.pi * 2.0 * t))
    g = carrier.gait(f, 0.005)
    assert g.stepping == g.windows == 10
    assert g.cadence_hz == 2.0 and abs(g.amplitude_g - 0.3) < 0.005
    f[:, 2] = 9.80665 * (1.0 + 0.3 * np.sin(2 * np.pi * 1.875 * t))
    assert 0.25 < carrier.gait(f, 0.005).amplitude_g < 0.3
    f[:, 2] = 9.80665 * (1.0 + 0.1 * np.sin(2 * np.pi * 2.0 * t))  # a car's bounce is weaker
    assert carrier.gait(f, 0.005).stepping == 0


def test_a_replay_of_a_walk_runs_handheld_and_says_why(tmp_path):
    assert main(["export", "--scenario", "walk", "--duration", "90", "--seed", "2", "--out",
                 str(tmp_path)]) == 0  # fmt: skip
    ds = kfgins.read(tmp_path)
    rep = to_stimulus.convert(ds)
    assert rep.stimulus.config["profile"] == 1 and rep.sources["profile"] == "detected"
    note = next(n for n in rep.notes if n.startswith("profile"))
    assert "handheld), chosen from the data: a walker's steps" in note
    given = to_stimulus.convert(ds, to_stimulus.ReplayOptions(config=(("profile", 0),)))
    assert given.stimulus.config["profile"] == 0
    assert any(n.startswith("WARNING: profile=0 (car; --set), but a walker") for n in given.notes)
