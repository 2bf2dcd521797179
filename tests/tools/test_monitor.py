"""tools.monitor: the incremental decoder equals host_emulator.frames.decode on any chunking
(garbage, a bad checksum, a bad CRC and a dropped frame counted exactly); the emulator's real
output read from a file and from a pseudo-terminal at the configured baud into CSV, MDF4 and a
replayable session file; Ctrl-C ends a live session cleanly; user mistakes give one clear
message, no traceback."""

import _thread
import csv
import datetime
import errno
import io
import os
import random
import re
import signal
import termios
import threading
import time
import tty

import numpy as np
import pytest

from common.proto import frame as frame_schema
from common.proto import session_file, stream
from common.proto.stream import StreamDecoder
from host_emulator.eval import gnss_dump
from host_emulator.runtimes import cpython
from host_emulator.session import replay
from host_emulator.sim import board_input
from host_emulator.sim.nmea import sentence
from tools.monitor import cli, export, nmea, view
from tools.monitor.clock import TickClock

BAUD = 460800
SECONDS = 4.0  # 800 ticks: frames, 40 extended frames, 800 raw-input records


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    """The emulator's output for 4 s of highway_outage (GNSS fixes from the start), with the
    raw-input records on: what a board sends. Returns (bytes, path of frames.bin, config)."""
    stim = board_input.simulate("highway_outage", SECONDS, seed=1).stimulus
    d = tmp_path_factory.mktemp("board")
    run = cpython.run(stim, d, {"raw_record": 1})
    path = d / "frames.bin"
    path.write_bytes(run.out)
    return run.out, path, d / "flash" / "ins.cfg"


def _records(data):
    """[(offset, length, type)] of the records of a clean stream (proto's decoder)."""
    return [(off, len(r), r[1]) for _, off, r in StreamDecoder().records(data, final=True)]


def test_tick_clock_follows_the_counter_and_the_extended_frames(board):
    d = stream.decode(board[0])
    clock = TickClock()
    ticks = []
    e = iter(d.ext)
    nxt = next(e)
    for k, f in enumerate(d.frames):
        ticks.append(clock.tick(clock.frame(f["counter"])))
        if nxt is not None and nxt["frame_index"] == k:
            clock.ext(nxt)
            assert clock.tick(clock.u) == nxt["tick"]
            nxt = next(e, None)
    assert ticks == list(range(1, len(d.frames) + 1))  # tick T sends counter T - 1
    # joined late (counter 200 first) and output every 2 ticks: anchored on the tick field
    clock = TickClock(every=2)
    clock.frame(200)
    clock.frame(201)
    clock.ext({"counter": 202, "tick": 10 * 512 + 404})
    assert clock.tick(clock.u) == 10 * 512 + 404
    assert clock.tick(clock.frame(203)) == 10 * 512 + 408  # a dropped frame: 2 steps
    assert clock.wrap_losses == 0


def test_frames_lost_in_whole_counter_wraps_are_counted(board):
    # 512 frames (and the extended frames among them) lost in a row: the counter cannot see
    # it, the next extended frame's tick does (a listener that was not reading for 2.56 s)
    recs = _records(board[0])
    frame_ix = [k for k, r in enumerate(recs) if r[2] == frame_schema.FRAME_TYPE]
    a, b = recs[frame_ix[100]][0], recs[frame_ix[612]][0]
    data = board[0][:a] + board[0][b:]
    mon = cli.Monitor(view.Status("test"), every=1)
    mon.feed(data)
    mon.finish()
    c = mon.counts()
    assert c["dropped_frames"] == 0 and c["wrap_losses"] == 512
    assert "512 lost in whole counter wraps" in view.error_line(c)


