"""The NumPy float32 model of the navigator (host_emulator/model/nav.py and its mixins) against
the firmware's Navigator (firmware/lib/nav.py on the float32 seam), bit for bit after every
tick.

Both are fed the same simulated drive the way host_emulator/bench/navigator.py feeds the firmware
(BMI055 counts every 5 ms, each GNSS fix at the first tick after it becomes available, with its
PPS tick). After every tick every piece of navigator state is compared through its float32 bit
pattern: p, v, q, C, biases, the 225 elements of P (also between the slices of a propagation
or update), dx, the filter's work buffers, the state-history ring, the corrections, the
standstill detector, the alignment sums, the origin and its coefficients, and all integer
state (tick, state, health, job, slice step, counters). NaN payloads are not compared (any NaN
equals any NaN), as in docs/float32.md. Each scenario also asserts that the features it is
meant to exercise really happened, so it cannot pass vacuously.
"""

import math
from dataclasses import dataclass, field

import numpy as np
import pytest

import eskf
import f32
import geo
import ins as ins_mod
import nav as nav_mod
import nav_align
import navcfg
import yaw_gsf
from host_emulator.bench import navigator as nav_runner
from host_emulator.model.nav import NavModel
from host_emulator.model.yaw_gsf import PARTS as GSF_PARTS
from host_emulator.sim import gnss as sim_gnss
from host_emulator.sim import imu as sim_imu
from host_emulator.sim import trajectory
from nav import CAUSE_GNSS_IMPLAUSIBLE, NAVIGATING, Navigator

F32 = np.float32
DT = trajectory.DT_S
E7_PER_M_NORTH = 1e7 / 111_000.0  # ~ 1e-7 deg of latitude per metre


# ---- scenarios -------------------------------------------------------------------------------


@dataclass
class Drive:
    truth: trajectory.Truth
    imu: sim_imu.ImuData
    fixes: list  # GnssFix, possibly edited
    outage: tuple  # (start_s, length_s) or ()
    gyro: list = field(init=False)
    accel: list = field(init=False)

    def __post_init__(self):
        self.gyro = self.imu.gyro_counts.astype(int).tolist()
        self.accel = self.imu.accel_counts.astype(int).tolist()


def simulate(script, duration_s, seed, outages=(), origin=trajectory.ORIGIN_XIAN,
             gnss_model=None):  # fmt: skip
    truth = trajectory.truth_from_script(script, duration_s, outages=outages, origin=origin)
    imu = sim_imu.simulate(truth, seed=seed)
    gnss = sim_gnss.simulate(truth, gnss_model, seed=seed, outages=outages)
    return truth, imu, list(gnss)


def glitch(fix, metres):
    """The same fix displaced by about `metres` north, east and (1.5x) up: fully gated."""
    lon_per_m = E7_PER_M_NORTH / math.cos(math.radians(fix.lat_e7 * 1e-7))
    return fix._replace(
        lat_e7=fix.lat_e7 + round(metres * E7_PER_M_NORTH),
        lon_e7=fix.lon_e7 + round(metres * lon_per_m),
        h_m=fix.h_m + 1.5 * metres,
    )


def fix_at(fixes, t_s):
    return min(range(len(fixes)), key=lambda i: abs(fixes[i].t_fix_s - t_s))


def city_drive(duration_s):
    """Static start (levelling), away past 3 m/s (heading from the GNSS course), a left turn,
    a 5 s stop (zero-velocity updates), away again, a right turn inside a 12 s GNSS outage,
    re-acquisition, a left turn; gentle grade and bank throughout. One fully gated fix (a 40 m
    jump), one fix above the HDOP limit and one whose speed is 4 m/s off (velocity gated)."""
    s = trajectory.DriveScript(yaw0_rad=0.6)
    s.add_road(np.random.default_rng(11), 1500.0, 0.03, 0.02, (60.0, 150.0), (20.0, 50.0))
    s.hold(6.0)
    s.speed_to(9.0, 1.5)  # past 3 m/s at ~8 s
    s.hold(4.0)
    s.turn(0.5 * math.pi, 0.5)
    s.hold(3.0)
    s.speed_to(0.0, 1.5)
    s.hold(5.0)  # stop: ~30-35 s
    s.speed_to(10.0, 1.5)
    s.hold(4.0)
    s.turn(-0.5 * math.pi, 0.5)  # inside the outage
    s.hold(6.0)
    s.turn(0.25 * math.pi, 0.4)
    s.hold(max(0.0, duration_s - s.t_s))
    outage = (44.0, 12.0)
    truth, imu, fixes = simulate(s, duration_s, seed=21, outages=[outage])
    i = fix_at(fixes, 20.0)
    fixes[i] = glitch(fixes[i], 40.0)
    i = fix_at(fixes, 25.0)
    fixes[i] = fixes[i]._replace(hdop=3.0)
    i = fix_at(fixes, 40.0)
    fixes[i] = fixes[i]._replace(speed_m_s=fixes[i].speed_m_s + 4.0)
    return Drive(truth, imu, fixes, outage)


