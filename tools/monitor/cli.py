"""`python -m tools.monitor`: decode, watch, record and export what a board sends.

    python -m tools.monitor --port /dev/ttyUSB0 [--baud 460800] [--record s.ins] [--csv s.csv]
    python -m tools.monitor --file frames.bin --csv s.csv --mdf s.mf4 --quiet
    python -m tools.monitor --list-ports

See docs/monitor.md. Exit status: 0 done (end of file, --duration reached, Ctrl-C), 1 a problem
the message explains (no such port, nothing decodable, a failed write, ...), 2 bad command
line, 128 + N ended by signal N (SIGTERM 143, SIGHUP 129: the files completed first).
"""

import argparse
import datetime
import os
import signal
import sys
import threading
import time

from common import progress
from common.errors import os_error_text, quiet_broken_pipe
from common.proto import config as board_config
from common.proto import session_file
from common.proto.stream import EXT, FRAME, RAW, StreamDecoder
from tools.monitor import export, view
from tools.monitor.clock import TICK_S, CaptureClock, TickClock
from tools.monitor.source import FileSource, MonitorError, PortSource, list_ports

DRAW_EVERY_S = 0.25  # live view redraws (terminal)
LINE_EVERY_S = 1.0  # one line per second (not a terminal)
CTRL_C = "interrupted (Ctrl-C)"
STOP_SIGNALS = ("SIGTERM", "SIGHUP")  # `timeout`, kill; a closed terminal, a dropped ssh
PENDING_MAX = 400  # frames held for the first extended frame's tick (2 s at 200 Hz)


class Monitor:
    """The decoded stream to the view and the files. TickClock gives each frame its board
    time, CaptureClock the capture's time (0 at the first frame, monotonic across restarts).
    Frames wait (up to PENDING_MAX) for the next extended frame when their time is not sure
    yet: before the first one (joining a running board) and after a counter gap (a restart
    shows as one, and the extended frame's tick then times them in the new run)."""

    def __init__(self, status, every=1, outputs=(), recorder=None, warn=None, start_unix_s=None):
        self.warn = warn or (lambda _msg, _kind="warning": None)  # a line to the user
        self.decoder = StreamDecoder()
        self.clock = TickClock(every)
        self.capture = CaptureClock()
        self.status = status
        self.outputs = list(outputs)  # exports: frame(stamp, f), ext(stamp, e), close()
        self.failures = []  # why an export stopped (export.WriteFailed)
        self.recorder = recorder
        self.start_unix_s = start_unix_s  # host UTC of capture time 0; None: at the first frame
        self._pending = []
        self._hold = False  # a counter gap: wait for the next extended frame's tick
        self._restarted = False  # the next frame given out is a restarted run's first
        self.board_limit_s = None  # a file with --seconds: ignore what comes after this
        self.done = False
        self.restarts = 0  # board restarts seen (an extended frame's tick went back)
        self._restart_gaps = 0  # the counter gaps they made: not dropped frames
        self._gap = 0  # the newest counter gap since the last extended frame

    def counts(self):
        c = self.decoder.counts()
        c["dropped_frames"] -= self._restart_gaps
        return {**c, "wrap_losses": self.clock.wrap_losses, "restarts": self.restarts}

    def feed(self, chunk):
        if self.recorder is not None and chunk and not self.recorder.write(chunk):
            self.warn(self.recorder.failed)  # a full disk: the monitor goes on without it
            self.recorder = None
        self._handle(self.decoder.feed(chunk))

    def finish(self):
        self._handle(self.decoder.finish())
        self._flush()

    def _handle(self, records):
        for kind, rec in records:
            if self.done:
                return
            if kind == FRAME:
                self._frame(rec)
            elif kind == EXT:
                self._ext(rec)
            elif kind == RAW:
                self.status.on_raw(rec)  # the receiver's sentences, for the view

    def _frame(self, rec):
        if self.start_unix_s is None:
            self.start_unix_s = time.time()  # the host's clock at the first frame
        u = self.clock.frame(rec["counter"])
        if self.clock.gap:
            self._gap = self.clock.gap
            self._hold = self.clock.anchored
        if self.clock.anchored and not self._hold and not self._pending:
            self._out(u, rec)
        else:
            self._pending.append((u, rec))
            if len(self._pending) >= PENDING_MAX:
                self._flush()

    def _ext(self, rec):
        if self.clock.ext(rec):
            self._restart()
        self._gap = 0
        self._hold = False
        self._flush()
        if self.done:
            return
        self.status.on_ext(rec)
        stamp = self._stamp(self.capture.at(rec["tick"] * TICK_S), rec["tick"] * TICK_S, 0)
        self._each_output(lambda o: o.ext(stamp, rec))

    def _restart(self):
        """The board restarted since the last extended frame: the counter gap it made is no
        loss, and its new run is timed on from the last frame's capture time."""
        self.restarts += 1
        self._restart_gaps += self._gap
        run_s = self.status.on_restart(self.capture.last_s)
        self.capture.restart()
        self._restarted = True
        self.warn(f"the board restarted (board time {run_s:.1f} s in the run before the restart)")

    def _stamp(self, t_s, board_s, restart):
        """The times of a row: capture time, the run's board time, the restart flag and the
        host's UTC (Unix s: the start plus the capture time)."""
        return {
            "time_s": t_s,
            "board_time_s": board_s,
            "restart": restart,
            "utc_unix_s": self.start_unix_s + t_s,
        }

    def _out(self, u, f):
        board_s = self.clock.time_s(u)
        t = self.capture.frame(board_s)
        if self.board_limit_s is not None and t >= self.board_limit_s:
            self.done = True
            return
        self.status.on_frame(t, f)
        stamp = self._stamp(t, board_s, int(self._restarted))
        self._restarted = False
        self._each_output(lambda o: o.frame(stamp, f))

    def _each_output(self, write):
        """write(output) for each output; one that fails (a full disk) is dropped with a
        warning naming its file, and the capture goes on."""
        for o in list(self.outputs):
            try:
                write(o)
            except export.WriteFailed as e:
                self.outputs.remove(o)
                self.failures.append(str(e))
                self.warn(str(e), "error")

    def _flush(self):
        for u, f in self._pending:
            if self.done:
                break
            self._out(u, f)
        self._pending = []


