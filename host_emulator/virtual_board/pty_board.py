"""A virtual INS board on pseudo-terminals: MicroPython's REPL on one, the RS485 output on the
other, so deploy and monitor tools can be tried without hardware (docs/virtual_board.md).

    python -m host_emulator virtual-board --fs DIR [--flash-kb N] [--scenario S] [--duration S]

`port` (the USB REPL console) speaks MicroPython 1.29's REPL as the stm32 port does
(shared/runtime/pyexec.c): the friendly REPL, the raw REPL (Ctrl-A), raw paste (Ctrl-E 'A'
Ctrl-A, with flow control), soft resets (Ctrl-D). Code runs in the real MicroPython VM
(the unix port, vm.micropython_exe()): one persistent VM per session between soft resets
running repl_server.py (beside this file), with `fs_dir` mounted at /flash (capacity `flash_kb`).

A soft reset from the friendly REPL runs the firmware in fs_dir as main.py does, in a second
VM (emulated_board/mpy/emulate.py in its streaming mode) fed from a simulated scenario generated
when the board starts: its console lines come out on `port`, its RS485 bytes on `rs485_port`; Ctrl-C
stops it. `machine.reset()` in the REPL resets the board (`resets` counts them): a new REPL
VM, then main.py as at power-up, whose maintenance check (board.maintenance_start) reads the
RTC backup registers the REPL's `stm` stand-in wrote (emulated_board/mpy/backup_domain.py: a file
both VMs share, as the backup domain outlives a reset). Everything runs on one background thread
around select().
"""

import argparse
import os
import pathlib
import pty
import secrets
import select
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
import tty

from host_emulator.emulated_board import EMULATE, MPY_DIR
from host_emulator.runtimes.mpy_unix import vm
from host_emulator.sim import board_input

REPL_SERVER = pathlib.Path(__file__).resolve().parent / "repl_server.py"

BANNER = (
    b"MicroPython v1.29.0 on 2026-11-22; virtual INS board (STM32F411, host emulator)\r\n"
    b'Type "help()" for more information.\r\n'
)
PROMPT = b">>> "
RAW_BANNER = b"raw REPL; CTRL-B to exit\r\n"
SOFT_REBOOT = b"MPY: soft reboot\r\n"
STOPPED = b"ins: stopped (Ctrl-D restarts it)"
PASTE_WINDOW = 128  # raw paste flow-control window (MICROPY_REPL_STDIN_BUFFER_MAX 256 / 2)
CTRL_A, CTRL_B, CTRL_C, CTRL_D, CTRL_E = 1, 2, 3, 4, 5
REPL_HEAP = "2M"
# The firmware VM's heap. Not the board's (its ~100 KB is measured on the emulated Cortex-M4F):
# this is the x64 unix port, whose objects are twice the size, and with --frozen it compiles
# the "frozen" modules from source in this heap, which the image never does. 512K left the
# frozen firmware 16 KB short at Board() once nav.py passed 1,400 lines.
FW_HEAP = "1M"
WRITE_TIMEOUT_S = 1.0  # a console nobody reads drops its output after this


# `mpremote mount` serves the host's files over the REPL's own stdin, which the virtual
# board's code cannot read (its VM's stdin carries this emulation's requests)
MOUNT_REFUSED = (
    b'Traceback (most recent call last):\n  File "<stdin>", line 1, in <module>\n'
    b"OSError: the virtual board cannot serve mpremote mount (its REPL has no channel back "
    b"to the host); copy files with mpremote cp or deploy them\n"
)


def _cook(data):
    """The stm32 port's stdout: every \\n goes out as \\r\\n."""
    return data.replace(b"\n", b"\r\n")


