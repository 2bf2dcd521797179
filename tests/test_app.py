"""firmware/app.py with the firmware's own board.py and drivers on the emulated board
(emulated_board/mpy: `machine` with the BMI055 register model on SPI, UARTs; `time`'s virtual
clock): frames out, GNSS silence, a missing or wrong
IMU, a corrupt configuration, and a real receiver log flowing through to the frames."""

import importlib
import pathlib
import struct
import time

import numpy as np
import pytest

from common.proto import stimulus, stream
from host_emulator.bench import navigator as nav_runner
from host_emulator.emulated_board import install_machine

NMEA = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data" / "nmea"
LEVEL_COUNTS = ([3, -2, 1], [10, -5, 1024])  # a board at rest, z up: about 1 g on accel z
# ... as the BMI055's data registers (gyro, then accel with the new_data bits)
LEVEL_REGS = (
    stimulus.gyro_registers([LEVEL_COUNTS[0]])[0].tobytes()
    + stimulus.accel_registers([LEVEL_COUNTS[1]])[0].tobytes()
)
# every other sample: a count more on gyro z (a real sensor's noise; counts that never change
# are a stuck sensor to the firmware)
NOISY_COUNTS = ([3, -2, 2], [11, -5, 1024])
NOISY_REGS = (
    stimulus.gyro_registers([NOISY_COUNTS[0]])[0].tobytes()
    + stimulus.accel_registers([NOISY_COUNTS[1]])[0].tobytes()
)


def take_tx(port):
    """What the firmware wrote to a UART since the last take (the transmit buffer emptied)."""
    out = bytes(port.tx[: port.tx_n])
    port.tx_clear()
    return out


class Bench:
    """An emulated board, freshly powered on, with the firmware loaded on it."""

    def __init__(self, tmp_path, chip=True, chip_id=None, cfg_bytes=None):
        self.machine = machine = install_machine()
        machine.power_on()
        import board

        self.board = importlib.reload(board)
        self.board.CONFIG_PATH = str(tmp_path / "ins.cfg")
        if cfg_bytes is not None:
            pathlib.Path(self.board.CONFIG_PATH).write_bytes(cfg_bytes)
        pins = self.board.PINS
        self.imu = machine.Bmi055(present=chip, gyro_chip_id=chip_id)
        self.imu.attach(
            machine.spi_bus(pins["spi_id"]),
            machine.pin(pins["cs_accel"]),
            machine.pin(pins["cs_gyro"]),
        )
        self.imu.set_registers(LEVEL_REGS, 0, 6)
        self.console = []
        import app

        self.app = app.App(self.board, console=self.console.append)
        self.app.start()
        self.gnss_uart = machine.uart(pins["gnss_uart"])
        self.out_uart = machine.uart(pins["out_uart"])

    def run(self, ticks, nmea=b"", per_tick=8):
        """`ticks` timer periods; NMEA bytes arrive `per_tick` at a time (9600 baud: ~5)."""
        sent = bytearray()
        for k in range(ticks):
            self.imu.set_registers(NOISY_REGS if k & 1 else LEVEL_REGS, 0, 6)  # its next sample
            self.gnss_uart.feed(nmea[k * per_tick : (k + 1) * per_tick])
            time.advance_us(5000)
            self.machine.fire_timers()
            self.app.service()
            sent += take_tx(self.out_uart)
        self.decoded = stream.decode(bytes(sent))
        d = self.decoded
        assert d.bad_checksum == d.bad_crc == d.skipped_bytes == 0
        return [f["raw"] for f in d.frames]


def field(f, fmt, off):
    return struct.unpack_from("<" + fmt, f, off)[0]


def test_the_app_constants_are_the_correctly_rounded_values():
    import nav_kern

    assert nav_kern.CDEG_PER_RAD == np.float32(18000 / np.pi)
    assert nav_kern.RAD_PER_CDEG == np.float32(np.pi / 18000)


