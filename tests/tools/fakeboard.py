"""A scripted stand-in for a board's serial REPL, for unit tests of the raw-REPL client and
of deploy without hardware or the virtual board.

It speaks the raw REPL as pyexec.c does (banner, raw-paste with flow control, plain raw mode
with "OK", stdout/stderr each ended by 0x04, then ">") and runs the code it receives in CPython
with a stand-in `os`/`open` that map /flash onto a host directory, so deploy's board-side code
runs unchanged. `frozen` gives it modules as an image would carry them frozen (e.g. the
firmware id module `fwid`). It is not MicroPython: the virtual board
(host_emulator.virtual_board) is.

The maintenance start (tools/flash/maintenance.py), with `firmware` given: `stm.mem32` over
the RTC backup registers (the backup domain's backup_domain.Mem32 semantics, in memory:
`backup`), and `machine.reset()`, after which the board starts again as `firmware` says:
"maintenance" (this checkout's main.py: the marker MAINTENANCE_ASKED makes a maintenance
start, its line and the REPL; otherwise the firmware runs, `boot_output`), "old" (a main.py
that ignores the marker: it runs), "none" (no main.py: the REPL). `vanish_s`: after a reset
the port is gone that long (a USB board re-enumerating): `gone()` says so, reads and writes
raise serial.SerialException meanwhile. `resets` counts the resets, `soft_resets` the Ctrl-Ds.
`lose_code`: that many file chunks (mpremote's `w(...)` runs) arrive cut in half, a
SyntaxError on the board (a UART REPL losing characters while a flash erase stalls the CPU).
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

import serial


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
        firmware=None,
        vanish_s=0.0,
        lose_code=0,
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
        self.firmware = firmware  # None: no stm/machine.reset (a board without the marker)
        self.vanish_s = vanish_s
        self.lose_code = lose_code  # file chunks (`w(...)`) that arrive cut short: SyntaxError
        self._gone_until = 0.0
        self.backup = [0] * 20  # RTC_BKP0R-19R
        self.pwr_cr = 0x8000
        self.resets = 0
        self.soft_resets = 0
        self.maintenance_starts = 0
        self.mode_at_start = "firmware"  # what the last start was: firmware, maintenance, repl
        self.events = []  # ("reset"|"soft reset", start), ("write", path, start) in order

    # pyserial interface
    def gone(self):
        return time.monotonic() < self._gone_until

    def _check_gone(self):
        if self.gone():
            raise serial.SerialException("device reports readiness to read but returned no data")

    @property
    def in_waiting(self):
        self._check_gone()
        with self.lock:
            return len(self.out)

    def inWaiting(self):  # noqa: N802 (pyserial's older name, which mpremote calls)
        return self.in_waiting

    def read(self, n=1):
        self._check_gone()
        with self.lock:
            data = bytes(self.out[:n])
            del self.out[:n]
        if not data:
            time.sleep(self.timeout)
        return data

    def write(self, data):
        self._check_gone()
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
                self.soft_resets += 1
                self._emit(b"\r\n")
                self._start()
                self.events.append(("soft reset", self.mode_at_start))
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

    def _start(self):
        """main.py at a start (a soft or a hard reset), as `firmware` says."""
        from tools.flash import maintenance as maint

        if self.firmware != "none":
            v = self.backup[18]
            if self.firmware == "maintenance" and v == maint.MAINTENANCE_ASKED:
                self.backup[18] = maint.MAINTENANCE_ON
                self.maintenance_starts += 1
                self.mode_at_start = "maintenance"
                self._emit(b"ins: maintenance start (asked by the board tools): loop and "
                           b"watchdog off; Ctrl-D or a reset starts the firmware\r\n"
                           b"MicroPython v1.29.0; fake\r\n>>> ")  # fmt: skip
                self.mode = "friendly"
                return
            if self.firmware == "maintenance" and v:
                self.backup[18] = 0
            self._emit(self.boot_output)
            self.mode = "running"
            self.mode_at_start = "firmware"
            return
        self._emit(b"MicroPython v1.29.0; fake\r\n>>> ")  # "none": no main.py
        self.mode = "friendly"
        self.mode_at_start = "repl"

    def _reset(self):
        """machine.reset(): the board starts anew; a USB port goes away for vanish_s."""
        self.resets += 1
        self.pwr_cr = 0x8000
        self.line.clear()
        self._gone_until = time.monotonic() + self.vanish_s
        self.mode = "friendly"
        self._start()
        self.events.append(("reset", self.mode_at_start))
        if self.vanish_s:  # what it printed while the port was gone is lost
            with self.lock:
                self.out.clear()

    def _run(self, code):
        if self.lose_code > 0 and code.startswith(b"w("):  # characters lost on the way
            self.lose_code -= 1
            code = code[: len(code) // 2]
        self.received.append(code)
        out, err = io.StringIO(), ""
        ns = self.ns
        ns["__builtins__"] = self._builtins()
        try:
            with contextlib.redirect_stdout(out):
                exec(compile(code.decode(), "<stdin>", "exec"), ns)
        except _Reset:
            self._emit(out.getvalue().replace("\n", "\r\n").encode())
            self._reset()
            return
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
                fake.events.append(("write", path, fake.mode_at_start))
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
        if self.firmware is not None:
            modules["stm"] = types.SimpleNamespace(mem32=_Mem32(fake))
            modules["machine"] = types.SimpleNamespace(reset=_reset)

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


class _Reset(BaseException):
    pass


def _reset():
    raise _Reset()


class _Mem32:
    """stm.mem32 over the fake's backup registers, PWR_CR (DBP) and RCC_APB1ENR, as
    host_emulator/emulated_board/mpy/backup_domain.py: a backup register written without DBP keeps
    its value; any other address raises ValueError."""

    BKP0, PWR_CR, APB1ENR = 0x40002850, 0x40007000, 0x40023840

    def __init__(self, fake):
        self.fake = fake

    def _bkp(self, addr):
        if addr & 3:
            raise ValueError(f"address {addr:08x} is not aligned to 4 bytes")
        if self.BKP0 <= addr < self.BKP0 + 80:
            return (addr - self.BKP0) // 4
        if addr in (self.PWR_CR, self.APB1ENR):
            return None
        raise ValueError(f"no register at {addr:08x}")

    def __getitem__(self, addr):
        i = self._bkp(addr)
        if i is not None:
            return self.fake.backup[i]
        return self.fake.pwr_cr if addr == self.PWR_CR else 0x10000000

    def __setitem__(self, addr, value):
        i = self._bkp(addr)
        if i is not None:
            if self.fake.pwr_cr & 0x100:
                self.fake.backup[i] = value & 0xFFFFFFFF
        elif addr == self.PWR_CR:
            self.fake.pwr_cr = value & 0xCFFF
