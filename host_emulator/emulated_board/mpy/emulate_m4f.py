"""The guest side of the m4f runtime: the unmodified firmware loop on the emulated Cortex-M4F
(MicroPython built for QEMU's mps2-an386 with the board's float32 arithmetic; see
host_emulator/runtimes/m4f), fed from a stimulus file, counting the instructions of every tick.

Frozen into that build with the firmware, machine.py, bmi055_model.py, time.py and feed.py;
the host starts it through the raw REPL:

    import emulate_m4f; emulate_m4f.main(STIM, OFFSET, N_TICKS, TICK_US, CONFIG, OUT_DIR,
                                         BOARD_HEAP, BUILD_HEAP[, NAVK[, SETUP]])

Host files go through ARM semihosting (the `m4f` module): the stimulus is read from byte
OFFSET (its first record) of STIM, the configuration CONFIG is copied to /flash/ins.cfg on a
FAT RAM disk as on the board, the output goes to OUT_DIR. With a 9th argument NAVK (a host
path), the native kernels' navk.mpy goes to /flash/lib as on the board (docs/native.md); without
it the firmware runs its Python kernels.

The heap the firmware gets is the board's. BOARD_HEAP is the board image's heap region and
BUILD_HEAP this build's (MICROPY_HEAP_SIZE: the board's plus a reserve for the emulated
peripherals and the driver). What the board has free when the firmware starts is its region's
usable bytes (the GC's tables take their share) less what MicroPython itself holds by then
(start-up objects, /flash's FAT object; measured here, before the emulator's objects exist);
a ballast takes what the reserve leaves over beyond that, so the firmware starts with the
board's free heap. The app collects garbage itself (firmware/app.py's low-water rule), as on
the board.

Counting, per tick k (fire_inputs + app.service(), the board's interrupt handlers and one pass
of its loop): the instructions executed (m4f.icount, 40-instruction resolution), those spent in
the emulated peripherals (m4f.emu_total: machine.py and time.py bracket themselves), the bytes
the tick allocated (gc.mem_alloc after - before; a tick that collected shows what was freed)
and whether the app collected (its gc_runs counter). Nothing the driver does between ticks
allocates (checked: `driver_alloc_bytes` must be 0), so the heap the app sees is its own.

Output (OUT_DIR): out.bin (the output UART's bytes), display.bin (the screen's UART's) and
ticks.bin, per tick 16 bytes: instructions i32, emulation instructions i32, allocated bytes
i32, navigation state u8, collected u8, display bytes u16. Stdout lines as feed.py says; S
lines carry the run's statistics, one each; a driver that raises ends QEMU with status 4.

The screen: when the firmware made its status page (`app.page`, the display setting on), the
driver takes what it wrote to the display UART (board.PINS["display_uart"]) after start-up and
after every tick, outside the counted window: appended to display.bin, its count in the tick's
record (start-up's is S's display_start_bytes), and the UART's transmit buffer emptied (so it
never fills). No screen answers: no `OK` comes back into the UART, and the page takes the
screen as absent (no fault; the bytes it sends do not depend on the answers).
"""

import gc
import json
import os
import struct
import sys

import m4f
import vfs

# machine (emulated_board/mpy/machine.py, frozen as `machine`, with bmi055_model) and feed are
# imported in main(), after the heap MicroPython itself holds is measured: their objects are
# the emulator's

MASK = 0x3FFFFFFF  # m4f counters are modulo 2**30 (small ints)
CHUNK = 64  # ticks per write of the per-tick records (small: the heap is the board's)
TX_CAPACITY = 1024  # output UART buffer: a tick writes at most 446 bytes (frame, extended
# frame, raw record with 232 GNSS bytes); emptied when over half full
BLOCK = 512  # RAM disk sector


class HostFile:
    """A host file through semihosting: readinto(buf, n) as feed.read_exact wants."""

    def __init__(self, path, mode):
        self.h = m4f.open(path, mode)

    def readinto(self, buf, n):
        return m4f.readinto(self.h, buf, n)

    def write(self, buf, n):
        m4f.write(self.h, buf, n)

    def seek(self, pos):
        m4f.seek(self.h, pos)

    def close(self):
        m4f.close(self.h)


class RamDisk:
    """A block device over the m4f module's static RAM disk (outside the heap)."""

    def __init__(self):
        self.mem = memoryview(m4f.ramdisk())
        self.blocks = len(self.mem) // BLOCK

    def readblocks(self, n, buf):
        buf[:] = self.mem[n * BLOCK : n * BLOCK + len(buf)]

    def writeblocks(self, n, buf):
        self.mem[n * BLOCK : n * BLOCK + len(buf)] = buf

    def ioctl(self, op, arg):
        if op == 4:  # block count
            return self.blocks
        if op == 5:  # block size
            return BLOCK
        return 0


