"""The yaw estimator's bank (firmware/lib/yaw_gsf.py): its exponential, the native kernels
against the Python reference bit for bit, and the heading it finds on a simulated walk with
the board held across the way it goes (the NumPy model's agreement: tests/model)."""

import math

import numpy as np
import pytest

from common import firmware_env
from host_emulator.bench import navigator as nav_runner
from host_emulator.sim import gnss as sim_gnss
from host_emulator.sim import imu as sim_imu
from host_emulator.sim import trajectory

firmware_env.install()
import f32  # noqa: E402
import kern  # noqa: E402
import nav as nav_mod  # noqa: E402
import navcfg  # noqa: E402
import yaw_gsf  # noqa: E402

G = nav_mod._M_GSF


def test_exp_neg_is_the_exponential_where_the_weights_need_it():
    ys = np.linspace(0.0, 40.0, 4001, dtype=np.float32)
    got = np.array([float(yaw_gsf.exp_neg(f32.f32(float(y)))) for y in ys])
    want = np.exp(-ys.astype(float))
    rel = np.abs(got - want) / want
    assert rel[ys <= 4.0].max() < 1e-5
    assert rel[ys <= 16.0].max() < 5e-4
    assert rel[ys < 32.0].max() < 0.012
    assert (got[ys >= 32.0] == 0.0).all()
    assert float(yaw_gsf.exp_neg(f32.f32(0))) == 1.0


def _bank_after(steps, native, seed, chord=False):
    """A Navigator's mem after `steps` bank steps on random sums and fixes, through the native
    kernels or the Python reference; `chord`: the first fix without speed (the bank starts at
    the second, from the chord)."""
    rng = np.random.default_rng(seed)
    nav = nav_mod.Navigator(navcfg.NavConfig("handheld"))
    m, c = nav.mem, nav.ctl
    accum = kern.navk.gsf_accum if native else yaw_gsf.gsf_accum
    step = kern.navk.gsf_step if native else yaw_gsf.gsf_step
    c[nav_mod._C_STATE] = nav_mod.NAVIGATING
    results = []
    for s in range(steps):
        for _ in range(int(rng.integers(20, 220))):
            for i in range(3):
                m[nav_mod._M_F + i] = f32.f32(
                    float(rng.normal(0.0, 2.0)) + (9.8 if i == 2 else 0.0)
                )
            accum(m)
        for i in range(2):
            m[nav_mod._M_GP + i] = f32.f32(float(rng.normal(0.0, 5.0)) + s)
        speed = float(rng.uniform(-1.0, 3.0))
        m[nav_mod._M_FX + nav_mod._FX_SPEED] = f32.f32(-1.0 if chord and s == 0 else speed)
        m[nav_mod._M_FX + nav_mod._FX_COURSE] = f32.f32(float(rng.uniform(-0.5, 6.0)))
        m[nav_mod._M_FX + nav_mod._FX_SIG_H] = f32.f32(float(rng.uniform(0.0, 6.0)))
        m[nav_mod._M_FX + nav_mod._FX_HDOP] = f32.f32(float(rng.uniform(0.5, 2.0)))
        m[G + yaw_gsf._G_DYAW] = f32.f32(float(rng.normal(0.0, 0.3)))
        c[nav_mod._C_TICK] += 200
        c[nav_mod._C_FIX_TICK] = c[nav_mod._C_TICK] - int(rng.integers(-5, 40))
        results.append(step(c, m))
    return np.asarray(m).view(np.uint32).copy(), results


@pytest.mark.skipif(not kern.NATIVE, reason="the native kernels are not built (make native)")
@pytest.mark.parametrize("chord", [False, True], ids=["at-rest", "chord"])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_native_bank_is_the_python_reference_bit_for_bit(seed, chord):
    native, r_native = _bank_after(40, True, seed, chord)
    python, r_python = _bank_after(40, False, seed, chord)
    sl = slice(G, G + yaw_gsf.NG)
    assert r_native == r_python and any(r_native)
    diff = np.flatnonzero(native[sl] != python[sl])
    assert diff.size == 0, diff
    # and the bank moved: weights apart, offsets apart from their start
    w = native[sl].view(np.float32)[yaw_gsf._G_HYP + yaw_gsf._H_W :: yaw_gsf._NH]
    assert w.max() > 2.0 * w.min()