def fast_drive(duration_s):
    """Static start 250 m west of the 180th meridian, then away to 15 m/s east-south-east on
    a gently curving road: hundreds of metres, across the meridian (longitudes wrap)."""
    s = trajectory.DriveScript(yaw0_rad=-2.0)
    s.hold(6.0)
    s.speed_to(15.0, 2.0)
    s.hold(3.0)
    s.turn(0.3, 0.1, ramp_s=3.0)
    s.hold(max(0.0, duration_s - s.t_s))
    origin = trajectory.Origin(lat_e7=342600000, lon_e7=1799972000, h_m=400.0)
    truth, imu, fixes = simulate(s, duration_s, seed=5, origin=origin)
    return Drive(truth, imu, fixes, ())


def simple_drive(duration_s, offsets_m=tuple(8.0 * k for k in range(1, 13))):
    """For the board's simple model: no fix for the first 2.5 s, static start, away to 8 m/s,
    the fixes from 11 s on offsets_m north and east of the track (by default twelve walking
    away from it, 8 m further each: no jump, nav_aid._jumped, the navigator resets to GNSS,
    and again as they go on), then back on it at once (a jump that undoes no reset: refused,
    nav_aid.refused), a 5 s stop, away again."""
    s = trajectory.DriveScript(yaw0_rad=2.5)
    s.hold(6.0)
    s.speed_to(8.0, 1.5)
    s.hold(2.0)
    s.turn(-0.4 * math.pi, 0.5)
    s.hold(8.0)
    s.speed_to(0.0, 2.0)
    s.hold(5.0)  # stop: ~29.8-34.8 s
    s.speed_to(8.0, 2.0)
    s.hold(max(0.0, duration_s - s.t_s))
    truth, imu, fixes = simulate(s, duration_s, seed=8, outages=[(0.0, 2.5)])
    i = fix_at(fixes, 11.0)
    for k, metres in enumerate(offsets_m, i):
        fixes[k] = glitch(fixes[k], metres)
    return Drive(truth, imu, fixes, ())


def track_drive(duration_s):
    """A receiver without speed and course (the heading comes from the GNSS track): static
    start, a crawl below 3 m/s (a window too slow: the anchor moves on), one fix above the HDOP
    limit (the anchor is dropped), a sharp right turn at 6 m/s (a window turning beyond
    track_turn_max), a 9 s gap without fixes (a window too long), then a steady right curve
    in which the gyro yaw crosses -pi within the window (the wrap) and navigation starts with
    the half-turn correction; a stop (zero-velocity updates from the INS speed alone), away
    again."""
    s = trajectory.DriveScript(yaw0_rad=2.0)
    s.hold(6.0)
    s.speed_to(2.5, 1.0)
    s.hold(3.5)
    s.speed_to(6.0, 1.5)
    s.turn(-2.45, 0.3, ramp_s=1.0)
    s.turn(-1.2, 0.12, ramp_s=1.0)
    s.speed_to(0.0, 2.0)
    s.hold(5.0)
    s.speed_to(8.0, 2.0)
    s.hold(max(0.0, duration_s - s.t_s))
    truth, imu, fixes = simulate(s, duration_s, seed=31)
    fixes = [f._replace(speed_m_s=-1.0, course_deg=math.nan) for f in fixes]
    i = fix_at(fixes, 9.0)
    fixes[i] = fixes[i]._replace(hdop=3.0)
    fixes = [f for f in fixes if not 18.5 < f.t_fix_s < 27.5]
    return Drive(truth, imu, fixes, ())


def car_config(**settings):
    """The car profile with `settings` applied. What a test means to cover is set explicitly,
    so that retuning the defaults cannot silently drop it."""
    cfg = navcfg.NavConfig("car")
    for name, value in settings.items():
        assert hasattr(cfg, name), name
        setattr(cfg, name, value)
    return cfg


# ---- side by side ----------------------------------------------------------------------------


def firmware_snapshot(nav):
    """The firmware's state under the model's names (see NavModel.snapshot)."""
    floats, ints = _firmware_floats(nav), _firmware_ints(nav)
    return floats, {k: int(v) for k, v in ints.items()}


