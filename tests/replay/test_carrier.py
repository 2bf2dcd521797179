"""replay/carrier.py: a walker's steps in the accelerometer choose the handheld profile of a
replay that names none, and a car profile given for a walker's data is said loudly."""

import numpy as np
import pytest

from host_emulator.__main__ import main
from host_emulator.replay import carrier, kfgins, to_stimulus
from host_emulator.sim import imu, trajectory


@pytest.mark.parametrize(
    "name, walking",
    [("walk", True), ("walk_ideal", True), ("bicycle", False), ("urban_drive", False),
     ("static", False)],
)  # fmt: skip
def test_a_walkers_steps_and_nothing_else(name, walking):
    truth = trajectory.SCENARIOS[name](duration_s=120.0, seed=2)
    g = carrier.gait(imu.simulate(truth, seed=2).f_b_m_s2, truth.dt_s)
    assert g.windows == 30 and g.walking is walking, g.describe()
    if walking:
        # 90 s of the 120 s walk; the cadence is the simulated walker's 1.6-2.2 steps/s
        assert 0.5 < g.share < 0.85 and 1.5 <= g.cadence_hz <= 2.3 and g.amplitude_g > 0.15
    else:
        assert g.stepping == 0 and "no walking steps" in g.describe()


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
