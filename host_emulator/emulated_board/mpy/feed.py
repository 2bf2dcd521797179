"""The feed loop: the unmodified firmware fed from a stimulus, the one way every runtime feeds
it: emulate.py (the MicroPython unix VM, mpy_unix runtime, both its modes), emulate_m4f.py
(the emulated Cortex-M4F, m4f runtime) and runtimes/cpython.py (on CPython, which loads this
file as `feed` with the emulated board: host_emulator.emulated_board.install_machine). Plain
MicroPython on the emulated `machine` and `time` beside it.

Per stimulus record k (common/proto/stimulus.py; the host has checked the CRC), in `ticks`:
the BMI055 data and temperature registers take the record's bytes, the GNSS UART receives its
bytes (`next_input`); then the runtime runs the tick, `run_tick`: the clock moves to
t_k - pps_before_us and the PPS pin fires (if the record has an edge), the clock moves to t_k,
the timer fires (`fire_inputs`), and unless the board is stalled (`stalled`) the loop makes
one pass, `app.service()`. t_k = t0 + k * tick_us (virtual us since power-on), t0 =
`first_tick_us(tick_us)`, the first multiple of tick_us at or after the clock when start-up
ended. Each runtime keeps what it measures around that (GC blocks, output, progress).
emulate_m4f.py writes the loop out, the same calls in the same order: `ticks`' generator
would come out of the board's heap there (the firmware gets exactly the board's), and
run_tick's own call and return would count as the firmware's instructions between its
counters.

Reports on stdout, one line each, parsed by host_emulator/runtimes/guest_output.py:
    C <text>        a line the firmware printed on its console
    P <k> <n>       progress: k of n ticks done
    E <k>           the firmware raised at tick k (-1: at start-up); the traceback follows
                    (sys.print_exception), then a line "E-END"; the driver then exits with 3
    S <json>        statistics at the end
"""

import gc
import sys
import time  # emulated_board/mpy/time.py
from array import array

from feed_protocol import (  # common/proto/mpy: the record, as the host writes it
    EXIT_FIRMWARE_ERROR,
    FLAG_IMU_SILENT,
    FLAG_PPS,
    FLAG_STALL,
    REC_ACCEL,
    REC_FLAGS,
    REC_GYRO,
    REC_LEN,
    REC_N,
    REC_PPS_BEFORE_US,
    REC_TEMP,
)

import machine  # emulated_board/mpy/machine.py

PROGRESS_EVERY = 1000  # ticks between progress lines

# MicroPython's count of the bytes asked for (micropython.mem_total), which the firmware reads
# to know when to look at its heap (app.py, _heap_room): on a board it counts the firmware's
# allocations only, here the emulator's too. So the firmware is given the count without the
# emulator's bytes: those between its windows (`window_start`/`window_end` around each tick's
# interrupts and loop pass, outside any counted instructions) and, on the emulated Cortex-M4F,
# those of the emulated peripherals inside them (m4f.emu_alloc). _ALLOC: the emulator's bytes
# between windows so far, and at the last window's end the count and emu_alloc (all wrap at
# 2**30).
try:
    from micropython import mem_total as _mem_total
except ImportError:
    _mem_total = None
try:
    from m4f import emu_alloc as _emu_alloc
except ImportError:  # not the m4f runtime: the emulated peripherals count as the firmware

    def _emu_alloc():
        return 0


# made from a bytes constant: a tuple's iterator would leave a hole of garbage in the heap that
# the M4F's ballast (emulate_m4f.py), which gives the firmware the board's free heap, cannot fill
_ALLOC = array("i", b"\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00")


def window_start():
    if _mem_total is not None:
        between = (_mem_total() - _ALLOC[1]) - (_emu_alloc() - _ALLOC[2])
        _ALLOC[0] = (_ALLOC[0] + between) & 0x3FFFFFFF


def window_end():
    if _mem_total is not None:
        _ALLOC[1] = _mem_total()
        _ALLOC[2] = _emu_alloc()


def firmware_mem_total():
    """micropython.mem_total as the board would count it: the firmware's bytes only."""
    return (_mem_total() - _ALLOC[0] - _emu_alloc()) & 0x3FFFFFFF


def console(msg):
    """The firmware's console: one "C" line per line of text (no allocation for one line)."""
    if "\n" in msg:
        for line in msg.split("\n"):
            print("C", line)
    else:
        print("C", msg)


def firmware_error(k, e, exit=sys.exit):
    """Report an exception the firmware raised (at tick k, -1 at start-up) and exit."""
    print("E", k)
    sys.print_exception(e, sys.stdout)
    print("E-END")
    exit(EXIT_FIRMWARE_ERROR)


def read_exact(f, buf, n, what):
    """n bytes into buf from f (anything with readinto(buf, n)); EOFError if fewer came."""
    got = f.readinto(buf, n) if n else 0
    if got != n:
        raise EOFError("stimulus file cut short in " + what)


