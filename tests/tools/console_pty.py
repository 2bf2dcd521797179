"""`python -m tools.flash console` (mpremote repl) driven from a pseudo-terminal, as a user at a
terminal would (mpremote's console wants a terminal), for the tests of the console."""

import os
import pty
import select
import sys
import time

from common.firmware_env import REPO_DIR


class Console:
    """The console on `port` in a child process whose terminal is a pty; `seen` holds what it
    printed."""

    def __init__(self, port):
        self.seen = bytearray()
        self.status = None
        self.pid, self.fd = pty.fork()
        if self.pid == 0:  # the child: the console, on the pty
            os.chdir(REPO_DIR)
            os.execv(sys.executable,
                     [sys.executable, "-m", "tools.flash", "console", "--port", port])  # fmt: skip

    def read_until(self, text, timeout=20.0):
        t0 = time.monotonic()
        while text not in self.seen and time.monotonic() - t0 < timeout:
            if select.select([self.fd], [], [], 0.1)[0]:
                try:
                    self.seen.extend(os.read(self.fd, 4096))
                except OSError:
                    break
        return text in self.seen

    def ready(self):
        """mpremote's console is up (it puts the terminal in raw mode after its banner)."""
        ok = self.read_until(b"Use Ctrl-] or Ctrl-x to exit")
        time.sleep(1.0)
        return ok

    def send(self, data):
        os.write(self.fd, data)

    def leave(self, timeout=10.0):
        """Ctrl-]; the exit status once the console has ended (None if it did not)."""
        self.send(b"\x1d")
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout:
            done, status = os.waitpid(self.pid, os.WNOHANG)
            if done:
                self.status = os.waitstatus_to_exitcode(status)
                return self.status
            self.read_until(b"\x00never", timeout=0.1)
        return None

    def close(self):
        if self.status is None:
            os.kill(self.pid, 9)
            os.waitpid(self.pid, 0)
        os.close(self.fd)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
