"""What surrounds the emulated STM32F411 on the board, fed from a stimulus.

- The BMI055: both dies of emulated_board/mpy/bmi055_model.py (the register model every runtime
  shares) on SPI1 behind their chip-select pins, timing their start-up on the twin's clock.
  At tick k's moment T_k the data and temperature registers take stimulus record k; in an
  interval flagged IMU-silent neither die answers.
- The firmware's tick: T_0 is the first expiry of the 5 ms timer the firmware starts (the
  port's soft timer: seen when the image calls soft_timer_insert with a 5 ms period; it expires
  on the SysTick interrupt at which HAL's uwTick reaches its expiry), T_k = T_0 + k x 5 ms.
- The GNSS receiver: record k's bytes finish arriving in (T_(k-1), T_k], back to back at the
  receiver's baud rate, the last one ending at T_k (so the firmware's read of tick k-1, which
  comes a fraction of a millisecond after T_(k-1), sees none of them: the stimulus says which
  tick reads them; 5 bytes a tick at 9600 baud leave it 0.8 ms); more than the interval holds
  at that baud rate arrive faster (counted: `gnss_bytes_compressed`). The receiver's baud
  must match the UART's (within 3 %), else the run stops: a board would read garbage.
- The PPS: a rising edge at T_k - pps_before_us on PB0 (EXTI), 100 ms high (an edge while the
  line is still high, a spurious one, dips it low first: every edge of the stimulus is one).
- The RS485 transceiver: every character the output USART starts while the transceiver's
  driver enable (DE) is high is the output stream, in order (a character counts once its start
  bit is on the line); one started with DE low never reaches the bus (counted: `rs485_muted`).
- The UsartGPU screen (display/device.py), with the firmware's display setting on and a board
  that has a USART for it (the Black Pill's USART6): every character the display USART starts
  reaches the screen at the end of its frame (strict: a stream that breaks the screen's rules
  stops the run); the OKs it answers that are due by T_k come back into the USART's receive
  side from T_k on, back to back at its baud (late by at most a tick, never early). The
  display stream's marks give each byte the tick it started in (start-up: -1), and its
  counters are counted from the stream (Screen.stats).
- The console: what MicroPython prints (mp_hal_stdout_tx_strn), whichever port it goes to.

Per tick, from T_k to T_(k+1): busy = from T_k to the loop's first WFI after it (the tick's
work: interrupt, loop pass, frames; late when the loop never slept before T_(k+1): the next
tick then starts late, and is lost only if it is two periods late, which the firmware counts as
an overrun in its extended frame), the instructions
executed, of which in handler mode and in the port's UART and SPI/DMA code, the cycles waited
on polled peripheral flags (blocking UART writes spin on TXE), exceptions taken.
"""

import bisect

import numpy as np

from common.errors import EmulatorError
from common.proto import records, stream
from host_emulator.display.device import UsartGpu
from host_emulator.display.usartgpu import REPLY, DisplayError
from host_emulator.emulated_board import bmi055_model
from host_emulator.f411 import image as image_mod
from host_emulator.model import display as page_model

PPS_HIGH_US = 100_000
_CAT = {name: i for i, name in enumerate(image_mod.CATEGORIES)}
_PERIODIC = 2  # SOFT_TIMER_MODE_PERIODIC
_ENTRY_MODE, _ENTRY_DELTA = 18, 24  # soft_timer_entry_t offsets (shared/runtime/softtimer.h)