def _firmware_floats(nav):
    """The firmware's float arrays (INS, filter, aligner, watches) by the model's names."""
    ins, kf, fr = nav.ins, nav.kf, nav.frame
    return {
        "p_n": ins.p_n,
        "v_n": ins.v_n,
        "q_bn": ins.q_bn,
        "c_bn": ins.c_bn,
        "bg": ins.bg,
        "ba": ins.ba,
        "dvn_sum": ins.dvn_sum,
        "a_n": ins.a_n,
        "w_ie_n": ins.w_ie_n,
        "p_comp": ins._pk,
        "theta_prev": ins._th_prev,
        "dv_prev": ins._dv_prev,
        "earth_model": ins.x[ins_mod.X_G0 : ins_mod.X_H0 + 1],
        "P": kf.P,
        "dx": kf.dx,
        "kf_A": kf._a,
        "kf_v": kf._v,
        "kf_K": kf._k,
        "kf_f_n": kf._fn,
        "kf_c_bn": kf._c,
        "kf_w_ie_n": kf._w,
        "kf_scalars": kf._s,
        "q_psd": kf.q_psd,
        "p_floor": kf.p_floor,
        "p_ceiling": kf.p_ceiling,
        "w_b": nav._w,
        "f_b": nav._f,
        "still_lp": nav._st,
        "level_sums": nav._lvl,
        "init_diag": nav._init,
        # made at the first fix without a course (zeros until then, as the model's)
        "track": nav._trk[0] if nav._trk is not None else f32.zeros(3 * nav_align._TR_SLOTS),
        "ring_p": nav._ring_p,
        "ring_v": nav._ring_v,
        "corr": nav._corr,
        "drift_watch": f32.view(nav.mem, nav_mod._M_BW, nav_mod._BW_N),
        "suspect_watch": f32.view(nav.mem, nav_mod._M_BS, nav_mod._BW_N),
        "aid_watch": f32.view(nav.mem, nav_mod._M_AW, 2),
        "consistency": f32.view(nav.mem, nav_mod._M_CN, nav_mod._NCN),
        "lag_search": f32.view(nav.mem, nav_mod._M_LS, nav_mod._NLS),
        "gnss_p": nav._gp,
        "fix": nav._fx,
        "used_fix": nav._used,
        "ypr": nav.ypr,
        "frame_coef": fr.coef,
        **{
            name: f32.view(nav.mem, nav_mod._M_GSF + a, b - a) for name, (a, b) in GSF_PARTS.items()
        },
    }


def _firmware_ints(nav):
    """The firmware's integer state (flags, runner controls, counters) by the model's names."""
    kf, fr = nav.kf, nav.frame
    ints = {
        "tick": nav.tick,
        "state": nav.state,
        "health": nav.health,
        "leveled": nav.leveled,
        "still": nav.still,
    }
    ints.update(_runner_controls(nav))
    ints.update(
        {
            "updates": nav.updates,
            "resets": nav.resets,
            "reanchors": nav.reanchors,
            "kf_job": kf.job,
            "kf_step": kf.i[eskf.I_STEP],
            "kf_m": kf.i[eskf.I_M],
            "kf_ready": kf.ready,
            "kf_n_scalars": kf.n_scalars,
            "kf_accepted": kf.accepted,
            "kf_rejected": kf.rejected,
            "kf_gate_mask": kf.gate_mask,
            "origin_lat_e7": fr.lat0_e7,
            "origin_lon_e7": geo.join_e7(fr.lon0_deg, fr.lon0_frac),
            "frame_valid": fr.valid,
            "gsf_state": nav.ctl[nav_mod._C_GSF],
            "gsf_dis": nav.ctl[nav_mod._C_GSF_DIS],
        }
    )
    return ints


def _runner_controls(nav):
    """The navigator's control words (nav_runner.control), by the model's names."""
    return {
        "n_level": nav_runner.control(nav, "n_level"),
        "n_still": nav_runner.control(nav, "n_still"),
        "n_stable": nav_runner.control(nav, "n_stable"),
        "fix_pending": nav_runner.control(nav, "fix_pending"),
        "fix_queued": nav_runner.control(nav, "fix_queued"),
        "used_tick": nav_runner.control(nav, "used_tick"),
        "speed_tick": nav_runner.control(nav, "speed_tick"),
        "trk_set": nav_runner.control(nav, "trk_set"),
        "trk_tick": nav_runner.control(nav, "trk_tick"),
        "fix_lat_e7": nav_runner.control(nav, "fix_lat"),
        "fix_lon_e7": geo.join_e7(
            nav_runner.control(nav, "fix_lon_deg"), nav_runner.control(nav, "fix_lon_frac")
        ),
        "fix_quality": nav_runner.control(nav, "fix_quality"),
        "fix_tick": nav_runner.control(nav, "fix_tick"),
        "last_fix_tick": nav_runner.control(nav, "last_fix_tick"),
        "last_accept_tick": nav_runner.control(nav, "accept_tick"),
        "rejects": nav_runner.control(nav, "rejects"),
        "gated_until": nav_runner.control(nav, "gated_until"),
        "fault_until": nav_runner.control(nav, "fault_until"),
        "sat_until": nav_runner.control(nav, "sat_until"),
        "held_until": nav_runner.control(nav, "held_until"),
        "dead_until": nav_runner.control(nav, "dead_until"),
        "reset_until": nav_runner.control(nav, "reset_until"),
        "data_until": nav_runner.control(nav, "data_until"),
        "causes": nav_runner.control(nav, "causes"),
        "uncertain": nav_runner.control(nav, "uncertain"),
        "v_rejects": nav_runner.control(nav, "v_rejects"),
        "n_held": nav_runner.control(nav, "n_held"),
        "n_same_g": nav_runner.control(nav, "n_same_g"),
        "n_same_a": nav_runner.control(nav, "n_same_a"),
        "inflate": nav_runner.control(nav, "inflate"),
        "drift_until": nav_runner.control(nav, "drift_until"),
        "step_until": nav_runner.control(nav, "step_until"),
        "lag_tick": nav_runner.control(nav, "lag_tick"),
        "since_prop": nav_runner.control(nav, "since_prop"),
        "since_zupt": nav_runner.control(nav, "since_zupt"),
        "since_nhc": nav_runner.control(nav, "since_nhc"),
        "job": nav_runner.control(nav, "job"),
    }


