"""The 5 ms loop (docs/requirements.md, original main loop): the timer ISR counts a due tick; the
loop reads the IMU, drains the GNSS bytes, runs the navigator and sends the frame.

Per tick, in this order: BMI055 burst read -> bytes waiting on the GNSS UART into the NMEA
parser -> a completed fix to the navigator (its measurement tick from the PPS edge when one
was seen in the last second, else the configured latency) -> navigator tick -> the 52-byte
frame (every `output_every_ticks`) -> watchdog -> timing statistics -> garbage collection if
the heap runs low. Ticks the timer signalled while the loop was busy elsewhere are counted as
overruns, and the navigator steps through them on the last sample before this tick's
(`_catch_up`): its clock, which fixes are stamped in, keeps the timer's. Automatic collection
is off: a collection only ever runs here, after the frame has gone out, so it never delays a
sample or a frame.

Buffers are made once in `__init__`. With the native kernels (lib/kern.py) a navigating tick
allocates nothing, fix delivery and both frames included (the float work is in the kernels,
longitudes travel as (degrees, fraction) small ints); re-anchoring and resets still compute in
Python. With the Python kernels every float result is a heap object.

Errors a user meets never end the loop: a missing or wrong configuration falls back to
defaults and says so; a missing IMU is reported on the console every second and retried
(the watchdog is fed meanwhile, so the board does not reset-loop).
"""

import gc
import time
from array import array

from micropython import const

import config
import frame
import kern
import records
from drivers.bmi055 import BMI055, Bmi055Error
from drivers.gnss import Nmea
from nav import NAVIGATING, Navigator, nav_frame
from status_page import StatusPage, font_for

_ext_pack = records.ext_pack

_US_PER_TICK = const(5000)
_SECOND_TICKS = const(200)  # ticks in a second: how long an app cause lasts
# missed ticks the navigator steps through at most: board.WDT_TIMEOUT_MS (50) / 5 ms. The
# loop feeds the watchdog once a tick, so a board that missed more has been reset by it
_CATCH_UP_MAX = const(10)
_PPS_TOL_US = const(20000)  # how far from whole seconds apart two PPS edges may be
_EDGE_REF_MAX_US = const(300000000)  # an older reference edge is dropped (ticks_us wraps 2^30)
_DAY_S = const(86400)
_LATE = const(-0x40000000)  # _fix_tick: the epoch is late (no tick - age can be this low)
_K_PPS_LAST = const(0)  # App._chk: the last PPS edge seen (ticks_us; _pps_seen)
_K_PPS_BAD = const(1)  # CAUSE_PPS until this tick (App.ticks)
_K_EDGE_US = const(2)  # the PPS edge of the last on-time epoch (ticks_us; _late_s)
_K_EDGE_S = const(3)  # and its UTC second of the day (-1: none yet)
_K_LATE_BAD = const(4)  # CAUSE_GNSS_LATE until this tick
_K_NMEA_REJ = const(5)  # the parser's rejected() at the last look
_K_NMEA_BAD = const(6)  # CAUSE_NMEA until this tick
_K_EDGES_OK = const(7)  # regular PPS edges in a row that each had an epoch after them
_K_OVERDUE = const(8)  # the tick from which the last edge's epoch is overdue (_pps_seen)
_K_MSL_MM = const(9)  # the last height the receiver gave, above mean sea level, mm (0 before one)
_K_H_MM = const(10)  # ... and above the ellipsoid (_fix_fields); _FI_NO_HEIGHT: none yet
_K_STEP_S = const(11)  # the lateness (s) of the epochs in a row that had one (_late_s; 0: none)
_K_STEP_N = const(12)  # how many had it, of a clock step; -1: it began at a missed edge (late)
_K_STEP_BAD = const(13)  # CAUSE_GNSS_CLOCK until this tick
_K_CAUSES = const(14)  # the app's causes for the whole run: CAUSE_CONFIG on the defaults
_K_MEM0 = const(15)  # micropython.mem_total() when an aligning tick began (_heap_ahead)
_K_AHEAD = const(16)  # the look ahead's next stage: 0 a look, 1 a collection, 2 a look again
_STEP_EPOCHS = const(3)  # a clock step's lateness seen this many epochs in a row: re-synchronised
_OVERDUE_TICKS = const(160)  # no epoch 0.8 s after an edge: overdue (a late receiver)
_OVERDUE_EDGES = const(5)  # ... once this many seconds in a row had theirs (1 Hz output)
_NEVER = const(0x3FFFFFFF)  # a tick count the loop does not reach (years)
_GC_LOW_WATER = const(12 * 1024)  # the Python kernels: collect when fewer bytes are free
# gc.mem_free() scans the heap: ~140,000 instructions on the board, 3.6 ms at 96 MHz (the image
# on the emulated STM32F411), so a tick that looks comes close to the next tick's moment. With
# the native kernels nothing per tick allocates; the navigator's rare Python steps do (the
# origin: 816 bytes, a track window: 416, Python floats; measured on the emulated Cortex-M4F;
# the starts from a course or the yaw estimator and the resets are a kernel, nav_restart) and
# ask for room first (_heap_room). The heap is looked at only
# when what was allocated since the last look may have brought it within a step of the
# reserve: MicroPython's own count of the bytes asked for (micropython.mem_total, which the
# image's board definitions turn on: MICROPY_MEM_STATS) taken twice (a float's 8 bytes fill a
# block of 16), plus _STEP_BYTES; with less than a step over it free, the heap is collected.
# Charging each step a fixed cost against the room instead made a scan in the tick where navigation
# starts (emulated board, urban_drive, the status page on: a late tick); counting every
# screened fix made 2 late ticks in the 76 s urban_drive stands still. While aligning, a quiet
# tick looks ahead of the steps (_heap_ahead): with a heap a few KB from the reserve, the start
# itself had to look (a late tick on the emulated STM32F411).
_STEP_BYTES = const(2048)
_HEAP_RESERVE = const(4096)
try:
    from micropython import mem_total as _mem_total