def _read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def _check_exports(tmp_path, d, prefix):
    head, rows = _read_csv(tmp_path / f"{prefix}.csv")
    assert head == [c[0] for c in export.FRAME_COLUMNS] and len(rows) == len(d.frames)
    utc = [datetime.datetime.fromisoformat(r[head.index("utc")]) for r in rows]
    cells = [[x or "nan" for k, x in enumerate(r) if head[k] != "utc"] for r in rows]
    a = np.array(cells, dtype=float)  # an empty fix cell: no valid fix (NaN)
    col = {name: a[:, k] for k, name in enumerate(h for h in head if h != "utc")}
    # a board started under the monitor: capture time from its first frame, board time from
    # its start, the host's UTC the first row's plus the capture time
    assert np.allclose(col["time_s"], 0.005 * np.arange(len(d.frames)))
    assert np.allclose(col["board_time_s"], 0.005 * np.arange(1, len(d.frames) + 1))
    assert not col["restart"].any()
    assert utc[0].tzinfo == datetime.UTC
    assert abs(utc[0] - datetime.datetime.now(datetime.UTC)) < datetime.timedelta(seconds=60)
    assert [round((u - utc[0]).total_seconds(), 3) for u in utc] == list(np.round(col["time_s"], 3))
    assert np.array_equal(col["counter"], [f["counter"] for f in d.frames])
    valid = np.array([f["gnss_valid"] for f in d.frames]) == 1
    lat = np.where(valid, [f["lat_e7"] / 1e7 for f in d.frames], np.nan)
    lon = np.where(valid, [f["lon_e7"] / 1e7 for f in d.frames], np.nan)
    np.testing.assert_allclose(col["lat_deg"], lat, atol=1e-9)  # NaN where not valid
    np.testing.assert_allclose(col["lon_deg"], lon, atol=1e-9)
    np.testing.assert_allclose(col["yaw_deg"], [f["yaw_deg"] for f in d.frames], atol=1e-9)
    np.testing.assert_allclose(col["accel_z_g"], [f["accel_g"][2] for f in d.frames], atol=1e-6)
    fix = next(k for k, f in enumerate(d.frames) if f["gnss_valid"])
    assert float(rows[fix][head.index("lat_deg")]) == d.frames[fix]["lat_e7"] / 1e7 != 0
    ehead, erows = _read_csv(tmp_path / f"{prefix}_ext.csv")
    assert ehead == [c[0] for c in export.EXT_COLUMNS] and len(erows) == len(d.ext)
    assert [int(r[ehead.index("tick")]) for r in erows] == [e["tick"] for e in d.ext]
    assert [int(r[ehead.index("causes")]) for r in erows] == [e["causes"] for e in d.ext]

    from asammdf import MDF

    with MDF(tmp_path / f"{prefix}.mf4") as mdf:
        assert len(mdf.groups) == 2
        names = {n for n in mdf.channels_db if not n.startswith("time")}
        assert len(names) == len(export.FRAME_COLUMNS) - 1 + len(export.EXT_COLUMNS) - 1
        lat = mdf.get("lat_deg")
        assert lat.unit == "deg" and len(lat.samples) == len(d.frames)
        assert lat.samples[fix] == d.frames[fix]["lat_e7"] / 1e7
        assert lat.timestamps[0] == 0 and lat.timestamps[-1] == pytest.approx(
            0.005 * (len(d.frames) - 1)
        )
        assert abs(mdf.header.start_time - utc[0]) < datetime.timedelta(milliseconds=1)
        sp = mdf.get("sigma_pos_e_m")
        assert sp.unit == "m" and len(sp.samples) == len(d.ext)
        assert sp.timestamps[-1] == pytest.approx(d.ext[-1]["tick"] * 0.005 - 0.005)


def test_a_capture_file_to_csv_mdf_and_session(board, tmp_path):
    data, path, cfg = board
    out = io.StringIO()
    rc = cli.main(
        [
            "--file", str(path), "--csv", str(tmp_path / "f.csv"), "--mdf",
            str(tmp_path / "f.mf4"), "--record", str(tmp_path / "f.ins"), "--config", str(cfg),
        ],
        out=out,
    )  # fmt: skip
    assert rc == 0
    text = out.getvalue()
    assert "800 frames, 40 extended frames, 800 raw records" in text
    assert "checksum failures 0  CRC failures 0  skipped bytes 0" in text
    assert "NAVIGATING" in text or "ALIGNING" in text
    d = stream.decode(data)
    _check_exports(tmp_path, d, "f")
    header, rec = session_file.read_session(tmp_path / "f.ins")
    assert rec == data and header["config"]["raw_record"] == 1
    # the recorded session replays through the emulator to the same bytes
    result = replay.replay(tmp_path / "f.ins", tmp_path / "replay")
    assert result.identical
    # and the session file is read back as a capture (its header's config used)
    out = io.StringIO()
    assert cli.main(["--file", str(tmp_path / "f.ins"), "--quiet"], out=out) == 0
    assert "800 frames" in out.getvalue()


def _pty(baud):
    master, slave = os.openpty()
    for fd in (master, slave):
        tty.setraw(fd)
        attrs = termios.tcgetattr(fd)
        speed = getattr(termios, f"B{baud}")
        attrs[4] = attrs[5] = speed
        termios.tcsetattr(fd, termios.TCSANOW, attrs)
    return master, slave, os.ttyname(slave)


@pytest.fixture
def port_opened(monkeypatch):
    """Set once the monitor has opened its port (pyserial flushes the input on opening: bytes
    written before would be lost)."""
    ev = threading.Event()

    class Port(cli.PortSource):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            ev.set()

    monkeypatch.setattr(cli, "PortSource", Port)
    return ev


def _stream(master, data, baud, done, opened, then_interrupt=True):
    """Once the port is open, write `data` into the pty master at the pace of the baud (10 bits
    a byte), then press Ctrl-C for the monitor (KeyboardInterrupt in the main thread)."""
    assert opened.wait(10)
    rate = baud / 10
    t0 = time.monotonic()
    sent = 0
    step = int(rate / 100)  # 10 ms of bytes
    while sent < len(data):
        n = os.write(master, data[sent : sent + step])
        sent += n
        wait = t0 + sent / rate - time.monotonic()
        if wait > 0:
            time.sleep(wait)
    done["seconds"] = time.monotonic() - t0
    time.sleep(0.4)
    if then_interrupt:
        _thread.interrupt_main()