def _flat(floats, names):
    return np.concatenate([np.asarray(floats[k], dtype=F32).ravel() for k in names])


def first_difference(tick, fw, model):
    """A readable account of the first differing field (None if all agree)."""
    fw_f, fw_i = fw
    mo_f, mo_i = model
    for k in mo_i:
        if fw_i[k] != mo_i[k]:
            return f"tick {tick}: {k} firmware {fw_i[k]} model {mo_i[k]}"
    for k in mo_f:
        a = np.asarray(fw_f[k], dtype=F32).ravel()
        b = np.asarray(mo_f[k], dtype=F32).ravel()
        if a.shape != b.shape:
            return f"tick {tick}: {k} shapes {a.shape} vs {b.shape}"
        bad = (a.view(np.uint32) != b.view(np.uint32)) & ~(np.isnan(a) & np.isnan(b))
        if bad.any():
            i = np.flatnonzero(bad)
            return (
                f"tick {tick}: {k}[{i.tolist()[:8]}] firmware {a[i][:8].tolist()} "
                f"model {b[i][:8].tolist()} (bits {a[i][:4].view(np.uint32).tolist()} vs "
                f"{b[i][:4].view(np.uint32).tolist()})"
            )
    return None


@dataclass
class Seen:
    """What happened during a run (firmware side; the model agrees bit for bit)."""

    nav_tick: int | None = None  # first tick in NAVIGATING
    nav_ticks: int = 0
    accepted_gnss: list = field(default_factory=list)  # ticks of accepted GNSS injections
    rejected_gnss: int = 0  # GNSS updates with every position scalar gated out
    partly_gated: int = 0  # GNSS updates with some scalars gated out
    unusable_fixes: int = 0  # quality or HDOP, while navigating
    unusable_aligning: int = 0  # ... while aligning
    timeout_ticks: list = field(default_factory=list)  # health 1 for lack of accepted GNSS
    still_ticks: int = 0
    zupts: int = 0
    nhcs: int = 0
    propagations: int = 0
    floored: int = 0  # ticks with a variance at its floor
    ceiled: int = 0  # ticks with a variance at its ceiling
    origins: set = field(default_factory=set)
    health: set = field(default_factory=set)
    causes: dict = field(default_factory=dict)  # nav.CAUSE_* bits -> ticks


def observe(seen, nav, before):
    t = nav.tick
    kf = nav.kf
    seen.health.add(nav.health)
    seen.causes[nav.causes] = seen.causes.get(nav.causes, 0) + 1
    if nav.frame.valid:
        seen.origins.add((nav.frame.lat0_e7, geo.join_e7(nav.frame.lon0_deg, nav.frame.lon0_frac)))
    new_fix = nav_runner.control(nav, "last_fix_tick") == t and before["last_fix_tick"] != t
    if nav.state != NAVIGATING:
        seen.unusable_aligning += new_fix and not nav._fix_usable()
        return
    if seen.nav_tick is None:
        seen.nav_tick = t
    seen.nav_ticks += 1
    seen.still_ticks += nav.still
    seen.zupts += nav_runner.control(nav, "since_zupt") == 0 and nav.still  # started this tick
    seen.nhcs += nav_runner.control(nav, "since_nhc") == 0
    seen.propagations += nav_runner.control(nav, "since_prop") == 0 and kf.job == 1
    seen.unusable_fixes += new_fix and not nav._fix_usable()
    injected_gnss = before["job"] == 1 and nav_runner.control(nav, "job") == 0
    # rejected: every position row gated (east and north when the fix had no height)
    full = 7 if nav._used[6] >= 0.0 else 3
    if injected_gnss and kf.gate_mask & full == full:
        seen.rejected_gnss += 1
    elif injected_gnss:
        seen.accepted_gnss.append(t)
        seen.partly_gated += kf.gate_mask != 0
    quiet_ticks = t - nav_runner.control(nav, "accept_tick")
    if nav.health == 1 and quiet_ticks > nav_runner.control(nav, "t_timeout"):
        seen.timeout_ticks.append(t)
    d = np.diagonal(np.asarray(kf.P).reshape(15, 15))
    seen.floored += bool(np.any(d == kf.p_floor))
    seen.ceiled += bool(np.any(np.abs(d - kf.p_ceiling) <= 1e-5 * kf.p_ceiling))