def start_firmware(imu, config_path, exit=sys.exit, compiles=False):
    """The firmware's start-up: its modules, the App (configuration, BMI055 init), start().
    Returns (app, board pins); an exception is reported (firmware_error) and ends the run.
    compiles: the VM compiles the firmware's modules into its heap (the unix port; the M4F's
    are frozen, as the board's): room is made for that first (below)."""
    try:
        import board

        board.CONFIG_PATH = config_path
        pins = board.PINS
        if compiles:
            # the UARTs' transmit buffers (machine.TX_CAPACITY each) before the modules, and
            # the garbage collected where nothing else holds on to it: compiling app's modules
            # (nav.py's 1,400 lines) with only the collector's automatic run, in the middle of
            # the compiler, raised MemoryError in a 512 KB heap with 400 KB free
            for key in ("gnss_uart", "out_uart", "display_uart"):
                if pins.get(key) is not None:
                    machine.uart(pins[key])
            gc.collect()
        imu.attach(
            machine.spi_bus(pins["spi_id"]),
            machine.pin(pins["cs_accel"]),
            machine.pin(pins["cs_gyro"]),
        )
        import app

        if _mem_total is not None and getattr(app, "_mem_total", None) is not None:
            app._mem_total = firmware_mem_total
        window_start()  # what came before was the emulator's; the start-up is the firmware's
        a = app.App(board, console=console)
        a.start()
        window_end()
    except Exception as e:  # noqa: BLE001  (reported with its traceback, then exit)
        firmware_error(-1, e, exit)
    return a, pins


def first_tick_us(tick_us):
    """t0: the first multiple of tick_us at or after the clock (start-up has ended)."""
    return (time.now_us() + tick_us - 1) // tick_us * tick_us


def next_input(f, rec, ubuf, imu, gnss):
    """The next record into the BMI055 registers and the GNSS UART; returns the UART byte
    buffer (grown when a record carries more)."""
    read_exact(f, rec, REC_LEN, "a record")
    answers = not rec[REC_FLAGS] & FLAG_IMU_SILENT
    imu.accel.responds = answers
    imu.gyro.responds = answers
    imu.set_registers(rec, REC_GYRO, REC_ACCEL)
    t = rec[REC_TEMP]
    imu.set_temperature_raw(t - 256 if t >= 128 else t)
    n = rec[REC_N] | (rec[REC_N + 1] << 8)
    if n:
        if n > len(ubuf):
            ubuf = bytearray(n)
        read_exact(f, ubuf, n, "UART bytes")
        gnss.feed(ubuf, n)
    return ubuf


def ticks(f, n_ticks, imu, gnss, rec, ubuf):
    """The feed loop: for k in range(n_ticks), the next record of f (positioned at the first
    record; anything with readinto(buf, n)) into rec, the BMI055's registers and the GNSS UART
    (next_input, through the byte buffer ubuf, replaced by a larger one if a record carries
    more); yields k, for the runtime to run the tick (run_tick). Resuming allocates nothing."""
    for k in range(n_ticks):
        ubuf = next_input(f, rec, ubuf, imu, gnss)
        yield k


def run_tick(a, rec, t_k, pps, at=None):
    """One tick of the board: the record's interrupts at t_k (fire_inputs; at(t_k) once the
    clock reads t_k, before the timer fires), then one pass of the app's loop unless the
    board is stalled over it."""
    window_start()
    fire_inputs(rec, t_k, pps, at)
    if not rec[REC_FLAGS] & FLAG_STALL:  # stalled(rec), written out: every tick
        a.service()
    window_end()


def stalled(rec):
    """True if the board is busy over this record's tick (an injected stall): the interrupt
    handlers run (fire_inputs), the loop does not."""
    return rec[REC_FLAGS] & FLAG_STALL


def fire_inputs(rec, t_k, pps, at=None):
    """The record's PPS edge (never back in time: an edge during start-up), then the clock to
    t_k (and at(t_k): what else reaches the board then, e.g. the screen's answers) and the
    tick timer: the firmware's interrupt handlers run."""
    if rec[REC_FLAGS] & FLAG_PPS:
        edge = t_k - (rec[REC_PPS_BEFORE_US] | (rec[REC_PPS_BEFORE_US + 1] << 8))
        if edge > time.now_us():
            time.set_us(edge)
        pps.fire()
    time.set_us(t_k)
    if at is not None:
        at(t_k)
    machine.fire_timers()


def display_uart(a, pins):
    """The screen's emulated UART (board.PINS["display_uart"]) when the firmware made its
    status page (`app.page`, the display setting on), else None. The drivers take what it
    transmitted after start-up and after every tick, and empty it."""
    if getattr(a, "page", None) is None:
        return None
    return machine.uart(pins["display_uart"])


def bytes_per_block():
    """Bytes of one GC block: what boxing one float allocates (as runtimes/mpy_unix/vm.py
    measures it)."""
    a = array("f", bytes(4))
    gc.collect()
    gc.disable()
    m0 = gc.mem_alloc()
    x = a[0]
    m1 = gc.mem_alloc()
    gc.enable()
    del x
    return m1 - m0


def app_stats(a, n_ticks, t0, pins):
    """The run's counters every runtime reports (the drivers in their "S" line): the
    firmware's own and the emulated board's; with the status page, its batches, OKs and
    misses, and the bytes its UART's transmit buffer dropped."""
    wdt = machine.watchdog
    out_uart = machine.uart(pins["out_uart"])
    stats = {
        "ticks": n_ticks,
        "t0_us": t0,
        "overruns": a.overruns,
        "gnss_rx_overflow": machine.uart(pins["gnss_uart"]).overflow,
        "nmea_rejected": a.gnss.rejected(),
        "wdt_feeds": wdt.feeds if wdt else 0,
        "imu_error": a.imu_error,
        "config_status": a.config_status,
        "app_gc_runs": a.gc_runs,
        "nav_resets": a.nav.resets,
        "tx_overflow": out_uart.tx_overflow,
    }
    disp = display_uart(a, pins)
    if disp is not None:  # the status page's counters (no screen answers: no OKs)
        stats["display_batches"] = a.page.batches
        stats["display_oks"] = a.page.oks
        stats["display_missed"] = a.page.missed
        stats["display_tx_overflow"] = disp.tx_overflow
    return stats
