"""Progress lines for the command-line tools: each fits the terminal's width, so that a bar
redrawn with \\r stays on one row (a line wider than the terminal wraps, and every redraw then
leaves a row behind).

    bar = Bar("cpython", total=600, unit="s")   # bar(k, n): a redrawn bar, 10 % lines in a log
    stage("evaluating the frames against truth")  # one line: what the next wait is

On a terminal the bar is redrawn at most every 0.2 s and ends with a newline at 100 %; written
to a file or a pipe it gives a line per 10 %, which a log can hold.
"""

import os
import shutil
import sys
import time

DEFAULT_COLUMNS = 80
REDRAW_S = 0.2
LINE_EVERY_S = 5.0  # a counter off a terminal: a line this often, no more
BAR_COLUMNS = 30
ELLIPSIS = "…"


def is_tty(stream):
    return bool(getattr(stream, "isatty", lambda: False)())


def columns(stream=None):
    """The width of the terminal `stream` writes to (COLUMNS when set, else shutil's guess
    from stdout); 80 when unknown."""
    env = os.environ.get("COLUMNS", "")
    if env.isdigit() and int(env) > 0:
        return int(env)
    try:
        own = os.get_terminal_size((stream or sys.stderr).fileno()).columns
    except (AttributeError, OSError, ValueError):
        own = 0
    return own or shutil.get_terminal_size((DEFAULT_COLUMNS, 24)).columns


def fit(text, width):
    """text cut to width - 1 columns, an ellipsis marking the cut (the last column is left
    free: a terminal that filled it may wrap before the \\r)."""
    room = max(width - 1, 1)
    return text if len(text) <= room else text[: room - 1] + ELLIPSIS


def stage(text, stream=None, enabled=True):
    """One line saying what the tool does next (a wait of its own), cut to the terminal."""
    if not enabled:
        return
    stream = stream or sys.stderr
    stream.write(fit(text, columns(stream)) + "\n")
    stream.flush()


def bar_line(label, frac, detail, width):
    """`  label [####----] 45%  detail`: a bar of BAR_COLUMNS, narrower when the width leaves
    less room (at least 10 columns, else none); the detail cut last."""
    pct = f"{100 * frac:3.0f}%"
    head = f"  {label} "
    room = min(BAR_COLUMNS, width - 1 - len(head) - len(pct) - 2 - len(detail) - 3)
    if room >= 10:
        filled = int(room * frac)
        line = f"{head}[{'#' * filled}{'-' * (room - filled)}] {pct}  {detail}"
    else:
        line = f"{head}{pct}  {detail}"
    return fit(line, width)


class Bar:
    """bar(k, n): k of n done. detail(k, n, wall_s) -> the text after the percentage (None:
    "k/n"). On a terminal: one row redrawn with \\r; else a line per 10 %."""

    def __init__(self, label, detail=None, stream=None, enabled=True):
        self.label = label
        self.detail = detail or (lambda k, n, _wall: f"{k}/{n}")
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = is_tty(self.stream)
        self.t0 = time.perf_counter()
        self.last_decile = -1
        self.last_draw = None
        self.ended = False

    def __call__(self, k, n):
        if not self.enabled or n <= 0 or self.ended:
            return
        frac = min(max(k / n, 0.0), 1.0)
        now = time.perf_counter()
        text = self.detail(k, n, now - self.t0)
        if self.tty:
            if self.last_draw is not None and now - self.last_draw < REDRAW_S and k < n:
                return
            self.last_draw = now
            line = bar_line(self.label, frac, text, columns(self.stream))
            self.stream.write("\r" + line + "\x1b[K" + ("\n" if k >= n else ""))
        else:
            decile = int(10 * frac)
            if decile <= self.last_decile:
                return
            self.last_decile = decile
            self.stream.write(f"  {self.label}: {100 * frac:3.0f}%  {text}\n")
        self.ended = k >= n
        self.stream.flush()

    def clear(self):
        """Blank the bar's row (a message is about to be written there); the next call
        redraws it below the message."""
        if self.tty and self.last_draw is not None and not self.ended:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self.last_draw = None

    def end(self):
        """Leave the row as drawn (a bar stopped before 100 %): the next line starts below."""
        if self.tty and self.last_draw is not None and not self.ended:
            self.stream.write("\n")
            self.stream.flush()
        self.ended = True


class Counter:
    """counter(text): how far a wait of unknown length got (e.g. "120 C files compiled"),
    with the seconds it has taken. On a terminal one row redrawn with \\r; else a line
    every LINE_EVERY_S. end() closes the row."""

    def __init__(self, label, stream=None, enabled=True):
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = is_tty(self.stream)
        self.t0 = time.perf_counter()
        self.last_draw = None

    def __call__(self, text):
        now = time.perf_counter()
        every = REDRAW_S if self.tty else LINE_EVERY_S
        if not self.enabled or (self.last_draw is not None and now - self.last_draw < every):
            return
        self.last_draw = now
        line = fit(f"  {self.label}: {text}, {now - self.t0:.0f} s", columns(self.stream))
        self.stream.write(("\r" + line + "\x1b[K") if self.tty else (line + "\n"))
        self.stream.flush()

    def end(self):
        if self.enabled and self.tty and self.last_draw is not None:
            self.stream.write("\n")
            self.stream.flush()
        self.last_draw = None
