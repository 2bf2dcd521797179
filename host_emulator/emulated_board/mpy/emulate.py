"""Run the unmodified firmware loop inside the MicroPython VM, fed from a stimulus file, and
count the GC blocks every tick allocates. Started by host_emulator/runtimes/mpy_unix:

    micropython emulate.py FIRMWARE_DIR STIMULUS CONFIG OUT_DIR

sys.path: this directory first (the VM puts the script's directory there), so `machine` and
`time` are the emulated ones beside this file; then FIRMWARE_DIR/lib and FIRMWARE_DIR, the
board's layout. board.CONFIG_PATH = CONFIG, then `app.App(board, console=...)`, `start()`.

Each stimulus record is fed by feed.py's loop (beside this file), the one every runtime runs.

Counting: the collector is off (the app turns it off in start()); gc.mem_alloc() is read just
before and after service(), and the difference in GC blocks (bytes / bytes per block,
measured like the `_bytes_per_block` of runtimes/mpy_unix/vm.py: one boxed float) is the
tick's count. Garbage is collected between ticks, outside that window, whenever the free
heap gets below a margin of several worst ticks, so the app's own low-water collection
(12 KB) never runs during a tick (its gc_runs counter is reported to prove it).

Output (OUT_DIR): out.bin (the output UART's bytes), blocks.bin (int32 LE per tick: GC
blocks of the tick), state.bin (u8 per tick: the navigation state after it), display.bin and
display_n.bin (the screen's UART, when the firmware made its status page, `app.page`: after
start-up and after every tick the driver takes what the firmware wrote to the display UART,
board.PINS["display_uart"], appends it to display.bin and empties the UART's transmit buffer;
display_n.bin has u16 LE per tick, the bytes that tick wrote, and what start-up wrote is the
rest of display.bin; both files are empty with the page off). No screen answers: the UART
receives no `OK`, so the page takes the screen as absent (docs/display.md). Stdout lines:
    C <text>        a line the firmware printed on its console
    P <k> <n>       progress: k of n ticks done
    E <k>           the firmware raised at tick k (-1: at start-up); the VM's traceback
                    follows (sys.print_exception), then a line "E-END"; exit status 3
    S <json>        statistics at the end (exit status 0)

Streaming mode (host_emulator/virtual_board): with the environment variable
INS_VM_STREAM=realtime (paced at the tick rate by the VM's own clock) or INS_VM_STREAM=fast
(as fast as possible), OUT_DIR is ignored and nothing is counted: each tick's output UART bytes
go to stdout as a line "O <hex>", console lines as "C <text>" as above, errors as "E"; the run
ends with a line "X ended" (the stimulus is used up) or "X stopped" (SIGINT, i.e. Ctrl-C at the
virtual board's console: the App is stopped as after a KeyboardInterrupt on the board). What
the status page writes to the display UART goes out as a line "D <hex>" after each tick (the
start page with the first tick's); no OK comes back. With INS_VM_BACKUP (the virtual board's
backup-domain file, backup_domain.py), the firmware's start is main.py's: first its
maintenance check (backup_domain.maintenance_start: board.maintenance_start on that file's
registers); a maintenance start prints its line and ends the run with "X maintenance", as
main.py returns to the REPL.
"""

import gc
import json
import os
import struct
import sys
import time  # emulated_board/mpy/time.py: this directory is sys.path[0]
from array import array

from feed import (
    PROGRESS_EVERY,
    app_stats,
    bytes_per_block,
    display_uart,
    firmware_error,
    first_tick_us,
    run_tick,
    start_firmware,
    ticks,
)
from feed_protocol import MAGIC, REC_LEN  # common/proto/mpy

import machine  # emulated_board/mpy/machine.py

if len(sys.argv) != 5:
    print("usage: micropython emulate.py FIRMWARE_DIR STIMULUS CONFIG OUT_DIR")
    sys.exit(2)
FIRMWARE_DIR = sys.argv[1]
STIM_PATH = sys.argv[2]
CONFIG_PATH = sys.argv[3]
OUT_DIR = sys.argv[4]
sys.path.insert(1, FIRMWARE_DIR + "/lib")  # the firmware's modules, after this directory
sys.path.insert(2, FIRMWARE_DIR)