def side_by_side(drive, cfg, n_ticks, hooks=None, setup=None, pps=True, heights=True):
    """Feed firmware and model identically for n_ticks, comparing all state after every tick.
    hooks: {tick index k: fn(nav, model, k)} runs instead of tick k's IMU input (the same
    input or edit to both); setup(nav, model) runs once at the start; pps=False hands the
    fixes over without their measurement tick (the navigator assumes its configured latency).
    """
    lever = drive.truth.antenna_b_m  # the simulated receiver's (sim_gnss.simulate)
    for i in range(3):
        cfg.lever_b_m[i] = lever[i]
    nav = Navigator(cfg)
    model = NavModel(cfg)
    if setup:
        setup(nav, model)
    hooks = hooks or {}
    names = list(model.snapshot()[0])
    fixes = [f for f in drive.fixes if f.t_avail_s < n_ticks * DT]
    sat = drive.imu.saturated.tolist()
    fi = 0
    seen = Seen()
    for k in range(n_ticks):
        while fi < len(fixes) and fixes[fi].t_avail_s <= k * DT + 1e-9:
            args, fix_tick = nav_runner.fix_args(fixes[fi], DT, pps=pps)
            kw = {}
            if not heights:  # an RMC-only receiver's fix (nav.gnss: sigma_v_m < 0)
                args = (*args[:2], 0.0, *args[3:])
                kw["sigma_v_m"] = -1.0
            nav_runner.gnss_e7(nav, *args, fix_tick=fix_tick, **kw)
            model.gnss(*args, fix_tick=fix_tick, **kw)
            fi += 1
        before = {
            "last_fix_tick": nav_runner.control(nav, "last_fix_tick"),
            "job": nav_runner.control(nav, "job"),
        }
        if k in hooks:
            hooks[k](nav, model, k)
        else:
            nav.imu_raw(drive.gyro[k], drive.accel[k], sat[k])
            model.imu_raw(drive.gyro[k], drive.accel[k], sat[k])
        fw = firmware_snapshot(nav)
        mo = model.snapshot()
        if fw[1] != mo[1] or not _bits_equal(_flat(fw[0], names), _flat(mo[0], names)):
            pytest.fail("model and firmware differ: " + str(first_difference(nav.tick, fw, mo)))
        observe(seen, nav, before)
    return nav, model, seen


def _bits_equal(a, b):
    same = a.view(np.uint32) == b.view(np.uint32)
    return bool(same.all()) or bool((same | (np.isnan(a) & np.isnan(b))).all())


def assert_gnss_seen(seen, outage):
    assert seen.nav_tick is not None and seen.nav_tick * DT < 12.0, seen.nav_tick
    assert len(seen.accepted_gnss) >= 10
    assert seen.propagations > 50 and seen.nhcs > 10
    if outage:
        start, length = outage
        end = round((start + length) / DT)
        in_outage = [t for t in seen.timeout_ticks if round(start / DT) < t <= end]
        # no accepted fix for the whole outage: the timeout warning holds to its end
        assert len(in_outage) > round((length - 3.0) / DT)
        assert any(t > end for t in seen.accepted_gnss)  # re-acquired


# ---- tests -------------------------------------------------------------------------------------


def test_model_tracks_the_firmware_bit_for_bit_for_a_minute_with_an_outage():
    """> 60 s of navigation of the city drive: levelling, heading from the course, GNSS
    updates (one fully gated, one partly, one unusable), turns (NHC), a stop (ZUPT), a 12 s
    outage inside a turn and the re-acquisition after it."""
    drive = city_drive(80.0)
    n = len(drive.truth.t_s) - 1
    cfg = car_config(earth_terms=True, coning=True, zupt=True, nhc=True, slices_per_tick=1)
    _, _, seen = side_by_side(drive, cfg, n)
    assert seen.nav_ticks * DT > 60.0
    assert_gnss_seen(seen, drive.outage)
    assert seen.rejected_gnss >= 1 and seen.partly_gated >= 1 and seen.unusable_fixes >= 10
    assert seen.zupts >= 3 and seen.still_ticks >= 400
    # warnings for the gated fixes and the outage; nothing that makes health 2 (a fault)
    assert seen.health == {0, 1}
    gnss = nav_mod.CAUSE_GNSS_GATED | nav_mod.CAUSE_GNSS_LOST
    assert {k for k in seen.causes if k} <= {
        nav_mod.CAUSE_NOT_NAVIGATING,  # while it aligns
        nav_mod.CAUSE_GNSS_GATED,
        nav_mod.CAUSE_GNSS_LOST,
        gnss,
    }


def test_model_of_an_accelerometer_step_the_aiding_watch_contains():
    """Every accelerometer count 5 % larger from 16 s on (a scale step: 0.5 m/s^2 on the
    vertical axis): the aiding watch sees the non-holonomic constraint and the zero-velocity
    update broken, says drift (health 2) and widens the vertical velocity and accelerometer-bias
    variances (P grows between jobs without a reset), bit for bit in model and firmware."""
    drive = city_drive(40.0)
    n = len(drive.truth.t_s) - 1
    cfg = car_config(earth_terms=True, coning=True, zupt=True, nhc=True, slices_per_tick=1)
    step = round(16.0 / DT)
    widened = []

    def scaled(nav, model, k):
        i = (eskf.IX_BA + 2) * (eskf.N + 1)
        p_before = float(nav.kf.P[i])
        a = [round(v * 21 / 20) for v in drive.accel[k]]
        nav.imu_raw(drive.gyro[k], a, drive.imu.saturated[k])
        model.imu_raw(drive.gyro[k], a, drive.imu.saturated[k])
        if float(nav.kf.P[i]) > 100 * p_before:
            widened.append(k)

    hooks = {k: scaled for k in range(step, n)}
    nav, _, seen = side_by_side(drive, cfg, n, hooks)
    assert seen.zupts >= 3 and seen.nhcs >= 10
    assert any(k & nav_mod.CAUSE_DRIFT for k in seen.causes) and 2 in seen.health
    assert widened and (widened[0] - step) * DT < 10.0, widened  # measured: after 3.9 s


