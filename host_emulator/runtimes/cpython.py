"""The cpython runtime: the unmodified firmware loop on CPython, fed from a stimulus, on an
emulated board.

The firmware's own `board.py`, drivers and `app.py` run against the emulated board of
emulated_board/mpy, the one the VM runtimes use too (`machine`: pins, SPI with the BMI055 register
model, UARTs with their receive rings, the PPS interrupt, the timer, the watchdog; `time`: the
virtual clock), loaded by install_machine() and powered on afresh for every run.
Floats are the float32 seam's NumPy backend, so what comes out is what the board computes, bit
for bit.

Per stimulus record k (proto/stimulus.py), by the feed loop the VM runtimes run
(emulated_board/mpy/feed.py, loaded here by file): the BMI055 data and temperature registers
take the record's values, the GNSS UART receives the record's bytes, the clock advances to the
PPS edge (its interrupt fires) and to the tick's moment, the timer fires, the loop makes one
pass (`App.service()`), and the output UART's transmit buffer is emptied. Time starts at
power-on: the firmware's start-up (configuration, the BMI055 resets and their waits) takes
virtual time, and tick 0 is the first timer moment after it.
The loop's own run time is zero on the virtual clock (the board's timing is not modelled: the
extended frame's tick times read 0).

The board's flash is a directory: its configuration file is written there from the stimulus
header's "config" (plus any overrides) before the firmware starts.

Kernels: native (the cffi build of firmware/native as `navk`, default) or python (no navk: the
firmware's Python kernels); firmware_env.use_kernels() switches them, re-importing the
firmware when the choice changes.
"""

import gc
import os
import struct
import time  # CPython's, with the board's ticks_us, now_us, set_us... (install_machine)
import traceback

from common import firmware_env
from common.errors import EmulatorError, FirmwareError
from common.proto import config as board_config
from common.proto import stimulus as stim_mod
from common.proto.mpy.feed_protocol import REC_LEN
from host_emulator import emulated_board
from host_emulator.emulated_board import install_machine
from host_emulator.runtimes import FirmwareRun


def _firmware_traceback(exc):
    """The traceback frames inside firmware/ (what a firmware developer needs)."""
    fw = str(firmware_env.FIRMWARE_DIR)
    frames = [f for f in traceback.extract_tb(exc.__traceback__) if f.filename.startswith(fw)]
    lines = traceback.format_list(frames or traceback.extract_tb(exc.__traceback__))
    return "".join(lines) + f"{type(exc).__name__}: {exc}"


def _firmware_failed(exc, where):
    return FirmwareError(f"the firmware raised {where}:\n{_firmware_traceback(exc)}")


def _use_kernels(kernels):
    """firmware_env.use_kernels(kernels), the native module built first: EmulatorError if it
    cannot be (rather than an error inside the firmware's `import navk`)."""
    from common import native

    kind = firmware_env.use_kernels(kernels)
    if kind == "native":
        from common.firmware_env import navk_host

        try:
            navk_host.load()
        except (native.NativeError, ValueError) as e:  # ValueError: bindings.HeaderError
            raise EmulatorError(f"cannot build the native kernels for CPython: {e}") from None
    return kind


def run(stim, workdir, config_overrides=None, progress=None, kernels=None):
    """Run the firmware on CPython over a whole Stimulus (or stimulus file); a FirmwareRun.

    workdir: the emulated board's flash (a directory; the configuration file goes there).
    progress(k, n): called every 2000 ticks. kernels: "native", "python" or None (the
    default: $INS_KERNELS, else native). A firmware exception -> FirmwareError; EmulatorError
    if the native kernels are asked for and cannot be built."""
    records = _Records.of(stim)
    stim = records.stim
    cfg_path = board_config.write_flash(workdir, board_config.run_values(stim, config_overrides))
    machine = install_machine()
    kind = _use_kernels(kernels)
    machine.power_on()
    import app
    import board

    board.CONFIG_PATH = str(cfg_path)
    pins = board.PINS
    imu = machine.Bmi055()
    imu.attach(
        machine.spi_bus(pins["spi_id"]), machine.pin(pins["cs_accel"]), machine.pin(pins["cs_gyro"])
    )
    console = []
    gc_was_enabled = gc.isenabled()
    t_wall = time.perf_counter()
    try:
        try:
            a = app.App(board, console=console.append)
            a.start()
        except Exception as e:
            raise _firmware_failed(e, "at start-up") from e
        screen = _Screen(machine, a, pins)
        screen.after(-1, time.now_us())  # the start page
        out, t0_us = _feed(machine, a, pins, imu, records, screen, progress)
    finally:
        if gc_was_enabled:
            gc.enable()  # app.start() turned the collector off (board behaviour)
    wall = time.perf_counter() - t_wall
    n = len(stim)
    if progress and n % 2000:
        progress(n, n)
    stats = _stats(machine, a, pins, n, t0_us, kind)
    run = FirmwareRun("cpython", out, console, n, wall, None, stats)
    run.display, run.display_marks = bytes(screen.out), screen.marks
    return run


