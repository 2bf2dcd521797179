"""The report lines a MicroPython guest prints (host_emulator/board/mpy/feed.py: C console,
P progress, E error + traceback + E-END, S statistics), read back on the host, for the runtimes
that run the firmware in a MicroPython (mpy_unix, m4f)."""

import json
import subprocess
import threading
import time

from host_emulator.errors import EmulatorError, FirmwareError


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
            try:
                self.stats = json.loads(rest)
            except ValueError:
                self.other.append(text)
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
