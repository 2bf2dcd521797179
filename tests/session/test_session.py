"""Board sessions (host_emulator/session/): a recording of the firmware's output with the
raw-input records on, made here by the emulator, replays through the emulator to the same
bytes; damaged, truncated or gapped recordings are refused with a message that says where;
PPS edges are rebuilt from the records, across the 2**30 us wrap of ticks_us."""

import os
import struct
import threading
import time

import numpy as np
import pytest

from common.proto import config as board_config
from common.proto import session_file, stream
from common.proto.ticks import ticks_diff
from host_emulator.emulated_board import install_machine
from host_emulator.runtimes import cpython
from host_emulator.session import cli, compare, rebuild, record, replay, walk
from host_emulator.sim import board_input

DURATION_S = 100.0  # urban_drive stands for 60 s, then drives: the run navigates from ~64 s
TICK = 5000


@pytest.fixture(scope="module")
def sim():
    return board_input.simulate("urban_drive", DURATION_S, seed=0).stimulus


@pytest.fixture(scope="module")
def values(sim):
    return board_config.run_values(sim, {"raw_record": 1})


@pytest.fixture(scope="module")
def capture(sim, tmp_path_factory):
    """What a logger on the board's output port receives: the emulator's output bytes."""
    return cpython.run(sim, tmp_path_factory.mktemp("board"), {"raw_record": 1}).out


@pytest.fixture(scope="module")
def session_path(capture, values, tmp_path_factory):
    d = tmp_path_factory.mktemp("session")
    (d / "capture.bin").write_bytes(capture)
    res = record.record(d / "capture.bin", d / "drive.ins", config=values)
    assert res["bytes"] == len(capture)
    return d / "drive.ins"


@pytest.fixture(scope="module")
def replayed(session_path, tmp_path_factory):
    return replay.replay(session_path, tmp_path_factory.mktemp("replay"))


def _records(capture):
    """[(offset, type, bytes)] of a clean stream."""
    f, e, r, err = stream.split(capture)
    assert err is None
    out = []
    pos = 0
    while pos < len(capture):
        n = 52 if capture[pos + 1] == 0x90 else 3 + capture[pos + 2] + 4
        out.append((pos, capture[pos + 1], capture[pos : pos + n]))
        pos += n
    assert len(out) == len(f) + len(e) + len(r)
    return out


def _raw_of_tick(recs, k):
    return [x for x in recs if x[1] == 0x92][k]


def _head(capture, ticks):
    """The capture up to and including tick `ticks - 1`'s raw record."""
    off, _, rec = _raw_of_tick(_records(capture), ticks - 1)
    return capture[: off + len(rec)]


# ---- the replay ------------------------------------------------------------------------


def test_a_recorded_session_replays_byte_for_byte(replayed, sim, capture):
    r = replayed
    assert r.identical, r.summary()
    c = r.comparison
    assert (c.frame.compared, c.ext.compared, c.raw.compared) == (20000, 1000, 20000)
    assert r.run.out == capture  # the whole stream, timing fields included (both emulated)
    assert "REPLAY: identical, 20000 ticks" in r.summary()
    # the input was rebuilt exactly: registers, PPS edges, GNSS bytes
    st = r.stimulus
    assert np.array_equal(st.gyro_regs, sim.gyro_regs)
    assert np.array_equal(st.accel_regs, sim.accel_regs)
    assert np.array_equal(st.pps_before_us, sim.pps_before_us)
    assert st.uart_bytes == sim.uart_bytes
    assert np.array_equal(st.uart_offsets, sim.uart_offsets)
    assert st.header["notes"] == []  # nothing skipped, no timing the emulator cannot follow
    # not vacuous: fixes every second, and navigation after the stand
    d = stream.decode(capture)
    assert sum(f["gga"] for f in d.frames) >= DURATION_S - 2
    assert sum(f["nav_state"] == 2 for f in d.frames) > 1000


def test_the_pps_timing_shapes_the_output(replayed, capture, values, tmp_path):
    """Each PPS edge one tick late: the frame's PPS flag moves, and the fix times with it
    change the navigation (the rebuilt edge times are not decoration)."""
    st = rebuild.to_stimulus(replayed.recording, values)
    k = np.flatnonzero(st.pps_before_us >= 0)
    st.pps_before_us[:] = -1
    st.pps_before_us[k + 1] = 0
    run = cpython.run(st, tmp_path)
    c = compare.compare(replayed.recording.stream, run.out)
    assert not c.identical
    assert c.frame.first == 0 and {f.name for f in c.frame.fields} == {"pps", "checksum"}
    assert c.ext.first is not None and any("pos_enu_m" in f.name for f in c.ext.fields)
    assert "first difference at frame 0 (tick 0, t = 0.000 s): pps recorded 1 replayed 0" in (
        c.summary()
    )