class World:
    def __init__(self, chip, board, stim, gnss_baud, display=None):
        """display: ((width, height), baud) of the screen when the firmware's display setting
        is on (None: off); attached only if the board has a USART for it."""
        self.chip = chip
        self.board = board
        self.stim = stim
        self.gnss_baud = gnss_baud
        clock = chip.clock
        self.clock = clock
        self.imu = bmi055_model().Bmi055(now_us=lambda: int(clock.us()))
        spi = chip.spi1
        spi.attach(self.imu.accel, *chip.pin(board.cs_accel))
        spi.attach(self.imu.gyro, *chip.pin(board.cs_gyro))
        self.out = []  # (start cycle, byte) off the RS485 USART
        self.rs485_muted = 0  # characters sent while the transceiver's driver was disabled
        self._de = chip.pin(board.rs485_de)
        chip.usart[board.out_uart].on_tx.append(self._rs485)
        self.gnss = chip.usart[board.gnss_uart]
        self.pps_gpio, self.pps_pin = chip.pin(board.pps)
        self.pps_gpio.drive(self.pps_pin, 0)
        self._console = bytearray()
        lo = chip.image.address("machine_idle") & ~1
        self._idle_lo, self._idle_hi = lo, lo + chip.image.size("machine_idle")
        chip.hook("mp_hal_stdout_tx_strn", self._stdout)
        chip.hook("soft_timer_insert", self._timer_inserted)
        chip.on_reset.append(self._reset)
        self.resets = []
        self.error = None
        self.t0 = None
        self.gnss_bytes_compressed = 0
        self.gnss_ticks_compressed = 0
        self._tick_k = -1
        self._busy_end = None
        self._snap = None
        self.per_tick = None
        self.screen = None
        if display is not None and board.display_uart is not None:
            self.screen = Screen(self, chip.usart[board.display_uart], *display)

    # -- observing the image ------------------------------------------------------------

    def _rs485(self, byte, at):
        gpio, pin = self._de
        if gpio.level(pin):
            self.out.append((at, byte))
        else:  # DE low: the transceiver does not drive the bus, the character is lost
            self.rs485_muted += 1

    def _stdout(self, chip):
        self._console.extend(chip.cpu.uc.mem_read(chip.reg(0), chip.reg(1)))

    def _timer_inserted(self, chip):
        entry, delta_ms = chip.reg(0), chip.reg(1)
        mode = int.from_bytes(chip.cpu.uc.mem_read(entry + _ENTRY_MODE, 2), "little")
        period = chip.read_word(entry + _ENTRY_DELTA)
        if self.t0 is not None or mode != _PERIODIC or period * 1000 != self.stim.tick_us:
            return
        # expiry_ms = uwTick + delta: the delta-th SysTick interrupt from now
        st = chip.scs.systick
        self.t0 = st.next_zero_cycle() + (delta_ms - 1) * st.period_cycles()

    def _reset(self, reason):
        self.resets.append((self.clock.us(), reason))
        if self.t0 is not None and self.error is None:
            self.error = f"the chip reset ({reason}) at {self.clock.us() / 1e6:.3f} s"

    def console_text(self):
        return self._console.decode(errors="replace")

    def console_lines(self):
        return [ln.rstrip("\r") for ln in self.console_text().split("\n") if ln.strip("\r")]

    # -- start-up -----------------------------------------------------------------------

    def wait_for_start(self, limit_s):
        """Run from reset until the firmware has started its tick timer (True), the limit
        of board time passing or the image going to sleep for good (False)."""
        chip = self.chip
        while self.t0 is None:
            r = chip.run_for_ms(20, lambda: self.t0 is not None)
            if r == "asleep" or self.clock.us() > limit_s * 1e6:
                return False
        self._check_baud()
        return True

    def _check_baud(self):
        u = self.gnss
        actual = u.baud()
        if abs(actual - self.gnss_baud) > 0.03 * self.gnss_baud:
            raise EmulatorError(
                f"the firmware set USART{u.number} to {actual:.0f} baud but the GNSS receiver "
                f"sends at {self.gnss_baud}: a board would receive garbage"
            )
        self._char = round(self.clock.hz * 10 / self.gnss_baud)

    # -- feeding ------------------------------------------------------------------------

    def tick_cycle(self, k):
        return self.t0 + k * self._tick_cycles

    def feed(self, progress=None):
        """Feed every record of the stimulus, tick by tick; the run ends just before tick N."""
        stim = self.stim
        n = len(stim)
        self._tick_cycles = self.clock.cycles_for_us(stim.tick_us)
        self._regs = np.concatenate((stim.gyro_regs, stim.accel_regs), axis=1).tobytes()
        self._temp = stim.temp_raw.tolist()
        self._silent = stim.imu_silent.tolist()
        self._pps = stim.pps_before_us.tolist()
        self._offs = stim.uart_offsets.tolist()
        self._ub = stim.uart_bytes
        self.per_tick = np.zeros(n, dtype=_per_tick_dtype())
        self._inputs(0)
        self.clock.at(self.tick_cycle(0), lambda: self._tick(0))
        self.chip.cpu.on_sleep = self._sleeping
        end = self.tick_cycle(n) - 1
        step = 2000 * self._tick_cycles
        while self.clock.now() < end and self.error is None:
            r = self.chip.run(min(end, self.clock.now() + step), lambda: self.error is not None)
            if r == "asleep":
                self.error = "the image went to sleep with nothing left to wake it"
            k = max(self._tick_k, 0)
            if progress and self.error is None:
                progress(min(k + 1, n), n)
        if self.error is None:
            self._account(n)

    def _inputs(self, k):
        """Record k's GNSS bytes and PPS edge, scheduled in (T_(k-1), T_k]."""
        t_k = self.tick_cycle(k)
        lo = max(t_k - self._tick_cycles, self.clock.now())
        a, b = self._offs[k], self._offs[k + 1]
        m = b - a
        if m:
            char = self._char
            room = t_k - lo
            if (m - 1) * char < room:
                step = char
            else:
                step = room // m
                self.gnss_bytes_compressed += m
                self.gnss_ticks_compressed += 1
            first_end = t_k - (m - 1) * step
            ub = self._ub
            for i in range(m):
                self.gnss.receive(ub[a + i], first_end + i * step)
        pb = self._pps[k]
        if pb >= 0:
            edge = max(t_k - self.clock.cycles_for_us(pb), self.clock.now())
            self.clock.at(edge, self._pps_rise)

    def _pps_rise(self):
        if self.pps_gpio.level(self.pps_pin):  # an edge within the last pulse (a spurious
            self.pps_gpio.drive(self.pps_pin, 0)  # one, injected): the line dips, then rises
        self.pps_gpio.drive(self.pps_pin, 1)
        self.clock.after(self.clock.cycles_for_us(PPS_HIGH_US), self._pps_fall)

    def _pps_fall(self):
        self.pps_gpio.drive(self.pps_pin, 0)

    def _tick(self, k):
        """T_k: the sample of record k in the registers; measurements of tick k-1 closed."""
        self._account(k)
        self._tick_k = k
        imu = self.imu
        silent = self._silent[k]
        imu.accel.responds = imu.gyro.responds = not silent
        imu.set_registers(self._regs, 12 * k, 12 * k + 6)
        imu.set_temperature_raw(self._temp[k])
        if self.screen is not None:
            self.screen.answer()
        n = len(self.stim)
        if k + 1 < n:
            self._inputs(k + 1)
            self.clock.at(self.tick_cycle(k + 1), lambda: self._tick(k + 1))

    # -- measuring ----------------------------------------------------------------------

    def _counters(self):
        c = self.chip.cpu.counter
        cc = c.category_count
        return (
            c.icount,
            c.handler_icount,
            cc[_CAT["uart"]],
            cc[_CAT["spi_dma"]],
            cc[_CAT["gc"]],
            self.chip.bus.poll_wait_cycles,
            self.chip.cpu.exceptions_taken,
        )

    def _sleeping(self, pc):
        # the loop's idle (machine.idle's WFI), not a driver's wait (spi_transfer's WFI)
        if self._busy_end is None and self._idle_lo <= pc < self._idle_hi:
            self._busy_end = self.clock.now()

    def _account(self, k):
        """Close tick k-1's record (at T_k) and open tick k's."""
        now = self._counters()
        j = k - 1
        if self._snap is not None and 0 <= j < len(self.per_tick):
            s = self._snap
            r = self.per_tick[j]
            t_j = self.tick_cycle(j)
            busy_end = self._busy_end if self._busy_end is not None else self.clock.now()
            r["busy_cycles"] = busy_end - t_j
            r["late"] = self._busy_end is None
            r["instr"] = now[0] - s[0]
            r["handler_instr"] = now[1] - s[1]
            r["uart_instr"] = now[2] - s[2]
            r["spi_dma_instr"] = now[3] - s[3]
            r["gc_instr"] = now[4] - s[4]
            r["poll_wait_cycles"] = now[5] - s[5]
            r["exceptions"] = min(now[6] - s[6], 0xFFFF)
        self._snap = now
        self._busy_end = None

    # -- results ------------------------------------------------------------------------

    def output(self):
        """The RS485 stream: every character started before the run ended, in order."""
        return bytes(b for _, b in sorted(self.out, key=lambda x: x[0]))

    def stats(self):
        chip = self.chip
        pt = self.per_tick
        hz = self.clock.hz
        margin = chip.iwdg.margin()
        busy_ms = pt["busy_cycles"] * 1000.0 / hz if pt is not None and len(pt) else np.zeros(0)
        ext = stream.decode(self.output()).ext
        return {
            "ticks": int(len(pt)) if pt is not None else 0,
            "t0_us": self.clock.us(self.t0) if self.t0 is not None else None,
            "hclk_hz": hz,
            # the firmware's own count of the ticks its loop missed (the last extended frame's)
            "overruns": int(ext[-1]["overruns"]) if ext else None,
            "app_gc_runs": int(ext[-1]["gc_runs"]) if ext else None,
            # ticks whose work ran past the next tick's moment (late, but none missed)
            "late_ticks": int(pt["late"].sum()) if pt is not None else 0,
            "busy_ms_mean": float(busy_ms.mean()) if len(busy_ms) else None,
            "busy_ms_p99": float(np.percentile(busy_ms, 99)) if len(busy_ms) else None,
            "busy_ms_max": float(busy_ms.max()) if len(busy_ms) else None,
            "gnss_rx_bytes": self.gnss.rx_bytes,
            "gnss_rx_lost": self.gnss.rx_lost,
            "gnss_bytes_compressed": self.gnss_bytes_compressed,
            "rs485_muted": self.rs485_muted,
            "watchdog_longest_gap_ms": margin[0] if margin else None,
            "watchdog_timeout_ms": margin[1] if margin else None,
            "resets": [r for r in self.resets],
            "instructions": int(chip.clock.instructions),
            "polls_skipped": chip.bus.polls_skipped,
            "poll_wait_ms_by_peripheral": {
                k: v * 1000 / hz for k, v in sorted(chip.bus.poll_wait_by.items())
            },  # fmt: skip
            "flash_erases": chip.flash_if.erases,
            **(self.screen.stats(ext) if self.screen is not None else {}),
        }

    def display(self):
        """(FirmwareRun.display, display_marks): every byte the display USART started, in
        order, and (tick, end offset) after each tick whose bytes started in it (-1: before
        T_0; a byte started after the run's end counts in its last tick)."""
        if self.screen is None:
            return b"", []
        return self.screen.data(), self.screen.marks(self.t0, self._tick_cycles, len(self.stim))