def _feed(machine, a, pins, imu, records, screen, progress):
    """The stimulus through the firmware by feed.py's loop, the one the VM runtimes run (the
    screen's answers arrive at each tick's moment); (the output UART's bytes, t0 in us)."""
    feed = emulated_board.feed()
    gnss_uart = machine.uart(pins["gnss_uart"])
    out_uart = machine.uart(pins["out_uart"])
    tx = out_uart.tx  # the transmit buffer, emptied after every tick
    pps = machine.pin(pins["pps"])
    tick_us = records.stim.tick_us
    t0_us = feed.first_tick_us(tick_us)  # the first timer moment after start-up
    out = bytearray()
    rec = bytearray(REC_LEN)
    n = len(records.stim)
    for k in feed.ticks(records, n, imu, gnss_uart, rec, bytearray(2048)):
        t_k = t0_us + k * tick_us
        try:
            feed.run_tick(a, rec, t_k, pps, screen.answer)
        except Exception as e:
            raise _firmware_failed(e, f"at tick {k} (t = {k * tick_us * 1e-6:.3f} s)") from e
        if out_uart.tx_n:
            out += tx[: out_uart.tx_n]
            out_uart.tx_clear()
        screen.after(k, t_k)
        if k % 2000 == 1999 and progress:
            progress(k + 1, n)
    if out_uart.tx_overflow:
        raise EmulatorError(f"the firmware wrote more than {machine.TX_CAPACITY} bytes in a tick")
    return bytes(out), t0_us


def _stats(machine, a, pins, n, t0_us, kind):
    """The run's counters: feed.py's, as every runtime reports them, with the kernels and the
    reads that asked for more than had arrived (on the board each waits timeout_char)."""
    stats = emulated_board.feed().app_stats(a, n, t0_us, pins)
    stats["kernels"] = kind
    stats["uart_rx_waits"] = machine.uart(pins["gnss_uart"]).rx_waits
    if a.page is not None:
        stats["uart_rx_waits"] += machine.uart(pins["display_uart"]).rx_waits
    return stats


class _Records:
    """A stimulus' records as feed.py reads a stimulus file: readinto(buf, n) from its first
    record on (the file's bytes: common/proto/stimulus.py), and the parsed Stimulus."""

    def __init__(self, stim, data):
        self.stim = stim
        (hlen,) = struct.unpack_from("<I", data, len(stim_mod.MAGIC))
        self._data = memoryview(data)
        self._pos = len(stim_mod.MAGIC) + 4 + hlen

    @classmethod
    def of(cls, stim):
        """From a Stimulus (its bytes made again) or a stimulus file (its bytes as read: a
        600 s drive's re-serialisation took a seventh of the run)."""
        if isinstance(stim, (str, os.PathLike)):
            data = stim_mod.read_bytes(stim)
            return cls(stim_mod.from_bytes(data, str(stim)), data)
        return cls(stim, stim.to_bytes())

    def readinto(self, buf, n):
        got = self._data[self._pos : self._pos + n]
        buf[: len(got)] = got
        self._pos += len(got)
        return len(got)


class _Screen:
    """The emulated UsartGPU on the display UART when the firmware drives one: what the loop
    wrote reaches it at the line's pace after the tick, its OKs come back into the UART's
    receive ring (display/device.py)."""

    def __init__(self, machine, a, pins):
        self.out = bytearray()
        self.marks = []
        self.gpu = None
        if a.page is None:
            return
        from host_emulator.display.device import UsartGpu

        cfg = a.cfg
        self.uart = machine.uart(pins["display_uart"])
        self.gpu = UsartGpu((cfg.display_w, cfg.display_h), cfg.display_baud)

    def after(self, k, t_us):
        """Tick k (-1: start-up) wrote what the UART holds; it has all left by t_us + line."""
        if self.gpu is None or not self.uart.tx_n:
            return
        u = self.uart
        data = bytes(u.tx[: u.tx_n])
        u.tx_clear()
        self.out += data
        self.marks.append((k, len(self.out)))
        self.gpu.receive(data, t_us + len(data) * 10e6 / u.baudrate)

    def answer(self, t_us):
        if self.gpu is not None:
            ok = self.gpu.replies(t_us)
            if ok:
                self.uart.feed(ok)
