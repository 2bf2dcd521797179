"""Parity of the host emulator: the firmware loop on CPython (the cpython runtime) and the
NumPy float32 model (model/app.py) produce the same output stream, byte for byte, and a
difference is found and reported with the tick and the field's name."""

import dataclasses

import numpy as np
import pytest

from common import firmware_env
from common.proto import records as rec_schema
from common.proto import stimulus, stream
from host_emulator.eval import parity
from host_emulator.model import app as model_runner
from host_emulator.model import rot as ref_rot
from host_emulator.sim import board_input
from host_emulator.sim import gnss as sim_gnss

F32 = np.float32
NAV_START_TICK = 30 * 200  # highway_outage stands still for 30 s, then accelerates


@pytest.fixture(scope="module")
def highway():
    """50 s of highway_outage: 30 s standing (levelling), away to 30 m/s, navigation from
    ~37 s with GNSS updates and the non-holonomic constraint."""
    return board_input.simulate("highway_outage", 50.0, seed=0).stimulus


@pytest.fixture(scope="module")
def highway_parity(highway):
    calls = []
    r = parity.compare(highway, progress=lambda k, n: calls.append((k, n)))
    return r, calls


def _frames(out):
    d = stream.decode(out)
    assert d.bad_checksum == d.bad_crc == d.skipped_bytes == 0
    return d


def test_parity_holds_through_levelling_heading_and_navigation(highway, highway_parity):
    r, calls = highway_parity
    assert r.identical, r.summary()
    assert r.frame.compared == r.frame.count("firmware") == 10000 and r.frame.first is None
    assert r.ext.compared == 500 and r.ext.identical and r.raw.count("firmware") == 0
    assert sorted(set(calls)) == [(k, 10000) for k in range(2000, 10001, 2000)]
    assert calls[-1] == (10000, 10000) and len(calls) >= 10  # both sides, to the end
    # not vacuous: the stream shows a fix every second, a heading, and navigation with a
    # covariance the filter keeps working on
    d = _frames(r.out_firmware)
    states = np.array([f["nav_state"] for f in d.frames])
    nav = np.flatnonzero(states == 2)
    assert nav[0] > NAV_START_TICK and len(nav) > 10 * 200 and (states[nav[0] :] == 2).all()
    assert sum(f["gga"] for f in d.frames) == 50 and sum(f["pps"] for f in d.frames) == 50
    speed = np.hypot(*np.array([f["vel_enu_m_s"][:2] for f in d.frames[-200:]]).T)
    assert (speed > 20.0).all()
    p_pos = np.array([e["p_diag"][0] for e in d.ext if e["nav_state"] == 2])
    assert len(set(p_pos.tolist())) > 50  # propagations and GNSS updates change P
    # normal but for the simulated receiver's damaged RMC: its epoch is released at it, without
    # a speed (no overdue epoch, no gap in the fixes), and the rejected sentence is seen on the
    # next PPS edge (a warning for a second); and not_navigating while it aligns
    bits = {name: bit for bit, name in rec_schema.CAUSES}
    nmea, aligning = bits["nmea_errors"], bits["not_navigating"]
    seen = {(e["health"], e["causes"]) for e in d.ext}
    assert seen == {(0, 0), (1, nmea), (1, aligning)}


def test_a_flipped_state_bit_is_found_at_its_tick_and_named(highway, highway_parity):
    """One bit of the model's north velocity flipped before the navigator's step at tick K:
    the first differing frame is K's, and the report names the velocity field."""
    r0, _ = highway_parity
    k_flip = 9000  # 45 s: navigating at ~30 m/s

    def flip(k, model):
        if k == k_flip:
            assert model.state == 2
            v = model.ins.v_n.copy()
            v.view(np.uint32)[1] ^= 1 << 22  # the top mantissa bit: several m/s
            model.ins.v_n = v

    out = model_runner.run(highway, tick_hook=flip)
    r = parity.compare_streams(r0.out_firmware, out)
    assert not r.identical
    assert r.frame.first == r.frame.tick == k_flip and r.frame.compared == 10000
    fields = {f.name: f for f in r.frame.fields}
    assert "vel_n_cm_s" in fields and "checksum" in fields
    f = fields["vel_n_cm_s"]
    assert f.labels == ("firmware", "model") and abs(f.values[0] - f.values[1]) > 100  # 1 m/s
    # the next extended frame (tick 9019) carries the position that has drifted since
    assert r.ext.first == 450 and r.ext.tick == 9019
    assert "pos_enu_m[1]" in {f.name for f in r.ext.fields}
    text = r.summary()
    assert "frame 9000 (tick 9000, t = 45.000 s)" in text and "vel_n_cm_s firmware" in text
    assert "DIFFERENT" in text


