"""A scripted stand-in for a board's serial REPL, for unit tests of the raw-REPL client and
of deploy without hardware or the virtual board.

It speaks the raw REPL as pyexec.c does (banner, raw-paste with flow control, plain raw mode
with "OK", stdout/stderr each ended by 0x04, then ">") and runs the code it receives in CPython
with a stand-in `os`/`open` that map /flash onto a host directory, so deploy's board-side code
runs unchanged. `frozen` gives it modules as an image would carry them frozen (e.g. the
firmware id module `fwid`). It is not MicroPython: the virtual board
(host_emulator.virtual_board) is.
"""

import binascii
import builtins
import contextlib
import errno
import io
import os as host_os
import pathlib
import threading
import time
import traceback
import types


class FakeSerial:
    """pyserial's write/read/in_waiting over a scripted board."""

    def __init__(
        self,
        fs_dir=None,
        raw_paste=True,
        window=64,
        flash_kb=2048,
        corrupt_writes=0,
        on_ctrl_c=b"",
        boot_output=b"MPY: soft reboot\r\nno configuration file /flash/ins.cfg: using defaults\r\n"
        b"ins: running\r\n",
        silent=False,
        garbage=None,
        frozen=None,
    ):
        self.fs_dir = pathlib.Path(fs_dir) if fs_dir else None
        self.raw_paste = raw_paste
        self.window = window
        self.flash_kb = flash_kb
        self.corrupt_writes = corrupt_writes
        self.on_ctrl_c = on_ctrl_c
        self.boot_output = boot_output
        self.silent = silent
        self.garbage = garbage
        self.frozen = frozen or {}  # {module name: {attribute: value}}: the image's frozen modules
        self.timeout = 0.01
        self.out = bytearray()
        self.lock = threading.Lock()
        self.mode = "running"  # running, friendly, raw, paste
        self.line = bytearray()
        self.pasted = 0
        self.received = []  # every code block executed
        self.ns = {}
        self.written = []  # paths opened for writing, in order
        self.closed = False

    # pyserial interface
    @property
    def in_waiting(self):
        with self.lock:
            return len(self.out)

    def inWaiting(self):  # noqa: N802 (pyserial's older name, which mpremote calls)
        return self.in_waiting

    def read(self, n=1):
        with self.lock:
            data = bytes(self.out[:n])
            del self.out[:n]
        if not data:
            time.sleep(self.timeout)
        return data

    def write(self, data):
        for b in data:
            self._byte(bytes((b,)))
        return len(data)

    def close(self):
        self.closed = True

    def _emit(self, data):
        with self.lock:
            self.out += data

    # the board
    def _byte(self, c):
        if self.silent:
            return
        if self.garbage is not None:
            self._emit(self.garbage)
            return
        if self.mode == "running":
            if c == b"\x03":
                self._emit(self.on_ctrl_c + b"\r\nMicroPython v1.29.0; fake\r\n>>> ")
                self.mode = "friendly"
            return
        if self.mode == "friendly":
            if c == b"\x01":
                self._emit(b"\r\nraw REPL; CTRL-B to exit\r\n>")
                self.mode = "raw"
                self.line.clear()
            elif c == b"\x03":
                self._emit(b"\r\n>>> ")
            elif c == b"\x04":
                self._emit(b"\r\n" + self.boot_output)
                self.mode = "running"
            elif c == b"\x02":
                self._emit(b"\r\nMicroPython v1.29.0; fake\r\n>>> ")
            return
        if self.mode == "paste":
            if c in (b"\x04", b"\x03"):
                self._emit(b"\x04")
                self.mode = "raw"
                self._run(bytes(self.line))
                self.line.clear()
                self._emit(b">")
                return
            self.line += c
            self.pasted += 1
            if self.pasted % self.window == 0:
                self._emit(b"\x01")
            return
        # raw
        if c == b"\x01":
            if bytes(self.line) == b"\x05A" and self.raw_paste:
                w = self.window
                self._emit(b"R\x01" + bytes((w & 0xFF, w >> 8)) + b"\x01")
                self.mode = "paste"
                self.pasted = 0
                self.line.clear()
                return
            self.line.clear()
            self._emit(b"raw REPL; CTRL-B to exit\r\n>")
        elif c == b"\x02":
            self._emit(b"\r\nMicroPython v1.29.0; fake\r\n>>> ")
            self.mode = "friendly"
        elif c == b"\x03":
            self.line.clear()
        elif c == b"\x04":
            self._emit(b"OK")
            self._run(bytes(self.line))
            self.line.clear()
            self._emit(b">")
        else:
            self.line += c

    def _run(self, code):
        self.received.append(code)
        out, err = io.StringIO(), ""
        ns = self.ns
        ns["__builtins__"] = self._builtins()
        try:
            with contextlib.redirect_stdout(out):
                exec(compile(code.decode(), "<stdin>", "exec"), ns)
        except OSError as e:  # as MicroPython prints it: "OSError: [Errno 2] ENOENT"
            name = errno.errorcode.get(e.errno, str(e.errno))
            err = (
                traceback.format_exc().rsplit("\n", 2)[0] + f"\nOSError: [Errno {e.errno}] {name}\n"
            )
        except Exception:
            err = traceback.format_exc()
        self._emit(out.getvalue().replace("\n", "\r\n").encode() + b"\x04" + err.encode() + b"\x04")

    # board-side modules over fs_dir
    def _host(self, path):
        if not path.startswith("/flash"):
            raise OSError(2, "ENOENT")
        return self.fs_dir / path[len("/flash") :].lstrip("/")

    def _used(self):
        return sum(-(-p.stat().st_size // 512) for p in self.fs_dir.rglob("*") if p.is_file())

    def _builtins(self):
        fake = self

        class _File(io.FileIO):
            def write(self, data):
                data = bytes(data)
                if fake.corrupt_writes > 0:
                    fake.corrupt_writes -= 1
                    data = bytes((data[0] ^ 0xFF,)) + data[1:]
                if (fake._used() + 1) * 512 > fake.flash_kb * 1024:
                    raise OSError(28, "ENOSPC")
                return super().write(data)

        def _open(path, mode="r"):
            if "w" in mode:
                fake.written.append(path)
                return _File(fake._host(path), "w")
            return open(fake._host(path), mode)

        os_mod = types.SimpleNamespace(
            ilistdir=lambda d: [
                (p.name, 0x4000 if p.is_dir() else 0x8000, 0)
                for p in sorted(fake._host(d).iterdir())
            ],
            stat=lambda p: (
                tuple(host_os.stat(fake._host(p)))[:6]
                + (host_os.stat(fake._host(p)).st_size, 0, 0, 0)
            ),
            mkdir=lambda p: fake._host(p).mkdir(),
            rmdir=lambda p: fake._host(p).rmdir(),
            remove=lambda p: fake._host(p).unlink(),
            statvfs=lambda p: (
                512,
                512,
                fake.flash_kb * 2,
                fake.flash_kb * 2 - fake._used(),
                fake.flash_kb * 2 - fake._used(),
                0,
                0,
                0,
                0,
                255,
            ),
        )
        modules = {"os": os_mod, "binascii": binascii}

        def _import(name, globals=None, locals=None, fromlist=(), level=0):
            if name in modules:
                return modules[name]
            if name in fake.frozen:
                return types.SimpleNamespace(**fake.frozen[name])
            return builtins.__import__(name, globals, locals, fromlist, level)

        b = dict(builtins.__dict__)
        b["__import__"] = _import
        b["open"] = _open
        return b