def test_a_cut_or_damaged_recording_is_shown_with_what_it_lost(board, tmp_path):
    """A session file cut short, or with a flipped byte, is decoded up to the cut or around
    the damage, with a warning that says what was lost."""
    data, path, cfg = board
    session_file.write_session(tmp_path / "s.ins", data, config=None)
    whole = (tmp_path / "s.ins").read_bytes()
    (tmp_path / "cut.ins").write_bytes(whole[: len(whole) * 2 // 3])
    out, err = io.StringIO(), io.StringIO()
    assert cli.main(["--file", str(tmp_path / "cut.ins"), "--quiet"], out=out, err=err) == 0
    assert "was cut (no end marker" in err.getvalue() and "Traceback" not in err.getvalue()
    n = session_file.load(tmp_path / "cut.ins").data
    assert f"{len(stream.decode(n).frames)} frames" in out.getvalue()
    bad = bytearray(whole)
    bad[len(bad) // 2] ^= 0x40
    (tmp_path / "bad.ins").write_bytes(bytes(bad))
    out, err = io.StringIO(), io.StringIO()
    assert cli.main(["--file", str(tmp_path / "bad.ins"), "--quiet"], out=out, err=err) == 0
    assert "1 damaged part(s) skipped" in err.getvalue()


def test_a_full_disk_stops_the_recording_not_the_monitor(board, tmp_path, monkeypatch):
    """ENOSPC while the monitor records: one warning, the monitor goes on to the end of its
    input, the session file holds what was written (a cut recording), the exit status is 1."""
    import errno

    data, path, cfg = board
    calls = {"n": 0}
    real = session_file.SessionWriter._out

    def out_(self, b):
        calls["n"] += 1
        if calls["n"] > 3:
            raise_ = OSError(errno.ENOSPC, "No space left on device")

            def full(_b):
                raise raise_

            self.f.write = full
        real(self, b)

    monkeypatch.setattr(session_file.SessionWriter, "_out", out_)
    out, err = io.StringIO(), io.StringIO()
    argv = ["--file", str(path), "--record", str(tmp_path / "r.ins"), "--config", str(cfg)]
    assert cli.main([*argv, "--quiet"], out=out, err=err) == 1
    e = err.getvalue()
    assert e.count("No space left on device") == 1 and "Traceback" not in e, e
    assert "800 frames" in out.getvalue() and "r.ins" not in out.getvalue()  # no "wrote"
    s = session_file.load(tmp_path / "r.ins")
    assert s.cut and data.startswith(s.data) and len(s.data) > 0


def test_a_board_on_a_serial_port_at_the_baud_then_ctrl_c(board, tmp_path, port_opened):
    # Ctrl-C is Python's KeyboardInterrupt here, whatever the worker's SIGINT handler is
    # (interrupt_main() does nothing under SIG_DFL or SIG_IGN)
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        _board_then_ctrl_c(board, tmp_path, port_opened)
    finally:
        signal.signal(signal.SIGINT, old)


def _board_then_ctrl_c(board, tmp_path, port_opened):
    data, _path, cfg = board
    master, slave, name = _pty(BAUD)
    done = {}
    t = threading.Thread(target=_stream, args=(master, data, BAUD, done, port_opened), daemon=True)
    out = io.StringIO()
    try:
        t.start()
        rc = cli.main(
            [
                "--port", name, "--baud", str(BAUD), "--seconds", "30", "--config", str(cfg),
                "--csv", str(tmp_path / "p.csv"), "--mdf", str(tmp_path / "p.mf4"),
                "--record", str(tmp_path / "p.ins"),
            ],
            out=out,
        )  # fmt: skip
        t.join(5)
    finally:
        os.close(master)
        os.close(slave)
    assert rc == 0
    assert done["seconds"] >= len(data) / (BAUD / 10) * 0.95  # paced at 46 kB/s
    text = out.getvalue()
    assert "interrupted (Ctrl-C)" in text, text
    assert "summary: 800 frames, 40 extended frames, 800 raw records" in text
    assert "checksum failures 0  CRC failures 0  skipped bytes 0  dropped frames " in text
    assert "(counter gaps) 0" in text
    assert "\x1b[" not in text and " Hz " in text  # not a terminal: a line a second
    d = stream.decode(data)
    _check_exports(tmp_path, d, "p")
    header, rec = session_file.read_session(tmp_path / "p.ins")  # closed properly on Ctrl-C
    assert rec == data and header["baud"] == BAUD and header["source"] == name
    import xml.etree.ElementTree as ET

    from asammdf import MDF

    with MDF(tmp_path / "p.mf4") as mdf:  # the port and its baud in the MDF4 header
        props = {e.get("name"): e.text for e in ET.fromstring(mdf.header.comment).iter("e")}
    assert props["source"] == name and props["baud"] == str(BAUD) and "capture_file" not in props


def _opened_by(pid, path):
    """True once process `pid` has `path` open (Linux /proc)."""
    fds = f"/proc/{pid}/fd"
    try:
        return any(os.readlink(f"{fds}/{fd}") == path for fd in os.listdir(fds))
    except OSError:
        return False


def _feed_until(proc, master, data, done, baud=BAUD):
    """Write `data` (again and again) into the pty at the baud's pace until done() or `proc`
    has ended."""
    rate = baud / 10
    t0 = time.monotonic()
    sent = 0
    while not done() and proc.poll() is None:
        k = sent % len(data)
        try:
            sent += os.write(master, data[k : k + int(rate / 100)])
        except BlockingIOError:
            pass
        time.sleep(max(0.0, t0 + sent / rate - time.monotonic()))


def _after(seconds):
    end = time.monotonic() + seconds
    return lambda: time.monotonic() >= end


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_or_sighup_ends_the_capture_as_ctrl_c_does(board, tmp_path, sig):
    """The real monitor in a subprocess, reading a board on a pty, gets a real SIGTERM or
    SIGHUP in the middle of the stream: it exits 128 + the signal with every file complete
    (the session file with its end marker, the MDF4 with its samples, whole CSV rows)."""
    import subprocess
    import sys

    data, _path, cfg = board
    master, slave, name = _pty(BAUD)
    os.set_blocking(master, False)
    files = {"record": tmp_path / "s.ins", "csv": tmp_path / "s.csv", "mdf": tmp_path / "s.mf4"}
    argv = [sys.executable, "-m", "tools.monitor", "--port", name, "--baud", str(BAUD)]
    argv += ["--config", str(cfg), "--quiet"]
    for option, path in files.items():
        argv += [f"--{option}", str(path)]
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = {**os.environ, "PYTHONPATH": root}
    proc = subprocess.Popen(argv, cwd=root, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 30
        while not _opened_by(proc.pid, name) and proc.poll() is None:
            assert time.monotonic() < deadline, "the monitor never opened its port"
            time.sleep(0.02)
        # until the recorder has written two chunks (4096 bytes each: the monitor reads)
        rec = files["record"]
        _feed_until(proc, master, data, lambda: rec.exists() and rec.stat().st_size > 8192)
        _feed_until(proc, master, data, _after(0.3))
        proc.send_signal(sig)
        _feed_until(proc, master, data, _after(10.0))  # the board goes on sending
        out, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
        os.close(slave)
    assert proc.returncode == 128 + sig, err.decode()
    text = out.decode()
    assert f"stopped by {signal.Signals(sig).name}" in text, text
    assert b"error" not in err and b"Traceback" not in err, err.decode()  # (the data repeats:
    # the board restarts after it, a warning)
    header, rec = session_file.read_session(files["record"])  # refuses a file without its end
    assert header["source"] == name and len(rec) > 20000, text
    frames = stream.decode(rec).frames
    head, rows = _read_csv(files["csv"])
    assert len(rows) == len(frames) > 100 and all(len(r) == len(head) for r in rows)
    assert [int(r[head.index("counter")]) for r in rows] == [f["counter"] for f in frames]
    from asammdf import MDF

    with MDF(files["mdf"]) as mdf:
        assert len(mdf.get("yaw_deg").samples) == len(frames)
    assert f"wrote {files['mdf']} (MDF4: {len(frames)} frames" in text


def test_the_live_view_on_a_terminal(board):
    d = stream.decode(board[0])
    st = view.Status("/dev/ttyX", BAUD)
    dec = StreamDecoder()
    dec.feed(board[0])
    for k, f in enumerate(d.frames):
        st.on_frame((k + 1) * 0.005, f)
    st.on_ext(d.ext[-1])
    st.sample(0.0, {**dec.counts(), "frames": 0, "ext": 0, "bytes": 0})
    st.sample(1.0, dec.counts())
    lines = view.render(st, dec.counts(), 1.0)
    text = "\n".join(lines)
    for word in ("state", "GNSS", "position", "velocity", "attitude", "sigma", "rates", "errors"):
        assert word in text
    # 4 s into the drive the board still aligns: a warning that says so
    assert "800.0 frames/s" in text and "health 1 WARNING" in text and "last fix" in text
    assert "not_navigating" in text

    class Tty(io.StringIO):
        def isatty(self):
            return True

    scr = cli._Screen(Tty(), quiet=False)
    scr.draw(st, dec.counts(), 1.0, 1.0)
    scr.draw(st, dec.counts(), 1.3, 1.3)
    assert f"\x1b[{len(lines)}F\x1b[J" in scr.out.getvalue()  # redrawn in place


def test_the_live_view_fits_80_columns_and_says_when_data_stopped(board):
    """Every line of the live view fits an 80-column terminal, with the widest values a
    board sends (a long port name is cut, not wrapped); a second without frames shows STALE
    (the values are old), in the view and in the line-a-second output."""
    d = stream.decode(board[0])
    st = view.Status("/dev/serial/by-id/usb-FTDI_FT232R_USB_UART_A50285BI-if00-port0", 921600)
    f = dict(d.frames[-1])
    f.update(pos_enu_m=[-123456.78, -123456.78, -1234.5], vel_enu_m_s=[-99.99, -99.99, -9.99],
             yaw_deg=-179.99, pitch_deg=-89.99, roll_deg=-179.99)  # fmt: skip
    st.on_frame(1234.5, f)
    e = dict(d.ext[-1], causes=0xFFFF, tick=123456789)
    st.on_ext(e)
    big = {"frames": 10**7, "ext": 10**6, "raw": 10**7, "bytes": 10**10}
    counts = {**StreamDecoder().counts(), **big, "dropped_frames": 12345, "wrap_losses": 512,
              "restarts": 3}  # fmt: skip
    st.sample(100.0, {**counts, "frames": 0})
    st.sample(101.0, counts)
    lines = view.render(st, counts, 99999.9, now=101.2)
    assert all(len(x) <= view.WIDTH for x in lines), [x for x in lines if len(x) > 80]
    assert not any(x.startswith("STALE") for x in lines)
    lines = view.render(st, counts, 99999.9, now=103.5)
    assert lines[1] == "STALE      no frames for 2.5 s: the values below are old"
    assert "STALE (no frames for 2.5 s)" in view.one_line(st, counts, 100.0, now=103.5)


def test_a_board_restart_is_a_restart_not_dropped_frames(board, tmp_path):
    """A recording across a board restart (the board's output, then the same board from its
    start again): one restart, no dropped frames, and the board time of both runs."""
    data = board[0]
    (tmp_path / "twice.bin").write_bytes(data + data)
    out, err = io.StringIO(), io.StringIO()
    assert cli.main(["--file", str(tmp_path / "twice.bin"), "--quiet"], out=out, err=err) == 0
    text = out.getvalue()
    assert "1600 frames" in text and "dropped frames (counter gaps) 0" in text, text
    assert "board restarts 1" in text and "the board restarted" in err.getvalue()
    # the first run from its first frame (3.995 s), the second from the board's start (4 s)
    assert "board time 8.00 s (200.0 frames/s)" in text, text


def test_joining_a_running_board_and_its_restarts_give_the_capture_time(board, tmp_path):
    """Joined 1.5 s into a run (2.5 s of it captured), then two whole 4 s runs: the board time
    is the 10.5 s captured, each restart reports its run's own span, and the exported time
    goes on across the restarts (a restart flag, not a jump back), so a time cut works."""
    data = board[0]
    frames = [r[0] for r in _records(data) if r[2] == frame_schema.FRAME_TYPE]
    capture = data[frames[300] :] + data + data
    started = "2026-05-01T09:30:00+00:00"
    session_file.write_session(tmp_path / "j.ins", capture, config=None, started_utc=started)
    out, err = io.StringIO(), io.StringIO()
    argv = ["--file", str(tmp_path / "j.ins"), "--quiet", "--csv", str(tmp_path / "j.csv")]
    assert cli.main([*argv, "--mdf", str(tmp_path / "j.mf4")], out=out, err=err) == 0
    assert "board time 10.50 s (200.0 frames/s)" in out.getvalue(), out.getvalue()
    runs = re.findall(r"board time (\S+) s in the run before the restart", err.getvalue())
    assert runs == ["2.5", "4.0"], err.getvalue()
    head, rows = _read_csv(tmp_path / "j.csv")
    t = np.array([float(r[0]) for r in rows])
    assert len(rows) == 2100 and (np.diff(t) > 0).all()
    restarts = [k for k, r in enumerate(rows) if r[head.index("restart")] == "1"]
    assert restarts == [500, 1300]
    assert [rows[k][:3] for k in restarts] == [["2.500", "0.005", "1"], ["6.500", "0.005", "1"]]
    assert rows[0][:4] == ["0.000", "1.505", "0", "2026-05-01T09:30:00.000Z"]
    assert rows[-1][head.index("utc")] == "2026-05-01T09:30:10.495Z"
    ehead, erows = _read_csv(tmp_path / "j_ext.csv")
    assert (np.diff([float(r[0]) for r in erows]) > 0).all()
    from asammdf import MDF

    with MDF(tmp_path / "j.mf4") as mdf:
        start = datetime.datetime.fromisoformat(started)
        assert mdf.header.start_time == start
        assert list(mdf.get("restart").timestamps[mdf.get("restart").samples == 1]) == [2.5, 6.5]
        with mdf.cut(3, 5, include_ends=False) as part:  # 3.000 .. 5.000 s: 401 frames, 20 ext
            assert len(part.get("yaw_deg").samples) == 401
            assert len(part.get("sigma_pos_e_m").samples) == 20
        utc = mdf.get("utc_unix_s")
        assert utc.samples[-1] == pytest.approx(start.timestamp() + 10.495)


def _no_space(path):
    """The one error line naming `path` for a full disk."""
    return f"error: writing {path} failed: No space left on device (the disk is full); nothing of it is kept"  # noqa: E501


@pytest.mark.parametrize("option", ["--csv", "--mdf", "--record"])
def test_an_output_on_a_full_device_is_an_error_not_wrote(board, option):
    """/dev/full takes the open and refuses every write: exit 1, one line naming it and the
    OS reason, and no "wrote" line for it."""
    _data, path, _cfg = board
    out, err = io.StringIO(), io.StringIO()
    assert cli.main(["--file", str(path), "--quiet", option, "/dev/full"], out=out, err=err) == 1
    lines = [x for x in err.getvalue().splitlines() if "/dev/full" in x]
    assert len(lines) == 1 and "No space left on device" in lines[0], err.getvalue()
    assert "wrote /dev/full" not in out.getvalue() and "Traceback" not in err.getvalue()
    if option == "--csv":  # the extended frames' CSV beside it is not kept either
        assert lines[0] == _no_space("/dev/full")
        assert not os.path.exists("/dev/full_ext.csv") and not os.path.exists(
            "/dev/.full_ext.csv.part"
        )


class _FillsUp(io.FileIO):
    """A file on a disk that takes `room` bytes more, then fails as a full disk does (the
    buffered file above it meets the error when it flushes, as on a real disk)."""

    room = 20000

    def write(self, b):
        self.room -= len(b)
        if self.room < 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        return super().write(b)


def _open_filling_up(name, mode="r", newline=None, **_kw):
    raw = _FillsUp(name, mode.replace("+", "").replace("b", "") + ("+" if "+" in mode else ""))
    buffered = io.BufferedRandom(raw) if "+" in mode else io.BufferedWriter(raw)
    return buffered if "b" in mode else io.TextIOWrapper(buffered, newline=newline)


def test_a_disk_that_fills_up_keeps_no_half_written_export(board, tmp_path, monkeypatch):
    """ENOSPC in the middle of the CSV (while the capture runs) and of the MDF4 (saved at the
    end): one line each naming the file, exit 1, neither file nor its part left, and the
    session recorded beside them complete."""
    data, path, cfg = board
    real_open = open

    def opener(name, mode="r", **kw):
        if str(name).endswith((".c.csv.part", ".m.mf4.part")):
            return _open_filling_up(name, mode, **kw)
        return real_open(name, mode, **kw)

    monkeypatch.setattr(export, "open", opener, raising=False)
    out, err = io.StringIO(), io.StringIO()
    argv = ["--file", str(path), "--quiet", "--csv", str(tmp_path / "c.csv"), "--mdf"]
    argv += [str(tmp_path / "m.mf4"), "--record", str(tmp_path / "r.ins"), "--config", str(cfg)]
    assert cli.main(argv, out=out, err=err) == 1
    e = err.getvalue().splitlines()
    assert e == [_no_space(tmp_path / "c.csv"), _no_space(tmp_path / "m.mf4")], e
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.ins"]
    assert "wrote" not in out.getvalue().replace(f"wrote {tmp_path / 'r.ins'}", "")
    assert session_file.read_session(tmp_path / "r.ins")[1] == data


def _err(argv):
    out, err = io.StringIO(), io.StringIO()
    rc = cli.main(argv, out=out, err=err)
    return rc, err.getvalue()


def test_user_mistakes_give_one_clear_message(tmp_path):
    rc, msg = _err(["--file", str(tmp_path / "nope.bin")])
    assert rc == 1 and "no such file" in msg and "Traceback" not in msg
    rc, msg = _err(["--port", "/dev/ttyNOPE_monitor"])
    assert rc == 1 and "no such serial port: /dev/ttyNOPE_monitor" in msg
    assert "serial ports found" in msg or "no serial ports found" in msg
    junk = tmp_path / "junk.bin"
    junk.write_bytes(bytes(random.Random(3).randrange(256) for _ in range(5000)))
    rc, msg = _err(["--file", str(junk), "--quiet"])
    assert rc == 1 and "5000 bytes but no frames" in msg and "not a capture" in msg
    (tmp_path / "empty.bin").write_bytes(b"")
    rc, msg = _err(["--file", str(tmp_path / "empty.bin")])
    assert rc == 1 and "is empty" in msg
    bad = tmp_path / "cut.ins"
    session_file.write_session(bad, b"\xeb\x90" * 100)
    bad.write_bytes(bad.read_bytes()[:-10])
    rc, msg = _err(["--file", str(bad)])
    assert rc == 1 and "was cut (no end marker" in msg and "200 bytes but no frames" in msg
    rc, msg = _err(["--file", str(junk), "--csv", str(tmp_path / "no_dir" / "x.csv")])
    assert rc == 1 and "cannot write" in msg
    with pytest.raises(SystemExit) as e:  # argparse: usage and status 2
        _err([])
    assert e.value.code == 2


def test_a_port_that_sends_only_garbage_or_nothing_or_is_busy(tmp_path, port_opened):
    master, slave, name = _pty(BAUD)
    try:
        junk = bytes(random.Random(5).randrange(256) for _ in range(20000))
        t = threading.Thread(
            target=_stream, args=(master, junk, BAUD, {}, port_opened, False), daemon=True
        )
        t0 = time.monotonic()
        t.start()
        rc, msg = _err(["--port", name, "--timeout", "0.3", "--quiet"])
        t.join(5)
        assert rc == 1 and "bytes arrived" in msg and "but no frames: check the baud" in msg
        assert "output_baud" in msg and time.monotonic() - t0 < 5
        rc, msg = _err(["--port", name, "--timeout", "0.2", "--quiet"])
        assert rc == 1 and "no bytes received" in msg
        import serial

        with serial.Serial(name, BAUD, exclusive=True):
            rc, msg = _err(["--port", name, "--quiet"])
        assert rc == 1 and "busy" in msg
    finally:
        os.close(master)
        os.close(slave)


def test_the_view_names_the_causes_of_the_health_code():
    """An extended frame's cause bits are shown by name in the live view and the log line."""
    from common.proto import records
    from tools.monitor import view

    st = view.Status("test")
    f = frame_schema.decode(frame_schema.encode(1, nav_state=2))
    st.on_frame(0.005, f)
    fields = {n: ([0.0] * c if c > 1 else 0) for n, _, c in records.EXT_FIELDS}
    fields.update(health=2, nav_state=2, causes=0x204)  # imu_dead, uncertain
    st.on_ext(records.decode_ext(records.encode_ext(1, fields)))
    counts = dict.fromkeys(("bytes", "skipped_bytes", "bad_checksum", "bad_crc",
                            "dropped_frames", "frames", "ext", "raw"), 0)  # fmt: skip
    text = "\n".join(view.render(st, counts, 1.0, live=False))
    assert "health 2 FAULT" in text and "causes     imu_dead uncertain" in text
    assert "health=2 (imu_dead,uncertain)" in view.one_line(st, counts, 1.0)


def test_recording_without_a_configuration_or_raw_records_is_noted(tmp_path):
    """Recording a port: a session without the board's configuration, or from a board that
    sends no raw-input records, would not replay; the monitor says so before it starts."""
    master, slave, name = _pty(BAUD)
    try:
        for extra, note in (
            ([], "will hold no board configuration"),
            (["--config", str(tmp_path / "c.json")], "raw_record = 0"),
        ):
            (tmp_path / "c.json").write_text('{"raw_record": 0}')
            err = io.StringIO()
            argv = ["--port", name, "--record", str(tmp_path / "r.ins"), "--timeout", "0.3",
                    "--quiet", *extra]  # fmt: skip
            assert cli.main(argv, out=io.StringIO(), err=err) == 1  # nothing came
            assert note in err.getvalue(), err.getvalue()
    finally:
        os.close(master)
        os.close(slave)


def test_board_time_adds_up_over_several_restarts(board, tmp_path):
    """Three runs of the board in one file: the board time is the three runs', each counted
    once (a restart adds the time since the last one, not all the time again), and each
    restart's warning gives the run before it alone."""
    (tmp_path / "thrice.bin").write_bytes(board[0] * 3)
    out, err = io.StringIO(), io.StringIO()
    assert cli.main(["--file", str(tmp_path / "thrice.bin"), "--quiet"], out=out, err=err) == 0
    text = out.getvalue()
    assert "board restarts 2" in text and "board time 12.00 s (200.0 frames/s)" in text, text
    said = err.getvalue().count("(board time 4.0 s in the run before the restart)")
    assert said == 2, err.getvalue()


def _gnss_bytes(board):
    return b"".join(r["gnss_bytes"] for r in stream.decode(board[0]).raw)


def test_every_gga_agrees_with_the_firmware_driver(board):
    data = _gnss_bytes(board)
    rows, _driver = gnss_dump.dump(data)
    want = [
        (round(float(r["utc_s"]) * 1000), r["quality"], r["nsat"], float(r["hdop"]))
        for r in rows
        if r["type"] == "GGA"
    ]
    got = []
    rx = nmea.Receiver()
    for k in range(0, len(data), 7):  # any chunking: sentences span records
        rx.feed(data[k : k + 7])
        if rx.gga is not None and (not got or rx.n_gga != len(got)):
            g = rx.gga
            got.append((g.utc_ms, g.quality, g.n_sats, g.hdop))
    assert len(want) >= 3 and got == want
    assert rx.rmc.date_iso == "2026-11-22" and rx.rmc.utc_ms == want[-1][0]
    assert rx.bad_checksums == 0


def test_a_damaged_or_empty_sentence_is_not_used():
    rx = nmea.Receiver()
    good = sentence("GNGGA,123519.50,4807.038,N,01131.000,E,4,12,0.9,545.4,M,46.9,M,,")
    rx.feed(good)
    assert rx.gga == nmea.Gga(utc_ms=45319500, quality=4, n_sats=12, hdop=0.9)
    assert rx.last_fix == rx.gga and nmea.fix_type(4) == "RTK fixed"
    bad = bytearray(sentence("GNGGA,123520.50,4807.038,N,01131.000,E,5,11,1.0,545.4,M,,M,,"))
    bad[20] ^= 1  # a flipped bit: the checksum fails
    rx.feed(bytes(bad))
    assert rx.gga.utc_ms == 45319500 and rx.bad_checksums == 1
    rx.feed(sentence("GPGGA,,,,,,0,,,,,,,,"))  # a receiver without a fix
    assert rx.gga == nmea.Gga(utc_ms=None, quality=0, n_sats=None, hdop=None)
    assert rx.last_fix.utc_ms == 45319500  # the last fix stays
    rx.feed(b"$GNGGA,1235x9.50,,,,,1,05,2.1,,,,,,*00\r\n")  # bad checksum and bad field
    rx.feed(sentence("GNGGA,12x519.50,,,,,1,05,2.1,,,,,,"))  # bad field: not used
    assert rx.gga.quality == 0 and rx.bad_fields == 1


def _hms(utc_ms):
    s, ms = divmod(utc_ms, 1000)
    return f"{s // 3600:02d}:{s // 60 % 60:02d}:{s % 60:02d}.{ms // 10:02d}"


def test_the_live_view_shows_the_receiver_and_the_recording(board, tmp_path):
    """What gpsmon shows: fix type, satellites, HDOP and the UTC of the last fix, read from the
    raw-input records' GNSS bytes (the firmware's driver reads the same values), and REC with
    the session file's size; '-' with the setting that gives them when no raw record came."""
    d = stream.decode(board[0])
    rec = session_file.SessionWriter(tmp_path / "run.ins", {"format": session_file.FORMAT})
    rec.write(b"\0" * 1_234_567)
    st = view.Status("/dev/ttyX", BAUD, recorder=rec)
    for k, f in enumerate(d.frames):
        st.on_frame((k + 1) * 0.005, f)
    st.on_ext(d.ext[-1])
    lines = view.render(st, {**StreamDecoder().counts(), "bytes": 0}, 4.0)
    assert lines[1].startswith("REC        ") and lines[1].endswith("/run.ins  1.2 MB")
    assert "receiver   fix -  sats -  HDOP -  UTC -  (needs raw_record = 1)" in lines
    for r in d.raw:
        st.on_raw(r)
    gga = [r for r in gnss_dump.dump(_gnss_bytes(board))[0] if r["type"] == "GGA"][-1]
    want = (
        f"receiver   fix GPS  sats {gga['nsat']}  HDOP {gga['hdop']}  "
        f"UTC 2026-11-22 {_hms(round(float(gga['utc_s']) * 1000))}"
    )
    lines = view.render(st, {**StreamDecoder().counts(), "bytes": 0}, 4.0)
    assert want in lines, lines
    assert f"fix GPS sats {gga['nsat']} hdop {gga['hdop']}" in view.one_line(
        st, {**StreamDecoder().counts(), "bytes": 0}, 4.0
    )
    rec.close()


def test_the_receiver_and_recording_lines_fit_80_columns(board, tmp_path):
    d = stream.decode(board[0])
    rec = session_file.SessionWriter(tmp_path / ("x" * 90 + ".ins"), {})
    rec.n = 12_345_678_901  # 12.3 GB recorded
    st = view.Status("/dev/serial/by-id/usb-FTDI_FT232R_USB_UART_A50285BI-if00-port0", 921600,
                     recorder=rec)  # fmt: skip
    st.on_frame(1.0, d.frames[-1])
    st.on_raw({"gnss_bytes": sentence("GNGGA,235959.99,,,,,6,99,99.99,,,,,,")})
    st.on_raw({"gnss_bytes": sentence("GNRMC,235959.99,A,,,,,,,311299,,,A")})
    lines = view.render(st, {**StreamDecoder().counts(), "bytes": 0}, 99999.9)
    assert all(len(x) <= view.WIDTH for x in lines), [x for x in lines if len(x) > 80]
    assert lines[1].startswith("REC        ...") and lines[1].endswith("x.ins  12345.7 MB")
    assert "receiver   fix dead reckoning  sats 99  HDOP 99.99  UTC 1999-12-31 23:59:59.99" in lines
    rec.close()


def test_frames_without_a_valid_fix_have_no_position_in_the_exports(board, tmp_path):
    """gnss_valid 0: empty lat/lon/height cells in the CSV (NaN in the MDF4), not 0,0."""
    d = stream.decode(board[0])
    argv = ["--file", str(board[1]), "--quiet", "--csv", str(tmp_path / "g.csv"),
            "--mdf", str(tmp_path / "g.mf4")]  # fmt: skip
    assert cli.main(argv, out=io.StringIO()) == 0
    head, rows = _read_csv(tmp_path / "g.csv")
    cells = [[r[head.index(c)] for c in ("lat_deg", "lon_deg", "height_m")] for r in rows]
    valid = [f["gnss_valid"] for f in d.frames]
    assert 0 in valid and 1 in valid
    for f, c in zip(d.frames, cells, strict=True):
        if f["gnss_valid"]:
            assert float(c[0]) == f["lat_e7"] / 1e7 and float(c[2]) == pytest.approx(f["height_m"])
        else:
            assert c == ["", "", ""]
    from asammdf import MDF

    with MDF(tmp_path / "g.mf4") as mdf:
        lat = mdf.get("lat_deg").samples
    assert np.array_equal(np.isnan(lat), np.array(valid) == 0)


def test_the_mdf4_file_says_what_it_holds(board, tmp_path):
    """Header: source, baud, the board's configuration, the start time, the tool and its
    version; every channel a unit (where it has one) and a comment naming its field; the
    navigation state and the health as names."""
    import tomllib
    import xml.etree.ElementTree as ET

    from asammdf import MDF

    data, _path, cfg = board
    src = tmp_path / "s.ins"
    recorded = {
        "format": session_file.FORMAT,
        "source": "/dev/ttyUSB7",
        "baud": 921600,
        "started_utc": "2026-05-01T09:30:00+00:00",
        "config": {"raw_record": 1, "output_every_ticks": 1},
    }
    w = session_file.SessionWriter(src, recorded)
    w.write(data)
    w.close()
    assert cli.main(["--file", str(src), "--quiet", "--mdf", str(tmp_path / "m.mf4")],
                    out=io.StringIO()) == 0  # fmt: skip
    version = tomllib.loads(open("pyproject.toml").read())["project"]["version"]
    with MDF(tmp_path / "m.mf4") as mdf:
        root = ET.fromstring(mdf.header.comment)
        props = {e.get("name"): e.text for e in root.iter("e")}
        assert "INS board output" in root.find("TX").text
        assert props["source"] == "/dev/ttyUSB7" and props["baud"] == "921600"
        assert props["capture_file"] == str(src)
        assert props["start_utc"] == "2026-05-01T09:30:00.000Z"
        assert mdf.header.start_time == datetime.datetime(2026, 5, 1, 9, 30, tzinfo=datetime.UTC)
        assert props["tool"] == "python -m tools.monitor" and props["tool_version"] == version
        tree = {t.get("name"): t for t in root.iter("tree")}
        config = {e.get("name"): e.text for e in tree["config"].iter("e")}
        assert config == {"raw_record": "1", "output_every_ticks": "1"}
        yaw = mdf.get("yaw_deg")
        assert yaw.unit == "deg" and "yaw_cdeg" in yaw.comment and "byte 29" in yaw.comment
        assert mdf.get("sigma_pos_e_m").comment.startswith("1-sigma")
        for name in export.MDF_FRAME_NAMES[1:] + export.MDF_EXT_NAMES[1:]:
            assert mdf.get(name).comment, name
        nav = mdf.get("nav_state")
        assert set(nav.samples) == {b"aligning"}  # 4 s into the drive: still aligning
        assert set(mdf.get("nav_state", raw=True).samples) == {1}
        health = mdf.get("health")
        assert set(health.samples) <= {b"ok", b"warning", b"fault"} and b"warning" in set(
            health.samples
        )
        conv = mdf.get("ext_nav_state", raw=True).conversion
        assert conv.convert(np.array([1, 2])).tolist() == [b"aligning", b"navigating"]