def test_pps_edges_across_the_ticks_us_wrap(capture, monkeypatch, tmp_path):
    """A board whose ticks_us wraps (2**30 us, ~17.9 min after boot) during the recording,
    with PPS edges 4 ms before their tick: the edge of tick 400 comes before the wrap and the
    tick after it, and is rebuilt 4000 us before the tick; the replay (whose clock does not
    wrap there) is identical."""
    stim = board_input.simulate("urban_drive", 12.0, seed=1).stimulus
    stim.pps_before_us[stim.pps_before_us >= 0] = 4000
    first_tick_us = stream.decode(capture[:400]).raw[0]["t0_us"]
    assert first_tick_us % TICK == 0  # the first timer moment after start-up (clock from 0)
    start = (1 << 30) + 3176 - 2_000_000 - first_tick_us  # tick 400: 3176 us after the wrap

    machine = install_machine()
    power_on = machine.power_on
    monkeypatch.setattr(machine, "power_on", lambda: power_on(start))  # a late power-on clock
    out = cpython.run(stim, tmp_path / "board", {"raw_record": 1}).out
    monkeypatch.undo()
    values = board_config.run_values(stim, {"raw_record": 1})
    rec = walk.parse(out, values)
    assert (rec.t0_us[399], rec.t0_us[400]) == ((1 << 30) - 1824, 3176)
    assert rec.pps_us[400] == (1 << 30) - 824  # the edge before the wrap
    st = rebuild.to_stimulus(rec, values)
    assert np.array_equal(st.pps_before_us[1:], stim.pps_before_us[1:])
    run = cpython.run(st, tmp_path / "replay")
    c = compare.compare(rec.stream, run.out)
    assert c.identical, c.summary()


def _recording(t0, pps, frame_pps=None):
    n = len(t0)
    frame_pps = frame_pps or [0] * n
    recs = []
    for k in range(n):
        f = bytearray(52)
        f[0:3] = bytes((0xEB, 0x90, k & 0xFF))
        f[15] = frame_pps[k]
        recs.append(bytes(f))
    return walk.Recording(
        {"raw_record": 1},
        0,
        0,
        np.array(t0, np.int64),
        np.array(pps, np.int64),
        np.zeros((n, 6), np.uint8),
        np.zeros((n, 6), np.uint8),
        np.zeros(n, np.uint8),
        np.zeros(n + 1, np.int64),
        b"",
        recs,
    )


def test_pps_edge_rules_on_board_like_timing():
    w = 1 << 30
    assert ticks_diff(100, w - 200) == 300 and ticks_diff(w - 200, 100) == -300
    # ticks with jitter (5000 +- 250 us, two overruns), ticks_us wrapping after tick 2
    t0 = [w - 10200, w - 5000, w - 100, 5150, 10000, 20000, 25000, 30000, 45000, 50000]
    pps = [
        0,
        0,
        w - 1100,  # 1000 us before tick 2, across the wrap
        w - 1100,
        12000,  # while tick 4 ran (after its start): its frame shows no PPS -> tick 5
        12000,
        27000,  # while tick 6 ran, and its frame shows the flag -> tick 6, at its start
        27000,
        36000,  # 9000 us before tick 8 (tick 7 overran)
        36000,
    ]
    frame_pps = [0, 0, 1, 0, 0, 1, 1, 0, 1, 0]
    before, notes = rebuild.pps_edges(_recording(t0, pps, frame_pps))
    assert before.tolist() == [-1, -1, 1000, -1, -1, 8000, 0, -1, 9000, -1]
    assert "2 PPS edges came while a tick ran" in notes[0]
    assert "1 PPS edges came more than a tick interval" in notes[1]
    (timing,) = rebuild.timing_notes(_recording(t0, pps))
    assert "6 tick starts not 5000 us after" in timing and "2 look like overruns" in timing


# ---- damage and gaps --------------------------------------------------------------------