def _two_fixes(speed, native=False):
    """A car's bank after two fixes 1 s apart, 10 m apart eastward, at 10 m/s east and
    accelerating 1 m/s^2 north in the navigator's frame (yaw offset 0 is the truth): each
    hypothesis's velocity and its covariance, and the bank's state after each fix."""
    nav = nav_mod.Navigator(navcfg.NavConfig("car"))
    m, c = nav.mem, nav.ctl
    accum = kern.navk.gsf_accum if native else yaw_gsf.gsf_accum
    step = kern.navk.gsf_step if native else yaw_gsf.gsf_step
    x = nav_mod._M_X
    for i in range(9):  # level, no accelerometer bias
        m[x + 10 + i] = f32.f32(1.0 if i in (0, 4, 8) else 0.0)
    states = []
    for k in range(2):
        for i in range(2):
            m[nav_mod._M_GP + i] = f32.f32(10.0 * k if i == 0 else 0.5 * k)
        m[nav_mod._M_FX + nav_mod._FX_SPEED] = f32.f32(speed)
        m[nav_mod._M_FX + nav_mod._FX_COURSE] = f32.f32(-1.0)
        m[nav_mod._M_FX + nav_mod._FX_SIG_H] = f32.f32(1.5)
        step(c, m)
        states.append(c[nav_mod._C_GSF])
        if k == 0:
            m[nav_mod._M_F + 1] = f32.f32(1.0)
            m[nav_mod._M_F + 2] = f32.f32(9.8)
            for _ in range(200):
                accum(m)
    h = np.asarray(m[G + yaw_gsf._G_HYP : G + yaw_gsf._G_HYP + yaw_gsf.GSF_N * yaw_gsf._NH],
                   float).reshape(yaw_gsf.GSF_N, yaw_gsf._NH)  # fmt: skip
    return h, states


@pytest.mark.parametrize("native", [False, True], ids=["python", "native"])
def test_a_receiver_without_speed_starts_the_bank_from_the_chord(native):
    """The first fix without speed is held; the second starts every hypothesis at the chord's
    velocity (10 m/s east) plus the interval's added 0.5 m/s (0.4975 in 200 ticks), turned
    by its offset: the true one (offset 0, between the 3rd and 4th at +-30 deg) 0.5 m/s north.
    Position and velocity share the fix's noise. At rest instead (a fix with a speed 0), the
    second fix's update leaves every velocity 4-6 m/s short of the car's."""
    if native and not kern.NATIVE:
        pytest.skip("the native kernels are not built (make native)")
    h, states = _two_fixes(-1.0, native)
    assert states == [yaw_gsf.GSF_HELD, yaw_gsf.GSF_ON]
    yaw = h[:, 4]
    want_e = 10.0 - 0.5 * np.sin(yaw)
    want_n = 0.5 + 0.5 * np.cos(yaw)
    assert np.allclose(h[:, 2], want_e, atol=5e-3) and np.allclose(h[:, 3], want_n, atol=5e-3)
    p = h[:, yaw_gsf._H_P : yaw_gsf._H_W].reshape(-1, 7, 7)
    assert np.allclose(p[:, 0, 0], 2.25) and np.allclose(p[:, 0, 2], 2.25)
    assert np.allclose(p[:, 2, 0], 2.25) and np.allclose(p[:, 3, 1], 2.25)
    assert (p[:, 2, 2] > 4.5).all() and (p[:, 2, 2] < 5.0).all()  # two fixes' 2 x 2.25, more
    at_rest, states = _two_fixes(0.0, native)
    assert states == [yaw_gsf.GSF_ON, yaw_gsf.GSF_ON]
    assert (np.abs(at_rest[:, 2] - 10.0) > 4.0).all()  # one update from rest: 4-6 m/s short


def _ready(state, var, velocity, native):
    """gsf_step's READY bit for a bank whose variance comes out as `var` (one hypothesis,
    every weight on it), aligning or navigating, at a fix with or without velocity."""
    nav = nav_mod.Navigator(navcfg.NavConfig("car"))
    m, c = nav.mem, nav.ctl
    c[nav_mod._C_STATE] = state
    c[nav_mod._C_GSF] = yaw_gsf.GSF_ON
    for k in range(yaw_gsf.GSF_N):
        h = G + yaw_gsf._G_HYP + k * yaw_gsf._NH
        m[h + yaw_gsf._H_W] = f32.f32(1.0 if k == 0 else 0.0)
        m[h + yaw_gsf._H_P + 32] = f32.f32(var)
    m[nav_mod._M_FX + nav_mod._FX_SPEED] = f32.f32(1.0 if velocity else -1.0)
    m[nav_mod._M_FX + nav_mod._FX_COURSE] = f32.f32(0.5 if velocity else -1.0)
    result = kern.navk.gsf_step if native else yaw_gsf.gsf_step
    return bool(result(c, m) & yaw_gsf.GSF_READY)