def test_parity_with_raw_records_other_rates_mounting_and_pps_lost(highway):
    """Raw-input records every tick, a frame every 3 ticks (flags accumulate between frames),
    an extended frame every 7, a mounting rotation, other sensor ranges, an explicit identity
    matrix, and no PPS after 40 s (fixes then take the configured latency)."""
    pps = highway.pps_before_us.copy()
    pps[40 * 200 :] = -1
    stim = stimulus.Stimulus(
        dict(highway.header),
        highway.gyro_regs,
        highway.accel_regs,
        highway.temp_raw,
        pps,
        highway.uart_offsets,
        highway.uart_bytes,
    )
    overrides = {
        "raw_record": 1,
        "output_every_ticks": 3,
        "ext_every_ticks": 7,
        "mount_ypr_deg": [1.5, -0.75, 0.5],
        "gyro_range_dps": 500,
        "accel_range_g": 4,
        "accel_matrix": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
    }
    r = parity.compare(stim, overrides)
    assert r.identical, r.summary()
    d = _frames(r.out_firmware)
    assert len(d.frames) == 10000 // 3 and len(d.ext) == 10000 // 7 and len(d.raw) == 10000
    # the raw records measure the firmware's clock: tick k starts at t0 + 5 ms k, where t0
    # is the first timer moment after the BMI055 start-up waits (as the model derives it)
    t0 = model_runner.first_tick_us(5000)
    assert t0 == 35000
    assert [x["t0_us"] for x in d.raw[:3]] == [t0, t0 + 5000, t0 + 10000]
    edges = np.flatnonzero(pps >= 0)  # the parser stamped each edge at t_k - pps_before
    assert len(edges) == 40
    assert all(d.raw[k]["pps_us"] == d.raw[k]["t0_us"] - pps[k] for k in edges)
    late = d.frames[40 * 200 // 3 :]
    assert sum(f["pps"] for f in late) == 0 and sum(f["gga"] for f in late) >= 9
    assert late[-1]["nav_state"] == 2


def test_parity_when_the_gnss_receive_ring_overflows():
    """Five seconds of NMEA bytes arrive at once: the 255-byte reads drain the 1 KB receive
    ring over several ticks and the rest is lost, the same way on both sides. Every epoch of a
    burst arrives after a later second's PPS edge than its own: each is reported late and none
    is used (stamped with the burst's edge, a fix would be seconds wrong), so the board never
    starts navigating."""
    s = board_input.simulate("highway_outage", 45.0, seed=3).stimulus
    k = np.arange(len(s) + 1)
    burst = np.minimum(-(-k // 1000) * 1000, len(s))
    stim = stimulus.Stimulus(
        dict(s.header),
        s.gyro_regs,
        s.accel_regs,
        s.temp_raw,
        s.pps_before_us,
        s.uart_offsets[burst],
        s.uart_bytes,
    )
    r = parity.compare(stim)
    assert r.identical, r.summary()
    assert r.firmware_stats["gnss_rx_overflow"] > 0 and r.firmware_stats["nmea_rejected"] > 0
    d = _frames(r.out_firmware)
    assert sum(f["gga"] for f in d.frames) > 10 and d.frames[-1]["nav_state"] == 1
    late = [e for e in d.ext if "gnss_late" in rec_schema.cause_names(e["causes"])]
    assert len(late) >= 50  # a second for each of the bursts' late epochs


def test_parity_without_receiver_speed_and_course():
    """Position-only NMEA (RMC with empty speed and course: a receiver configured without
    velocity, or the replay of position-only data), 1 Hz with 1.5 m noise: the app passes
    speed -1 and course -1, the navigator takes its heading from the GNSS track and starts
    with the track's velocity sigma; both sides agree byte for byte."""
    model = sim_gnss.GnssModel(sigma_h_m=1.5, sigma_v_m=3.0)
    sim = board_input.simulate("highway_outage", 50.0, seed=0, gnss_model=model)
    g = sim.gnss
    nan = np.full_like(g.speed_m_s, np.nan)
    gnss = dataclasses.replace(g, speed_m_s=nan, course_deg=nan.copy())
    stim, _ = board_input.to_stimulus(sim.truth, sim.imu, gnss, dict(sim.stimulus.header))
    rmc = [ln.split(b",") for ln in stim.uart_bytes.split(b"\r\n") if b"GNRMC," in ln]
    assert sum(len(f) > 8 and f[2] == b"A" and f[7] == f[8] == b"" for f in rmc) >= 45
    r = parity.compare(stim)
    assert r.identical, r.summary()
    d = _frames(r.out_firmware)
    states = np.array([f["nav_state"] for f in d.frames])
    nav = np.flatnonzero(states == 2)
    # the course start of this drive is at ~37 s; the track needs a 4 s window above 3 m/s
    assert nav[0] > NAV_START_TICK + 4 * 200 and len(nav) > 5 * 200
    assert (states[nav[0] :] == 2).all()
    first = next(e for e in d.ext if e["nav_state"] == 2)
    track_vel_var = 4.0  # navcfg track_vel_sigma = 2 m/s (course start: 0.25)
    assert first["p_diag"][3] == pytest.approx(track_vel_var, rel=0.05)
    speed = np.hypot(*np.array([f["vel_enu_m_s"][:2] for f in d.frames[-200:]]).T)
    assert (speed > 20.0).all()


def test_parity_with_a_gga_only_receiver():
    """A receiver configured for GGA (and GSA) only: with gnss_need_speed 1 (the rule before the
    parser learned what the receiver sends) no epoch ever completes (the parser waits for a
    speed sentence); by default (2, auto) the parser learns that none comes, every GGA is a fix
    without speed and course, and the navigator starts from the track, the same on both
    sides."""
    model = sim_gnss.GnssModel(sigma_h_m=1.5, sigma_v_m=3.0, sentences=("GGA", "GSA"))
    stim = board_input.simulate("highway_outage", 50.0, seed=0, gnss_model=model).stimulus
    assert b"RMC" not in stim.uart_bytes and b"VTG" not in stim.uart_bytes
    waiting = _frames(model_runner.run(stim, {"gnss_need_speed": 1}))
    assert {f["nav_state"] for f in waiting.frames} == {1}
    assert {f["gnss_valid"] for f in waiting.frames} == {0}
    r = parity.compare(stim)
    assert r.identical, r.summary()
    d = _frames(r.out_firmware)
    states = np.array([f["nav_state"] for f in d.frames])
    nav = np.flatnonzero(states == 2)
    assert nav[0] > NAV_START_TICK + 4 * 200 and len(nav) > 5 * 200
    assert sum(f["gga"] for f in d.frames) == 50


def test_the_command_exit_status(capsys, monkeypatch):
    assert parity.main(["--scenario", "static", "--duration", "3"]) == 0
    out = capsys.readouterr().out
    assert "600 compared, identical" in out and "PARITY: identical" in out

    assert parity.main(["--scenario", "no_such_place", "--duration", "3"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown scenario 'no_such_place'" in err
    for bad in ("0", "-5", "nan", "ten"):
        assert parity.main(["--scenario", "static", "--duration", bad]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "--duration" in err and "Traceback" not in err
    assert parity.main(["--scenario", "static", "--duration", "3", "--seed", "-2"]) == 2
    assert "--seed must be 0 or more" in capsys.readouterr().err

    real_run = model_runner.run_all

    def off_by_one_yaw(stim, overrides=None, progress=None, **kw):
        out, shown = real_run(stim, overrides, progress, **kw)
        out = bytearray(out)
        ext_len = len(stream.split(out)[1][0])
        out[100 * 52 + 5 * ext_len + 29] ^= 1  # frame 100's yaw (after 5 extended frames)
        return bytes(out), shown

    monkeypatch.setattr(model_runner, "run_all", off_by_one_yaw)
    assert parity.main(["--scenario", "static", "--duration", "3"]) == 1
    out = capsys.readouterr().out
    assert "first difference at frame 100 (tick 100" in out and "yaw_cdeg firmware" in out


def test_the_vectorised_frame_equals_the_firmware_packer():
    """model/app.py's frame_bytes against firmware/lib/frame.pack row by row, over the whole
    range of every field: rounding ties, the int16/int32 clamps, NaN and infinities, pitch
    at +-90 deg, longitudes beyond 107.37 deg, all sensor ranges."""
    import frame
    import nav_kern
    import rot

    rng = np.random.default_rng(5)
    n = 2000
    q = rng.normal(size=(n, 4))
    q[:50] = [1.0, 1.0, 0.0, 0.0]  # pitch +90 deg
    c = ref_rot.q_to_dcm((q / np.linalg.norm(q, axis=1, keepdims=True)).astype(F32))
    c[50:60, 1, 1] = np.nan
    scale = 10.0 ** rng.uniform(-3.0, 8.5, (n, 3))
    v = (rng.standard_normal((n, 3)) * np.minimum(scale, 3e3)).astype(F32)
    p = (rng.standard_normal((n, 3)) * scale).astype(F32)
    ties = np.array([0.005, -0.005, 0.015, -0.025, 327.675, -327.685, 3276.75, 0.0, -0.0])
    special = np.array([np.nan, np.inf, -np.inf, 1e30, -1e30, 10737418.23, -10737418.24])
    edge = np.concatenate([ties, special, special * 0.01]).astype(F32)
    v[60 : 60 + len(edge), 0] = edge
    p[60 : 60 + len(edge), 0] = edge
    p[100 : 100 + len(edge), 2] = edge
    t = {
        "counter": np.arange(n) & 0xFF,
        "gyro": rng.integers(-32768, 32768, (n, 3)),
        "accel": rng.integers(-2048, 2048, (n, 3)),
        "pps": rng.integers(0, 2, n),
        "gga": rng.integers(0, 2, n),
        "valid": rng.integers(0, 2, n),
        "lat_e7": rng.integers(-900000000, 900000001, n),
        "lon_e7": rng.integers(-1800000000, 1800000001, n),
        "height_dm": rng.integers(-40000, 40000, n),
        "state": rng.integers(1, 3, n),
        "c_bn": c,
        "v_n": v,
        "p_n": p,
    }
    t["gyro"][:4] = [[-32768, 32767, 0], [32766, -32767, 1], [-1, 1, 65], [-65, 66, -66]]

    def pair(e7):
        deg = e7 // 10**7 if e7 >= 0 else -((-e7) // 10**7)
        return [deg, e7 - deg * 10**7]

    buf = bytearray(frame.FRAME_LEN)
    ypr = np.zeros(3, F32)
    for gyro_range, accel_range in ((250, 2), (2000, 16), (125, 4)):
        cfg = type("Cfg", (), {"gyro_range_dps": gyro_range, "accel_range_g": accel_range})
        model = model_runner.frame_bytes(t, cfg)
        bmi055 = firmware_env.import_module("drivers.bmi055")
        lsb_x10 = bmi055.GYRO_LSB_PER_DPS_X10[gyro_range]
        lsb_g = bmi055.ACCEL_LSB_PER_G[accel_range]
        for i in range(n):
            rot.dcm_to_euler(ypr, c[i].ravel())
            frame.pack(
                buf, int(t["counter"][i]), t["gyro"][i].tolist(), t["accel"][i].tolist(),
                lsb_x10, lsb_g, int(t["pps"][i]), int(t["gga"][i]), int(t["valid"][i]),
                pair(int(t["lat_e7"][i])), pair(int(t["lon_e7"][i])), int(t["height_dm"][i]),
                int(t["state"][i]), nav_kern.CDEG_PER_RAD, ypr, v[i], p[i],
            )  # fmt: skip
            assert bytes(buf) == model[i].tobytes(), (gyro_range, i)


def test_a_5_hz_receiver_stamps_each_fix_at_its_own_moment(tmp_path):
    """5 fixes a second share their second's PPS edge: each is measured at the edge plus its
    epoch's offset into the second (app._fix_tick), on the firmware and the model alike. Before,
    all five were taken as the edge's: over this test's 90 s, 2.71 m horizontal RMS then,
    0.79 m now."""
    from host_emulator.eval import scenario_run

    model = sim_gnss.GnssModel(rate_hz=5, baud=115200, white_fraction=1.0)
    # seed 1: a clear sky (seed 0's 90 s draw has HDOP above 2 from 18 to 83 s, at every rate)
    sim = board_input.simulate("urban_drive", 90.0, 1, gnss_model=model)
    r = parity.compare(sim.stimulus)
    assert r.identical, r.summary()
    path = tmp_path / "s.bin"
    sim.stimulus.write(path)
    fw = scenario_run.run_firmware("cpython", path)
    m, _tr, _err = scenario_run.evaluate_run(sim, fw, sim.stimulus, tmp_path, "cpython")
    # navigating from 62 s: 28 s of a start, against the fixes' own 3.26 m
    assert m["align_time_s"] < 70.0 and m["horiz_rms_m"] < 1.5, m["horiz_rms_m"]


@pytest.mark.parametrize(
    "overrides",
    [{"display": 1}, {"display": 1, "ext_every_ticks": 0, "output_every_ticks": 3,
                      "display_w": 220, "display_h": 176, "display_fg": 7}],
)  # fmt: skip
def test_what_the_firmware_sends_to_the_screen_is_the_models(overrides):
    """The display UART byte for byte, through alignment into navigation (quick_start drives
    off at ~12 s), with the extended frame on (the 1-sigma, the health it carries) and off."""
    stim = board_input.simulate("quick_start", duration_s=20, seed=1).stimulus
    r = parity.compare(stim, overrides)
    assert r.identical and r.display_first_byte is None, r.summary()
    shown = r.display_firmware.decode()
    assert shown.count("\r\n") > 20 and "'navigating'" in shown
    assert ("'aligning  '" in shown) and ("DS12(" in shown) == ("display_w" in overrides)
    assert "display: identical" in r.summary()
    assert r.firmware_stats["display_missed"] == 0 and r.firmware_stats["display_oks"] > 20
    assert r.firmware_stats["uart_rx_waits"] == 0  # no read ever waits for bytes not there