if not hasattr(time, "now_us") or not hasattr(machine, "fire_timers"):
    print("emulate.py: the built-in time/machine modules shadow the emulated ones")
    sys.exit(2)

CHUNK = 2000  # ticks per write of the per-tick arrays
MARGIN0 = 65536  # free heap bytes to keep before a tick, at least
OUT_FLUSH = 8192  # write the output UART's bytes to the file beyond this many


def open_stimulus():
    """(the stimulus file at its first record, tick_us, number of ticks)."""
    f = open(STIM_PATH, "rb")
    if f.read(8) != MAGIC:
        raise ValueError("not a stimulus file: " + STIM_PATH)
    hlen = struct.unpack("<I", f.read(4))[0]
    header = json.loads(f.read(hlen))
    size = f.seek(0, 2)
    f.seek(size - 8)
    n_ticks = struct.unpack("<I", f.read(4))[0]
    f.seek(12 + hlen)
    return f, header.get("tick_us", 5000), n_ticks


class Outputs:
    """The run's output files (the module docstring's list), written a chunk of ticks at a
    time from arrays made once, so that keeping the record allocates nothing per tick."""

    def __init__(self, disp):
        self.fo = open(OUT_DIR + "/out.bin", "wb")
        self.fb = open(OUT_DIR + "/blocks.bin", "wb")
        self.fs = open(OUT_DIR + "/state.bin", "wb")
        self.fd = open(OUT_DIR + "/display.bin", "wb")
        self.fdn = open(OUT_DIR + "/display_n.bin", "wb")
        self.blocks = array("i", bytes(4 * CHUNK))
        self.state = bytearray(CHUNK)
        self.disp = disp  # the screen's UART, None with the status page off
        self.disp_n = array("H", bytes(2 * CHUNK))
        self.j = 0
        self.disp_start = 0
        if disp is not None and disp.tx_n:  # the start page
            self.disp_start = disp.tx_n
            self.fd.write(disp.tx, disp.tx_n)
            disp.tx_clear()

    def tick(self, blocks, state, out_uart):
        """The tick's GC blocks and navigation state, what it sent to the screen; the output
        UART's bytes once there are OUT_FLUSH of them."""
        j = self.j
        self.blocks[j] = blocks
        self.state[j] = state
        self.disp_n[j] = 0
        disp = self.disp
        if disp is not None and disp.tx_n:
            self.disp_n[j] = disp.tx_n
            self.fd.write(disp.tx, disp.tx_n)
            disp.tx_clear()
        self.j = j + 1
        if self.j == CHUNK:
            self.flush()
        if out_uart.tx_n >= OUT_FLUSH:
            self.output(out_uart)

    def flush(self):
        j = self.j
        if j:
            self.fb.write(self.blocks, 4 * j)
            self.fs.write(self.state, j)
            if self.disp is not None:
                self.fdn.write(self.disp_n, 2 * j)
        self.j = 0

    def output(self, out_uart):
        self.fo.write(out_uart.tx, out_uart.tx_n)
        out_uart.tx_clear()

    def close(self, out_uart):
        self.flush()
        self.output(out_uart)
        for f in (self.fo, self.fb, self.fs, self.fd, self.fdn):
            f.close()


