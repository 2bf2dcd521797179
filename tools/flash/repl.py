"""The board's raw REPL, spoken by mpremote (MicroPython's own tool, pinned in requirements.txt):
its `SerialTransport` runs code on the board (raw-paste with flow control, or plain raw mode
on a board without it) and moves files (`fs_writefile`, `fs_readfile`, ...). What is ours is
on top of it: getting into the raw REPL past a running firmware, keeping what the firmware
said when it stopped, and messages that say what went wrong and what to do.

    Ctrl-C (twice)          stops the firmware's loop (it prints "ins: stopped ...")
    Ctrl-A                  the raw REPL: b"raw REPL; CTRL-B to exit\\r\\n>"
    (mpremote)              code and files, each run answered with stdout, stderr, ">"
    Ctrl-B                  back to the friendly REPL; Ctrl-D there soft-resets
    (tools/flash/maintenance.py: between Ctrl-A and the work, the board reset into a
    maintenance start, its watchdog off, and the port opened and Ctrl-C, Ctrl-A again)

`ser` is anything with pyserial's write(bytes), read(n), in_waiting, inWaiting() (mpremote
asks the older name) and timeout: a serial.Serial (deploy.open_port), or a scripted fake in the
unit tests.
"""

import contextlib
import errno
import io
import struct
import time

from mpremote.transport import TransportError, TransportExecError
from mpremote.transport_serial import SerialTransport

from tools.flash.errors import BoardError, FlashError, NotMicroPython, NotResponding

BANNER = b"raw REPL; CTRL-B to exit\r\n"
CTRL_A, CTRL_C = b"\x01", b"\x03"


def transport(ser, port):
    """mpremote's SerialTransport over an already open port (deploy opens it itself, for its
    messages about missing and busy ports). The attributes are those SerialTransport.__init__
    sets (mpremote 1.29); reads poll `in_waiting`, so a pseudo-terminal (the virtual board) is
    read like a USB port."""
    t = SerialTransport.__new__(SerialTransport)
    t.in_raw_repl = False
    t.use_raw_paste = True
    t.device_name = port
    t.mounted = False
    t.serial = ser
    t.is_pty = False
    return t


def _bounded(t, limit):
    """mpremote waits 10 s for the raw REPL's prompt and acknowledgements: wait no longer
    than limit() s of silence, as the rest of our reads do."""
    read_until = t.read_until

    def bounded(min_num_bytes, ending, timeout=10, data_consumer=None, timeout_overall=None):
        if timeout is not None:
            timeout = min(timeout, limit())
        return read_until(min_num_bytes, ending, timeout, data_consumer, timeout_overall)

    t.read_until = bounded