class StopSignals:
    """SIGTERM and SIGHUP end the capture as Ctrl-C does: the handler only notes the signal
    (a write is never cut), the read loop stops at its next turn (within 50 ms), the files are
    completed, and the exit status is 128 + the signal. A second one acts at once (the
    default). Installed from the main thread only (Python's rule for signal handlers)."""

    def __init__(self):
        self.signum = None
        self._old = {}

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for name in STOP_SIGNALS:
                sig = getattr(signal, name, None)  # Windows has no SIGHUP
                if sig is not None:
                    self._old[sig] = signal.signal(sig, self._note)
        return self

    def __exit__(self, *_exc):
        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._old = {}

    def _note(self, signum, _frame):
        if self.signum is not None:  # asked twice: do not wait for the files
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
        self.signum = signum

    def stopped(self):
        """Why the capture stopped, or None while no signal came."""
        return None if self.signum is None else f"stopped by {signal.Signals(self.signum).name}"


class _Screen:
    """Live redraw on a terminal (ANSI: cursor up, clear to end), a line a second otherwise."""

    def __init__(self, out, quiet):
        self.out = out
        self.quiet = quiet
        self.tty = bool(getattr(out, "isatty", lambda: False)())
        self.every = DRAW_EVERY_S if self.tty else LINE_EVERY_S
        self._drawn = 0
        self._last = None

    def due(self, now):
        return not self.quiet and (self._last is None or now - self._last >= self.every)

    def draw(self, st, counts, elapsed, now):
        self._last = now
        if self.tty:
            lines = view.render(st, counts, elapsed, now=now)
            up = f"\x1b[{self._drawn}F" if self._drawn else ""
            self.out.write(up + "\x1b[J" + "\n".join(lines) + "\n")
            self._drawn = len(lines)
        else:
            self.out.write(view.one_line(st, counts, elapsed, now) + "\n")
        self.out.flush()