class Screen:
    """The emulated UsartGPU on the display USART (display/device.py)."""

    def __init__(self, world, usart, size, baud):
        self.world = world
        self.clock = world.clock
        self.usart = usart
        self.baud = baud
        self.gpu = UsartGpu(size, baud)
        self.sent = []  # (start cycle, byte)
        self.ok_ends = []  # the cycle each answered character completes
        usart.on_tx.append(self._tx)

    def _tx(self, byte, at):
        u = self.usart
        if not self.sent and abs(u.baud() - self.baud) > 0.03 * self.baud:
            raise EmulatorError(
                f"the firmware set USART{u.number} to {u.baud():.0f} baud but the screen "
                f"takes {self.baud} (display_baud): a screen would receive garbage"
            )
        self.sent.append((at, byte))
        try:
            self.gpu.receive(bytes((byte,)), self.clock.us(at + u.char_cycles()))
        except DisplayError as e:
            if self.world.error is None:
                self.world.error = f"the screen refused what USART{u.number} sent: {e}"

    def answer(self):
        """At T_k: the OKs the screen has answered by now, into the USART from now on."""
        now = self.clock.now()
        ok = self.gpu.replies(self.clock.us(now))
        char = self.usart.char_cycles()
        for i, b in enumerate(ok):
            end = now + (i + 1) * char
            self.usart.receive(b, end)
            self.ok_ends.append(end)

    def data(self):
        return bytes(b for _, b in self.sent)

    def marks(self, t0, tick_cycles, n):
        out = []
        for i, (at, _) in enumerate(self.sent):
            k = -1 if t0 is None or at < t0 else min((at - t0) // tick_cycles, n - 1)
            if out and out[-1][0] == k:
                out[-1] = (k, i + 1)
            else:
                out.append((k, i + 1))
        return out

    def stats(self, ext):
        """The screen's figures: its batches (each `\\r\\n`), the OKs it answered that
        reached the board, the batches the firmware counts as missed (its rule, status_page
        _end, replayed on the stream: at each batch's end, from T_k, the OKs arrived against
        the batches sent), the extended frames carrying the display cause, and the OK
        characters the USART lost."""
        w = self.world
        crlf = [at for i, (at, b) in enumerate(self.sent)
                if b == 10 and i and self.sent[i - 1][1] == 13]  # fmt: skip
        k = REPLY.index(b"K")  # the character status_page counts
        return {
            "display_bytes": len(self.sent),
            "display_batches": self.gpu.stream.batches,
            "display_oks": len(self.ok_ends) // len(REPLY),
            "display_missed": _missed(crlf, self.ok_ends[k :: len(REPLY)], w),
            "display_cause_frames": sum(1 for e in ext if (e["causes"] or 0) & CAUSE_DISPLAY),
            "display_rx_lost": self.usart.rx_lost,
            "display_demo_at_us": self.gpu.demo_at_us,
        }


CAUSE_DISPLAY = records.CAUSE_BITS["display_unanswered"]
_ROUND = page_model.SLOT * page_model.TURNS  # ticks of a round of the page
# the app's `ticks` of the batch's end
_END_PHASE = page_model.SLOT * page_model.FIELDS + page_model.PHASE


def _missed(crlf, ok_ends, w):
    """status_page._end's count of unanswered batches: at each batch end (tick k with app
    ticks k + 1 = _END_PHASE mod _ROUND, read from T_k), the OKs arrived (ok_ends: each OK's
    K) against the batches ended (crlf: each `\\r\\n`'s start)."""
    oks = missed = 0
    seen = 0
    for k in range(_END_PHASE - 1, len(w.stim), _ROUND):
        t = w.tick_cycle(k)
        now_seen = bisect.bisect_left(ok_ends, t)
        oks += now_seen - seen
        seen = now_seen
        batches = bisect.bisect_left(crlf, t)
        oks = min(oks, batches)
        if oks and batches > oks:
            missed += batches - oks
            oks = batches
    return missed


def _per_tick_dtype():
    from host_emulator.runtimes.f411 import PER_TICK

    return PER_TICK
