"""The report lines a MicroPython guest prints (host_emulator/emulated_board/mpy/feed.py: C
console, P progress, E error + traceback + E-END, S statistics in one line or several), read
back on the host, for the runtimes that run the firmware in a MicroPython (mpy_unix, m4f); and
the display stream's marks from the bytes per tick those guests record."""

import json
import subprocess
import threading
import time

import numpy as np

from common.errors import EmulatorError, FirmwareError


def display_marks(data, per_tick, start_bytes, where_run):
    """FirmwareRun.display_marks, [(tick, end offset in data)] after each tick that wrote (tick
    -1: start-up), from what a guest recorded: `data` all it wrote to the screen's UART,
    per_tick the bytes of each tick, start_bytes those of start-up (what precedes the first
    tick's). EmulatorError naming `where_run` if they do not add up to data."""
    per_tick = np.asarray(per_tick, np.int64)
    if start_bytes + int(per_tick.sum()) != len(data):
        raise EmulatorError(
            f"{where_run} recorded {len(data)} display bytes, but {start_bytes} at start-up and "
            f"{int(per_tick.sum())} in its ticks: its display output is incomplete"
        )
    marks = [(-1, int(start_bytes))] if start_bytes else []
    ticks = np.flatnonzero(per_tick)
    ends = start_bytes + np.cumsum(per_tick)[ticks]
    marks += [(int(k), int(e)) for k, e in zip(ticks, ends, strict=True)]
    return marks


class GuestOutput:
    """The guest's stdout lines, sorted by their prefix."""

    def __init__(self, progress):
        self.progress = progress
        self.console = []
        self.other = []  # lines that are none of the known kinds (VM errors, stray prints)
        self.stats = None
        self.reports = []  # "R" lines: (name, value) pairs of a guest setup's report
        self.error_tick = None  # "E k" seen
        self.error_lines = []
        self.last_tick = 0
        self._in_error = False

    def line(self, text):
        text = text.rstrip("\r\n")
        if self._in_error:
            if text == "E-END":
                self._in_error = False
            else:
                self.error_lines.append(text)
            return
        kind, _, rest = text.partition(" ")
        fields = rest.split()
        if kind == "P" and len(fields) == 2 and all(x.isdigit() for x in fields):
            self.last_tick = int(fields[0])
            if self.progress:
                self.progress(int(fields[0]), int(fields[1]))
        elif kind == "C":
            self.console.append(rest)
        elif kind == "E" and len(fields) == 1 and fields[0].lstrip("-").isdigit():
            self.error_tick = int(fields[0])
            self._in_error = True
        elif kind == "S" and rest.startswith("{"):
            try:  # one or several lines (emulate_m4f.py prints one per statistic)
                part = json.loads(rest)
            except ValueError:
                self.other.append(text)
            else:
                self.stats = {**(self.stats or {}), **part}
        elif kind == "R" and rest.startswith("["):
            try:
                self.reports.append(tuple(json.loads(rest)))
            except ValueError:
                self.other.append(text)
        else:
            self.other.append(text)


def firmware_error(out, stim, where_run, hint=""):
    """The FirmwareError (with .tick, .t_s, .vm_traceback) for an "E" report in `out`."""
    k = out.error_tick
    where = "at start-up" if k < 0 else f"at tick {k} (t = {k * stim.tick_us * 1e-6:.3f} s)"
    tb = "\n".join(out.error_lines)
    msg = f"the firmware raised {where} in {where_run}:\n{tb}"
    if hint and "MemoryError" in tb:
        msg += "\n" + hint
    err = FirmwareError(msg)
    err.tick = k
    err.t_s = None if k < 0 else k * stim.tick_us * 1e-6
    err.vm_traceback = tb
    return err


def run_guest(cmd, out, timeout_s, what, n_ticks, stdin=b"", cwd=None, start_marker=None,
              env=None):  # fmt: skip
    """Run the guest process `cmd`, its stdout lines into `out` (a GuestOutput) as they come
    (after `start_marker`, if given: what precedes it, a banner, is dropped); stop it after
    timeout_s; env: its environment (default: ours). Returns (exit status, wall seconds);
    EmulatorError naming `what` if it cannot start or times out."""
    t_wall = time.perf_counter()
    try:
        proc = subprocess.Popen(
            cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            cwd=cwd, env=env,
        )  # fmt: skip
    except OSError as e:
        raise EmulatorError(f"cannot start {what} ({cmd[0]}): {e.strerror}") from None
    timed_out = threading.Event()

    def kill():
        timed_out.set()
        proc.kill()

    watchdog = threading.Timer(timeout_s, kill)
    watchdog.start()
    try:
        proc.stdin.write(stdin)  # small: the pipe holds it whole
        proc.stdin.close()
        started = start_marker is None
        for raw in proc.stdout:
            text = raw.decode("utf-8", "replace")
            if not started:
                i = text.find(start_marker)
                if i < 0:
                    continue
                started = True
                text = text[i + len(start_marker) :]
            out.line(text)
        rc = proc.wait()
    finally:
        watchdog.cancel()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
    if timed_out.is_set():
        raise EmulatorError(
            f"{what} did not finish within {timeout_s:g} s (at tick {out.last_tick} of "
            f"{n_ticks}); it was stopped"
        )
    return rc, time.perf_counter() - t_wall