def _parser():
    p = argparse.ArgumentParser(
        prog="python -m tools.monitor",
        description="Decode, watch, record and export what an INS board sends (52-byte frames, "
        "extended frames, raw-input records). See docs/monitor.md.",
    )
    src = p.add_mutually_exclusive_group()
    src.add_argument("--port", help="serial port (e.g. /dev/ttyUSB0, COM3, a pyserial URL)")
    src.add_argument("--file", help="a raw capture or a session file (host_emulator session)")
    src.add_argument("--list-ports", action="store_true", help="list serial ports and exit")
    p.add_argument(
        "--baud",
        type=int,
        help="serial baud rate, 8N1 (default: --config's output_baud, else the board's default)",
    )
    p.add_argument(
        "--config",
        help="the board's configuration file (or JSON settings): its output_every_ticks sets the "
        "time base; kept in the --record session so it can be replayed",
    )
    p.add_argument(
        "--board-port", metavar="PORT",
        help="the board's USB (REPL) port: read its configuration and which board it is into "
        "the --record session, then restart its firmware so the recording holds its start "
        "(what a replay needs)",
    )  # fmt: skip
    p.add_argument("--record", metavar="FILE", help="write every byte received to a session file")
    p.add_argument("--csv", metavar="FILE", help="frames as CSV (+ FILE_ext.csv: extended frames)")
    p.add_argument("--mdf", metavar="FILE", help="frames and extended frames as MDF4 (.mf4)")
    p.add_argument(
        "--duration", dest="seconds", type=float,
        help="stop after N s (port: wall time; file: board time)",
    )  # fmt: skip
    p.add_argument("--seconds", type=float, help=argparse.SUPPRESS)  # --duration's old name
    p.add_argument("--quiet", action="store_true", help="no live view, only the summary")
    p.add_argument(
        "--timeout",
        type=float,
        default=5.0,
        help="port: give up when nothing decodable arrived in this many s (default 5)",
    )
    return p


def _every(values):
    try:
        return max(1, int((values or {}).get("output_every_ticks", 1)))
    except (TypeError, ValueError):
        return 1


def _no_data_error(src, counts, waited):
    n = counts["bytes"]
    if n == 0:
        return MonitorError(
            f"no bytes received from {src.name} in {waited:.1f} s: is the board powered and "
            "running, its RS485 output wired to this adapter (A/B swapped?), and the port right? "
            f"(serial ports: {', '.join(list_ports()) or 'none found'})"
        )
    return MonitorError(
        f"{n} bytes arrived from {src.name} in {waited:.1f} s but no frames: check the baud "
        f"(the board's output_baud setting; this port is at {src.baud}, --baud changes it) and "
        "that this is the board's output port"
    )


def _board_session(port, values, err):
    """(deploy.BoardSession, configuration values, where they came from) of the board on its
    REPL port: its firmware stopped until the caller restarts it."""
    from tools.flash import deploy
    from tools.flash.errors import FlashError

    try:
        board = deploy.BoardSession(port, 115200)
    except FlashError as e:
        raise MonitorError(f"the board's port {port}: {e}") from None
    where = f"{port}:/flash/ins.cfg"
    values_given = values is not None
    if values is None:
        if board.config is None:
            values = board_config.values_of(board_config.from_values({}))
            where = f"{port} (no /flash/ins.cfg: the defaults)"
        else:
            try:
                values = board_config.values_of(board_config.decode(board.config))
            except board_config.ConfigError as e:
                board.restart()
                raise MonitorError(f"the configuration on {port} is {e}") from None
    if values_given:
        where = "--config"
    err.write(
        f"configuration from {where}, board {board.facts['machine']} "
        f"({board.facts['floats']} floats); its firmware restarts now, so the recording holds "
        "its start (it aligns again)\n"
    )
    return board, values, where