def _parse_error(data, values, **kw):
    with pytest.raises(session_file.SessionError) as e:
        walk.parse(data, values, **kw)
    return str(e.value)


def test_a_flipped_byte_in_a_raw_record_is_a_gap_at_its_tick(capture, values):
    off, _, rec = _raw_of_tick(_records(capture), 1000)
    bad = bytearray(capture)
    bad[off + 14] ^= 0x10  # a gyro register byte: the record's CRC fails
    msg = _parse_error(bytes(bad), values)
    assert msg.startswith(f"gap at byte {off}, tick 1000 (t = 5.000 s): expected the raw-input")
    assert f"found {len(rec)} undecodable bytes" in msg and "--until-gap" in msg


def test_a_dropped_record_is_a_gap_and_until_gap_replays_the_ticks_before_it(
    capture, values, tmp_path
):
    off, _, rec = _raw_of_tick(_records(capture), 1000)
    dropped = capture[:off] + capture[off + len(rec) :]
    msg = _parse_error(dropped, values)
    assert f"gap at byte {off}, tick 1000" in msg
    assert "expected the raw-input record with counter 233, found a frame with counter 233" in msg
    session_file.write_session(tmp_path / "gap.ins", dropped, config=values)
    with pytest.raises(session_file.SessionError, match="tick 1000"):
        replay.replay(tmp_path / "gap.ins", tmp_path / "w1")
    r = replay.replay(tmp_path / "gap.ins", tmp_path / "w2", until_gap=True)
    assert r.identical and len(r.recording) == 1000 and "tick 1000" in r.recording.gap
    assert "replayed up to the first gap" in r.summary()