def copy_in(host_path, path):
    """A host file (semihosting) into the guest's file `path`, a block at a time."""
    f = HostFile(host_path, 1)
    left = m4f.flen(f.h)
    buf = bytearray(BLOCK)
    with open(path, "wb") as out:
        while left:
            k = BLOCK if left > BLOCK else left
            if f.readinto(buf, k) != k:
                raise OSError("cannot read " + host_path)
            out.write(buf if k == BLOCK else buf[:k])
            left -= k
    f.close()


def mount_flash(config_path=None, navk_path=None):
    """/flash: FAT on the RAM disk, with /flash and /flash/lib on sys.path after the frozen
    modules, as the stm32 port has them. config_path: the host's configuration file, copied to
    /flash/ins.cfg; navk_path: the native kernels (the armv7emsp navk.mpy), copied to
    /flash/lib/navk.mpy where a board keeps them (a native module cannot be frozen: mpy-tool
    refuses code with relocations). Without navk_path `import navk` fails: Python kernels."""
    bdev = RamDisk()
    vfs.VfsFat.mkfs(bdev)
    vfs.mount(vfs.VfsFat(bdev), "/flash")
    for p in ("/flash", "/flash/lib"):
        if p not in sys.path:
            sys.path.append(p)
    if config_path:
        copy_in(config_path, "/flash/ins.cfg")
    if navk_path:
        os.mkdir("/flash/lib")
        copy_in(navk_path, "/flash/lib/navk.mpy")


def icount_pair_cost():
    """Instructions of one m4f.icount() reading as measured by the next (subtracted from
    nothing: reported, so readers know the counter's own share of a tick)."""
    icount = m4f.icount
    c0 = icount()
    c1 = icount()
    return (c1 - c0) & MASK


def exit_firmware_error(code):
    m4f.exit(code)