def _open_outputs(args, header_info, mdf_info):
    """(outputs, recorder, files) for --csv, --mdf and --record: files are (writer, its
    description for the summary); writers have close() and `failed`. header_info: the
    session file's header; mdf_info: the MDF4 header's items (_mdf_info)."""
    outputs, files = [], []
    recorder = None
    try:
        if args.csv:
            c = export.CsvExport(args.csv)
            outputs.append(c)
            files.append((c, c.describe))
        if args.mdf:
            m = export.MdfExport(args.mdf, mdf_info)
            outputs.append(m)
            files.append((m, m.describe))
        if args.record:
            try:
                recorder = session_file.SessionWriter(args.record, header_info)
            except OSError as e:
                raise OSError(f"cannot write {args.record}: {e.strerror}") from None
            files.append((recorder, lambda r=recorder: f"{r.path} (session file, {r.n} bytes)"))
    except OSError as e:
        for o in outputs:
            o.abandon()
        raise MonitorError(str(e)) from None
    return outputs, recorder, files


def _close_all(files):
    """Close every file; the one-line problems of those that failed."""
    problems = []
    for writer, _describe in files:
        try:
            writer.close()
        except Exception as e:  # noqa: BLE001 (report, keep closing the others)
            problems.append(str(e))
    return problems


def _written(files):
    """The summary's descriptions of the files written whole."""
    return [describe() for writer, describe in files if not writer.failed]


def run(args, out=None, err=None, stop=None):
    """The monitor's work; stop: the StopSignals in force (main installs them)."""
    stop = stop or StopSignals()
    out = out or sys.stdout
    err = err or sys.stderr
    if args.list_ports:
        ports = list_ports()
        out.write("\n".join(ports) + "\n" if ports else "no serial ports found\n")
        return 0
    _check_args(args)
    values = _config_values(args.config)
    board = None
    config_file = str(args.config) if args.config else None
    if args.board_port:
        if not args.port:
            raise MonitorError("--board-port needs --port (the board's frames port)")
        board, values, where = _board_session(args.board_port, values, err)
        config_file = config_file or where
    src, values, baud = _open_source(args, values, board)
    if args.record and src.kind == "serial":
        _note_record_config(values, err)
    header = _session_header(src, baud, values, config_file, board)
    try:
        outputs, recorder, files = _open_outputs(args, header, _mdf_info(src, header))
    except MonitorError:
        src.close()
        raise
    finally:
        if board is not None:  # the firmware starts now, with the port open and read
            board.restart()
    status = view.Status(src.name, baud if src.kind == "serial" else None, recorder)
    screen = _Screen(out, args.quiet or src.kind == "file")
    bar = _file_bar(args, src, status, err)
    warnings = []
    warn = _warner(warnings, screen, status, err, bar.clear)
    for msg in getattr(src, "problems", ()):  # what a cut or damaged session file lost
        warn(msg)
    mon = Monitor(status, _every(values), outputs, recorder, warn, _start_unix_s(src))
    t0 = time.monotonic()
    stopped, failure, problems, skipped_before = _watch(src, mon, args, screen, t0, files, stop,
                                                        bar)  # fmt: skip
    wall = time.monotonic() - t0
    counts = mon.counts()
    cut = counts["skipped_bytes"] - skipped_before  # a record cut by the end of the input
    if failure is None and counts["frames"] == 0 and counts["ext"] == 0:
        interrupted = stopped == CTRL_C or stop.signum is not None
        failure = _nothing_decoded_error(src, counts, interrupted, wall)
    _show_end(args, src, status, screen, counts, wall, stopped, files, cut, out)
    if screen.tty and not screen.quiet:
        for kind, msg in warnings:
            err.write(f"{kind}: {msg}\n")
    for p in problems:
        err.write(f"error: {p}\n")
    if recorder is not None and recorder.failed and ("warning", recorder.failed) not in warnings:
        problems.append(recorder.failed)  # failed on closing
        err.write(f"error: {recorder.failed}\n")
    if failure is not None:
        raise failure
    if stop.signum is not None:  # the conventional status of a process ended by a signal
        return 128 + stop.signum
    failed = problems or mon.failures or (recorder is not None and recorder.failed)
    return 1 if failed else 0


