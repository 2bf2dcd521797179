"""A command run on an 80-column pseudo-terminal, each piece of its output timestamped: the
widest line it drew and its longest silence, as a user at a terminal sees them.

    python tests/tty_timing.py [--cols 80] [--show] -- COMMAND ARG...

prints the longest silent gaps (seconds without a byte written) with the text that ended each,
and the widest line. The tests import run() to check the progress lines of the real commands.
"""

import argparse
import fcntl
import os
import pty
import re
import select
import struct
import subprocess
import sys
import termios
import time
from dataclasses import dataclass, field

ANSI = re.compile(rb"\x1b\[[0-9;?]*[A-Za-z]")


@dataclass
class TtyRun:
    chunks: list = field(default_factory=list)  # (seconds since start, bytes read)
    status: int | None = None
    wall_s: float = 0.0

    @property
    def data(self):
        return b"".join(c for _, c in self.chunks)

    def segments(self):
        """Every stretch of text the terminal draws on one row: split at \\r and \\n."""
        text = ANSI.sub(b"", self.data).decode("utf-8", "replace")
        return re.split(r"\r\n|\r|\n", text)

    def widest(self):
        return max((len(s.expandtabs()) for s in self.segments()), default=0)

    def gaps(self):
        """(silence in s, the text that ended it), longest first; the end of the run counts."""
        out, last = [], 0.0
        for t, c in self.chunks:
            out.append((t - last, c))
            last = t
        out.append((self.wall_s - last, b"<exit>"))
        return sorted(out, key=lambda g: -g[0])


def _set_size(fd, cols, rows=24):
    fcntl.ioctl(fd, termios.TIOCSWINSZ, struct.pack("HHHH", rows, cols, 0, 0))


def run(cmd, cols=80, timeout=600.0, env=None, cwd=None):
    """A TtyRun of `cmd` with stdout and stderr on a pty `cols` columns wide (COLUMNS unset:
    the command must ask the terminal)."""
    master, slave = pty.openpty()
    _set_size(slave, cols)
    env = dict(os.environ if env is None else env)
    env.pop("COLUMNS", None)
    env.pop("LINES", None)
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, stdin=slave, stdout=slave, stderr=slave, env=env, cwd=cwd,
                            start_new_session=True)  # fmt: skip
    os.close(slave)
    r = TtyRun()
    try:
        while time.monotonic() - t0 < timeout:
            if select.select([master], [], [], 0.1)[0]:
                try:
                    c = os.read(master, 65536)
                except OSError:  # the child closed the pty (EIO on Linux)
                    break
                if not c:
                    break
                r.chunks.append((time.monotonic() - t0, c))
            elif proc.poll() is not None:
                break
    finally:
        if proc.poll() is None:
            proc.kill()
        r.status = proc.wait()
        r.wall_s = time.monotonic() - t0
        os.close(master)
    return r


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cols", type=int, default=80)
    p.add_argument("--show", action="store_true", help="print every chunk with its time")
    p.add_argument("--top", type=int, default=5, help="how many gaps to list")
    p.add_argument("cmd", nargs=argparse.REMAINDER)
    a = p.parse_args(argv)
    cmd = a.cmd[1:] if a.cmd[:1] == ["--"] else a.cmd
    r = run(cmd, a.cols, timeout=3600)
    if a.show:
        for t, c in r.chunks:
            print(f"{t:8.2f} {c[:120]!r}")
    print(f"exit {r.status} after {r.wall_s:.1f} s; widest line {r.widest()} columns")
    for gap, c in r.gaps()[: a.top]:
        print(f"  silent {gap:6.1f} s, then {c[:70]!r}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
