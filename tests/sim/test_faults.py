"""Fault injection (host_emulator/sim/faults.py): the written form and its errors, each kind
changing exactly the registers, bytes or edges it says over exactly its ticks, and the
unmodified firmware meeting every kind without raising or sending a non-finite float."""

import json
import re

import numpy as np
import pytest

from common.proto import records as rec_schema
from common.proto import stimulus as stim_mod
from common.proto import stream
from host_emulator.__main__ import main
from host_emulator.runtimes import cpython
from host_emulator.sim import board_input, faults, nmea

T0, DUR = 14.0, 1.0  # after quick_start starts navigating (13.4 s)
K0, K1 = 2800, 3000


@pytest.fixture(scope="module")
def stim():
    return board_input.simulate("quick_start", 16.0, seed=0).stimulus


def test_the_written_form_and_its_defaults():
    f = faults.parse("gyro-bias@300+60:2.5")
    assert (f.kind, f.t0_s, f.duration_s, f.param) == ("gyro-bias", 300.0, 60.0, 2.5)
    assert faults.parse(" IMU-Zeros@0+0.5 ") == faults.Fault("imu-zeros", 0.0, 0.5)
    assert faults.parse("accel-scale@1+2").param == 1.05  # the default
    assert str(faults.parse("uart-corrupt@1+2:0.5")) == "uart-corrupt@1+2:0.5"


@pytest.mark.parametrize(
    "spec, words",
    [
        ("imu-zeros", "expected KIND@T0+DURATION"),
        ("imu-zeros@5", "expected KIND@T0+DURATION"),
        ("stuck@1+1", "unknown kind 'stuck'"),
        ("imu-zeros@x+1", "T0 'x' is not a number"),
        ("imu-zeros@1+nan", "DURATION must be finite"),
        ("imu-zeros@-1+1", "T0 must be 0 or more"),
        ("imu-zeros@1+0", "DURATION more than 0"),
        ("imu-zeros@1+1:3", "imu-zeros takes no PARAM"),
        ("uart-corrupt@1+1:2", "a probability"),
        ("accel-scale@1+1:0", "a scale factor"),
        ("stall@1+0.6", "the board's watchdog timeout"),
    ],
)
def test_a_fault_written_wrong_says_what_is_wrong(spec, words):
    with pytest.raises(faults.FaultError, match=re.escape(words)):
        faults.parse(spec)


def _outside_unchanged(a, b):
    assert np.array_equal(a[:K0], b[:K0]) and np.array_equal(a[K1:], b[K1:])


def test_imu_faults_change_exactly_their_registers(stim):
    g0 = stim_mod.gyro_counts(stim.gyro_regs).astype(int)
    a0 = stim_mod.accel_counts(stim.accel_regs).astype(int)
    for spec, check in [
        ("imu-stuck", lambda s: (s.gyro_regs[K0:K1] == stim.gyro_regs[K0]).all()
         and (s.accel_regs[K0:K1] == stim.accel_regs[K0]).all()),
        ("imu-zeros", lambda s: (s.gyro_regs[K0:K1] == 0).all()
         and (s.accel_regs[K0:K1] == 0).all()),
        ("imu-ones", lambda s: (s.gyro_regs[K0:K1] == 255).all()
         and (s.accel_regs[K0:K1] == 255).all()),
        ("gyro-over", lambda s: (stim_mod.gyro_counts(s.gyro_regs[K0:K1]) == 32767).all()),
        ("accel-over", lambda s: (stim_mod.accel_counts(s.accel_regs[K0:K1]) == 2047).all()),
        ("gyro-vibe", lambda s: (stim_mod.gyro_counts(s.gyro_regs[K0:K1:2]) == 32767).all()
         and (stim_mod.gyro_counts(s.gyro_regs[K0 + 1:K1:2]) == -32768).all()),
        ("accel-vibe", lambda s: (stim_mod.accel_counts(s.accel_regs[K0:K1:2]) == 2047).all()
         and (stim_mod.accel_counts(s.accel_regs[K0 + 1:K1:2]) == -2048).all()),
        # 1 deg/s at the default +-250 deg/s: 131.2 LSB per deg/s
        ("gyro-bias:1", lambda s: (stim_mod.gyro_counts(s.gyro_regs[K0:K1]) - g0[K0:K1]
                                   == 131).all()),
        # 0.5 m/s^2 at +-2 g: 0.5 / 9.80665 * 1024 = 52.2 counts
        ("accel-bias:0.5", lambda s: (stim_mod.accel_counts(s.accel_regs[K0:K1]) - a0[K0:K1]
                                      == 52).all()),
        ("accel-scale:1.5", lambda s: np.array_equal(
            stim_mod.accel_counts(s.accel_regs[K0:K1]), np.round(a0[K0:K1] * 1.5))),
    ]:  # fmt: skip
        kind, _, param = spec.partition(":")
        full = f"{kind}@{T0:g}+{DUR:g}" + (f":{param}" if param else "")
        s = faults.apply(stim, [full])
        assert check(s), spec
        _outside_unchanged(s.gyro_regs, stim.gyro_regs)
        _outside_unchanged(s.accel_regs, stim.accel_regs)
        assert s.uart_bytes == stim.uart_bytes
        assert np.array_equal(s.pps_before_us, stim.pps_before_us)
        assert s.header["faults"] == [str(faults.parse(full))]
        if kind.startswith("accel-") and kind != "accel-over" and kind != "accel-vibe":
            # the data-ready flags (bit 0 of each LSB register) are the sensor's, kept
            assert np.array_equal(s.accel_regs[:, 0::2] & 1, stim.accel_regs[:, 0::2] & 1)