def test_a_missed_ticks_repeat_is_its_own_imu_status_bit():
    """The app marks a missed tick's sample with nav.IMU_REPEAT (its copy is generated,
    tests/native/test_const_copies.py): a bit no other IMU status uses."""
    import app
    import nav

    assert app._IMU_REPEAT == nav.IMU_REPEAT and not nav.IMU_REPEAT & (
        nav.IMU_OVER_RANGE | nav.IMU_FRESH
    )


def test_the_fix_fields_split_and_round_as_geo_and_frame_do(tmp_path):
    """App._fix_fields writes out geo.split_into (latitude) and frame.round_div (height in dm,
    half away from zero): the same integers on both sides of zero and at the halves."""
    import frame
    import geo
    import nav

    bench = Bench(tmp_path)
    a = bench.app
    for lat_e7, alt_mm in [(-338688000, -120050), (-5, -50), (0, 49), (5, 50), (899999999, 151),
                           (-10000000, -149), (10000000, 250), (-1, -250)]:  # fmt: skip
        g = a.gnss
        g.epoch_lat_e7, g.epoch_alt_mm, g.epoch_alt_ok = lat_e7, alt_mm, True
        a._fix_fields(g, a.nav.fix_in)
        want = [0, 0]
        geo.split_into(want, 0, lat_e7)
        ff = a._fields
        assert [ff[frame.F_LAT_DEG], ff[frame.F_LAT_FRAC]] == want
        assert ff[frame.F_HEIGHT_DM] == frame.round_div(alt_mm, 100)
        assert a.nav.fix_in[nav.FI_LAT_E7] == lat_e7


def test_gnss_silence_frames_every_tick_and_stays_aligning(tmp_path):
    bench = Bench(tmp_path)
    assert any("no configuration file" in m for m in bench.console)
    out = bench.run(600)
    assert len(out) == 600
    assert [f[2] for f in out[:3]] == [0, 1, 2] and out[256][2] == 0  # the counter wraps
    last = out[-1]
    assert last[28] == 1  # aligning: no GNSS, no heading
    assert last[17] == 0 and sum(f[16] for f in out) == 0  # no fix, no GGA
    # raw sensor fields: gyro 3 counts at 131.2 -> 3 at 131.07; accel 1024 (1 g) -> 16383,
    # 11 counts -> 176
    assert struct.unpack_from("<3h", last, 3) == (3, -2, 2)  # tick 599: NOISY_COUNTS
    assert struct.unpack_from("<3h", last, 9) == (176, -80, 16383)
    assert bench.machine.watchdog is not None and bench.machine.watchdog.feeds == 600
    assert bench.app.overruns == 0


def test_a_missing_imu_is_reported_and_retried_without_crashing(tmp_path):
    bench = Bench(tmp_path, chip=False)
    assert any("IMU not ready" in m and "read 0xFF" in m and "no power" in m for m in bench.console)
    assert bench.run(300) == []  # no frames without an IMU, the loop goes on
    assert bench.machine.watchdog.feeds == 300  # and keeps the watchdog fed
    bench.imu.accel.responds = bench.imu.gyro.responds = True  # a loose connector, pressed
    out = bench.run(300)
    assert bench.app.imu is not None and len(out) > 0


def test_a_wrong_chip_id_names_what_was_read(tmp_path):
    bench = Bench(tmp_path, chip_id=0x33)
    msg = [m for m in bench.console if "IMU not ready" in m]
    assert msg and "read 0x33" in msg[0] and "expected chip ID 0x0F" in msg[0]
    assert bench.run(50) == []


def test_a_corrupt_configuration_falls_back_to_defaults(tmp_path):
    bench = Bench(tmp_path, cfg_bytes=b"INSC\x01\x02not a configuration")
    assert any("corrupt" in m and "using defaults" in m for m in bench.console)
    assert len(bench.run(20)) == 20