def test_model_follows_re_anchoring_across_the_180th_meridian():
    """With a 200 m re-anchoring radius the origin moves twice, from east of the meridian to
    west of it. Also: two filter slices per tick, sensor calibration offsets and matrices (the
    input stage's other path), and P floors and ceilings set so that both clamps act."""
    cfg = car_config(earth_terms=True, coning=True, slices_per_tick=2, reanchor_m=f32.f32(200))
    cfg.gyro_bias0[:] = np.array([2e-4, -1e-4, 3e-4], dtype=F32)
    cfg.accel_bias0[:] = np.array([-0.01, 0.02, 0.005], dtype=F32)
    cfg.gyro_matrix = f32.zeros(9)
    cfg.gyro_matrix[:] = np.array([1.001, 2e-4, -1e-4, -3e-4, 0.999, 5e-4, 1e-4, 0, 1.002], F32)
    cfg.accel_matrix = f32.zeros(9)
    cfg.accel_matrix[:] = np.array([0.998, -1e-3, 0, 1e-3, 1.001, 2e-4, 0, -2e-4, 1.0], F32)

    def tight_bounds(nav, model):
        for kf in (nav.kf, model.kf):
            kf.p_ceiling[0:3] = np.array([1.0, 1.0, 4.0], dtype=F32)  # m^2
            kf.p_floor[9:12] = F32(9e-8)  # (0.017 deg/s)^2
            kf.p_floor[14] = F32(1e-5)  # (3 mm/s^2)^2

    drive = fast_drive(42.0)
    n = len(drive.truth.t_s) - 1
    nav, _, seen = side_by_side(drive, cfg, n, setup=tight_bounds)
    assert nav.reanchors >= 2 and len(seen.origins) >= 3
    lons = [lon for _, lon in seen.origins]
    assert max(lons) > 1799000000 and min(lons) < -1799000000
    assert_gnss_seen(seen, ())
    assert seen.floored >= 10 and seen.ceiled >= 10
    assert nav.resets == 0


def test_model_of_a_receiver_back_after_a_reset_followed_it():
    """Fixes that walk away from the track and stay there are reset to (no jump), and the
    reset's step, beyond 3 sigma of the filter's and the fix's variance, holds
    gnss_implausible (Aiding._hold); when they come back at once, the jump undoes that reset
    and is taken at once, not refused as a receiver that jumped (nav_aid.refused), and the
    hold ends with it; bit for bit."""
    cfg = car_config(earth_terms=False, coning=False, zupt=True, nhc=True)
    drive = simple_drive(40.0, (8.0, 16.0, 24.0, 32.0) + (40.0,) * 9)
    nav, _, seen = side_by_side(drive, cfg, len(drive.truth.t_s) - 1)
    assert nav.resets == 2
    held = sum(n for k, n in seen.causes.items() if k & CAUSE_GNSS_IMPLAUSIBLE)
    assert held > 5 * round(1.0 / DT)  # the ~10 s between the resets, not a second's flag
    assert not nav.causes & CAUSE_GNSS_IMPLAUSIBLE


def test_model_of_a_receiver_without_height():
    """The city drive from a receiver that gives no height (RMC only): east and north rows,
    the vertical velocity held at 0 in place of the height row, the unseen-error means kept
    for east and north only, the height reported unknown, and no health fault for the
    vertical variance the filter cannot bound; bit for bit."""
    drive = city_drive(80.0)
    n = len(drive.truth.t_s) - 1
    cfg = car_config(earth_terms=True, coning=False, zupt=True, nhc=True, slices_per_tick=1)
    nav, _, seen = side_by_side(drive, cfg, n, heights=False)
    assert seen.nav_ticks * DT > 60.0
    assert_gnss_seen(seen, drive.outage)
    assert seen.rejected_gnss >= 1 and seen.zupts >= 3
    assert nav._used[6] < 0.0  # nav_aid._US_SIG_V: the last fix had no height
    pd = f32.zeros(15)
    nav.p_diag(pd)
    assert float(pd[2]) >= 1e8 and float(pd[0]) < 10.0  # the height is unknown, east is not
    assert 2 not in seen.health


