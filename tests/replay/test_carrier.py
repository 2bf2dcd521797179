"""replay/carrier.py: a walker's steps in the accelerometer or a hand's tilting in the gyro
choose the handheld profile of a replay that names none, and a car profile given for a
walker's data is said loudly."""

import numpy as np
import pytest

from common.firmware_env import REPO_DIR
from host_emulator.__main__ import main
from host_emulator.replay import carrier, drive_0708, kfgins, replay_run, to_stimulus
from host_emulator.sim import imu, trajectory

DATA = REPO_DIR.parent / "shared" / "data"


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


def _gait(name, seed):
    truth = trajectory.SCENARIOS[name](seed=seed)
    data = imu.simulate(truth, seed=seed)
    return carrier.gait(data.f_b_m_s2, truth.dt_s, data.w_b_rad_s)


@pytest.mark.parametrize("seed", range(8))
def test_a_hand_as_held_tilts_and_a_bicycle_does_not_enough(seed):
    """A hand held in front (walk_real: steps of 0.02-0.2 g, no heel strikes) steps in no
    window but tilts in 83-100 % of them; the simulated bicycle, leaning and pedalled, tilts
    in 19-44 % (under the 60 % of a hand), the car drives in none."""
    hand = _gait("walk_real", seed)
    assert hand.stepping == 0 and hand.held and hand.walking, hand.describe()
    assert hand.tilt_share > 0.8 and hand.describe().startswith("a hand's tilting in")
    bike = _gait("bicycle", seed)
    assert not bike.walking and 0.1 < bike.tilt_share < 0.5, bike.describe()
    if seed < 2:
        car = _gait("urban_drive", seed)
        assert car.tilting == 0 and car.tilt_dps < 1.0 and not car.walking, car.describe()


def test_the_tilt_rate_is_the_rate_about_the_horizontal_without_its_mean():
    """A steady turn about the vertical and a constant bias count nothing; a 1 Hz rocking
    of 10 deg/s amplitude about a horizontal axis reads its rms, 7.07 deg/s."""
    t = np.arange(0, 40.0, 0.005)
    f = np.tile([0.0, 0.0, 9.80665], (t.size, 1))
    w = np.zeros((t.size, 3))
    w[:, 2] = 0.5  # a turn about the vertical
    w[:, 0] = np.radians(0.2)  # a bias about x
    assert np.all(carrier.tilt_rates_dps(w, f, 0.005) < 1e-9)
    w[:, 1] += np.radians(10.0) * np.sin(2 * np.pi * 1.0 * t)
    rates = carrier.tilt_rates_dps(w, f, 0.005)
    # 0.1 s means attenuate a 1 Hz sine by sinc(0.1): 1.6 %
    assert rates.shape == (10,) and np.allclose(rates, 7.07 * 0.984, rtol=0.01)
    assert not carrier.gait(f, 0.005, w).held  # 7 deg/s: under the 8 of a hand


@pytest.mark.skipif(not (DATA / "ipin_handheld").is_dir(), reason="ipin_handheld is not present")
@pytest.mark.parametrize("walk", ["T01_R01", "T01_R03", "T02_R03", "T02_R04"])
def test_a_real_hand_held_walk_without_heel_strikes_runs_handheld(walk):
    """Real phone walks (ipin_handheld) step in 0-40 % of their windows (0.14-0.20 g): these
    four in 0-3 %, too few; they tilt in 69-82 %: the replay runs them handheld."""
    ds = replay_run.load_dataset(kf_gins=str(DATA / "ipin_handheld" / walk / "dataset.yaml"))
    rep = to_stimulus.convert(ds)
    g = carrier.of_stimulus(rep.stimulus)
    assert not g.stepping_walker and 0.65 < g.tilt_share < 0.85, g.describe()
    assert rep.stimulus.config["profile"] == 1 and rep.sources["profile"] == "detected"
    note = next(n for n in rep.notes if n.startswith("profile"))
    assert note.startswith("profile 1 (handheld), chosen from the data: a hand's tilting")


@pytest.mark.skipif(not (DATA / "tokyo_1105").is_dir(), reason="tokyo_1105 is not present")
def test_real_city_drives_do_not_tilt_like_a_hand():
    """Every tokyo_1105 segment: no window tilts (medians 0.03-1.6 deg/s), a car profile."""
    for seg in sorted((DATA / "tokyo_1105").glob("seg[0-9]*")):
        rep = to_stimulus.convert(replay_run.load_dataset(kf_gins=str(seg / "dataset.yaml")))
        g = carrier.of_stimulus(rep.stimulus)
        assert g.tilting == 0 and g.tilt_dps < 2.0, (seg.name, g.describe())
        assert rep.stimulus.config["profile"] == 0, seg.name


@pytest.mark.skipif(not drive_0708.DEFAULT_DIR.is_dir(), reason="drive_0708 is not present")
def test_a_real_cars_drive_has_no_steps_and_runs_as_a_car():
    """drive_0708 (a real car): no window with a walker's steps, its strongest at a step's
    rate 0.11 g (a bump), below the 0.15 g a step needs; 1 % of its windows tilt (median
    1.5 deg/s); the replay runs the car profile."""
    rep = to_stimulus.convert(drive_0708.load())
    g = carrier.of_stimulus(rep.stimulus)
    assert g.windows > 100 and g.stepping == 0 and 0.05 < g.strongest_g < 0.13, g
    assert g.tilt_share < 0.05 and 1.0 < g.tilt_dps < 2.0, g
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
