"""The image's REPL console on the emulated STM32F411, as a serial port the board tools open:
the NUCLEO-F411RE image's REPL is USART2 (the ST-LINK's virtual COM port at 115200 baud),
which the twin models with its interrupts, so `tools.flash` (its raw REPL through mpremote's
transport, deploy, `config set`, the maintenance start's reset) runs against the image itself.

    board = TwinBoard(files={"main.py": ..., "ins.cfg": ...})   # NUCLEO_F411RE
    board.run_ms(2000)             # the image boots, main.py starts the firmware
    board.write(b"\\x03")           # a character on the REPL UART's receive line
    board.read(n), board.in_waiting  # what the image sent on its transmit line

Time: the twin runs only when the port is used: every `in_waiting` (and a `read` that finds
nothing) runs the chip for the wall-clock time since the last poll (at least SLICE_MS, at
most MAX_SLICE_MS of board time), so a tool polling the port with its wall-clock timeouts
moves the board's clock on about as fast as its own. A `read` that waits waits `timeout`
seconds of board time, however long the host takes to emulate them: a host slowed by other
work (a test run's parallel workers) sees a board that answers as late as a board would, not
a board that seems to say nothing. `write` catches the board up the same
way (the writer may have slept), then puts the characters on the line back to back at the
UART's baud rate from the board's now, as a USB-serial adapter sends them. The port stays
open across a reset (the ST-LINK's COM port does not re-enumerate), and closing it stops
nothing: `open_port` gives the same board again.

Around the chip: the BMI055 register model on SPI1 holding one sample of a simulated drive at
rest (the firmware's IMU answers and its loop runs); no GNSS bytes, no PPS. The firmware's
filesystem is what deploy writes next to the image (runtimes/f411: main.py, ins.cfg,
lib/navk.mpy) or `files`. Figures: `chip.resets` (cycle, reason) says whether the watchdog
(IWDG) or software (SYSRESETREQ) reset it, `chip.iwdg` its feeds, `chip.flash_if` the erases.
"""

import tempfile
import time

from common.errors import EmulatorError
from host_emulator.emulated_board import bmi055_model

BOARD = "NUCLEO_F411RE"
SLICE_MS = 2  # board time a poll of the port runs the chip for, at least ...
MAX_SLICE_MS = 50  # ... and at most


class TwinBoard:
    """The image on the twin with its REPL UART as a pyserial-like port (write, read,
    in_waiting, inWaiting, timeout, close)."""

    def __init__(self, files=None, board=BOARD, cpi=None, log=None, workdir=None):
        from host_emulator.f411 import boards
        from host_emulator.f411.chip import F411
        from host_emulator.f411.image import Image
        from host_emulator.runtimes import f411
        from host_emulator.runtimes.f411 import flashfs
        from host_emulator.sim import board_input

        bd = boards.get(board)
        if bd.repl_uart is None:
            raise EmulatorError(f"the {bd.name} image's REPL is on USB, which the twin does not "
                                "model: use NUCLEO_F411RE (REPL on USART2)")  # fmt: skip
        self.board = bd
        image = Image(*f411.image_files(bd.name, log))
        stim = board_input.simulate("quick_start", duration_s=1.0, seed=0).stimulus
        if files is None:
            with tempfile.TemporaryDirectory(prefix="twin-") as d:
                files = f411.deployed_files(stim, None, "native", workdir or d)
        part = flashfs.formatted(bd, image, log)
        if files:
            part = flashfs.with_files(part, files)
        self.chip = chip = F411(bd, image, cpi=cpi or f411.DEFAULT_CPI)
        chip.flash_write_raw(flashfs.PART_BASE, part)
        clock = chip.clock
        self.clock = clock
        self.imu = bmi055_model().Bmi055(now_us=lambda: int(clock.us()))
        chip.spi1.attach(self.imu.accel, *chip.pin(bd.cs_accel))
        chip.spi1.attach(self.imu.gyro, *chip.pin(bd.cs_gyro))
        regs = bytes(stim.gyro_regs[0]) + bytes(stim.accel_regs[0])  # at rest
        self.imu.set_registers(regs, 0, 6)
        self.imu.set_temperature_raw(int(stim.temp_raw[0]))
        self.uart = chip.usart[bd.repl_uart]
        self.uart.on_tx.append(self._tx)
        self.console = bytearray()  # every character the image sent on its REPL line
        self._out = bytearray()  # ... not read yet
        self._rx_end = 0  # the cycle the last character written ends on the line
        self.timeout = 1.0
        self.closed = False
        self._polled = time.monotonic()

    def _tx(self, byte, _at):
        self.console.append(byte)
        self._out.append(byte)

    # -- the board ------------------------------------------------------------------------

    def run_ms(self, ms):
        self.chip.run_for_ms(ms)

    def run_until(self, text, limit_ms, since=None):
        """Run until the console holds `text` (bytes) from offset `since` on (default: what
        comes from now on) or limit_ms of board time pass; whether it came."""
        start = len(self.console) if since is None else since
        end = self.clock.us() + limit_ms * 1000
        while text not in self.console[start:] and self.clock.us() < end:
            self.chip.run_for_ms(SLICE_MS * 10)
        return text in self.console[start:]

    def console_text(self):
        return self.console.decode(errors="replace")

    # -- pyserial -------------------------------------------------------------------------

    def write(self, data):
        self._poll()  # the board's time up to now: the writer may have slept since its last read
        u = self.uart
        ch = u.char_cycles()
        t = max(self.clock.now(), self._rx_end)
        for b in bytes(data):
            t += ch
            u.receive(b, t)
        self._rx_end = t
        return len(data)

    def _poll(self):
        now = time.monotonic()
        ms = min(max((now - self._polled) * 1000, SLICE_MS), MAX_SLICE_MS)
        self._polled = now
        self.chip.run_for_ms(ms)

    @property
    def in_waiting(self):
        if not self._out:
            self._poll()
        return len(self._out)

    def inWaiting(self):  # noqa: N802 (pyserial's older name, which mpremote calls)
        return self.in_waiting

    def read(self, n=1):
        if len(self._out) < n:
            self._poll()
        end = self.clock.us() + (self.timeout or 0) * 1e6  # the board's time, not the host's
        while len(self._out) < n and self.clock.us() < end:
            self.chip.run_for_ms(SLICE_MS)
        self._polled = time.monotonic()  # the emulation's own wall time is not the board's
        data = bytes(self._out[:n])
        del self._out[:n]
        return data

    def close(self):
        self.closed = True

    def reset_input_buffer(self):
        self._out.clear()