@pytest.mark.parametrize("log", ["neo-m8n.log", "ublox-lea-4h.log"])
def test_a_real_receiver_log_reaches_the_frames(tmp_path, log):
    """Frames carry the GGA flag on the tick its sentence completes, the fix's lat/lon and
    height, and the valid flag once the receiver has a fix."""
    data = (NMEA / log).read_bytes()
    bench = Bench(tmp_path)
    out = bench.run(len(data) // 8 + 10, nmea=data)
    g = bench.app.gnss
    assert g.n_gga > 0 and sum(f[16] for f in out) == g.n_gga
    valid = [f for f in out if f[17] == 1]
    assert valid, "the log has fixes"
    last = valid[-1]
    assert field(last, "i", 18) == g.epoch_lat_e7
    assert field(last, "i", 22) == g.epoch_lon_e7()
    assert field(last, "h", 26) == round(g.epoch_alt_mm / 100)


def test_extended_frames_carry_the_navigators_bits(tmp_path):
    """Every 20 ticks by default: health (1: running on defaults), timing, and P's diagonal,
    biases and position copied bit for bit from the navigator's float32 buffers."""
    bench = Bench(tmp_path)
    bench.run(600)
    ext = bench.decoded.ext
    assert len(ext) == 30 and [e["counter"] for e in ext[:2]] == [20, 40]
    last = ext[-1]
    nav = bench.app.nav
    assert last["health"] == 1 and last["config_status"] == 1  # MISSING: defaults
    assert last["nav_state"] == 1 and last["tick"] == nav.tick == 600
    p_diag = np.asarray(nav.kf.P, np.float32)[::16]
    assert np.array_equal(
        np.asarray(last["p_diag"], np.float32).view(np.uint32), p_diag.view(np.uint32)
    )
    assert np.array_equal(np.float32(last["gyro_bias_rad_s"]), np.asarray(nav.ins.bg))
    assert 0 <= last["mean_tick_us"] <= last["worst_tick_us"]


def test_raw_records_reproduce_the_input_exactly(tmp_path):
    """With raw_record on, one record per tick: the BMI055 register bytes and every GNSS byte
    fed to the parser, so a board session can be replayed bit for bit."""
    import config

    cfg = config.BoardConfig()
    cfg.raw_record = 1
    data = (NMEA / "triton400.log").read_bytes()[:3000]
    bench = Bench(tmp_path, cfg_bytes=config.encode(cfg))
    n = len(data) // 8 + 5
    bench.run(n, nmea=data)
    raw = bench.decoded.raw
    assert len(raw) == n
    assert b"".join(r["gnss_bytes"] for r in raw) == data
    counts = NOISY_COUNTS if (n - 1) & 1 else LEVEL_COUNTS
    assert list(struct.unpack("<3h", raw[-1]["gyro_regs"])) == counts[0]
    accel = [v >> 4 for v in struct.unpack("<3h", raw[-1]["accel_regs"])]
    assert accel == counts[1]


def test_a_late_loop_counts_overruns(tmp_path):
    """The timer fired three times before the loop got round to it: one tick runs, two are
    overruns (their samples are lost; the navigator steps through them), the tick count keeps
    the timer's, and the frame counter moves by one."""
    bench = Bench(tmp_path)
    bench.run(5)
    tick = bench.app.nav.tick
    for _ in range(3):
        time.advance_us(5000)
        bench.machine.fire_timers()
    bench.app.service()
    assert bench.app.overruns == 2 and bench.app.ticks == 8
    assert bench.app.nav.tick == tick + 3
    assert [f["counter"] for f in stream.decode(take_tx(bench.out_uart)).frames] == [5]


def _sentence(body):
    csum = 0
    for c in body.encode():
        csum ^= c
    return f"${body}*{csum:02X}\r\n".encode()


def _epoch(hms, rmc_speed_course=None):
    """One second's GGA and, unless None, an RMC with the given 'knots,course' fields."""
    out = _sentence(f"GPGGA,{hms}.00,3415.601386,N,10856.398020,E,1,09,0.90,429.458,M,-28.0,M,,")
    if rmc_speed_course is not None:
        out += _sentence(
            f"GPRMC,{hms}.00,A,3415.601386,N,10856.398020,E,{rmc_speed_course},221126,,,A"
        )
    return out


@pytest.mark.parametrize(
    "fields, need_speed, want",
    [
        ("5.000,90.00", 1, (2572, 157080)),  # speed 5 kn = 2.572 m/s, course 90 deg
        ("0.000,", 1, (0, None)),  # a standing receiver: speed 0, no course
        (",", 1, (None, None)),  # no velocity reported: speed and course unknown (-1)
        (None, 0, (None, None)),  # GGA only (gnss_need_speed 0): unknown
    ],
)
def test_the_navigator_is_told_whether_the_speed_is_known(tmp_path, fields, need_speed, want):
    """speed -1 and course -1 when the epoch carries no speed: an unknown speed is not a
    standing receiver's 0 (it must not reach the standstill detector as a measurement)."""
    import config

    cfg = config.BoardConfig()
    cfg.gnss_need_speed = need_speed
    bench = Bench(tmp_path, cfg_bytes=config.encode(cfg))
    import nav

    calls = []
    n = bench.app.nav
    real = n.gnss_fix

    def spy():
        real()
        calls.append((n._fx[nav._FX_SPEED], n._fx[nav._FX_COURSE]))

    n.gnss_fix = spy
    data = b"".join(_epoch(f"02000{s}", fields) for s in range(3))
    bench.run(len(data) // 8 + 2, nmea=data)
    assert len(calls) == 3
    speed_mm_s, course_e5 = want
    for speed, course in calls:
        speed, course = float(speed), float(course)
        assert speed == -1.0 if speed_mm_s is None else round(speed * 1000) == speed_mm_s
        assert course == -1.0 if course_e5 is None else round(course * 100000) == course_e5
    # the fixes were usable; only a known speed is a measurement for the standstill detector
    tick = nav_runner.control(bench.app.nav, "speed_tick")
    assert tick == -1000000 if speed_mm_s is None else tick > 0


def test_ctrl_c_stops_the_loop_and_keeps_the_repl_alive(tmp_path):
    bench = Bench(tmp_path)
    assert any(m.startswith("ins: running") and "460800 baud" in m for m in bench.console)
    bench.run(10)
    machine = bench.machine
    pps = machine.pin(bench.board.PINS["pps"])
    assert pps.irq_handler is not None and len(machine._timers) == 1
    calls = []
    enable_irq = machine.enable_irq
    machine.enable_irq = lambda state: calls.append(state)
    try:
        bench.app.stop()  # what main.py does on KeyboardInterrupt
    finally:
        machine.enable_irq = enable_irq
    # interrupts unmasked (a Ctrl-C may have raised in idle's masked section): the port's
    # enable_irq takes a bool, True: enabled
    assert calls == [True]
    assert bench.console[-1] == "ins: stopped (Ctrl-D restarts it)"
    assert pps.irq_handler is None
    # the tick timer is gone: nothing is due, no frame goes out
    bench.app.due = 0
    machine.fire_timers()
    assert bench.app.due == 0
    bench.app.service()
    assert take_tx(bench.out_uart) == b""
    # the timer left behind feeds the watchdog, which cannot be stopped once started, four
    # times per timeout (50 ms: every 12 ms, the port's 1000 // 80)
    assert [t.period_ms for t in machine._timers] == [12]
    feeds = machine.watchdog.feeds
    for _ in range(3):
        machine.fire_timers()
    assert machine.watchdog.feeds == feeds + 3


def test_an_epoch_is_late_when_its_pps_edge_belongs_to_a_later_second(tmp_path):
    """_late_s (an epoch's edge and UTC second) counts PPS edges (whole seconds of ticks_us)
    from the edge of the last on-time epoch: an epoch whose first sentence came after a later
    second's edge is late by that many seconds (its fix would be stamped wrong) and keeps the
    reference; an on-time epoch moves it; an edge off the seconds (spurious) is not counted;
    the UTC day wraps; a count that went backwards (the receiver's clock jumped) or a
    reference older than 300 s starts afresh."""
    a = Bench(tmp_path).app
    import app

    def edge_ref():
        return a._chk[app._K_EDGE_US]

    def second_ref():
        return a._chk[app._K_EDGE_S]

    def edge(us):
        return us % (1 << 30)  # ticks_us wraps at 2^30

    e0 = (1 << 30) - 400_000
    assert a._late_s(e0, 86_399) == 0  # the first epoch: the reference
    e1 = edge(e0 + 1_000_030)  # the next edge (30 us of board clock drift), over the wrap
    assert a._late_s(e1, 0) == 0  # midnight: second 0 follows 86399
    assert edge_ref() == e1 and second_ref() == 0
    assert a._late_s(edge(e1 + 2_000_000), 1) == 1  # second 1 after second 2's edge
    assert a._late_s(edge(e1 + 3_000_000), 1) == 2
    assert edge_ref() == e1  # late epochs keep the reference
    assert a._late_s(edge(e1 + 2_500_000), 1) == 0  # a spurious edge: not counted
    assert edge_ref() == e1
    assert a._late_s(edge(e1 + 4_000_000), 4) == 0  # on time again: the reference moves
    assert second_ref() == 4
    assert a._late_s(edge(e1 + 5_000_000), 9) == 0  # the clock jumped ahead: afresh
    assert second_ref() == 9
    assert a._late_s(edge(e1 + 400_000_000), 1) == 0  # an old reference: afresh
    assert second_ref() == 1
    assert a._late_s(edge(e1 + 401_000_000), -1) == 0  # no UTC time: nothing to count
    assert second_ref() == 1


def test_a_receiver_clock_that_steps_is_resynchronised_and_late_bytes_stay_late(tmp_path):
    """_late_s tells a receiver's clock that stepped back (its epochs' seconds jump while
    every PPS edge still had its epoch: GPS time to UTC, 18 s) from bytes that come late (the
    lateness begins at an edge without its epoch): the step's edge becomes the reference after
    _STEP_EPOCHS epochs and says CAUSE_GNSS_CLOCK; late bytes stay late (CAUSE_GNSS_LATE) as
    long as they are. A step forward re-references at once, with CAUSE_GNSS_CLOCK."""
    a = Bench(tmp_path).app
    import app

    k = a._chk
    e = 1_000_000
    assert a._late_s(e, 1000) == 0
    k[app._K_EDGES_OK] = app._OVERDUE_EDGES  # the edges so far each had their epoch
    lateness = [a._late_s(e + i * 1_000_000, 1000 + i - 18) for i in range(1, 6)]
    assert lateness == [18] * (app._STEP_EPOCHS - 1) + [0, 0, 0]  # then on time again
    assert k[app._K_EDGE_S] == 1000 + 5 - 18
    assert k[app._K_STEP_BAD] == a.ticks + app._SECOND_TICKS and k[app._K_LATE_BAD] == 0
    k[app._K_STEP_BAD] = 0
    assert a._late_s(e + 6_000_000, 1000 + 6) == 0  # back to GPS time: 18 s ahead, at once
    assert k[app._K_STEP_BAD] > 0 and k[app._K_EDGE_S] == 1006
    k[app._K_STEP_BAD] = 0
    # bytes 1.4 s late: the edge before them had no epoch (_pps_seen reset the run)
    k[app._K_EDGES_OK] = 0
    lateness = [a._late_s(e + (6 + i) * 1_000_000, 1006 + i - 1) for i in range(1, 8)]
    assert lateness == [1] * 7 and k[app._K_EDGE_S] == 1006
    assert k[app._K_LATE_BAD] > 0 and k[app._K_STEP_BAD] == 0
    k[app._K_EDGES_OK] = app._OVERDUE_EDGES  # regular again, still late: still late bytes
    assert a._late_s(e + 14_000_000, 1013) == 1
    # a step of 2 s or more is a step even at a missed edge (a damaged epoch beside it):
    # bytes that late would be a backlog growing without end
    k[app._K_EDGES_OK] = 0
    assert a._late_s(e + 15_000_000, 1015) == 0  # on time: the reference
    lateness = [a._late_s(e + (15 + i) * 1_000_000, 1015 + i - 18) for i in range(1, 5)]
    assert lateness == [18] * (app._STEP_EPOCHS - 1) + [0, 0]


class _Heap:
    """gc.mem_free/collect and micropython.mem_total as the board has them, counted: `free`
    bytes free, `asked` bytes asked for so far."""

    def __init__(self, free):
        self.free = free
        self.asked = 0
        self.scans = 0
        self.collects = 0

    def mem_free(self):
        self.scans += 1
        return self.free

    def collect(self):
        self.collects += 1
        self.free = 30_000

    def alloc(self, n):
        """n bytes asked for: taking n rounded up to 16-byte blocks."""
        self.asked += n
        self.free -= -(-n // 16) * 16


def _on_heap(tmp_path, monkeypatch, free):
    """A Bench whose app sees a _Heap with `free` bytes free: (bench, the app module, heap)."""
    b = Bench(tmp_path)
    import app as fw_app

    heap = _Heap(free=free)
    monkeypatch.setattr(fw_app, "_mem_total", lambda: heap.asked)
    monkeypatch.setattr(fw_app.gc, "mem_free", heap.mem_free, raising=False)
    monkeypatch.setattr(fw_app.gc, "collect", heap.collect)
    return b, fw_app, heap


def test_the_heap_is_looked_at_only_when_the_steps_may_have_reached_the_reserve(
    tmp_path, monkeypatch
):
    """A step that allocates asks for room first (the navigator's heap_check): it is charged
    twice what MicroPython counted since the last look plus one step, so a few steps pass
    without a heap scan (~140,000 instructions on the board), the one that may reach the
    reserve looks, and a heap with less than a step over the reserve is collected."""
    b, fw_app, heap = _on_heap(tmp_path, monkeypatch, 16_000)
    a = b.app
    a._heap_check()  # as start() leaves it: 16,000 free, nothing asked for since
    assert heap.scans == 1 and a._heap_free == 16_000
    steps = 0
    while 16_000 - 2 * heap.asked - fw_app._STEP_BYTES >= fw_app._HEAP_RESERVE:
        a.nav.heap_check()  # steps of 1,000 bytes within the room
        heap.alloc(1000)
        steps += 1
    assert steps == 5 and heap.scans == 1 and heap.collects == 0  # none of them scanned
    a.nav.heap_check()  # this one may reach the reserve: the heap is looked at
    assert heap.scans == 2 and heap.collects == 0 and a._heap_free == heap.free
    heap.alloc(16_000 - fw_app._STEP_BYTES - fw_app._HEAP_RESERVE)  # the heap nearly full
    a.nav.heap_check()
    assert heap.collects == 1 and a._heap_free == 30_000 and a.gc_runs == 1


def test_a_quiet_aligning_tick_looks_at_the_heap_ahead_of_the_steps(tmp_path, monkeypatch):
    """While aligning, a tick that allocated nothing looks at the heap when the estimate is
    within two steps of the reserve, so the step that follows (the start of navigation, a
    heavy tick) finds room without a scan of its own; a heap under what _heap_check collects
    at is collected in the next quiet tick and looked at again in the one after. A tick that
    allocated does none of it."""
    b, fw_app, heap = _on_heap(tmp_path, monkeypatch, 9_000)
    a = b.app
    a._heap_check()
    b.run(3)
    assert heap.scans == 1  # nothing asked for since the look
    heap.alloc(600)  # a fix's Python: 9,000 - 2 x 600 - 2 steps is under the reserve
    b.run(1)
    assert heap.scans == 2 and heap.collects == 0 and a._heap_free == 8_392
    a.nav.heap_check()  # the step that follows: room by the estimate, no scan
    assert heap.scans == 2
    heap.alloc(2_400)  # now under a step over the reserve: collected, then looked at
    b.run(1)
    assert heap.scans == 3 and heap.collects == 0
    b.run(1)
    assert heap.collects == 1 and a.gc_runs == 1 and heap.scans == 3
    b.run(2)
    assert heap.scans == 4 and a._heap_free == 30_000
    assert a.nav.ctl[fw_app._C_STATE] != fw_app.NAVIGATING

    def busy():  # every call asks for 16 bytes: every tick allocates
        heap.asked += 16
        return heap.asked

    monkeypatch.setattr(fw_app, "_mem_total", busy)
    heap.alloc(30_000 - 6_000)
    b.run(5)
    assert heap.scans == 4 and heap.collects == 1