def _start_unix_s(src):
    """The host's UTC (Unix s) of a session file's start (its header's started_utc); None for
    a port or a raw capture: the host's clock at the first frame."""
    started = (getattr(src, "header", None) or {}).get("started_utc")
    try:
        return datetime.datetime.fromisoformat(started).timestamp() if started else None
    except (TypeError, ValueError):
        return None


def _check_args(args):
    """MonitorError for a source missing or a --seconds or --baud out of range."""
    if not args.port and not args.file:
        raise MonitorError("give --port PORT (a board) or --file FILE (a capture); --help")
    if args.seconds is not None and args.seconds <= 0:
        raise MonitorError("--duration must be more than 0")
    if args.baud is not None and args.baud <= 0:
        raise MonitorError("--baud must be a positive baud rate")


def _config_values(config):
    """--config's configuration values, None without one; MonitorError when unreadable."""
    if not config:
        return None
    try:
        return board_config.load(config)
    except board_config.ConfigError as e:
        raise MonitorError(str(e)) from None


def _open_source(args, values, board):
    """(source, configuration values, baud): the file (its session's configuration when none
    was given) or the port (at --baud, else the configuration's output_baud, else the board's
    default); the board's firmware restarted when that fails."""
    try:
        if args.file:
            src = FileSource(args.file)
            if values is None:
                values = src.config_values()
            baud = src.baud
        else:
            baud = args.baud or int((values or {}).get("output_baud", 0))
            baud = baud or board_config.default_output_baud()
            src = PortSource(args.port, baud)
    except BaseException:
        if board is not None:
            board.restart()
        raise
    return src, values, baud


def _note_record_config(values, err):
    """A note when a port recording will not replay: no configuration, or no raw records."""
    if values is None:
        err.write(
            "note: the session will hold no board configuration, which a replay needs "
            "(give --board-port, the board's USB port, or --config; else replay --config)\n"
        )
    elif not values.get("raw_record"):
        err.write(
            "note: the configuration has raw_record = 0: the board sends no raw-input "
            "records, so the recording shows and exports but does not replay (deploy with "
            "SET='raw_record=1')\n"
        )


def _session_header(src, baud, values, config_file, board):
    """The --record session file's header."""
    return {
        "format": session_file.FORMAT,
        "source": src.name,
        "baud": baud if src.kind == "serial" else None,
        "started_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "config": values,
        "config_file": config_file,
        "board": board.facts if board is not None else None,
    }


def _mdf_info(src, header):
    """The MDF4 header's items: the session header's, where a session file read gives the
    port and baud it was recorded from (and the file itself as capture_file)."""
    info = dict(header)
    if src.kind == "file":
        info["capture_file"] = src.name
        recorded = getattr(src, "header", None) or {}
        info["source"] = recorded.get("source", src.name)
        info["baud"] = recorded.get("baud")
        info["board"] = info.get("board") or recorded.get("board")
    return info


def _file_bar(args, src, status, err):
    """A file's progress on a terminal (a long capture takes a minute to read and export):
    the share read and the board time it held; silent with --quiet or off a terminal."""

    def detail(k, n, _wall):
        return f"{k / 1e6:.1f}/{n / 1e6:.1f} MB, board time {status.board_seconds():.0f} s"

    on = src.kind == "file" and not args.quiet and progress.is_tty(err)
    return progress.Bar("reading", detail, err, enabled=on)


def _warner(warnings, screen, status, err, clear=lambda: None):
    """warn(msg) for the Monitor: each warning also kept in warnings; clear() blanks a
    progress bar's row first."""

    def warn(msg, kind="warning"):
        """A warning (or error) line now on stderr, or, under the live view of a terminal
        (stderr is the same screen), in the view and after the summary."""
        warnings.append((kind, msg))
        if screen.tty and not screen.quiet:
            status.note = msg
        else:
            clear()
            err.write(f"{kind}: {msg}\n")

    return warn