def main(stim_path, offset, n_ticks, tick_us, config_path, out_dir, board_heap, build_heap,
         navk_path=None, setup=None):  # fmt: skip
    """The run, as the module docstring says. One piece on purpose: its steps are measured in
    order against the heap (MicroPython's own bytes, then the emulator's, then the ballast that
    gives the firmware exactly the board's free heap), and helper functions would be objects
    of the emulator's taking that heap, and calls inside the counted window would count as
    the firmware's instructions."""
    m4f.init()
    icount = m4f.icount
    emu_total = m4f.emu_total
    emu_in = m4f.emu_in
    emu_out = m4f.emu_out
    mount_flash(config_path, navk_path)
    gc.collect()
    system_bytes = gc.mem_alloc()  # MicroPython's own (start-up objects, /flash), as on a board
    # setup (the profiler's, bench/profile.py): runs once /flash is there and before the
    # firmware is imported; it returns (report, firmware_bytes): report is called at the end
    # for (name, value) pairs, each printed as an "R" line; firmware_bytes is what the
    # firmware's modules it imported hold, which the board's free heap pays for. The rest of
    # what it keeps counts as the emulator's: the firmware still gets the board's heap when
    # the build's heap has room for both
    report, firmware_bytes = setup() if setup else (None, 0)
    usable = (gc.mem_alloc() + gc.mem_free()) * board_heap // build_heap  # the board's region
    from feed import (
        PROGRESS_EVERY,
        app_stats,
        bytes_per_block,
        display_uart,
        fire_inputs,
        firmware_error,
        first_tick_us,
        next_input,
        stalled,
        start_firmware,
        window_end,
        window_start,
    )
    from feed_protocol import REC_LEN  # common/proto/mpy

    import machine

    machine.TX_CAPACITY = TX_CAPACITY
    machine.reserve_tx(3)  # the GNSS, output and display UARTs': the emulator's
    bpb = bytes_per_block()
    f = HostFile(stim_path, 1)
    f.seek(offset)
    fo = HostFile(out_dir + "/out.bin", 5)
    ft = HostFile(out_dir + "/ticks.bin", 5)
    fd = m4f.open(out_dir + "/display.bin", 5)  # a semihosting handle (a small int)
    write = m4f.write
    rec = bytearray(REC_LEN)
    ubuf = bytearray(256)
    recs = bytearray(16 * CHUNK)
    imu = machine.Bmi055()
    gc.collect()
    # the emulated board's and the driver's
    emulator_bytes = gc.mem_alloc() - system_bytes - firmware_bytes
    board_free = usable - system_bytes - firmware_bytes
    spare = (gc.mem_free() - board_free - 16) // 16 * 16  # a bytearray: 16-byte head + data
    ballast = bytearray(spare) if spare > 0 else None
    gc.collect()
    free_at_start = gc.mem_free()
    c0 = icount()
    a, pins = start_firmware(imu, "/flash/ins.cfg", exit_firmware_error)
    startup_instr = (icount() - c0) & MASK
    gnss = machine.uart(pins["gnss_uart"])
    out_uart = machine.uart(pins["out_uart"])
    pps = machine.pin(pins["pps"])
    disp = display_uart(a, pins)  # None with the status page off
    disp_start = 0
    if disp is not None and disp.tx_n:  # the start page
        disp_start = disp.tx_n
        write(fd, disp.tx, disp_start)
        disp.tx_clear()
    nav = a.nav
    t0 = first_tick_us(tick_us)
    live_after_start = gc.mem_alloc()
    flush_at = TX_CAPACITY // 2
    driver_alloc = 0
    gc_runs = a.gc_runs
    j = 0
    m1 = gc.mem_alloc()
    for k in range(n_ticks):
        ubuf = next_input(f, rec, ubuf, imu, gnss)
        t_k = t0 + k * tick_us
        m0 = gc.mem_alloc()
        if m0 != m1:
            driver_alloc += m0 - m1
        window_start()  # micropython.mem_total as the board counts it (feed.py)
        e0 = emu_total()
        c0 = icount()
        try:  # the firmware's code: its interrupt handlers and one pass of its loop
            emu_in()
            fire_inputs(rec, t_k, pps)
            # the driver's test is emulation (inside the bracket); the loop's pass is counted
            # exactly as without a stall flag: emu_out() and then service(), nothing between
            if stalled(rec):
                emu_out()
            else:
                emu_out()
                a.service()
        except Exception as e:  # noqa: BLE001  (reported with its traceback, then exit)
            fo.write(out_uart.tx, out_uart.tx_n)
            fo.close()
            firmware_error(k, e, exit_firmware_error)
        c1 = icount()
        e1 = emu_total()
        window_end()
        ma = gc.mem_alloc()
        dn = 0
        if disp is not None and disp.tx_n:  # what the tick sent to the screen
            dn = disp.tx_n
            write(fd, disp.tx, dn)
            disp.tx_clear()
        struct.pack_into("<iiiBBH", recs, 16 * j, (c1 - c0) & MASK, (e1 - e0) & MASK, ma - m0,
                         nav.state, a.gc_runs - gc_runs, dn)  # fmt: skip
        gc_runs = a.gc_runs
        j += 1
        if j == CHUNK:
            ft.write(recs, 16 * j)
            j = 0
        if out_uart.tx_n >= flush_at:
            fo.write(out_uart.tx, out_uart.tx_n)
            out_uart.tx_clear()
        if (k + 1) % PROGRESS_EVERY == 0:
            print("P", k + 1, n_ticks)
        m1 = gc.mem_alloc()
        driver_alloc += m1 - ma
    if j:
        ft.write(recs, 16 * j)
    fo.write(out_uart.tx, out_uart.tx_n)
    out_uart.tx_clear()
    fo.close()
    ft.close()
    m4f.close(fd)
    f.close()
    if n_ticks % PROGRESS_EVERY or not n_ticks:
        print("P", n_ticks, n_ticks)
    # the ticks are over: what the board would have free now, then the ballast goes (the
    # report below is the emulator's, and needs heap the board's firmware never left over)
    gc.collect()
    free_at_end = gc.mem_free()
    ballast_bytes = len(ballast) if ballast is not None else 0
    ballast = None
    gc.collect()
    stats = app_stats(a, n_ticks, t0, pins)
    stats.update(
        {
            "bytes_per_block": bpb,
            "heap_total_bytes": gc.mem_alloc() + gc.mem_free(),
            "emulator_bytes": emulator_bytes,
            "system_bytes": system_bytes,
            "setup_firmware_bytes": firmware_bytes,
            "board_free_at_start": board_free,
            "ballast_bytes": ballast_bytes,
            "free_at_start": free_at_start,
            "free_at_end": free_at_end,
            "live_after_start": live_after_start,
            "startup_instructions": startup_instr,
            "icount_cost": icount_pair_cost(),
            "driver_alloc_bytes": driver_alloc,
            "display_start_bytes": disp_start,
            "float32": 1.0 + 2.0**-30 == 1.0,  # the VM's floats are single precision
            "platform": sys.platform,
        }
    )
    # one "S" line per statistic, one "R" line per (name, value) pair: one long JSON string
    # would need a contiguous block that the run's fragmented heap may not have (measured:
    # 392 bytes failed with 8 KB free, 1.6 KB with 17 KB)
    for key in stats:
        print("S", json.dumps({key: stats[key]}))
    if report:
        for pair in report():
            print("R", json.dumps(pair))
    m4f.exit(0)