def main():
    bpb = bytes_per_block()
    f, tick_us, n_ticks = open_stimulus()
    rec = bytearray(REC_LEN)
    imu = machine.Bmi055()
    a, pins = start_firmware(imu, CONFIG_PATH, compiles=True)
    gc.disable()
    gnss = machine.uart(pins["gnss_uart"])
    out_uart = machine.uart(pins["out_uart"])
    pps = machine.pin(pins["pps"])
    outs = Outputs(display_uart(a, pins))
    nav = a.nav
    t0 = first_tick_us(tick_us)
    gc.collect()
    live = gc.mem_alloc()  # bytes in use after start-up (firmware bytecode, buffers)
    total = gc.mem_free() + live  # heap bytes
    worst = 0  # most bytes one tick allocated so far
    margin = MARGIN0  # collect when less than this is free (grows with the worst tick)
    m1 = gc.mem_alloc()
    collects = 0
    negative = 0  # ticks whose count went down (a collection inside the tick)
    for k in ticks(f, n_ticks, imu, gnss, rec, bytearray(2048)):
        if total - m1 < margin:  # free heap (m1: after the last tick; little since)
            gc.collect()
            collects += 1
        try:  # the firmware's code: its interrupt handlers and one pass of its loop
            m0 = gc.mem_alloc()
            run_tick(a, rec, t0 + k * tick_us, pps)
            m1 = gc.mem_alloc()
        except Exception as e:  # noqa: BLE001  (reported with its traceback, then exit)
            outs.output(out_uart)
            outs.fo.close()
            firmware_error(k, e)
        d = m1 - m0
        if d > worst:
            worst = d
            if 4 * d + 16384 > margin:  # the app collects below 12 KB free
                margin = 4 * d + 16384
        if d < 0:
            negative += 1
        outs.tick(d // bpb, nav.state, out_uart)
        if (k + 1) % PROGRESS_EVERY == 0:
            print("P", k + 1, n_ticks)
    outs.close(out_uart)
    f.close()
    if n_ticks % PROGRESS_EVERY or not n_ticks:
        print("P", n_ticks, n_ticks)
    stats = app_stats(a, n_ticks, t0, pins)
    stats.update(
        {
            "display_start_bytes": outs.disp_start,
            "gc_collects": collects,
            "negative_ticks": negative,
            "bytes_per_block": bpb,
            "heap_bytes": total,
            "live_bytes_at_start": live,
            "spi_bytes": machine.spi_bus(pins["spi_id"]).bytes_clocked,
        }
    )
    print("S", json.dumps(stats))


STREAM_LOW_BYTES = 32 * 1024  # stream_main collects between ticks below this much free heap


def stream_main(realtime):
    """The streaming mode (see the module docstring): the same replay, output as it happens."""
    import binascii

    import utime  # the VM's real clock (`time` is the emulated one)

    f, tick_us, n_ticks = open_stimulus()
    rec = bytearray(REC_LEN)
    imu = machine.Bmi055()
    a = None
    k = -1
    try:
        backup = os.getenv("INS_VM_BACKUP")
        if backup:
            import backup_domain

            if backup_domain.maintenance_start(backup):
                print("X maintenance")
                f.close()
                return
        a, pins = start_firmware(imu, CONFIG_PATH, compiles=True)
        gnss = machine.uart(pins["gnss_uart"])
        out_uart = machine.uart(pins["out_uart"])
        pps = machine.pin(pins["pps"])
        disp = display_uart(a, pins)
        t0 = first_tick_us(tick_us)
        wall0 = utime.ticks_us()
        for k in ticks(f, n_ticks, imu, gnss, rec, bytearray(2048)):
            try:
                run_tick(a, rec, t0 + k * tick_us, pps)
            except Exception as e:  # noqa: BLE001
                firmware_error(k, e)
            if out_uart.tx_n:
                print("O", binascii.hexlify(memoryview(out_uart.tx)[: out_uart.tx_n]).decode())
                out_uart.tx_clear()
            if disp is not None and disp.tx_n:  # what the status page sent to the screen
                print("D", binascii.hexlify(memoryview(disp.tx)[: disp.tx_n]).decode())
                disp.tx_clear()
            # this driver's garbage (the lines above) is its own to collect, between ticks:
            # the app, with automatic collection off, collects only for what it allocates
            if gc.mem_free() < STREAM_LOW_BYTES:
                gc.collect()
            if realtime:
                ahead = (k + 1) * tick_us - utime.ticks_diff(utime.ticks_us(), wall0)
                if ahead > 0:
                    utime.sleep_us(ahead)
        print("X ended")
    except KeyboardInterrupt:
        if a is not None and hasattr(a, "stop"):
            try:
                a.stop()
            except Exception as e:  # noqa: BLE001
                firmware_error(k, e)
        else:
            print("C ins: stopped (Ctrl-D restarts it)")
        print("X stopped")
    f.close()


_stream = os.getenv("INS_VM_STREAM")
if _stream:
    stream_main(_stream == "realtime")
else:
    main()