def _watch(src, mon, args, screen, t0, files, stop, bar):
    """Feed the source to the monitor until it ends, then close the source and the files:
    (why it stopped, MonitorError or None, problems closing the files, the decoder's skipped
    bytes before its end)."""
    stopped = "end of file"
    failure = None
    try:
        if src.kind == "file":
            stopped = _run_file(src, mon, args, stop, bar)
        else:
            stopped = _run_port(src, mon, args, screen, t0, stop)
    except KeyboardInterrupt:
        stopped = CTRL_C
    except MonitorError as e:
        failure = e
    finally:
        skipped_before = mon.decoder.skipped_bytes
        try:
            mon.finish()
        except Exception as e:  # noqa: BLE001 (still close the files)
            failure = failure or MonitorError(f"decoding the end of the stream failed: {e}")
        src.close()
        problems = _close_all(files)
        bar.end()
    return stopped, failure, problems, skipped_before


def _nothing_decoded_error(src, counts, interrupted, wall):
    """The MonitorError for a source that gave no frames, None when interrupted (a port)."""
    if src.kind == "file":
        if counts["bytes"] == 0:
            return MonitorError(f"{src.name} is empty: nothing to decode")
        return MonitorError(
            f"{src.name} holds {counts['bytes']} bytes but no frames: it is not a "
            "capture of the board's output (or it was captured at the wrong baud)"
        )
    if not interrupted:
        return _no_data_error(src, counts, wall)
    return None


def _show_end(args, src, status, screen, counts, wall, stopped, files, cut, out):
    """The final view (a file's, the terminal's last redraw) and the summary on out."""
    if not args.quiet and src.kind == "file" and status.frame is not None:
        out.write("\n".join(view.render(status, counts, status.board_seconds(), live=False)) + "\n")
    if screen.tty and not screen.quiet:
        screen.draw(status, counts, wall, time.monotonic())
    summary = view.summary(status, counts, wall, stopped, _written(files))
    if cut:
        summary.insert(3, f"  ({cut} of the skipped bytes: a record cut short by the end)")
    out.write("\n".join(summary) + "\n")
    out.flush()


def _run_file(src, mon, args, stop, bar):
    mon.board_limit_s = args.seconds
    size = 1 << 16 if args.seconds is None else 512  # stop near the limit: counts stay close
    while True:
        if stop.signum is not None:
            return stop.stopped()
        chunk = src.read(size=size)
        if not chunk:
            return "end of file"
        mon.feed(chunk)
        bar(src.position, src.size)
        if mon.done:
            return f"{args.seconds:g} s of board time"


def _run_port(src, mon, args, screen, t0, stop):
    while True:
        if stop.signum is not None:
            return stop.stopped()
        now = time.monotonic()
        elapsed = now - t0
        if args.seconds is not None and elapsed >= args.seconds:
            return f"after {args.seconds:g} s"
        chunk = src.read(0.05)
        if chunk:
            mon.feed(chunk)
        c = mon.counts()
        if c["frames"] == 0 and c["ext"] == 0 and elapsed >= args.timeout:
            raise _no_data_error(src, c, elapsed)
        mon.status.sample(now, c)
        if screen.due(now):
            screen.draw(mon.status, c, elapsed, now)


def main(argv=None, out=None, err=None):
    err = err or sys.stderr
    parser = _parser()
    args = parser.parse_args(argv)
    if not (args.port or args.file or args.list_ports):
        parser.error("give --port PORT (a board) or --file FILE (a capture)")
    if args.board_port and not args.record:  # it would only stop and restart the board
        parser.error("--board-port is for --record (it restarts the board so that the session "
                     "holds its start); to watch, give --config FILE or --baud")  # fmt: skip
    try:
        with StopSignals() as stop:
            return run(args, out, err, stop)
    except MonitorError as e:
        err.write(f"error: {e}\n")
        return 1
    except BrokenPipeError:  # `... | head`
        return quiet_broken_pipe()
    except OSError as e:  # an export file on a full disk
        err.write(f"error: {os_error_text(e)}\n")
        return 1