except ImportError:  # a build without MICROPY_MEM_STATS: the heap is looked at every step
    _mem_total = None
_RX_LEN = const(232)  # GNSS bytes per tick at most: a raw record (length u8 = 23 + n) holds them
# The indices and offsets of other modules' buffers the tick uses, written from their owners
# (an underscore const is inlined and exists only in its own module: it cannot be imported)
# ---- frame.py's consts used here: `python -m common.native.layout` writes them ----
_F_COUNTER = const(0)
_F_GYRO_LSB_X10 = const(1)
_F_ACCEL_LSB = const(2)
_F_PPS = const(3)
_F_GGA = const(4)
_F_VALID = const(5)
_F_HEIGHT_DM = const(6)
_F_STATE = const(7)
_F_LAT_DEG = const(8)
_F_LAT_FRAC = const(9)
_F_LON_DEG = const(10)
_F_LON_FRAC = const(11)
# ---- end of frame.py's consts ----
# ---- records.py's consts used here: `python -m common.native.layout` writes them ----
_EF_COUNTER = const(0)
_EF_HEALTH = const(1)
_EF_STATE = const(2)
_EF_CONFIG = const(3)
_EF_FLAGS = const(4)
_EF_WORST_US = const(5)
_EF_MEAN_US = const(6)
_EF_OVERRUNS = const(7)
_EF_GC_RUNS = const(8)
_EF_LAT0_E7 = const(9)
_EF_LON0_DEG = const(10)
_EF_LON0_FRAC = const(11)
_EF_TICK = const(12)
_EF_CAUSES = const(13)
_RF_COUNTER = const(0)
_RF_T0_US = const(1)
_RF_PPS_US = const(2)
_RF_SATURATED = const(3)
_RF_N = const(4)
# ---- end of records.py's consts ----
# ---- nav.py's consts used here: `python -m common.native.layout` writes them ----
_IMU_REPEAT = const(0x200)
_FI_LAT_E7 = const(0)
_FI_LON_DEG = const(1)
_FI_LON_FRAC = const(2)
_FI_ALT_MM = const(3)
_FI_QUALITY = const(4)
_FI_HDOP_X100 = const(5)
_FI_SPEED_MM_S = const(6)
_FI_COURSE_CDEG = const(7)
_FI_TICK = const(8)
_NFI = const(9)
_FI_NO_HEIGHT = const(0x3FFFFFFF)
_C_TICK = const(0)
_C_STATE = const(1)
_C_HEALTH = const(2)
_C_STILL = const(3)
_C_CAUSES = const(48)
# ---- end of nav.py's consts ----
# ---- geo.py's consts used here: `python -m common.native.layout` writes them ----
_E7 = const(10000000)
# ---- end of geo.py's consts ----
# ---- status_page.py's consts used here: `python -m common.native.layout` writes them ----
_PAGE_SLOT = const(8)
_PAGE_PHASE = const(3)
# ---- end of status_page.py's consts ----
# The app's own causes in the extended frame (nav.CAUSE_* are the navigator's)
CAUSE_NMEA = const(0x1000)  # a GNSS sentence rejected (checksum, framing, fields), seen at the
# next PPS edge or epoch: 1, 1 s
CAUSE_PPS = const(0x2000)  # a PPS edge not a whole number of seconds after the one before, or
# a fix without an edge in the second before it though edges came before (the fix is then
# timed by the configured latency): 1, for a second
CAUSE_GNSS_LATE = const(0x800)  # an epoch that arrived a second or more after its own PPS edge
# (its UTC second against the edges counted since an on-time epoch): older than the
# navigator's delay ring reaches, so not used; or one overdue (_pps_seen); 1, for a second
CAUSE_CONFIG = const(0x4000)  # running on default settings (a missing, corrupt or bad file): 1
# ticks the loop missed since the last extended frame (the board was busy: IMU samples lost,
# the navigator stepped through them on the last one read): a warning, 1. Run time on a board, so
# proto/stream.without_run_time removes it and the 1 it alone raised
CAUSE_OVERRUN = const(0x8000)
CAUSE_GNSS_CLOCK = const(0x10000)  # the receiver's clock stepped (its epochs' seconds no longer
# count the PPS edges): re-synchronised after _STEP_EPOCHS epochs (_late_s); for a second
CAUSE_DISPLAY = const(0x40000)  # the screen, which had answered before, left a batch
# unanswered (status_page.py): 1, for a second