class BoardRepl:
    """The board's raw REPL on an open port: enter(), exec()/exec_raw(), fs() (mpremote's file
    operations), exit(), drain(); every failure a FlashError that says what to do."""

    def __init__(self, ser, timeout=5.0, port="the port"):
        self.ser = ser
        self.timeout = timeout  # seconds of silence before the board counts as not responding
        self.port = port
        ser.timeout = timeout  # mpremote's reads of a fixed length wait this long
        self.transport = transport(ser, port)
        self._limit = timeout  # the silence a read of the current operation tolerates
        _bounded(self.transport, lambda: self._limit)
        self.console = b""  # what the board printed before the raw REPL (e.g. "ins: stopped")
        self.maintenance = None  # after maintenance.start: whether this is a maintenance start
        self.maintenance_console = b""  # what the board printed as it started in maintenance

    # -- reading what the board prints outside the raw REPL ----------------------------------

    def drain(self, quiet=0.2, overall=1.0):
        """Everything the board sends until it is quiet for `quiet` s (at most `overall` s)."""
        data = bytearray()
        start = last = time.monotonic()
        while True:
            now = time.monotonic()
            if now - last > quiet or now - start > overall:
                return bytes(data)
            n = self.ser.in_waiting
            if n:
                data += self.ser.read(n)
                last = time.monotonic()
            else:
                time.sleep(0.01)

    def _read_until(self, ending, timeout, overall):
        data = bytearray()
        start = last = time.monotonic()
        while not data.endswith(ending):
            now = time.monotonic()
            if now - last > timeout or now - start > overall:
                return bytes(data), False
            n = self.ser.in_waiting
            if n:
                data += self.ser.read(1)  # one at a time: nothing past the ending is taken
                last = time.monotonic()
            else:
                time.sleep(0.01)
        return bytes(data), True

    # -- the raw REPL ------------------------------------------------------------------------

    def enter(self):
        """Stop the running program (Ctrl-C twice) and enter the raw REPL; what the board
        printed on the way is kept in `console`."""
        seen = b""
        for _attempt in range(2):
            self.ser.write(b"\r" + CTRL_C)
            time.sleep(0.05)
            self.ser.write(CTRL_C)
            seen += self.drain(quiet=0.3, overall=1.5)
            self.ser.write(b"\r" + CTRL_A)
            data, ok = self._read_until(BANNER, min(self.timeout, 2.0), 4.0)
            seen += data
            if ok:
                self.console = seen[: -len(BANNER)]
                self.transport.in_raw_repl = True  # mpremote reads the ">" before each run
                return
        if not seen.strip(b"\r\n"):
            raise NotResponding(
                f"the board on {self.port} does not respond: nothing came back after Ctrl-C "
                "and Ctrl-A. Check that this is the board's USB port (not the RS485 adapter), "
                "that the board is powered and the cable carries data, then press the board's "
                "reset button and run the command again."
            )
        raise NotMicroPython(
            f"the device on {self.port} is not in MicroPython's REPL: it did not answer Ctrl-A "
            f"with the raw REPL banner; it sent {_quote(seen)}. If this is the RS485 or GNSS "
            "port, pick the board's USB port; if the board is in its DFU/ROM bootloader, reset "
            "it without BOOT0; if it runs other firmware, flash MicroPython first (docs/deploy.md)."
        )

    def exit(self):
        """Back to the friendly REPL."""
        self.transport.exit_raw_repl()

    def exec_raw(self, code, timeout=None, what="running code on the board"):
        """Run code on the board; (stdout, stderr) as bytes."""
        said = io.StringIO()  # mpremote prints what it got when the protocol fails
        self._limit = timeout or self.timeout
        try:
            with contextlib.redirect_stdout(said):
                return self.transport.exec_raw(code, timeout=self._limit)
        except (TransportError, struct.error) as e:  # struct: a window header cut short
            raise self._lost(what, e, said.getvalue()) from None

    def exec_no_follow(self, code, what="running code on the board"):
        """Send code to run without waiting for its end: for a reset, after which no answer
        comes (mpremote's exec_raw_no_follow: the raw REPL's acknowledgement only)."""
        said = io.StringIO()
        self._limit = self.timeout
        try:
            with contextlib.redirect_stdout(said):
                self.transport.exec_raw_no_follow(code)
        except (TransportError, struct.error) as e:
            raise self._lost(what, e, said.getvalue()) from None

    def exec(self, code, timeout=None, what="running code on the board"):
        """stdout of code run on the board; BoardError with its traceback if it raised."""
        out, err = self.exec_raw(code, timeout, what)
        if err:
            raise _board_error(what, err)
        return out

    def fs(self, op, *args, what, missing=False):
        """An mpremote filesystem call (fs_writefile, fs_readfile, ...), its errors ours;
        missing: a file that is not there gives None instead of an error."""
        said = io.StringIO()
        self._limit = self.timeout
        try:
            with contextlib.redirect_stdout(said):
                return getattr(self.transport, op)(*args)
        except OSError as e:  # mpremote's rendering of the board's OSError
            if missing and e.errno == errno.ENOENT:
                return None
            raise _board_error(what, f"OSError: [Errno {e.errno}] {e}".encode()) from None
        except TransportExecError as e:
            raise _board_error(what, e.error_output.encode()) from None
        except (TransportError, struct.error) as e:
            raise self._lost(what, e, said.getvalue()) from None

    def _lost(self, doing, e, said=""):
        """The error for a protocol failure: the board went silent, or answered garbage.
        said: what mpremote printed of the bytes it got (b'' when none came)."""
        left = self.drain(quiet=0.1, overall=0.5)
        silent = said.strip() in ("", "b''") and "unexpected" not in str(e)
        if not left and silent:
            return NotResponding(
                f"the board on {self.port} stopped responding while {doing}. Check the USB "
                "cable and hub, reset the board and run the command again."
            )
        return FlashError(
            f"the board on {self.port} answered unexpectedly while {doing} ({e}; then "
            f"{_quote(left)}). Another program may be using the port (close serial monitors "
            "and mpremote), or the link is corrupting data (try another cable or a lower "
            "--baud); then run the command again."
        )


def _board_error(what, err):
    return BoardError(
        f"the board raised while {what}:\n{err.decode(errors='replace').strip()}\n"
        "Run the command again; if it repeats, reset the board and check its filesystem "
        "(docs/deploy.md)."
    )


def _quote(data, limit=120):
    if not data:
        return "nothing"
    text = repr(bytes(data[:limit]))
    return text + (f" ... ({len(data)} bytes)" if len(data) > limit else f" ({len(data)} bytes)")