@pytest.mark.parametrize("native", [False, True], ids=["python", "native"])
def test_positions_alone_start_at_half_the_sigma_and_never_reset(native):
    """Ready under yaw_gsf_ready_sigma at a fix with velocity; on positions alone only while
    aligning and under half of it (a quarter of the variance); navigating, never on positions
    (no reset from them)."""
    if native and not kern.NATIVE:
        pytest.skip("the native kernels are not built (make native)")
    ready = float(navcfg.NavConfig("car").yaw_gsf_ready_sigma) ** 2
    al, nv = nav_mod.ALIGNING, nav_mod.NAVIGATING
    assert _ready(al, 0.9 * ready, True, native) and not _ready(al, 1.1 * ready, True, native)
    assert not _ready(al, 0.3 * ready, False, native)
    assert _ready(al, 0.2 * ready, False, native)
    assert _ready(nv, 0.2 * ready, True, native) and not _ready(nv, 0.2 * ready, False, native)


def _across(gsf):
    """highway_outage with the board turned 90 deg across the car (its x axis forward), the
    handheld profile (no non-holonomic constraint): the navigator's heading error (deg) each
    second it navigates from 5 s after its start, and its resets."""
    truth = trajectory.SCENARIOS["highway_outage"](120.0, 1)
    imu = sim_imu.simulate(truth, seed=1)
    gnss = sim_gnss.simulate(truth, seed=1)
    for counts in (imu.gyro_counts, imu.accel_counts):  # car body (x, y) is board (-y, x)
        x = counts[:, 0].copy()
        counts[:, 0] = counts[:, 1]
        counts[:, 1] = -x
    cfg = navcfg.NavConfig("handheld")
    cfg.yaw_gsf = gsf
    nav = nav_mod.Navigator(cfg)
    errors = []

    def on_tick(nav, k):
        if k % 200 == 0 and nav.state == nav_mod.NAVIGATING:
            board_yaw = float(truth.ypr[k + 1, 0]) + math.pi / 2
            errors.append(math.degrees(math.remainder(float(nav.euler()[0]) - board_yaw,
                                                      2 * math.pi)))  # fmt: skip

    nav_runner.feed(nav, imu, gnss, 0, len(truth.t_s) - 1, on_tick=on_tick)
    return errors[5:], nav.resets


def test_the_bank_finds_the_heading_of_a_board_across_the_way_it_moves():
    """The course says where the car goes, not where the board points: started from it the
    heading is 90 deg off, and the filter alone is still more than 40 deg off 50 s later (with
    the learned velocity noise, nav_kern.vel_noise, it undoes the rest after a minute and
    more); the bank finds it from the motion alone
    (the receiver's velocity and the IMU's specific force), within 10 deg throughout."""
    with_bank, _ = _across(True)
    course_only, resets = _across(False)
    assert len(with_bank) > 60 and max(abs(e) for e in with_bank) < 10.0, with_bank
    assert min(abs(e) for e in course_only[:45]) > 40.0, course_only
    assert resets > 0  # the course start's filter keeps rejecting its fixes


def _watch(nav):
    """_gsf_watch of a navigator (or the model) whose bank disagrees: (its answer, how many
    resets it asked for)."""
    resets = []
    nav._gsf_step = lambda: nav_mod._GSF_DISAGREES
    nav._gsf_reset = lambda: resets.append(1)
    return nav._gsf_watch(), len(resets)


@pytest.mark.parametrize("jumped", [False, True])
def test_a_receiver_that_jumped_does_not_reset_the_heading(jumped):
    """A receiver that jumped makes the navigator reject its fixes and the bank, fed the same
    fixes, disagree: that is no sign of a wrong heading, and the reset (position and velocity
    from the fix) would follow the receiver (2000 km off, in `make bench-faults`). Without the
    jump the same evidence resets the heading. The NumPy model decides alike."""
    from host_emulator.model.nav import NavModel

    cfg = navcfg.NavConfig("car")
    nav = nav_mod.Navigator(cfg)
    c = nav.ctl
    c[nav_mod._C_TICK] = 100000
    c[nav_mod._C_GSF_DIS] = 1
    c[nav_mod._C_REJECTS] = 3
    c[nav_mod._C_JUMPED] = 1 if jumped else 0
    assert c[nav_mod._C_T_GSF] < 100000 - 1
    assert _watch(nav) == (not jumped, 0 if jumped else 1)

    model = NavModel(cfg)
    model.tick, model.gsf_dis, model.rejects, model.jumped = 100000, 1, 3, jumped
    assert _watch(model) == (not jumped, 0 if jumped else 1)