def test_a_cut_session_file_keeps_what_came_before_the_cut(session_path, capture, tmp_path):
    """A recorder killed, a cable pulled, a disk full: the file has no end marker. Every
    chunk before the cut is kept (the chunk being filled is lost), the readers say so, and the
    strict reader refuses it with the way out."""
    data = session_path.read_bytes()
    for cut in (len(data) - 3, len(data) // 2, len(data) // 7 + 5):
        (tmp_path / "cut.ins").write_bytes(data[:cut])
        s = session_file.load(tmp_path / "cut.ins")
        assert s.cut and not s.lost and s.header["config"] is not None
        assert capture.startswith(s.data)
        # the chunk being filled at the cut is lost, and no more (chunks of CHUNK_BYTES)
        assert len(s.data) >= min(len(capture), cut - 200 - 2 * session_file.CHUNK_BYTES)
        (msg,) = s.problems("cut.ins")
        assert "recording was cut (no end marker" in msg and f"the {len(s.data)} bytes" in msg
    with pytest.raises(session_file.SessionError, match="was cut .* session repair"):
        session_file.read_session(tmp_path / "cut.ins")
    with pytest.raises(session_file.SessionError, match="cannot read session"):
        session_file.load(tmp_path / "missing.ins")


def test_a_damaged_session_file_loses_only_the_damaged_chunk(session_path, capture, tmp_path):
    """One flipped byte costs the chunk it is in (its CRC fails): the bytes before and after
    are kept, the loss is counted from the chunks' offsets, and `session repair` writes what
    survived into an intact file whose replay stops at the gap, with --until-gap."""
    data = bytearray(session_path.read_bytes())
    data[len(data) // 2] ^= 0x04
    (tmp_path / "bad.ins").write_bytes(bytes(data))
    s = session_file.load(tmp_path / "bad.ins")
    assert not s.cut and len(s.lost) == 1
    off, k = s.lost[0]
    assert 0 < k <= session_file.CHUNK_BYTES
    assert s.data == capture[:off] + capture[off + k :]
    (msg,) = s.problems("bad.ins")
    assert f"1 damaged part(s) skipped: {k} of {len(capture)} captured bytes lost" in msg
    assert cli.main(["repair", str(tmp_path / "bad.ins"), "--out", str(tmp_path / "ok.ins")]) == 0
    header, fixed = session_file.read_session(tmp_path / "ok.ins")
    assert fixed == s.data and header["repaired"]["lost"] == [[off, k]]
    assert header["config"] == session_file.load(session_path).header["config"]
    r = replay.replay(tmp_path / "ok.ins", tmp_path / "w", until_gap=True)
    assert r.identical and 0 < len(r.recording) and r.recording.gap


def test_a_format_1_session_file_still_reads(capture, values, tmp_path):
    """The files of before (one CRC at the end): intact ones read as they were, a cut one up
    to the cut, a damaged one whole with a warning that it cannot say where."""
    import json

    from common.proto.crc import crc32

    head = json.dumps({"format": 1, "config": values}).encode()
    body = b"INSSESS1" + struct.pack("<I", len(head)) + head + capture
    body += b"END1" + struct.pack("<Q", len(capture))
    v1 = body + struct.pack("<I", crc32(body))
    (tmp_path / "v1.ins").write_bytes(v1)
    assert session_file.read_session(tmp_path / "v1.ins") == ({"format": 1, "config": values},
                                                              capture)  # fmt: skip
    (tmp_path / "cut.ins").write_bytes(v1[:-100])
    s = session_file.load(tmp_path / "cut.ins")
    assert s.cut and capture.startswith(s.data) and len(s.data) > len(capture) - 100
    bad = bytearray(v1)
    bad[len(bad) // 2] ^= 1
    (tmp_path / "bad.ins").write_bytes(bytes(bad))
    s = session_file.load(tmp_path / "bad.ins")
    assert len(s.data) == len(capture) and "damaged somewhere" in s.problems("bad.ins")[0]


def test_a_full_disk_ends_the_recording_cleanly(capture, values, tmp_path, monkeypatch):
    """ENOSPC halfway through: the recording stops with one line (no traceback), and the file
    holds every chunk written before, readable as a cut recording."""
    import errno

    (tmp_path / "capture.bin").write_bytes(capture)
    real = session_file.SessionWriter._out
    budget = {"n": len(capture) // 2}

    def out(self, b):
        budget["n"] -= len(b)
        if budget["n"] < 0:
            self.f.write = _raise_enospc
        real(self, b)

    def _raise_enospc(_b):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(session_file.SessionWriter, "_out", out)
    with pytest.raises(session_file.SessionError, match="No space left on device.*the recording"):
        record.record(tmp_path / "capture.bin", tmp_path / "full.ins", config=values)
    s = session_file.load(tmp_path / "full.ins")
    assert s.cut and capture.startswith(s.data) and len(s.data) > len(capture) // 3
    budget["n"] = len(capture) // 2
    argv = ["record", str(tmp_path / "capture.bin"), "--out", str(tmp_path / "full2.ins")]
    assert cli.main(argv) == 1


def test_the_replay_starts_at_the_boards_first_tick(capture, values):
    """Before the board's start the logger may hold the end of an earlier run (cut mid-record)
    and line noise; a late start (the first tick missing) cannot be replayed; stray bytes
    between records that still chain are tolerated; a cut-off last tick is left out."""
    head = _head(capture, 3000)
    earlier = capture[-10_007:-5]  # an earlier run, its last record cut short
    noisy = bytearray(head)
    recs = _records(head)
    noisy[recs[500][0] : recs[500][0]] = b"\x00\xeb\x90\x17"  # between two records
    data = earlier + b"\xff" * 5 + bytes(noisy) + capture[len(head) : len(head) + 40]
    rec = walk.parse(data, values)
    assert rec.start_offset == len(earlier) + 5 and len(rec) == 3000
    assert rec.stream == head
    assert rec.notes == [
        f"{len(earlier) + 5} bytes before the board's first tick skipped",
        "4 stray bytes between records ignored (the records chain)",
        "40 bytes after the last complete tick left out",
    ]
    late = head[_raw_of_tick(recs, 299)[0] :]
    assert "does not hold the board's first tick" in _parse_error(late, values)


def test_a_board_restart_inside_the_recording_is_named(capture, values):
    first = _head(capture, 700)[:-9]  # the board resets while sending tick 699's raw record
    msg = _parse_error(first + _head(capture, 300), values)
    assert "gap at byte" in msg and "tick 699" in msg and "(the board restarted)" in msg
    assert f"--from-last-start the run that starts at byte {len(first)}" in msg


def test_a_recording_across_a_restart_replays_from_its_last_start(capture, values, tmp_path):
    """The board restarted while recording: --from-last-start replays the run after the
    restart, byte for byte, and says where the board started; --until-gap the run before."""
    first = _head(capture, 700)[:-9]
    session_file.write_session(tmp_path / "restart.ins", first + _head(capture, 1500),
                               config=values)  # fmt: skip
    r = replay.replay(tmp_path / "restart.ins", tmp_path / "w1", from_last_start=True)
    assert r.identical and len(r.recording) == 1500 and r.recording.start_offset == len(first)
    text = r.summary()
    assert f"the board started 2 times in the recording (at bytes 0, {len(first)})" in text
    assert "replayed from the last" in text
    r = replay.replay(tmp_path / "restart.ins", tmp_path / "w2", until_gap=True)
    assert r.identical and len(r.recording) == 699
    assert "replayed from the first (--from-last-start: the last)" in r.summary()
    argv = ["replay", str(tmp_path / "restart.ins"), "--from-last-start"]
    assert cli.main(argv) == 0


def test_configuration_and_stream_problems_are_clear(capture, values, tmp_path):
    head = _head(capture, 400)
    session_file.write_session(tmp_path / "nocfg.ins", head)
    with pytest.raises(session_file.SessionError, match="holds no board configuration.*--config"):
        replay.replay(tmp_path / "nocfg.ins", tmp_path / "w")
    with pytest.raises(session_file.SessionError, match="raw_record = 0"):
        walk.parse(head, {**values, "raw_record": 0})
    only_frames = b"".join(r for _, t, r in _records(head) if t != 0x92)
    with pytest.raises(session_file.SessionError, match="only frames: the board ran with raw_rec"):
        walk.parse(only_frames, values)
    with pytest.raises(session_file.SessionError, match="nothing in the recording decodes"):
        walk.parse(bytes(range(256)) * 4, values)
    # the board's own configuration file (binary) and a JSON file of settings both load
    (tmp_path / "ins.cfg").write_bytes(board_config.to_bytes(values))
    loaded = board_config.load(tmp_path / "ins.cfg")
    assert board_config.to_bytes(loaded) == board_config.to_bytes(values)
    (tmp_path / "cfg.json").write_text('{"raw_record": 1, "gyro_range_dps": 500}')
    assert board_config.load(tmp_path / "cfg.json")["gyro_range_dps"] == 500
    (tmp_path / "bad.json").write_text('{"raw_record": 1, "gyro_range": 500}')
    with pytest.raises(board_config.ConfigError, match="unknown board configuration setting"):
        board_config.load(tmp_path / "bad.json")


def test_a_decoded_stream_gives_the_same_input(replayed, capture, values):
    a = rebuild.to_stimulus(stream.decode(capture), values)
    b = replayed.stimulus
    assert np.array_equal(a.gyro_regs, b.gyro_regs) and np.array_equal(a.accel_regs, b.accel_regs)
    assert np.array_equal(a.pps_before_us, b.pps_before_us) and a.uart_bytes == b.uart_bytes


def test_compare_leaves_out_the_timing_fields_only(capture):
    head = _head(capture, 400)
    recs = _records(head)
    board = bytearray(head)
    ext_off = [o for o, t, _ in recs if t == 0x91]
    struct.pack_into("<HHHH", board, ext_off[3] + 8, 4100, 3900, 2, 1)  # a board's timing
    raw_off = [o for o, t, _ in recs if t == 0x92]
    struct.pack_into("<II", board, raw_off[7] + 4, 123, 456)  # its own clock
    c = compare.compare(bytes(board), head)
    assert c.identical and c.timing_differs == 1
    assert "timing fields differ in 1" in c.summary()
    frame_off = [o for o, t, _ in recs if t == 0x90]
    board[frame_off[250] + 30] ^= 1  # yaw
    c = compare.compare(bytes(board), head)
    assert not c.identical and (c.frame.first, c.frame.tick) == (250, 250)
    assert [f.name for f in c.frame.fields] == ["yaw_cdeg"]


# ---- recording and the command line -------------------------------------------------


def test_record_from_a_pipe_and_a_serial_port(capture, tmp_path):
    data = capture[:20_000]
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)

    def writer():
        with open(fifo, "wb") as f:
            for i in range(0, len(data), 4096):
                f.write(data[i : i + 4096])
                f.flush()
                time.sleep(0.01)

    t = threading.Thread(target=writer)
    t.start()
    res = record.record(fifo, tmp_path / "pipe.ins")
    t.join()
    assert res["stopped"] == "end of input"
    header, got = session_file.read_session(tmp_path / "pipe.ins")
    assert got == data and header["config"] is None and header["baud"] is None

    serial = pytest.importorskip("serial")
    master, slave = os.openpty()
    port = os.ttyname(slave)

    def board():
        time.sleep(0.2)  # after the recorder opened the port (opening flushes its input)
        for i in range(0, 6000, 1000):
            os.write(master, data[i : i + 1000])
            time.sleep(0.02)

    t = threading.Thread(target=board)
    t.start()
    res = record.record(port, tmp_path / "tty.ins", seconds=0.8, baud=115200)
    t.join()
    header, got = session_file.read_session(tmp_path / "tty.ins")
    assert got == data[:6000] and header["baud"] == 115200 and res["stopped"] == "time"
    with serial.Serial(port, exclusive=True):  # another program holds the port
        with pytest.raises(
            session_file.SessionError, match="cannot open serial port .* another pr"
        ):
            record.record(port, tmp_path / "busy.ins", seconds=0.2)
    os.close(master)
    os.close(slave)
    with pytest.raises(session_file.SessionError, match="cannot open serial port /dev/ttyNOPE0"):
        record.record("/dev/ttyNOPE0", tmp_path / "x.ins", seconds=0.2)
    with pytest.raises(session_file.SessionError, match="no such file or serial port: nope.bin"):
        record.record("nope.bin", tmp_path / "x.ins")


def test_command_line(capture, values, tmp_path, capsys):
    (tmp_path / "cap.bin").write_bytes(_head(capture, 2000))
    (tmp_path / "ins.cfg").write_bytes(board_config.to_bytes(values))
    cfg = str(tmp_path / "ins.cfg")
    ins = str(tmp_path / "s.ins")
    assert cli.main(["record", str(tmp_path / "cap.bin"), "--out", ins, "--config", cfg]) == 0
    assert "recorded" in capsys.readouterr().out
    assert cli.main(["replay", ins, "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "REPLAY: identical, 2000 ticks" in out and "configuration from the session file" in out
    assert (tmp_path / "out" / "replayed.bin").read_bytes() == _head(capture, 2000)
    # the board's screen run too (it changes no record), and drawn
    png = tmp_path / "screen.png"
    assert cli.main(["replay", ins, "--display", str(png)]) == 0
    out = capsys.readouterr().out
    assert "REPLAY: identical, 2000 ticks" in out and f"screen: {png}" in out
    assert png.stat().st_size > 1000 and (tmp_path / "screen_strip.png").stat().st_size > 1000
    assert cli.main(["replay", ins, "--display", str(tmp_path)]) == 2
    assert "--display takes the path of a .png file" in capsys.readouterr().err
    # the MicroPython VM: double-precision floats, compared to its tolerance
    assert cli.main(["replay", ins, "--runtime", "micropython"]) == 0
    out = capsys.readouterr().out
    assert "frames: 2000 compared, equal [not compared: checksum; attitude, velocity" in out
    assert "REPLAY: equal within the VM's tolerance, 2000 ticks" in out
    # a plain capture with the configuration given at replay time
    assert cli.main(["replay", str(tmp_path / "cap.bin"), "--config", cfg]) == 0
    capsys.readouterr()
    # the wrong configuration: a mismatch, exit 1, with a hint
    (tmp_path / "wrong.json").write_text('{"raw_record": 1, "gyro_range_dps": 500}')
    assert cli.main(["replay", ins, "--config", str(tmp_path / "wrong.json")]) == 1
    out = capsys.readouterr().out
    assert "first difference at frame 0 (tick 0, t = 0.000 s): gyro_" in out
    assert "sensor ranges are not the board's?" in out and "REPLAY: DIFFERENT" in out
    # a failure: one line, exit 1 (as tools.flash and tools.monitor); a bad command line: 2
    for argv, text, status in (
        (["replay", str(tmp_path / "none.ins")], "cannot read session", 1),
        (["replay", str(tmp_path / "cap.bin")], "holds no board configuration", 1),
        (["record", "/dev/ttyNOPE0", "--out", ins], "cannot open serial port", 1),
        (["record", "x", "--out", ins, "--duration", "-1"], "--duration must be positive", 2),
        (["record", "x", "--out", ins, "--seconds", "0"], "--duration must be positive", 2),
        (["replay"], "python -m host_emulator session replay: the following arguments are "
         "required: session", 2),
        (["play", ins], "invalid choice", 2),
    ):  # fmt: skip
        assert cli.main(argv) == status, argv
        err = capsys.readouterr().err
        assert err.startswith("error: ") and text in err and err.count("\n") == 1, (argv, err)