class VirtualBoard:
    """A virtual board; start() opens the ports and serves them until close()."""

    def __init__(
        self,
        fs_dir,
        flash_kb=2048,
        corrupt_writes=0,
        scenario="urban_drive",
        seed=0,
        duration_s=120.0,
        realtime=True,
        boot_main=False,
        frozen_dir=None,
        loop=False,
        display=None,
    ):
        self.fs_dir = pathlib.Path(fs_dir).resolve()
        # modules "frozen in the image": a directory both VMs import from as the stm32 port
        # imports frozen modules (tools.image.fwid.frozen_layout writes one)
        self.frozen_dir = pathlib.Path(frozen_dir).resolve() if frozen_dir else None
        self._fs_bytes = os.fsencode(self.fs_dir)
        self.flash_kb = int(flash_kb)
        self.corrupt_writes = int(corrupt_writes)
        self.corrupted = 0  # writes corrupted so far (over the whole session)
        self.scenario = scenario
        self.seed = int(seed)
        self.duration_s = float(duration_s)
        self.realtime = bool(realtime)
        self.boot_main = bool(boot_main)  # run main.py at power-up (else: the friendly REPL)
        self.loop = bool(loop)  # the input used up: the firmware starts again, as after a reset
        self._fw_ended = False
        # the UsartGPU screen: a PNG at `display` redrawn from what the status page sends
        self.display = pathlib.Path(display) if display else None
        self._gpu = None
        self._gpu_drawn = 0.0
        self.port = None
        self.rs485_port = None
        self.firmware_runs = 0
        self.resets = 0  # machine.reset() from the REPL
        self.maintenance_starts = 0  # starts main.py's check made maintenance starts
        self._reset_cause = 1  # machine.reset_cause(): PWRON_RESET, HARD_RESET after a reset
        self._thread = None
        self._stop = False
        self._tmp = None
        self._fds = []
        self._calls = []  # functions to run on the board's thread

    # ---- life cycle ------------------------------------------------------------------------

    def start(self):
        self.fs_dir.mkdir(parents=True, exist_ok=True)
        self._tmp = tempfile.TemporaryDirectory(prefix="vboard-")
        self._stim_path = pathlib.Path(self._tmp.name) / "stimulus.bin"
        self._backup = pathlib.Path(self._tmp.name) / "backup_domain.bin"
        self._backup.write_bytes(bytes(80))  # backup_domain.power_on: 20 registers, 0
        sim = board_input.simulate(self.scenario, self.duration_s, self.seed)
        sim.stimulus.write(self._stim_path)
        self._exe = vm.micropython_exe()
        self._master, self._slave = self._open_pty()
        self.port = os.ttyname(self._slave)
        self._rs_master, self._rs_slave = self._open_pty()
        self.rs485_port = os.ttyname(self._rs_slave)
        self._wake_r, self._wake_w = os.pipe()
        self._fds += [self._wake_r, self._wake_w]
        self._mode = "friendly"
        self._line = bytearray()
        self._pending = bytearray()  # input that came while code or the firmware ran
        self._repl = None
        self._fw = None
        self._start_repl_vm()
        self._thread = threading.Thread(target=self._serve, name="virtual-board", daemon=True)
        self._thread.start()
        if self.boot_main:
            self._call(self._power_up)
        return self

    def close(self):
        if self._thread is None:
            return
        self._stop = True
        os.write(self._wake_w, b"x")
        self._thread.join(5)
        self._thread = None
        for proc in (self._repl, self._fw):
            self._kill(proc)
        for fd in self._fds:
            try:
                os.close(fd)
            except OSError:
                pass
        self._fds = []
        self._tmp.cleanup()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.close()

    def _open_pty(self):
        master, slave = pty.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        self._fds += [master, slave]
        return master, slave

    def _call(self, fn):
        """Run fn on the board's thread (before the next input byte)."""
        self._calls.append(fn)
        os.write(self._wake_w, b"x")

    # ---- the VMs -------------------------------------------------------------------------

    def _start_repl_vm(self):
        self._kill(self._repl)
        self._nonce = secrets.token_hex(4)
        self._sentinel = b"\x00\x1bVB" + self._nonce.encode() + b":"
        left = max(0, self.corrupt_writes - self.corrupted)
        self._corrupt_base = self.corrupted
        env = dict(os.environ, INS_VB_BACKUP=str(self._backup), INS_VB_MPY=str(MPY_DIR),
                   INS_VB_RESET_CAUSE=str(self._reset_cause))  # fmt: skip
        self._repl = subprocess.Popen(
            [
                self._exe,
                "-X",
                f"heapsize={REPL_HEAP}",
                str(REPL_SERVER),
                str(self.fs_dir),
                str(self.flash_kb),
                str(left),
                self._nonce,
                *([str(self.frozen_dir)] if self.frozen_dir else []),
            ],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            bufsize=0,
            env=env,
        )
        self._repl_buf = b""
        self._busy = None  # what is running in the REPL VM: "raw" or "friendly"

    def _start_fw_vm(self):
        env = dict(os.environ, INS_VM_STREAM="realtime" if self.realtime else "fast",
                   INS_VM_BACKUP=str(self._backup))  # fmt: skip
        # after emulate.py's own entries (the firmware in /flash first): the frozen firmware if
        # any, and what the host shares with the VM (the stimulus record, common/proto/mpy)
        first = str(self.frozen_dir) if self.frozen_dir else vm.VM_PATH
        env["MICROPYPATH"] = f"{first}:{vm.SHARED_DIR}"
        self._fw = subprocess.Popen(
            [
                self._exe,
                "-X",
                f"heapsize={FW_HEAP}",
                str(EMULATE),
                str(self.fs_dir),
                str(self._stim_path),
                str(self.fs_dir / "ins.cfg"),
                "-",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            bufsize=0,
            env=env,
        )
        self.firmware_runs += 1
        self._gpu = None  # the screen starts again with the firmware's start page
        self._fw_t0 = time.monotonic()
        self._fw_buf = b""
        self._fw_error = None  # traceback lines while inside an "E" block
        self._fw_stopping = None  # time.monotonic() of the Ctrl-C
        self._fw_saw_stopped = False
        self._mode = "fw"

    @staticmethod
    def _kill(proc):
        if proc is None:
            return
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        for f in (proc.stdin, proc.stdout):
            if f is not None:
                f.close()

    # ---- output ----------------------------------------------------------------------------

    def _send(self, data, fd=None):
        """Bytes to a pty master; dropped after WRITE_TIMEOUT_S if nobody reads them."""
        fd = self._master if fd is None else fd
        view = memoryview(data)
        deadline = time.monotonic() + WRITE_TIMEOUT_S
        while view:
            try:
                n = os.write(fd, view)
                view = view[n:]
            except BlockingIOError:
                if fd == self._rs_master or time.monotonic() > deadline:
                    return  # a UART drops what nobody takes
                time.sleep(0.002)

    # ---- the serving thread ---------------------------------------------------------------

    def _serve(self):
        while not self._stop:
            fds = [self._master, self._wake_r, self._repl.stdout]
            if self._fw is not None:
                fds.append(self._fw.stdout)
            r, _, _ = select.select(fds, [], [], 0.1)
            if self._stop:
                return
            if self._wake_r in r:
                os.read(self._wake_r, 512)
            while self._calls:
                self._calls.pop(0)()
            if self._repl.stdout in r:
                data = os.read(self._repl.stdout.fileno(), 65536)
                if data:
                    self._on_repl_output(data)
                else:
                    self._on_repl_exit()
            if self._fw is not None and self._fw.stdout in r:
                data = os.read(self._fw.stdout.fileno(), 65536)
                if data:
                    self._on_fw_output(data)
                else:
                    self._on_fw_exit()
            if self._fw is not None and self._fw_stopping is not None:
                if time.monotonic() - self._fw_stopping > 3.0:
                    self._fw.kill()  # did not stop: its EOF ends the run
            if self._master in r:
                try:
                    data = os.read(self._master, 4096)
                except OSError:
                    data = b""
                for c in data:
                    self._input(c)

    # ---- input -----------------------------------------------------------------------------

    def _input(self, c):
        mode = self._mode
        if mode == "fw" or self._busy is not None:
            if c == CTRL_C:
                self._interrupt()
            else:
                self._pending.append(c)
            return
        if mode == "friendly":
            self._friendly(c)
        elif mode == "raw":
            self._raw(c)
        elif mode == "paste":
            self._paste(c)

    def _drain_pending(self):
        while self._pending and self._mode != "fw" and self._busy is None:
            c = self._pending.pop(0)
            self._input(c)

    def _interrupt(self):
        if self._mode == "fw":
            if self._fw_stopping is None:
                self._fw_stopping = time.monotonic()
                self._fw.send_signal(signal.SIGINT)
        elif self._busy is not None:
            self._repl.send_signal(signal.SIGINT)

    def _friendly(self, c):
        if c == CTRL_A:
            self._line.clear()
            self._mode = "raw"
            self._send(b"\r\n" + RAW_BANNER + b">")
        elif c == CTRL_B:
            self._line.clear()
            self._send(b"\r\n" + BANNER + PROMPT)
        elif c == CTRL_C:
            self._line.clear()
            self._send(b"\r\n" + PROMPT)
        elif c == CTRL_D:
            if not self._line:
                self._send(b"\r\n" + SOFT_REBOOT)
                self._soft_reset()
                self._power_up()
        elif c == 13:
            self._send(b"\r\n")
            if self._line.strip():
                self._exec(bytes(self._line), "friendly")
            else:
                self._send(PROMPT)
            self._line.clear()
        elif c in (8, 127):
            if self._line:
                self._line.pop()
                self._send(b"\x08 \x08")
        elif 32 <= c < 127 or c >= 128:
            self._line.append(c)
            self._send(bytes([c]))

    def _raw(self, c):
        if c == CTRL_A:
            line = self._line
            self._line = bytearray()
            if len(line) == 2 and line[0] == CTRL_E:
                if line[1] != ord("A"):
                    self._send(b"R\x00>")
                    return
                self._send(b"R\x01" + struct.pack("<H", PASTE_WINDOW) + b"\x01")
                self._mode = "paste"
                self._paste_remain = PASTE_WINDOW
                return
            self._send(RAW_BANNER + b">")
        elif c == CTRL_B:
            self._line.clear()
            self._mode = "friendly"
            self._send(b"\r\n" + BANNER + PROMPT)
        elif c == CTRL_C:
            self._line.clear()
        elif c == CTRL_D:
            self._send(b"OK")
            if not self._line:
                self._send(b"\r\n" + SOFT_REBOOT)
                self._soft_reset()
                self._send(RAW_BANNER + b">")  # main.py does not run from the raw REPL
                return
            code = bytes(self._line)
            self._line.clear()
            self._exec(code, "raw")
        else:
            self._line.append(c)

    def _paste(self, c):
        if c == CTRL_D:
            self._send(b"\x04")
            code = bytes(self._line)
            self._line.clear()
            self._mode = "raw"
            self._exec(code, "raw")
        elif c == CTRL_C:
            self._line.clear()
            self._mode = "raw"
            self._send(b"\x04\x04KeyboardInterrupt: \r\n\x04>")
        else:
            self._line.append(c)
            self._paste_remain -= 1
            if self._paste_remain == 0:
                self._send(b"\x01")
                self._paste_remain = PASTE_WINDOW

    # ---- code in the REPL VM --------------------------------------------------------------

    def _exec(self, code, kind):
        if b"class RemoteFS" in code:  # mpremote mount's board side: refused, not hung
            self._busy = kind
            self._exec_done(MOUNT_REFUSED)
            return
        self._busy = kind
        mode = b"s" if kind == "friendly" else b"x"
        try:
            self._repl.stdin.write(mode + b" %d\n" % len(code) + code)
        except OSError:
            self._on_repl_exit()

    def _on_repl_output(self, data):
        buf = self._repl_buf + data
        sent = self._sentinel
        while True:
            i = buf.find(sent)
            if i < 0:
                # forward all but a possible start of the sentinel
                j = buf.rfind(b"\x00")
                keep = j if j >= 0 and len(buf) - j < len(sent) else len(buf)
                self._forward_stdout(buf[:keep])
                buf = buf[keep:]
                break
            self._forward_stdout(buf[:i])
            rest = buf[i + len(sent) :]
            nl = rest.find(b"\n")
            if nl < 0:
                buf = buf[i:]
                break
            if rest[:nl] == b"reset":  # machine.reset(): the VM has ended
                self._repl_buf = b""
                self._hard_reset()
                return
            n_err, corrupted = (int(x) for x in rest[:nl].split())
            if len(rest) < nl + 1 + n_err:
                buf = buf[i:]
                break
            err = rest[nl + 1 : nl + 1 + n_err]
            buf = rest[nl + 1 + n_err :]
            self.corrupted = self._corrupt_base + corrupted
            self._exec_done(err)
        self._repl_buf = buf

    def _forward_stdout(self, data):
        if data:
            self._send(_cook(data))

    def _exec_done(self, err):
        kind = self._busy
        self._busy = None
        if kind == "friendly":
            self._send(_cook(err) + PROMPT)
        else:
            self._send(b"\x04" + _cook(err) + b"\x04>")
        self._drain_pending()

    def _on_repl_exit(self):
        """The REPL VM died (e.g. os._exit or a crash): a hard fault; the board resets."""
        rest = self._repl_buf
        self._forward_stdout(rest)
        kind = self._busy
        self._start_repl_vm()
        if kind == "raw":
            self._send(b"\x04\x04>")
        elif kind == "friendly":
            self._send(PROMPT)

    def _soft_reset(self):
        self._start_repl_vm()

    def _hard_reset(self):
        """machine.reset(): what was typed is lost, the board starts as at power-up (main.py
        if there is one) with the backup domain kept; the port stays (a UART console: a USB
        board's would leave and come back)."""
        self.resets += 1
        self._reset_cause = 2  # HARD_RESET
        self._busy = None
        self._line.clear()
        self._pending.clear()
        self._mode = "friendly"
        self._start_repl_vm()
        self._power_up()

    # ---- the firmware --------------------------------------------------------------------

    def _power_up(self):
        """After a reset in friendly mode: main.py if it exists, then the friendly REPL."""
        if (self.fs_dir / "main.py").is_file():
            self._start_fw_vm()
        else:
            self._send(BANNER + PROMPT)

    def _on_fw_output(self, data):
        buf = self._fw_buf + data
        lines = buf.split(b"\n")
        self._fw_buf = lines.pop()
        for line in lines:
            self._fw_line(line)

    def _fw_line(self, line):
        if self._fw_error is not None:
            line = line.replace(self._fs_bytes, b"/flash")
            if line == b"E-END":
                self._send(b"\r\n".join(self._fw_error) + b"\r\n")
                self._fw_error = None
            else:
                self._fw_error.append(line)
            return
        kind, _, rest = line.partition(b" ")
        if kind == b"O":
            try:
                self._send(bytes.fromhex(rest.decode()), self._rs_master)
            except ValueError:
                pass
        elif kind == b"C":
            rest = rest.replace(self._fs_bytes, b"/flash")  # the board's own paths
            if rest.startswith(STOPPED):
                self._fw_saw_stopped = True
            self._send(rest + b"\r\n")
        elif kind == b"D":
            self._screen(rest)
        elif kind == b"P":
            pass
        elif kind == b"E" and rest.strip().lstrip(b"-").isdigit():
            self._fw_error = []
        elif kind == b"X":
            if rest == b"maintenance":
                self.maintenance_starts += 1
            elif rest == b"ended":
                self._fw_ended = True
                again = b"it starts again (a reset)" if self.loop else b"Ctrl-D runs it again"
                self._send(
                    b"virtual board: the input ended (simulated %s, %g s, seed %d); %s\r\n"
                    % (self.scenario.encode(), self.duration_s, self.seed, again)
                )
        else:
            self._send(line + b"\r\n")

    def _screen(self, hex_bytes):
        """Bytes the status page sent: into the emulated screen; its picture to `display`,
        at most twice a second (and when the firmware stops)."""
        if self.display is None:
            return
        from common.proto import config as board_config
        from host_emulator.display.device import UsartGpu
        from host_emulator.display.usartgpu import DisplayError

        try:
            if self._gpu is None:
                cfg = board_config.from_values(board_config.load(self.fs_dir / "ins.cfg"))
                self._gpu = UsartGpu((cfg.display_w, cfg.display_h), cfg.display_baud)
            t_us = (time.monotonic() - self._fw_t0) * 1e6
            self._gpu.receive(bytes.fromhex(hex_bytes.decode()), t_us)
        except (ValueError, DisplayError, board_config.ConfigError) as e:
            self._send(b"virtual board: the screen stops: %s\r\n" % str(e).encode())
            self.display = None
            return
        if time.monotonic() - self._gpu_drawn >= 0.5:
            self._draw_screen()

    def _draw_screen(self):
        if self._gpu is None or self.display is None:
            return
        import io

        from common.errors import write_atomic

        buf = io.BytesIO()
        self._gpu.screen.image(scale=2).save(buf, "PNG")
        try:
            write_atomic(self.display, buf.getvalue())
        except OSError as e:
            self._send(b"virtual board: cannot write the screen: %s\r\n" % str(e).encode())
            self.display = None
        self._gpu_drawn = time.monotonic()

    def _on_fw_exit(self):
        self._draw_screen()
        if self._fw_buf:
            self._fw_line(self._fw_buf)
        if self._fw_error:
            self._send(b"\r\n".join(self._fw_error) + b"\r\n")
        stopping = self._fw_stopping is not None
        if stopping and not self._fw_saw_stopped:
            self._send(STOPPED + b"\r\n")
        self._kill(self._fw)
        self._fw = None
        ended, self._fw_ended = self._fw_ended, False
        if ended and self.loop and not stopping:  # endless: the board starts again
            self._send(b"MPY: soft reboot\r\n")
            self._start_fw_vm()
            return
        self._mode = "friendly"
        self._send(BANNER + PROMPT)
        self._drain_pending()


def main(argv=None):
    """`python -m host_emulator virtual-board`: serve a virtual board until Ctrl-C."""
    args = _parser().parse_args(argv)
    wrong = _args_error(args)
    if wrong is not None:
        print(f"virtual board: {wrong}", file=sys.stderr)
        return 2
    frozen_tmp = None
    if args.frozen:
        frozen_tmp = _frozen_layout()
        if frozen_tmp is None:
            return 1
    board = VirtualBoard(
        args.fs,
        frozen_dir=frozen_tmp.name if frozen_tmp else None,
        flash_kb=args.flash_kb,
        corrupt_writes=args.corrupt_writes,
        scenario=args.scenario,
        seed=args.seed,
        duration_s=args.duration or 120.0,
        realtime=not args.fast,
        boot_main=args.run,
        loop=args.duration == 0,
        display=args.display,
    )
    try:
        board.start()
    except (RuntimeError, OSError) as e:
        print(f"virtual board: cannot start: {e}", file=sys.stderr)
        return 1
    _print_ports(board, frozen_tmp)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        board.close()
        if frozen_tmp:
            frozen_tmp.cleanup()
    return 0


def _parser():
    """The virtual-board command line."""
    p = argparse.ArgumentParser(
        prog="python -m host_emulator virtual-board",
        description="A virtual INS board on pseudo-terminals (docs/virtual_board.md).",
    )
    p.add_argument("--fs", required=True, help="host directory holding the board's /flash")
    p.add_argument("--flash-kb", type=int, default=2048, help="filesystem capacity (KB)")
    p.add_argument("--scenario", default="urban_drive", help="simulated scenario")
    p.add_argument("--seed", type=int, default=0, help="the simulation's random seed (0)")
    p.add_argument(
        "--duration", type=float, default=120.0,
        help="scenario length (s); 0: endless (the 120 s scenario again and again, the "
        "firmware starting anew each time as after a reset)",
    )  # fmt: skip
    p.add_argument("--corrupt-writes", type=int, default=0, help="corrupt the first N writes")
    p.add_argument("--fast", action="store_true", help="run the firmware faster than real time")
    p.add_argument("--run", action="store_true", help="run main.py at power-up")
    p.add_argument(
        "--display", metavar="PATH",
        help="the board's UsartGPU screen as a PNG, redrawn while the firmware runs with "
        "display=1 in ins.cfg (docs/display.md)",
    )  # fmt: skip
    p.add_argument(
        "--frozen",
        action="store_true",
        help="an image with the firmware frozen (this checkout's firmware/ and its fwid)",
    )
    return p


def _args_error(args):
    """What is wrong with the parsed arguments (an EmulatorError's text), or None."""
    from common.errors import EmulatorError
    from host_emulator import args as cli_args

    try:
        cli_args.check_scenario(args.scenario)
        if args.duration != 0:
            cli_args.check_duration(args.duration)
        cli_args.check_seed(args.seed)
        if args.flash_kb < 1 or args.corrupt_writes < 0:
            raise EmulatorError("--flash-kb must be 1 or more and --corrupt-writes 0 or more")
    except EmulatorError as e:
        return str(e)
    return None


def _frozen_layout():
    """A temporary directory holding this checkout's firmware laid out to be frozen (with its
    fwid); None, after saying why on stderr, if it cannot be laid out."""
    from common.toolchain import ToolchainError
    from tools.image import fwid

    frozen_tmp = tempfile.TemporaryDirectory(prefix="vboard-frozen-")
    try:
        fwid.frozen_layout(frozen_tmp.name)
    except (ToolchainError, fwid.FirmwareIdError, OSError) as e:
        print(f"virtual board: cannot lay out the frozen firmware: {e}", file=sys.stderr)
        return None
    return frozen_tmp


def _print_ports(board, frozen_tmp):
    """Where the started board's console, RS485 output, filesystem and screen are."""
    print(f"REPL console (USB): {board.port}")
    print(f"RS485 output:       {board.rs485_port}")
    print(f"filesystem /flash:  {board.fs_dir} ({board.flash_kb} KB)")
    if board.display:
        print(f"screen:             {board.display} (redrawn while the firmware runs, with "
              "display=1 in ins.cfg)")  # fmt: skip
    if frozen_tmp:
        print(f"frozen firmware:    {frozen_tmp.name} (this checkout's firmware/, with fwid)")
    print("Ctrl-C to stop", flush=True)