@pytest.mark.parametrize("heights", [True, False], ids=["gga", "rmc_only"])
def test_model_of_the_simple_board_model_and_the_recovery_paths(heights):
    """earth_terms=False and coning=False (the board's simple model), fixes without their
    PPS tick (arrival minus the configured latency), and the recovery paths: fixes without a
    position while aligning, five rejected fixes (reset to GNSS, twice), a non-finite IMU
    sample (fault), a saturated tick, and a non-finite state (fault reset, re-alignment while
    moving, navigation again)."""
    cfg = car_config(earth_terms=False, coning=False, zupt=True, nhc=True)
    drive = simple_drive(50.0)
    n = len(drive.truth.t_s) - 1

    def saturated(nav, model, k):
        nav.imu_raw(drive.gyro[k], drive.accel[k], True)
        model.imu_raw(drive.gyro[k], drive.accel[k], True)

    def nan_sample(nav, model, k):
        w = f32.zeros(3)
        w[1] = F32(np.nan)
        f = f32.zeros(3)
        f[2] = F32(9.8)
        nav.imu(w, f)
        model.imu(w.copy(), f.copy())

    def blow_up(nav, model, k):
        nav.ins.v_n[0] = F32(np.inf)
        model.ins.v_n[0] = F32(np.inf)
        nav.imu_raw(drive.gyro[k], drive.accel[k])
        model.imu_raw(drive.gyro[k], drive.accel[k])

    hooks = {round(23.0 / DT): nan_sample, round(32.0 / DT): saturated}
    hooks[round(41.0 / DT)] = blow_up
    nav, model, seen = side_by_side(drive, cfg, n, hooks, pps=False, heights=heights)
    assert seen.unusable_aligning >= 2
    assert seen.nav_tick is not None and len(seen.accepted_gnss) >= 5
    assert seen.rejected_gnss >= 5 and nav.resets >= 3  # reset to GNSS twice, fault reset
    assert any(k & CAUSE_GNSS_IMPLAUSIBLE for k in seen.causes)  # the first resets refused
    assert seen.zupts >= 3 and seen.nhcs >= 10
    assert seen.health == {0, 1, 2}
    assert nav.state == NAVIGATING  # navigating again after the fault


def test_model_of_the_start_from_the_gnss_track():
    """No speed and course from the receiver: the track anchor (kept, moved on by a window too
    slow, too long or turning too much, dropped at an unusable fix), the yaw wrap within the
    window, the start from the chord with the half-turn correction and the track's velocity
    sigma, then navigation on positions alone with a stop, all bit for bit."""
    cfg = car_config(earth_terms=True, coning=False, zupt=True, nhc=True, slices_per_tick=1,
                     heading_speed_m_s=f32.f32(3), track_min_m=f32.f32(12),
                     track_max_s=f32.f32(8), yaw_gsf=False)  # fmt: skip
    drive = track_drive(60.0)
    n = len(drive.truth.t_s) - 1
    anchors = []  # the anchor fix's time (s) whenever the anchors start anew
    start_p_vel = []

    def anchor(nav):
        return nav_runner.control(nav, "trk_set"), nav_runner.control(nav, "trk_tick")

    def tick(nav, model, k):
        held = anchor(nav)
        was = nav.state
        nav.imu_raw(drive.gyro[k], drive.accel[k])
        model.imu_raw(drive.gyro[k], drive.accel[k])
        if anchor(nav)[0] == 1 and anchor(nav) != held:
            anchors.append(round(anchor(nav)[1] * DT))
        if was != NAVIGATING and nav.state == NAVIGATING:
            start_p_vel.append(float(nav.kf.P[3 * 16]))

    nav, _, seen = side_by_side(drive, cfg, n, hooks=dict.fromkeys(range(n), tick))
    # 4 s: first; 14: after the unusable fix at 9 s (5 stable fixes again); 18: a window of
    # 4 s whose chord reached 12 m turning beyond 30 deg; after the 9 s gap the anchors are
    # older than track_max_s, so the start's window begins at 28 s
    assert anchors == [4, 14, 18], anchors
    # the 28-32 s window: track_s (4 s) long, its chord beyond 12 m
    assert 32.0 < seen.nav_tick * DT < 32.5, seen.nav_tick
    assert start_p_vel == [float(cfg.track_vel_sigma) ** 2]
    assert nav_runner.control(nav, "speed_tick") == -1000000  # no fix had a speed
    assert len(seen.accepted_gnss) >= 15 and seen.zupts >= 3 and seen.still_ticks >= 400
    assert nav.resets == 0 and nav.state == NAVIGATING


