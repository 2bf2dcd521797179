"""A client for MicroPython's raw REPL over a serial port (written from the protocol in
MicroPython's shared/runtime/pyexec.c; mpremote speaks the same protocol).

    Ctrl-A                      enter the raw REPL: b"raw REPL; CTRL-B to exit\\r\\n>"
    b"\\x05A\\x01"                ask for raw-paste: b"R\\x01" + u16 LE window (+ b"\\x01" for each
                                further window the board frees), b"R\\x00" if not supported;
                                the host ends the code with b"\\x04", the board echoes b"\\x04"
    code b"\\x04"                plain raw mode: the board answers b"OK"
    then                        stdout b"\\x04" stderr b"\\x04" b">"
    Ctrl-B                      back to the friendly REPL; Ctrl-D there soft-resets

`ser` is anything with pyserial's write(bytes), read(n) (returning what arrived within its
short timeout) and in_waiting: a serial.Serial, or a scripted fake in the unit tests.
"""

import time

from tools.flash.errors import BoardError, FlashError, NotMicroPython, NotResponding

BANNER = b"raw REPL; CTRL-B to exit\r\n"
CTRL_A, CTRL_B, CTRL_C, CTRL_D = b"\x01", b"\x02", b"\x03", b"\x04"


class RawRepl:
    def __init__(self, ser, timeout=5.0, port="the port"):
        self.ser = ser
        self.timeout = timeout  # seconds of silence before the board counts as not responding
        self.port = port
        self.buf = bytearray()
        self.use_raw_paste = True
        self.prompt_ready = False
        self.console = b""  # what the board printed before the raw REPL (e.g. "ins: stopped")

    # -- reading -----------------------------------------------------------------------------

    def _fill(self):
        """Append whatever arrives within the port's short read timeout; True if anything."""
        n = self.ser.in_waiting
        data = self.ser.read(n if n > 0 else 1)
        if data:
            self.buf += data
            return True
        return False

    def read_until(self, ending, timeout=None, overall=None):
        """(bytes up to and including ending, True), or (everything read, False) after timeout
        seconds of silence or overall seconds in all."""
        timeout = self.timeout if timeout is None else timeout
        start = last = time.monotonic()
        while True:
            i = self.buf.find(ending)
            if i >= 0:
                end = i + len(ending)
                data = bytes(self.buf[:end])
                del self.buf[:end]
                return data, True
            now = time.monotonic()
            if now - last > timeout or (overall is not None and now - start > overall):
                data = bytes(self.buf)
                self.buf.clear()
                return data, False
            if self._fill():
                last = time.monotonic()

    def read_exact(self, n, timeout=None):
        timeout = self.timeout if timeout is None else timeout
        last = time.monotonic()
        while len(self.buf) < n:
            if self._fill():
                last = time.monotonic()
            elif time.monotonic() - last > timeout:
                break
        data = bytes(self.buf[:n])
        del self.buf[:n]
        return data

    def drain(self, quiet=0.2, overall=1.0):
        """Everything the board sends until it is quiet for `quiet` s (at most `overall` s)."""
        data, _ = self.read_until(b"\x00\xff\x00never", timeout=quiet, overall=overall)
        return data

    # -- raw REPL ----------------------------------------------------------------------------

    def enter(self):
        """Stop the running program (Ctrl-C twice) and enter the raw REPL."""
        seen = b""
        for _attempt in range(2):
            self.ser.write(b"\r" + CTRL_C)
            time.sleep(0.05)
            self.ser.write(CTRL_C)
            seen += self.drain(quiet=0.3, overall=1.5)
            self.ser.write(b"\r" + CTRL_A)
            data, ok = self.read_until(BANNER + b">", timeout=min(self.timeout, 2.0), overall=4.0)
            seen += data
            if ok:
                self.console = seen[: len(seen) - len(data)] + data[: -len(BANNER) - 1]
                self.prompt_ready = True
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
        self.ser.write(b"\r" + CTRL_B)
        self.prompt_ready = False

    def exec_raw(self, code, timeout=None):
        """Run code on the board; (stdout, stderr) as bytes."""
        if isinstance(code, str):
            code = code.encode()
        if not self.prompt_ready:
            data, ok = self.read_until(b">", timeout=timeout)
            if not ok:
                raise self._lost("waiting for the raw REPL prompt", data)
        self.prompt_ready = False
        sent = False
        if self.use_raw_paste:
            self.ser.write(b"\x05A\x01")
            reply = self.read_exact(2, timeout)
            if reply == b"R\x01":
                self._paste(code, timeout)
                sent = True
            elif reply == b"R\x00":
                self.use_raw_paste = False
            else:  # a firmware without raw-paste took the bytes as text; Ctrl-A reset its line
                data, ok = self.read_until(b"w REPL; CTRL-B to exit\r\n>", timeout=timeout)
                if not ok:
                    raise self._lost("asking for raw-paste mode", reply + data)
                self.use_raw_paste = False
        if not sent:
            for i in range(0, len(code), 256):
                self.ser.write(code[i : i + 256])
                time.sleep(0.01)
            self.ser.write(CTRL_D)
            reply = self.read_exact(2, timeout)
            if reply != b"OK":
                raise self._lost("sending code in raw mode", reply)
        out, ok = self.read_until(CTRL_D, timeout=timeout)
        if not ok:
            raise self._lost("waiting for the output of the code it runs", out)
        err, ok = self.read_until(CTRL_D, timeout=timeout)
        if not ok:
            raise self._lost("waiting for the error output", err)
        _, self.prompt_ready = self.read_until(b">", timeout=timeout)
        return out[:-1], err[:-1]

    def exec(self, code, timeout=None, what="running code on the board"):
        """stdout of code run on the board; BoardError with its traceback if it raised."""
        out, err = self.exec_raw(code, timeout)
        if err:
            raise BoardError(
                f"the board raised while {what}:\n{err.decode(errors='replace').strip()}\n"
                "Run the command again; if it repeats, reset the board and check its filesystem "
                "(docs/deploy.md)."
            )
        return out

    def _paste(self, code, timeout):
        header = self.read_exact(2, timeout)
        if len(header) != 2:
            raise self._lost("starting raw-paste mode", header)
        window = header[0] | header[1] << 8
        remain = window
        i = 0
        while i < len(code):
            while remain == 0 or self.buf or self.ser.in_waiting:
                b = self.read_exact(1, timeout)
                if b == b"\x01":
                    remain += window
                elif b == CTRL_D:  # the board stopped reading (e.g. a syntax error)
                    self.ser.write(CTRL_D)
                    return
                else:
                    raise self._lost("sending code in raw-paste mode", b)
            chunk = code[i : i + remain]
            self.ser.write(chunk)
            remain -= len(chunk)
            i += len(chunk)
        self.ser.write(CTRL_D)
        data, ok = self.read_until(CTRL_D, timeout=timeout)
        if not ok:
            raise self._lost("ending raw-paste mode", data)

    def _lost(self, doing, data):
        if not data:
            return NotResponding(
                f"the board on {self.port} stopped responding while {doing}. Check the USB "
                "cable and hub, reset the board and run the command again."
            )
        return FlashError(
            f"the board on {self.port} answered unexpectedly while {doing}: {_quote(data)}. "
            "Another program may be using the port (close serial monitors and mpremote), or "
            "the link is corrupting data (try another cable or a lower --baud); then run the "
            "command again."
        )


def _quote(data, limit=120):
    if not data:
        return "nothing"
    text = repr(bytes(data[:limit]))
    return text + (f" ... ({len(data)} bytes)" if len(data) > limit else f" ({len(data)} bytes)")