def _chunks(s):
    o = s.uart_offsets
    return [s.uart_bytes[o[k] : o[k + 1]] for k in range(len(s))]


def test_gnss_faults_change_exactly_their_bytes_and_edges(stim):
    before = _chunks(stim)
    lost = faults.apply(stim, [f"gnss-loss@{T0:g}+{DUR:g}"])
    after = _chunks(lost)
    assert all(c == b"" for c in after[K0:K1]) and any(before[K0:K1])
    assert after[:K0] == before[:K0] and after[K1:] == before[K1:]
    assert np.array_equal(lost.pps_before_us, stim.pps_before_us)

    bad = faults.apply(stim, [f"uart-corrupt@{T0:g}+{DUR:g}:0.5"], seed=3)
    after = _chunks(bad)
    assert [len(c) for c in after] == [len(c) for c in before]
    flipped = [np.unpackbits(np.frombuffer(a, np.uint8) ^ np.frombuffer(b, np.uint8)).sum()
               for a, b in zip(after[K0:K1], before[K0:K1], strict=True)]  # fmt: skip
    n_bytes = sum(len(c) for c in before[K0:K1])
    assert 0.3 * n_bytes < sum(flipped) < 0.7 * n_bytes  # one bit in about half of them
    assert after[:K0] == before[:K0] and after[K1:] == before[K1:]
    assert faults.apply(stim, ["uart-corrupt@14+1:0.5"], seed=3).uart_bytes == bad.uart_bytes

    edges = np.flatnonzero(stim.pps_before_us >= 0)
    inside = edges[(edges >= K0) & (edges < K1)]
    assert len(inside) == 1
    none = faults.apply(stim, [f"pps-missing@{T0:g}+{DUR:g}"])
    assert (none.pps_before_us[K0:K1] < 0).all()
    _outside_unchanged(none.pps_before_us, stim.pps_before_us)
    extra = faults.apply(stim, [f"pps-spurious@{T0:g}+{DUR:g}"])
    new = np.flatnonzero((extra.pps_before_us >= 0) & (stim.pps_before_us < 0))
    assert list(new) == [inside[0] + 100]  # half a second after the receiver's edge
    assert extra.pps_before_us[new[0]] == stim.pps_before_us[inside[0]]


def test_a_fault_after_the_end_is_refused(stim):
    with pytest.raises(faults.FaultError, match="after the stimulus ends"):
        faults.apply(stim, ["imu-zeros@16+1"])