class App:
    def __init__(self, board_module, console=print):
        # the navigator's 6.6 KB state block before anything else, while the heap still has
        # long free runs: made after the configuration and the board, it failed to find one
        # when the heap held other objects before the firmware started (test_m4f's padding).
        # Through Navigator, not f32 and nav.MEM_FLOATS: two more globals in this module made
        # every navigating tick dearer (`make bench-board`, measured both ways)
        mem = Navigator.memory()
        self.console = console
        cfg, status, msg = config.load(board_module.CONFIG_PATH)
        console(msg)
        console(kern.describe())
        # which profile runs, and why: the file's setting or the default (docs/navigation.md)
        console(
            ("profile: 1 (handheld)" if cfg.profile == 1 else "profile: 0 (car)")
            + (" from ins.cfg" if status == config.OK else ", the default")
        )
        self.cfg = cfg
        self.config_status = status
        self.board = board_module.Board(gnss_baud=cfg.gnss_baud, out_baud=cfg.output_baud)
        self._gnss_uart = self.board.gnss_uart
        self._out = self.board.out  # the output UART's transmitter (board.py)
        self._wdt = None  # the board's watchdog once started
        nav_cfg = cfg.nav_config()
        gc.collect()  # the start-up's garbage (the file's decoding, the settings' conversion)
        self.nav = Navigator(nav_cfg, mem)
        self.nav.heap_check = self._heap_room
        # what completes an epoch: 2 (auto) the receiver's sentences decide (GGA+RMC, RMC
        # only, GGA only, ...: drivers/gnss.py "Epochs"); 1 and 0 force GGA + RMC/VTG, GGA
        self.gnss = Nmea(need_speed=cfg.gnss_need_speed)
        self.rx = bytearray(_RX_LEN)
        self.out = bytearray(frame.FRAME_LEN)
        self._fields = array("i", bytes(4 * frame.NF))
        self.counter = 0
        self.due = 0  # ticks signalled by the timer, not yet run
        self.ticks = 0
        self.overruns = 0
        self._ext_overruns = 0  # self.overruns at the last extended frame
        # the PPS, late/overdue-epoch and NMEA checks' state (_K_*), read once a second or
        # less (the overdue tick at each extended frame): one array attribute. Every method
        # call on self first misses the instance's attribute table (a hash table grown only
        # when full): as attributes of their own (36 in a table of 37 for the first three),
        # they made every navigating tick dearer (`make bench-board`, measured both ways)
        self._chk = array("i", (0, 0, 0, -1, 0, 0, 0, 0, _NEVER, 0, _FI_NO_HEIGHT, 0, 0, 0,
                                CAUSE_CONFIG if status != config.OK else 0, 0, 0))  # fmt: skip
        self.t_worst_us = 0
        self.t_sum_us = 0
        self.gc_runs = 0
        self._heap_free = 0  # what the last look at the heap found free (_heap_check)
        self._heap_total = 0  # and micropython.mem_total() then
        self._native = kern.NATIVE
        self.rx_n = 0  # GNSS bytes fed to the parser this tick
        self.ext = records.ExtFrame(self.nav.cv)
        self.ext.fields[_EF_CONFIG] = status
        self.raw = records.RawRecord()
        self._period_ticks = 0  # ticks in the current extended-frame period (for the mean)
        self._led = False
        self.page = None  # the screen's status page, when the display setting is on
        if cfg.display:
            self._start_page(cfg)
        self.imu = None
        self.imu_error = None
        self._start_imu()

    # ---- start-up --------------------------------------------------------------------

    def _start_imu(self):
        cfg = self.cfg
        b = self.board
        try:
            self.imu = BMI055(
                b.spi,
                b.cs_accel,
                b.cs_gyro,
                gyro_range_dps=cfg.gyro_range_dps,
                accel_range_g=cfg.accel_range_g,
            )
            self.imu_error = None
            self._fields[_F_GYRO_LSB_X10] = self.imu.gyro_lsb_per_dps_x10
            self._fields[_F_ACCEL_LSB] = self.imu.accel_lsb_per_g
        except (Bmi055Error, OSError) as e:
            self.imu = None
            self.imu_error = str(e)
            self.console("IMU not ready: " + self.imu_error)

    def _start_page(self, cfg):
        if font_for(cfg.display_w, cfg.display_h) == 0:  # validate() keeps the sizes that fit
            return
        if not self.board.start_display(cfg.display_baud):
            self.console("display: this board has no UART for the screen (docs/display.md)")
            return
        b = self.board
        self.page = StatusPage(b.display, b.display_uart, cfg, self)
        self.console("display: status page on the screen's UART at " + str(cfg.display_baud))

    def start(self):
        """Timer, PPS interrupt, watchdog; automatic garbage collection off with the native
        kernels (a navigating tick allocates nothing; the app collects between ticks when the
        heap runs low, _heap_room). With the Python kernels every tick allocates, and a tick
        that needs more than the heap has left would raise MemoryError (automatic collection
        is the collector's only retry): it stays on there. The console line starting
        "ins: running" is what deploy tools wait for."""
        b = self.board
        if self.page is not None:
            self.page.start()  # the cleared page: the screen's demo loop starts after ~10 s
        self.console(
            "ins: running, frames on the RS485 UART at " + str(self.cfg.output_baud) + " baud"
        )
        # collected before the timer starts: a collection takes ~2 ticks on the board, and
        # after it the first two ticks overran (measured on the emulated STM32F411); the room
        # it leaves is counted here, while a heap scan delays no tick (_heap_room)
        gc.collect()
        self._heap_check()
        if self._native:
            gc.disable()
        b.on_pps(self.gnss.pps_isr)
        b.start_tick(self.isr_tick)
        b.start_watchdog()
        self._wdt = b.wdt

    def stop(self):
        """After Ctrl-C at the console: no more ticks or PPS interrupts, garbage collection
        back on, and the watchdog (which cannot be stopped once started) fed by a timer so the
        REPL stays usable. Not for writing the filesystem: a flash erase stalls the CPU, the
        timer with it, beyond the watchdog's 50 ms (the board tools reset the board into a
        maintenance start first: main.py). A soft reset (Ctrl-D) starts the firmware anew."""
        self.board.stop()
        gc.enable()
        self.console("ins: stopped (Ctrl-D restarts it)")

    def isr_tick(self, _timer):
        self.due += 1  # the ISR's only job

    # ---- per tick --------------------------------------------------------------------

    def run(self):
        """Forever: run each due tick, sleeping until the next interrupt between them (the
        board's idle: WFI on the board, so the CPU waits instead of spinning)."""
        idle = self.board.idle
        while True:
            self.service()
            idle(self)

    # Every method below that runs per tick keeps its frame within the VM's on-stack limit of
    # 11 words (locals, arguments and stack): a larger frame is allocated on the heap and freed
    # at every call (py/objfun.c), a search of the heap that costs thousands of instructions
    # depending on where the free blocks lie. tests/runtimes/test_frames.py checks them; so
    # the tick is split where its locals would not fit (and not elsewhere: a Python call costs
    # about a thousand instructions on the board).

    def service(self):
        """One pass of the loop: the tick, if one is due. Further ticks the timer signalled
        meanwhile are overruns (the board was busy): their IMU samples are lost, and the
        navigator steps through them on the last sample read (_catch_up), so that its clock,
        which fixes are stamped in, keeps the timer's."""
        if not self.due:
            return
        if self.due > 1:
            self._catch_up(self.due - 1)
        self.due = 0
        t0 = time.ticks_us()
        self.ticks += 1
        imu = self.imu
        if imu is None:
            if self.ticks % 200 == 0:
                self._start_imu()
            if self.page is not None and self.ticks % _PAGE_SLOT == _PAGE_PHASE:
                self.page.turn(self.ticks, -1)
            self.board.wdt_feed()
            return
        imu.read()
        if _mem_total is not None and self.nav.ctl[_C_STATE] != NAVIGATING:
            self._chk[_K_MEM0] = _mem_total() & 0x3FFFFFFF  # one that allocates none is quiet
        # an epoch the parser completed in an earlier tick to the navigator, then the GNSS
        # bytes that arrived into the parser: an epoch's parsing and its screening fall in two
        # ticks, so neither makes one long (_deliver_fix)
        if self.gnss.epoch_ready:
            self.gnss.epoch_ready = 0
            self._deliver_fix()
        n = self._gnss_uart.any()
        if n:
            n = self._gnss_read(n)
        self.rx_n = n
        self.nav.imu_counts(imu.gyro, imu.accel, imu.status)
        # the frame, the extended frame and the raw record when due; the watchdog
        state = self.nav.ctl[_C_STATE]
        cfg = self.cfg
        if self.ticks % cfg.output_every_ticks == 0:
            self._send_frame(imu, state)
        if cfg.ext_every_ticks and self.ticks % cfg.ext_every_ticks == 0:
            self._send_ext(imu)
        if cfg.raw_record:
            self._send_raw(imu, t0)
        if self.page is not None and self.ticks % _PAGE_SLOT == _PAGE_PHASE:
            self.page.turn(self.ticks, state)  # one field of the screen's page
        if self._wdt is not None:
            self._wdt.feed()
        # the tick's time for the extended frame's worst and mean (n reused: a twelfth word
        # would put the frame on the heap); with the Python kernels the heap is looked at
        n = time.ticks_diff(time.ticks_us(), t0)
        if n > self.t_worst_us:
            self.t_worst_us = n
        self.t_sum_us += n
        self._period_ticks += 1
        if not self._native:
            self._heap_low()
        elif state != NAVIGATING and _mem_total is not None:
            if _mem_total() & 0x3FFFFFFF == self._chk[_K_MEM0]:
                self._heap_ahead()

    def _catch_up(self, lost):
        """Ticks the loop missed: counted, and stepped by the navigator on the last sample
        read (theirs are gone: the registers hold only the newest), at most _CATCH_UP_MAX
        (the watchdog's timeout in ticks: a board busy longer has been reset)."""
        self.overruns += lost
        self.ticks += lost
        imu = self.imu
        if imu is None:
            return
        if lost > _CATCH_UP_MAX:
            lost = _CATCH_UP_MAX
        nav = self.nav
        st = imu.status | _IMU_REPEAT  # not a read: no evidence of a stuck IMU
        for _ in range(lost):
            nav.imu_counts(imu.gyro, imu.accel, st)

    def _heap_room(self):
        """The navigator's heap_check, before a step that allocates (the origin, the start of
        navigation, a track window, re-anchoring, a reset: Python floats, rare): the heap is
        looked at only when what was allocated since the last look, twice over, and one step
        more may reach the reserve (see _STEP_BYTES)."""
        if _mem_total is not None:
            used = (_mem_total() - self._heap_total) & 0x3FFFFFFF  # it wraps as a small int
            if self._heap_free - 2 * used - _STEP_BYTES >= _HEAP_RESERVE:
                return
        self._heap_check()

    def _heap_ahead(self):
        """In a quiet aligning tick (one that allocated nothing: no fix, no Python step),
        one stage of a look at the heap when the next step might need one (the estimate
        within two steps of the reserve): so that the alignment's steps (the first levelled
        fix, the start of navigation, heavy ticks of their own) find room by the estimate
        instead of scanning the heap themselves (a scan, 3.6 ms, made them late on the
        emulated STM32F411). A look; then, if it found what _heap_check collects at, a
        collection, and a look again, each in a quiet tick of its own: a collection comes
        no sooner than without the look ahead, in a tick that does nothing else. Not while
        navigating: no collection there (docs/requirements.md)."""
        chk = self._chk
        stage = chk[_K_AHEAD]
        if stage == 1:
            gc.collect()
            self.gc_runs += 1
            chk[_K_AHEAD] = 2
            return
        if stage == 0:
            used = (_mem_total() - self._heap_total) & 0x3FFFFFFF
            if not used or self._heap_free - 2 * used - 2 * _STEP_BYTES >= _HEAP_RESERVE:
                return
        free = gc.mem_free()
        self._heap_free = free
        self._heap_total = _mem_total()
        chk[_K_AHEAD] = 1 if stage == 0 and free < _HEAP_RESERVE + _STEP_BYTES else 0

    def _heap_check(self):
        """The heap's free bytes, collected when less than a step over the reserve is: a
        collection is the longest thing the loop does (milliseconds: ticks missed)."""
        self._chk[_K_AHEAD] = 0  # this look replaces the look ahead's
        free = gc.mem_free()
        if free < _HEAP_RESERVE + _STEP_BYTES:
            gc.collect()
            self.gc_runs += 1
            free = gc.mem_free()
        self._heap_free = free
        if _mem_total is not None:
            self._heap_total = _mem_total()

    def _heap_low(self):
        """At least _GC_LOW_WATER bytes of heap free (the Python kernels, every tick)."""
        if gc.mem_free() < _GC_LOW_WATER:
            gc.collect()
            self.gc_runs += 1

    def _send_raw(self, imu, t0):
        raw = self.raw
        f = raw.fields
        f[_RF_COUNTER] = self.counter
        f[_RF_T0_US] = t0
        f[_RF_PPS_US] = self.gnss.pps_us
        f[_RF_SATURATED] = 1 if imu.saturated else 0
        f[_RF_N] = self.rx_n
        raw.pack(imu.raw_gyro, imu.raw_accel, self.rx)
        self._out.write_n(raw.data, raw.length)

    def _gnss_read(self, n):
        """Up to _RX_LEN of the n bytes waiting on the GNSS UART into the parser; how many."""
        if n > _RX_LEN:
            n = _RX_LEN
        n = self._gnss_uart.readinto(self.rx, n) or 0
        self.gnss.feed(self.rx, n)
        return n

    def _deliver_fix(self):
        """A completed epoch (what the receiver sends for a second: gnss.py "Epochs"): the
        frame's fix fields, and the navigator's input. A no-fix epoch counts as lost; so does a
        fix with a physically impossible field (gnss.epoch_bad), which the navigator is told of
        by quality -1, and a late one (_fix_tick), shown in the frame but given to the
        navigator as no fix."""
        g = self.gnss
        n = g.rejected()  # sentences rejected since the last look: CAUSE_NMEA for a second
        k = self._chk
        if n != k[_K_NMEA_REJ]:
            k[_K_NMEA_REJ] = n
            k[_K_NMEA_BAD] = self.ticks + _SECOND_TICKS
        ok = g.epoch_pos_ok and g.epoch_quality > 0
        if ok and g.epoch_bad:
            self._fields[_F_VALID] = 0
            self._no_fix(self.nav.fix_in, -1)
        elif ok:
            self._fields[_F_VALID] = 1  # the frame's fix fields change only here
            self._fix_fields(g, self.nav.fix_in)
            if self.nav.fix_in[_FI_TICK] == _LATE:  # the receiver's fix, too old to use
                self._no_fix(self.nav.fix_in, 0)
        else:
            self._fields[_F_VALID] = 0
            self._no_fix(self.nav.fix_in, 0)
        self.nav.gnss_fix()

    def _no_fix(self, fi, quality):
        for i in range(_NFI):
            fi[i] = 0
        fi[_FI_QUALITY] = quality
        fi[_FI_HDOP_X100] = 9900
        fi[_FI_SPEED_MM_S] = -1
        fi[_FI_COURSE_CDEG] = -1
        fi[_FI_TICK] = -1

    def _fix_fields(self, g, fi):
        """The epoch's fix into the frame's fields and the navigator's fix_in. An epoch without
        speed (empty RMC/VTG fields, a GGA-only receiver) passes speed -1 and course -1:
        unknown, unlike a standing receiver's speed 0.00 with an empty course. An epoch without
        height (an RMC's fix, a GGA with an empty altitude) carries the last height the
        receiver gave (a GGA-and-RMC-in-alternate-seconds receiver: a second old), not 0;
        until a receiver gives one (RMC only: never), the frame shows height 0 and the
        navigator gets _FI_NO_HEIGHT: east and north alone (docs/gnss.md)."""
        ff = self._fields
        # geo.split_into and frame.round_div written out: a Python call less for each
        v = g.epoch_lat_e7
        fi[_FI_LAT_E7] = v
        d = v // _E7 if v >= 0 else -((-v) // _E7)
        ff[_F_LAT_DEG] = d
        ff[_F_LAT_FRAC] = v - d * _E7
        v = g.epoch_lon_deg
        ff[_F_LON_DEG] = v
        fi[_FI_LON_DEG] = v
        v = g.epoch_lon_frac_e7
        ff[_F_LON_FRAC] = v
        fi[_FI_LON_FRAC] = v
        k = self._chk
        if g.epoch_alt_ok:
            k[_K_MSL_MM] = g.epoch_alt_mm
            k[_K_H_MM] = g.epoch_alt_mm + (g.epoch_sep_mm if g.epoch_sep_ok else 0)
        v = k[_K_MSL_MM]
        # the frame carries the GGA altitude, in dm rounded half away from zero
        d = (2 * v + 100) // 200 if v >= 0 else -((100 - 2 * v) // 200)
        ff[_F_HEIGHT_DM] = d
        fi[_FI_ALT_MM] = k[_K_H_MM]  # ellipsoidal
        fi[_FI_QUALITY] = g.epoch_quality
        fi[_FI_HDOP_X100] = g.epoch_hdop_x100  # < 0: unknown, the worst accepted
        fi[_FI_SPEED_MM_S] = g.epoch_speed_mm_s  # < 0: unknown
        fi[_FI_COURSE_CDEG] = g.epoch_course_cdeg if g.epoch_speed_mm_s >= 0 else -1
        fi[_FI_TICK] = self._fix_tick(g.epoch_pps_us, g.epoch_utc_ms)

    def _fix_tick(self, pps_us, utc_ms):
        """The fix's measurement tick: the PPS edge's plus the epoch's offset into its second
        (a 5 or 10 Hz receiver's epochs at .2, .4 ... s share their second's edge), when the
        fix's moment came less than a second before its epoch's first sentence and the edge
        belongs to the epoch's second; _LATE when it belongs to a later one (_late_s), else
        -1 (the navigator applies the configured latency); CAUSE_PPS for a second when there
        is no edge though edges came before (a missing edge)."""
        age_us = time.ticks_diff(time.ticks_us(), pps_us)
        if utc_ms > 0:
            age_us -= utc_ms % 1000 * 1000  # from the fix's own moment, not its second's
        if pps_us and 0 <= age_us < 1000000:
            if self._late_s(pps_us, utc_ms // 1000) > 0:
                return _LATE
            return self.nav.ctl[_C_TICK] - age_us // _US_PER_TICK
        if self._chk[_K_PPS_LAST]:
            self._chk[_K_PPS_BAD] = self.ticks + _SECOND_TICKS
        return -1

    def _late_s(self, p_us, s):
        """Whole seconds by which edge p_us is later than the epoch's UTC second s (of the
        day; < 0: unknown): the edges are counted from the reference, the edge of the last
        on-time epoch (a receiver whose bytes come 1.4 s late would otherwise have its fixes
        stamped a second late). 0 makes p_us the reference; so does a first epoch or an old
        reference. An edge off the whole seconds (spurious) is not counted.
        A lateness that begins while every edge has had its epoch (_K_EDGES_OK: the bytes
        come on time), or of 2 s or more (bytes that late would be a backlog growing without
        end), is the receiver's clock that stepped back (GPS time to UTC at a cold start, a
        leap second, a reset), not late bytes: after _STEP_EPOCHS epochs in a row with it,
        their edge becomes the reference; a 1 s lateness that begins at a missed edge stays
        late (CAUSE_GNSS_LATE). A clock that steps forward (the count comes out negative)
        re-references at once. Both say CAUSE_GNSS_CLOCK. Few locals: the frame stays on the
        C stack (tests/runtimes/test_frames.py)."""
        if s < 0:
            return 0
        k = self._chk
        if k[_K_EDGE_S] >= 0:
            d = time.ticks_diff(p_us, k[_K_EDGE_US]) + 500000  # rounds to whole seconds below
            if -_EDGE_REF_MAX_US < d < _EDGE_REF_MAX_US:
                if d % 1000000 < 500000 - _PPS_TOL_US or d % 1000000 > 500000 + _PPS_TOL_US:
                    return 0  # a spurious edge, off the seconds (CAUSE_PPS): no count
                d = (k[_K_EDGE_S] + d // 1000000 - s) % _DAY_S
                if 0 < d < _DAY_S // 2:
                    if d != k[_K_STEP_S]:  # a new lateness: a step if the edges had epochs
                        k[_K_STEP_S] = d
                        k[_K_STEP_N] = 0 if k[_K_EDGES_OK] >= _OVERDUE_EDGES or d > 1 else -1
                    if k[_K_STEP_N] < 0:
                        k[_K_LATE_BAD] = self.ticks + _SECOND_TICKS
                        return d
                    k[_K_STEP_BAD] = self.ticks + _SECOND_TICKS
                    k[_K_STEP_N] += 1
                    if k[_K_STEP_N] < _STEP_EPOCHS:
                        return d
                elif d:
                    k[_K_STEP_BAD] = self.ticks + _SECOND_TICKS
        k[_K_EDGE_US] = p_us
        k[_K_EDGE_S] = s
        k[_K_STEP_S] = 0
        return 0

    def _send_frame(self, imu, state):
        fi = self._fields
        g = self.gnss
        fi[_F_COUNTER] = self.counter
        if g.pps_flag:  # read and cleared here (gnss.py: pps_flag_take)
            g.pps_flag = 0
            fi[_F_PPS] = 1
            self._pps_seen()
        else:
            fi[_F_PPS] = 0
        fi[_F_GGA] = g.gga_seen
        g.gga_seen = 0
        fi[_F_STATE] = state
        nav_frame(self.out, fi, imu.gyro, imu.accel, self.nav.mem)
        self.counter = (self.counter + 1) & 0xFF
        self._out.write(self.out)
        if (state == NAVIGATING) != self._led:
            self._led = state == NAVIGATING
            self.board.navigating_led(self._led)

    def _send_ext(self, imu):
        """The extended frame: health, timing, covariance, biases, position and origin."""
        t = self.ticks
        k = self._chk
        if t >= k[_K_OVERDUE]:  # no epoch yet after the last edge? (_pps_seen)
            k[_K_OVERDUE] = _NEVER
            if self.gnss.epoch_pps_us != k[_K_PPS_LAST]:  # none: a late receiver
                k[_K_LATE_BAD] = t + _SECOND_TICKS
                k[_K_EDGES_OK] = 0
        causes = k[_K_CAUSES]  # the app's own, each a warning (running on defaults among them)
        if t < k[_K_NMEA_BAD]:
            causes |= CAUSE_NMEA
        if t < k[_K_PPS_BAD]:
            causes |= CAUSE_PPS
        if t < k[_K_LATE_BAD]:
            causes |= CAUSE_GNSS_LATE
        if t < k[_K_STEP_BAD]:
            causes |= CAUSE_GNSS_CLOCK
        if self.overruns != self._ext_overruns:
            self._ext_overruns = self.overruns
            causes |= CAUSE_OVERRUN
        if self.page is not None and t < self.page.bad_until:
            causes |= CAUSE_DISPLAY
        k = self.nav.ctl  # (k reused: a twelfth word would put the frame on the heap)
        t = k[_C_HEALTH]  # ... and t: the health
        if causes and t == 0:
            t = 1
        fi = self.ext.fields
        fi[_EF_HEALTH] = t
        fi[_EF_CAUSES] = causes | k[_C_CAUSES]
        fi[_EF_COUNTER] = self.counter
        fi[_EF_STATE] = k[_C_STATE]
        fi[_EF_FLAGS] = (
            self._fields[_F_VALID] | (2 if k[_C_STILL] else 0) | (4 if imu.saturated else 0)
        )
        fi[_EF_WORST_US] = self.t_worst_us
        fi[_EF_MEAN_US] = self.t_sum_us // self._period_ticks if self._period_ticks else 0
        fi[_EF_OVERRUNS] = self.overruns & 0xFFFF
        fi[_EF_GC_RUNS] = self.gc_runs & 0xFFFF
        fi[_EF_TICK] = k[_C_TICK] & 0x3FFFFFFF
        self._send_ext_state(fi)

    def _pps_seen(self):
        """A PPS edge (its frame tick; the checks are here, not every tick: they cost).
        CAUSE_PPS for a second if it is not a whole number of seconds after the last one (a
        spurious edge); CAUSE_NMEA for a second if a sentence was rejected since the last
        edge (or epoch: _deliver_fix). After _OVERDUE_EDGES regular edges in a row that each
        had an epoch (one whose first sentence came after it), the next epoch is due within
        _OVERDUE_TICKS: _send_ext says CAUSE_GNSS_LATE if it has not come by then (a late
        receiver, told before its late epoch comes: _late_s); a receiver that sends less
        often than once a second never has that run."""
        g = self.gnss
        p = g.pps_us
        k = self._chk
        if g.epoch_pps_us == k[_K_PPS_LAST]:
            k[_K_EDGES_OK] += 1
        else:
            k[_K_EDGES_OK] = 0
        if k[_K_PPS_LAST]:
            d = (time.ticks_diff(p, k[_K_PPS_LAST]) + 500000) % 1000000
            if d < 500000 - _PPS_TOL_US or d > 500000 + _PPS_TOL_US:
                k[_K_PPS_BAD] = self.ticks + _SECOND_TICKS
                k[_K_EDGES_OK] = 0
        k[_K_PPS_LAST] = p
        k[_K_OVERDUE] = self.ticks + _OVERDUE_TICKS if k[_K_EDGES_OK] >= _OVERDUE_EDGES else _NEVER
        p = g.rejected()  # (p reused: a twelfth word would put the frame on the heap)
        if p != k[_K_NMEA_REJ]:
            k[_K_NMEA_REJ] = p
            k[_K_NMEA_BAD] = self.ticks + _SECOND_TICKS

    def _send_ext_state(self, fi):
        """The extended frame's origin, covariance and state, packed and sent."""
        nav = self.nav
        fr = nav.frame
        fi[_EF_LAT0_E7] = fr.lat0_e7
        fi[_EF_LON0_DEG] = fr.lon0_deg
        fi[_EF_LON0_FRAC] = fr.lon0_frac
        # the kernel itself, not ExtFrame.pack: a Python call less (its module attribute
        # through a global: records.ext_pack's method form takes a word more of the frame)
        _ext_pack(self.ext.data, fi, nav.kf.P, nav.ins.x, fr.coef, nav.cv)
        self._out.write(self.ext.data)
        self.t_sum_us = 0
        self._period_ticks = 0