def test_model_of_a_receiver_whose_fixes_are_late():
    """Fixes 0.15 s older than their stamps, stop-and-go, 0.05 s of it set (gnss_stamp_lag_s):
    the set lag, the lag search's residuals and running means, the rest found and applied, and
    the fixes compared with the state of that moment, bit for bit."""
    s = trajectory.DriveScript(yaw0_rad=-0.4)
    s.add_road(np.random.default_rng(5), 1500.0, 0.02, 0.01, (60.0, 150.0), (20.0, 50.0))
    s.hold(4.0)
    for _ in range(4):
        s.speed_to(12.0, 2.0)
        s.hold(3.0)
        s.turn(0.3 * math.pi, 0.4)
        s.speed_to(3.0, 2.0)
        s.hold(2.0)
    duration = s.t_s + 2.0
    s.hold(2.0)
    truth, imu, fixes = simulate(s, duration, seed=8,
                                 gnss_model=sim_gnss.GnssModel(stamp_lag_s=0.15))  # fmt: skip
    drive = Drive(truth, imu, fixes, ())
    cfg = car_config(earth_terms=True, coning=False, zupt=True, nhc=True, slices_per_tick=1,
                     gnss_lag_learn=True, gnss_stamp_lag_s=np.float32(0.05))  # fmt: skip
    applied = []

    def tick(nav, model, k):
        nav.imu_raw(drive.gyro[k], drive.accel[k])
        model.imu_raw(drive.gyro[k], drive.accel[k])
        applied.append(int(nav.mem[nav_mod._M_CN + nav_mod._CN_LAGT]))

    n = len(truth.t_s) - 1
    nav, _, _ = side_by_side(drive, cfg, n, hooks=dict.fromkeys(range(n), tick))
    assert nav.state == NAVIGATING and max(applied) > 0, max(applied)
    assert sum(a > 0 for a in applied) > 2000  # applied over 10 s at least
    # the set 0.05 s is 10 ticks; the search applies the 0.1 s left (measured: median 20)
    assert nav.ctl[nav_mod._C_T_STAMP_LAG] == 10
    assert 16 <= sorted(applied)[len(applied) // 2] <= 24, sorted(applied)[len(applied) // 2]


def test_model_of_the_yaw_estimator_start_and_reset():
    """The yaw estimator (yaw_gsf.py) on the city drive: its bank from the first levelled fix,
    navigation started from it alone (no course start), the bank's offsets kept relative to
    the navigator through every yaw correction; then at 40 s the navigator's heading turned 60
    deg off, as a start from a course that is not the heading would leave it (the bank told of
    the turn, as of any start's): the bank disagrees, the navigator's fixes are gated,
    and the heading is reset to the bank's, all bit for bit."""
    cfg = car_config(earth_terms=True, coning=False, zupt=True, nhc=True, slices_per_tick=1,
                     yaw_gsf=True, heading_from_course=False,
                     yaw_gsf_ready_sigma=f32.from_bits(0x3F000000))  # 0.5 rad  # fmt: skip
    drive = city_drive(70.0)
    n = len(drive.truth.t_s) - 1
    k_turn = round(40.0 / DT)
    off = f32.from_bits(0x3F860A92)  # 1.0472 rad
    offsets = []  # the bank's offset from the navigator's heading, each second navigating

    def turn(nav, model, k):
        # the heading turned by `off` as a correction turns it (the filter's job left as it
        # is), and the bank told, as a start or a reset tells it
        e, dx = nav.kf.e, model.kf.dx
        kept, kept_m = [e[eskf.E_DX + i] for i in range(eskf.N)], dx.copy()
        for i in range(eskf.N):
            e[eskf.E_DX + i] = 0.0
        e[eskf.E_DX + eskf.IX_ATT + 2] = off
        nav._apply_dx()
        model.kf.dx = np.zeros(eskf.N, np.float32)
        model.kf.dx[eskf.IX_ATT + 2] = off
        model._apply_dx()
        for i in range(eskf.N):
            e[eskf.E_DX + i] = kept[i]
        model.kf.dx = kept_m
        nav._turned(off)
        model._turned(off)
        watch(nav, model, k)

    def watch(nav, model, k):
        nav.imu_raw(drive.gyro[k], drive.accel[k])
        model.imu_raw(drive.gyro[k], drive.accel[k])
        if k % 200 == 0 and nav.state == NAVIGATING:
            offsets.append((k * DT, float(nav.mem[nav_mod._M_GSF + yaw_gsf._G_YAW]), nav.resets))

    hooks = dict.fromkeys(range(n), watch)
    hooks[k_turn] = turn
    nav, _, seen = side_by_side(drive, cfg, n, hooks=hooks)
    assert nav.ctl[nav_mod._C_GSF] == 1
    # the start came from the bank, before the first turn (the course start is off)
    assert seen.nav_tick is not None and seen.nav_tick * DT < 12.0, seen.nav_tick
    before = [abs(y) for t, y, _ in offsets if 30.0 <= t < 40.0]
    after = [y for t, y, _ in offsets if 41.0 <= t < 43.0]
    end = [abs(y) for t, y, _ in offsets if t >= 60.0]
    resets = {t: r for t, _, r in offsets}
    assert before and max(before) < 0.1, offsets  # the bank agrees with the navigator
    assert after and all(y < -0.5 for y in after), offsets  # ... sees the turn at once
    # a reset after the turn, none before it, and health 2 (CAUSE_RESET) until a fix agrees
    assert resets[40.0] == 0 and nav.resets >= 1, offsets
    assert any(k & nav_mod.CAUSE_RESET for k in seen.causes)
    assert end and max(end) < 0.15, offsets  # and after the reset agrees again (9 deg)