@pytest.mark.parametrize("kind", list(faults.KINDS))
def test_the_firmware_meets_every_kind_without_raising_or_non_finite_output(stim, kind, tmp_path):
    """It runs on, and every float it sends, in frames and extended frames, is finite
    (detection and recovery: tests/bench/test_fault_matrix.py, a kind of each family)."""
    dur = faults.STALL_MAX_S if kind == "stall" else DUR
    s = faults.apply(stim, [f"{kind}@{T0:g}+{dur:g}"])
    r = cpython.run(s, tmp_path)
    d = stream.decode(r.out)
    run = ~s.stalled  # a stalled tick sends nothing (the board is busy)
    assert len(d.frames) == run.sum()
    assert len(d.ext) == (run & ((np.arange(len(stim)) + 1) % 20 == 0)).sum()
    for f in d.frames:
        assert all(np.isfinite(v) for v in f.values() if isinstance(v, float)), kind
    for e in d.ext:
        for v in e.values():
            if isinstance(v, (float, list, tuple, np.ndarray)):
                assert np.isfinite(np.asarray(v, float)).all(), kind


def test_run_injects_faults_and_lists_them(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["run", "--scenario", "quick_start", "--duration", "16", "--out", str(out), "--quiet"]
    assert main([*argv, "--fault", "imu-zeros@14+1", "--fault", "gnss-loss@14+2"]) == 0
    text = capsys.readouterr().out
    assert "fault injected: imu-zeros@14+1" in text
    assert "faults injected        imu-zeros@14+1, gnss-loss@14+2" in text
    both = ["imu-zeros@14+1", "gnss-loss@14+2"]
    assert json.loads((out / "metrics.json").read_text())["faults"] == both
    assert stim_mod.read(out / "stimulus.bin").header["faults"] == both
    again = tmp_path / "again"
    rerun = ["run", "--stimulus", str(out / "stimulus.bin"), "--out", str(again), "--quiet"]
    assert main([*rerun, "--fault", "pps-missing@15+1"]) == 0
    assert json.loads((again / "metrics.json").read_text())["faults"] == [
        *both,
        "pps-missing@15+1",
    ]
    assert main([*argv, "--fault", "imu-zeros@14"]) == 1
    err = capsys.readouterr().err
    assert "expected KIND@T0+DURATION" in err and "Traceback" not in err
    assert main([*argv, "--fault", "help"]) == 0
    assert "pps-spurious" in capsys.readouterr().out


def _epochs(stim):
    """(tick, epoch fields) of every epoch the firmware's NMEA parser completes, fed the
    stimulus' bytes tick by tick; and its count of rejected lines."""
    from common import firmware_env

    firmware_env.install()
    from drivers.gnss import Nmea

    p = Nmea(need_speed=True)
    out = []
    for k, c in enumerate(_chunks(stim)):
        if c:
            buf = bytearray(c)
            p.feed(buf, len(buf))
        if p.epoch_ready:
            p.epoch_ready = 0
            out.append((k, p.epoch_lat_e7, p.epoch_alt_mm, p.epoch_quality, p.epoch_hdop_x100,
                        p.epoch_speed_mm_s, p.epoch_course_cdeg))  # fmt: skip
    return out, p.rejected()


@pytest.mark.parametrize(
    "spec, field, change",
    [
        ("gnss-jump:100", 1, lambda old, new: new - old == round(100 / faults.M_PER_DEG_LAT * 1e7)),
        ("gnss-height:100", 2, lambda old, new: new - old == 100_000),
        ("gnss-quality:6", 3, lambda old, new: new == 6),
        ("gnss-hdop:0", 4, lambda old, new: new == 0),
        ("gnss-speed:1000", 5, lambda old, new: abs(new - 1_000_000) <= 1),
        ("gnss-course:400", 6, lambda old, new: new == 40_000),
        ("gnss-pole:", 1, lambda old, new: new == 900_000_000),
    ],
)
def test_gnss_field_faults_edit_the_sentences_the_parser_reads(stim, spec, field, change):
    """The firmware's own parser reads the edited field in the epochs within the interval
    (valid checksums: nothing more rejected) and the same epochs elsewhere."""
    kind, _, param = spec.partition(":")
    before, rejected = _epochs(stim)
    after, rejected_after = _epochs(faults.apply(stim, [f"{kind}@11+4:{param}"]))  # moving
    assert rejected_after == rejected and len(after) == len(before)
    inside = 0
    for b, a in zip(before, after, strict=True):
        assert a[0] == b[0]  # the same tick: the edited sentence ends when the original did
        if 2200 < a[0] < 3000:
            inside += 1
            assert a[:field] + a[field + 1 :] == b[:field] + b[field + 1 :], (spec, b, a)
            assert change(b[field], a[field]), (spec, b, a)
        elif a[0] >= 3200 or a[0] < 2200:
            assert a == b
    assert inside >= 3


def test_a_frozen_receiver_repeats_its_first_solution(stim):
    """gnss-frozen: within the interval every epoch carries the position, height, speed and
    course of its first one (a receiver that keeps sending its last solution), with nothing
    more rejected; the epochs' times go on."""
    before, rejected = _epochs(stim)
    after, rejected_after = _epochs(faults.apply(stim, ["gnss-frozen@11+4"]))
    assert rejected_after == rejected and len(after) == len(before)
    inside = [a for a in after if 2200 < a[0] < 3000]
    assert len(inside) >= 3 and all(a[1:] == inside[0][1:] for a in inside)
    moved = [b for b in before if 2200 < b[0] < 3000]
    assert len({b[1:] for b in moved}) == len(moved)  # the receiver was moving
    assert [a for a in after if a[0] >= 3200] == [b for b in before if b[0] >= 3200]


def test_a_clock_fault_shifts_the_times_of_day(stim):
    """gnss-clock: GGA and RMC times PARAM s later within the interval (18 s back: GPS time to
    UTC), across midnight, in the receiver's format; the rest of each sentence unchanged."""
    f = faults.parse("gnss-clock@0+1:-18")
    gga = "GNGGA,{},3036.123456,N,11421.654321,E,1,12,0.8,25.3,M,,M,,"
    edited = faults._edit(nmea.sentence(gga.format("000010.20")), f, {})
    assert edited == nmea.sentence(gga.format("235952.20"))
    assert faults._shifted_time("235959.5", 1.0) == "000000.5"
    assert faults._shifted_time("120000", 3600) == "130000"


@pytest.mark.parametrize("kind", ["gnss-jump", "gnss-height", "gnss-quality", "gnss-hdop"])
def test_a_field_fault_leaves_a_damaged_sentence_damaged(kind):
    """An edit comes with a new checksum only where the old one held: a sentence that arrived
    broken (here one digit of its time replaced, as the simulated receiver does) stays broken,
    not repaired into a fix the receiver never sent."""
    good = nmea.sentence("GNGGA,020410.00,3036.123456,N,11421.654321,E,1,12,0.8,25.3,M,,M,,")
    broken = good.replace(b"020410", b"02041?")
    fault = faults.parse(f"{kind}@0+1")
    assert faults._edit(broken, fault, {}) == broken
    assert faults._edit(good, fault, {}) != good


def test_late_bytes_arrive_later_and_in_order(stim):
    before = _chunks(stim)
    late = faults.apply(stim, ["gnss-late@5+1:1.4"])
    after = _chunks(late)
    assert b"".join(after) == b"".join(before)  # nothing lost, nothing reordered
    assert all(c == b"" for c in after[1000:1280]) and any(before[1000:1200])
    assert after[:1000] == before[:1000]
    ep_before, _ = _epochs(stim)
    ep_after, _ = _epochs(late)
    first_b = next(e for e in ep_before if e[0] >= 1000)
    first_a = next(e for e in ep_after if e[0] >= 1000)
    # 1.4 s late; the next epoch's bytes queue behind and complete in the same tick (the
    # parser then keeps the later epoch: a burst loses epochs, as on a board)
    assert first_a[0] == first_b[0] + 280
    assert [e for e in ep_after if e[0] > 1400] == [e for e in ep_before if e[0] > 1400]


def test_a_silent_imu_is_a_flag_of_the_records_every_runtime_applies(stim, tmp_path):
    """imu-silent: a per-tick flag of the stimulus (it survives the file), which each runtime's
    driver applies to the emulated dies (SPI reads the bus' idle 0xFF) and the model mirrors:
    CPython and the emulated Cortex-M4F give the model's bytes, the VM's frames equal them."""
    from host_emulator.eval import parity
    from host_emulator.runtimes import mpy_unix

    s = faults.apply(stim, [f"imu-silent@{T0:g}+{DUR:g}"])
    assert s.imu_silent[K0:K1].all() and s.imu_silent.sum() == K1 - K0
    assert np.array_equal(s.gyro_regs, stim.gyro_regs)  # the registers are not what changed
    back = stim_mod.from_bytes(s.to_bytes())
    assert np.array_equal(back.imu_silent, s.imu_silent)
    for runtime in ("cpython", "m4f"):
        r = parity.compare(s, runtime=runtime, kernels="native")
        assert r.identical, (runtime, r.summary())
    frames = stream.decode(cpython.run(s, tmp_path / "c").out).frames
    # a dead bus: every axis reads the same count (0xFFFF, -1) in every silent tick
    dead = {tuple(f["gyro_dps"]) + tuple(f["accel_g"]) for f in frames[K0:K1]}
    assert len(dead) == 1 and len(set(next(iter(dead))[:3])) == 1
    assert tuple(frames[K1 + 5]["gyro_dps"]) + tuple(frames[K1 + 5]["accel_g"]) not in dead
    vm = stream.decode(mpy_unix.run(s, tmp_path / "vm", kernels="native").out).frames
    assert [f["raw"] for f in vm] == [f["raw"] for f in frames]


def test_a_stall_loses_its_frames_and_the_navigator_steps_through_its_ticks(stim, tmp_path):
    """stall: a per-tick flag (it survives the file); no loop runs over it, so its frames are
    missing; the next tick counts the missed ticks as overruns (health 1, `overrun`) and the
    navigator steps through them on that tick's sample, which is not taken for a stuck IMU:
    its clock (the extended frames' tick) keeps the timer's. 35 ms: a stall the board's 50 ms
    watchdog survives (the feeds before and after it 40 ms apart, plus the tick). CPython and
    the emulated Cortex-M4F give the model's bytes; the VM runs it too."""
    from host_emulator.eval import parity
    from host_emulator.runtimes import mpy_unix

    s = faults.apply(stim, [f"stall@{T0:g}+0.035"])
    k0, k1 = K0, K0 + 7
    assert s.stalled[k0:k1].all() and s.stalled.sum() == 7
    assert np.array_equal(stim_mod.from_bytes(s.to_bytes()).stalled, s.stalled)
    for runtime in ("cpython", "m4f"):
        r = parity.compare(s, runtime=runtime, kernels="native")
        assert r.identical, (runtime, r.summary())
    clean = stream.decode(cpython.run(stim, tmp_path / "clean").out)
    d = stream.decode(cpython.run(s, tmp_path / "c").out)
    assert len(d.frames) == len(clean.frames) - 7
    assert [e["tick"] for e in d.ext] == [e["tick"] for e in clean.ext]  # none stalled
    after = d.ext[k0 // 20]  # the first extended frame after the stall
    assert after["overruns"] == 7 and after["health"] >= 1
    assert "overrun" in rec_schema.cause_names(after["causes"])
    assert "overrun" not in rec_schema.cause_names(d.ext[k0 // 20 + 1]["causes"])
    # the steps repeat one read (IMU_REPEAT): not taken for a stuck IMU, health stays 1
    assert all(e["health"] <= 1 for e in d.ext[k0 // 20 : k0 // 20 + 15])
    assert after["nav_state"] == clean.ext[k0 // 20]["nav_state"]
    vm = stream.decode(mpy_unix.run(s, tmp_path / "vm", kernels="native").out)
    assert len(vm.frames) == len(d.frames) and vm.ext[k0 // 20]["overruns"] == 7


def test_the_navigator_steps_through_at_most_the_watchdogs_ticks(stim, tmp_path):
    """A 0.2 s stall, which the board's 50 ms watchdog would end in a reset: the 40 missed
    ticks are counted, but the navigator steps through app._CATCH_UP_MAX (10, the watchdog's
    timeout in ticks) of them, so its clock falls 30 ticks behind the timer's; CPython gives
    the model's bytes."""
    from common import firmware_env
    from host_emulator.eval import parity

    app = firmware_env.import_module("app")
    assert app._CATCH_UP_MAX == 10
    s = faults.apply(stim, [f"stall@{T0:g}+0.2"])
    k0, k1 = K0, K0 + 40
    r = parity.compare(s, runtime="cpython", kernels="native")
    assert r.identical, r.summary()
    clean = stream.decode(cpython.run(stim, tmp_path / "clean").out)
    d = stream.decode(cpython.run(s, tmp_path / "c").out)
    after = d.ext[k0 // 20]
    assert after["overruns"] == 40
    assert after["tick"] == clean.ext[k1 // 20]["tick"] - 30


def test_the_firmware_under_faults_is_the_models_bit_for_bit(stim):
    """Held IMU samples (zeros, over range, stuck), the covariance widened after a dead spell,
    a fix with an impossible field, a height jump, a spurious PPS edge: CPython and the
    emulated Cortex-M4F send the model's bytes, extended frames (health and causes) included."""
    from host_emulator.eval import parity

    s = faults.apply(stim, ["imu-zeros@13.6+0.3", "gyro-over@14.2+0.2", "imu-stuck@14.6+0.5",
                            "gnss-quality@13.5+1:8", "gnss-height@15+1:60",
                            "pps-spurious@11+2"])  # fmt: skip
    for runtime in ("cpython", "m4f"):
        r = parity.compare(s, runtime=runtime, kernels="native")
        assert r.identical, (runtime, r.summary())
    d = stream.decode(r.out_firmware)
    seen = set()
    for e in d.ext:
        seen.update(rec_schema.cause_names(e["causes"]))
    want = {"imu_sample_held", "imu_dead", "imu_saturated", "gnss_bad_data", "pps_irregular"}
    assert want <= seen


def test_replay_injects_faults_too(tmp_path, capsys):
    """`replay --fault`: the same kinds on a recording's converted input (drive_0708's first
    60 s; the fault while it navigates)."""
    out = tmp_path / "rp"
    argv = ["replay", "--dataset", "drive_0708", "--duration", "60", "--out", str(out), "--quiet"]
    assert main([*argv, "--fault", "gnss-height@45+5:500"]) == 0
    assert "fault injected: gnss-height@45+5:500" in capsys.readouterr().out
    assert json.loads((out / "metrics.json").read_text())["faults"] == ["gnss-height@45+5:500"]
    assert stim_mod.read(out / "stimulus.bin").header["faults"] == ["gnss-height@45+5:500"]
    assert main([*argv, "--fault", "gnss-height@45"]) == 1
    assert "expected KIND@T0+DURATION" in capsys.readouterr().err


def test_late_epochs_are_reported_and_not_used(stim, tmp_path):
    """gnss-late: the bytes of 13.5-15.5 s arrive 1.4 s late, the epoch of second 14 after
    the edge of second 15. The app says `gnss_late` once the epoch is overdue, counts the
    edges from the last on-time epoch when it comes, and gives the navigator no fix (stamped
    with the later edge it would be a second wrong), so the position variance does not fall
    where the clean run's does at a fix; CPython and the emulated Cortex-M4F send the model's
    bytes."""
    from host_emulator.eval import parity

    s = faults.apply(stim, ["gnss-late@13.5+2:1.4"])
    for runtime in ("cpython", "m4f"):
        r = parity.compare(s, runtime=runtime, kernels="native")
        assert r.identical, (runtime, r.summary())
    d = stream.decode(cpython.run(s, tmp_path / "late").out)
    clean = stream.decode(cpython.run(stim, tmp_path / "clean").out)
    names = [rec_schema.cause_names(e["causes"]) for e in d.ext]
    late = [k for k, n in enumerate(names) if "gnss_late" in n]
    # overdue (App._overdue): no epoch 0.8 s after the edge of second 14, said from the
    # extended frame of 14.9 s for a second; the late epoch itself (15.5 s) keeps it to the end
    assert late == list(range(148, 160)), late
    assert not any("gnss_late" in rec_schema.cause_names(e["causes"]) for e in clean.ext)

    def fix_drops(ext):  # the east variance falling by a fifth or more: a fix used
        var_e = [e["p_diag"][0] for e in ext[143:]]  # from 14.4 s, after the last on-time fix
        return sum(b < 0.8 * a for a, b in zip(var_e[:-1], var_e[1:], strict=True))

    assert fix_drops(d.ext) == 0 and fix_drops(clean.ext) >= 1


def test_a_receiver_clock_that_steps_is_resynchronised(stim, tmp_path):
    """gnss-clock: the receiver's time of day steps 18 s back at 5 s (GPS time to UTC) while
    its bytes and the PPS edges keep their moments. The app says `gnss_clock` from the first
    stepped epoch (6 s, its extended frame at 6.3 s) until a second after the third, whose
    edge it then counts from (never `gnss_late`), and the firmware aligns and navigates as
    without the step; stepping forward again (at 10 s) re-synchronises at once. CPython and
    the emulated Cortex-M4F send the model's bytes."""
    from host_emulator.eval import parity

    def said(d, name):
        return [k for k, e in enumerate(d.ext) if name in rec_schema.cause_names(e["causes"])]

    back = faults.apply(stim, ["gnss-clock@5+20:-18"])
    d = stream.decode(cpython.run(back, tmp_path / "back").out)
    assert said(d, "gnss_clock") == list(range(63, 93)) and said(d, "gnss_late") == []
    assert d.ext[-1]["nav_state"] == 2 and d.ext[-1]["health"] == 0
    both = faults.apply(stim, ["gnss-clock@5+5:-18"])
    for runtime in ("cpython", "m4f"):
        r = parity.compare(both, runtime=runtime, kernels="native")
        assert r.identical, (runtime, r.summary())
    d = stream.decode(cpython.run(both, tmp_path / "both").out)
    assert said(d, "gnss_clock") == [*range(63, 93), *range(103, 113)]


def test_a_receiver_that_lies_is_not_followed(tmp_path):
    """quick_start, navigating at ~10 m/s from 13.4 s: a frozen receiver (14-17 s: its first
    fix repeated), then one 2000 km north (18-25 s). The frozen fixes are not used, the jump
    is not reset to (the INS cannot have drifted 2000 km in 5 s): `gnss_implausible` and
    health 2 on both, the position stays within metres of the truth, and navigation goes on
    with the receiver's honest fixes after; CPython and the emulated Cortex-M4F send the
    model's bytes."""
    from host_emulator.eval import evaluate, parity

    sim = board_input.simulate("quick_start", 30.0, seed=0)
    s = faults.apply(sim.stimulus, ["gnss-frozen@14+3", "gnss-jump@18+7:2000000"])
    for runtime in ("cpython", "m4f"):
        r = parity.compare(s, runtime=runtime, kernels="native")
        assert r.identical, (runtime, r.summary())
    d = stream.decode(cpython.run(s, tmp_path / "lies").out)
    named = [(k / 10, rec_schema.cause_names(e["causes"]), e["health"])
             for k, e in enumerate(d.ext)]  # fmt: skip
    lies = [t for t, n, h in named if "gnss_implausible" in n]
    assert all(h == 2 for t, n, h in named if "gnss_implausible" in n)
    assert any(15 <= t < 18 for t in lies) and any(22 <= t < 26 for t in lies), lies
    o = sim.truth.origin
    tr = evaluate.track(d, s.tick_us * 1e-6, (o.lat_e7, o.lon_e7, o.h_m))
    t = sim.truth
    err = evaluate.errors(tr, t.t_s, t.p_n, t.v_n, t.ypr, [])
    h = np.hypot(err.dp[:, 0], err.dp[:, 1])
    assert h.max() < 10.0, h.max()  # measured
    assert not any("gnss_implausible" in n for t, n, h in named if t > 27)


def test_an_overdue_epoch_is_late_only_from_a_receiver_that_sends_every_second(stim, tmp_path):
    """App._overdue: after a run of seconds that each had their epoch, no epoch 0.8 s after
    a PPS edge says `gnss_late` for a second (a late receiver is told before its late epoch
    comes); a receiver that sends every other second never has that run, so its silent
    seconds are not called late."""
    once = faults.apply(stim, ["gnss-loss@14+1"])  # second 14's sentences missing
    d = stream.decode(cpython.run(once, tmp_path / "once").out)
    late = [k for k, e in enumerate(d.ext) if "gnss_late" in rec_schema.cause_names(e["causes"])]
    assert late == list(range(148, 158)), late  # from 14.9 s (edge 14 + 0.8 s) for a second
    sparse = faults.apply(stim, [f"gnss-loss@{t}+1" for t in range(1, 16, 2)])
    d = stream.decode(cpython.run(sparse, tmp_path / "sparse").out)
    assert sum(f["gga"] for f in d.frames) >= 6  # the even seconds' epochs came
    assert not any("gnss_late" in rec_schema.cause_names(e["causes"]) for e in d.ext)
