"""The m4f runtime: the unmodified app loop on the emulated Cortex-M4F (MicroPython v1.28.0's
qemu port for mps2-an386, single-precision hard float, the firmware frozen).

Built once into build/m4f (about 30 s on a clean checkout, then cached). The main run is 30 s
of quick_start (navigating from ~13 s), which takes about 30 s: its frames and extended frames
are compared with the NumPy model byte for byte and its instruction counts are checked.
"""

import numpy as np
import pytest

from common import toolchain
from common.errors import EmulatorError, FirmwareError
from common.proto import stream
from host_emulator import runtimes
from host_emulator.eval import board_cost, parity
from host_emulator.eval.scenario_run import firmware_metrics
from host_emulator.runtimes import m4f
from host_emulator.runtimes.m4f import build as m4f_build
from host_emulator.runtimes.m4f import guest
from host_emulator.sim import board_input


@pytest.fixture(scope="module")
def quick():
    """30 s of quick_start: firmware on the M4F against the model (parity.compare)."""
    stim = board_input.simulate("quick_start", 30.0, seed=0).stimulus
    r = parity.compare(stim, runtime="m4f")
    return stim, r


def test_the_counter_counts_every_instruction():
    """An inline-assembler loop of two instructions per turn (subs, bne): the difference of two
    lengths is exactly twice the difference of turns, to the counter's 40-instruction step."""
    out = guest.run(
        "import micropython\n"
        "@micropython.asm_thumb\n"
        "def spin(r0):\n"
        "    label(loop)\n"
        "    sub(r0, r0, 1)\n"
        "    bne(loop)\n"
        "def count(n):\n"
        "    c0 = m4f.icount()\n"
        "    spin(n)\n"
        "    return (m4f.icount() - c0) & 0x3FFFFFFF\n"
        # a first call fills MicroPython's attribute look-up caches: it costs more
        "count(1)\n"
        "print(count(100000), count(300000), count(100000))\n"
    )
    a, b, a2 = map(int, out.split()[-3:])
    assert abs((b - a) - 400_000) <= 80  # two readings of +-40 each
    assert abs(a - a2) <= 80  # repeatable
    assert 200_000 < a < 201_000  # the call itself costs a few hundred instructions


# The guest's instruction count of a call g() (its second: the first fills the look-up
# caches), the emulation's own instructions taken out; empty() is the bare call's
COST = (
    "def cost(g):\n"
    "    g()\n"
    "    e0 = m4f.emu_total(); c0 = m4f.icount()\n"
    "    g()\n"
    "    return ((m4f.icount() - c0) & 0x3FFFFFFF) - ((m4f.emu_total() - e0) & 0x3FFFFFFF)\n"
    "def empty():\n"
    "    pass\n"
)


def test_a_peripheral_call_costs_a_c_method_call():
    """The firmware holds the emulated parts through m4f.Periph (C): `pin.value(0)` is counted
    at about what a built-in method of one argument costs (`d.get(0)`), well below calling the
    Python part itself (its call is counted before its own bracket opens). Printed with -s."""
    out = guest.run(
        "import m4f, machine\n"
        "p = machine.Pin('X1', machine.Pin.OUT)\n"
        "q = machine.pin('X1')\n"  # the emulated part behind p
        "d = {}\n" + COST + "def periph():\n"
        "    p.value(0)\n"
        "def builtin():\n"
        "    d.get(0)\n"
        "def python():\n"
        "    q.value(0)\n"
        "print('R', type(p).__name__, *[cost(g) for g in (empty, periph, builtin, python)])\n"
    )
    kind, empty, periph, builtin, python = out.split("R ")[1].split()[:5]
    periph, builtin, python = (int(x) - int(empty) for x in (periph, builtin, python))
    print(f"counted per call: Periph {periph}, built-in method {builtin}, Python part {python}")
    assert kind == "Periph"
    # about the same, either way: MicroPython's map look-up cache (indexed by qstr) makes a
    # call's count depend by ~80 on which other names share its slots, i.e. on the build's
    # qstrs (d.get(0) counted 80 more than e.get(0) and than p.value(0) in one build)
    assert abs(periph - builtin) <= 200
    assert periph < python


def test_the_screens_transmitter_writes_a_character_through_the_c_handle():
    """The status page's transmitter without DMA (firmware/board.py _Chars) holds the display
    UART's `writechar` bound, and calls it for every byte: through m4f.Periph (a method it
    lists) the call costs what a built-in method costs, as on the board, and the byte lands in
    the emulated UART's transmit buffer. Printed with -s."""
    out = guest.run(
        "import m4f, machine\n"
        "u = machine.UART(6, baudrate=115200, rxbuf=64, timeout=0)\n"
        "put = u.writechar\n"
        "q = machine.uart(6)\n"
        "d = {}\n" + COST + "def periph():\n"
        "    put(0x141)\n"  # 9 bits: the low 8 are sent
        "def builtin():\n"
        "    d.get(0)\n"
        "def python():\n"
        "    q.writechar(66)\n"
        "c = [cost(g) for g in (empty, periph, builtin, python)]\n"
        "print('R', type(u).__name__, bytes(q.tx[: q.tx_n]).decode(), *c)\n"
    )
    kind, sent, empty, periph, builtin, python = out.split("R ")[1].split()[:6]
    periph, builtin, python = (int(x) - int(empty) for x in (periph, builtin, python))
    print(
        f"counted per writechar: Periph {periph}, built-in method {builtin}, Python part {python}"
    )
    assert kind == "Periph" and sent == "AABB"
    assert abs(periph - builtin) <= 200 and periph < python


def test_an_attribute_store_on_the_navigator_searches_its_class():
    """Navigator has properties, so MicroPython looks for a setter in the class and its bases
    before it stores any attribute of an instance (py/objtype.c); an instance of a class
    without properties stores directly, and `ctl[i] = v` is a subscript of a loaded attribute.
    Why the navigator's per-tick and per-fix ints live in ctl (docs/native.md). Printed with
    -s."""
    out = guest.run(
        "import m4f, nav, navcfg\n"
        "n = nav.Navigator(navcfg.NavConfig())\n"
        "n._probe = 0\n"
        "class Plain:\n"
        "    pass\n"
        "o = Plain()\n"
        "o.x = 0\n" + COST + "def on_nav():\n"
        "    n._probe = 1\n"
        "def on_plain():\n"
        "    o.x = 1\n"
        "def in_ctl():\n"
        "    n.ctl[46] = 0\n"  # _C_IMU_STATUS, an input the app sets every tick
        "print('R', *[cost(g) for g in (empty, on_nav, on_plain, in_ctl)])\n"
    )
    empty, on_nav, on_plain, in_ctl = (int(x) for x in out.split("R ")[1].split()[:4])
    on_nav, on_plain, in_ctl = on_nav - empty, on_plain - empty, in_ctl - empty
    print(
        f"counted per store: Navigator attribute {on_nav}, plain instance {on_plain}, ctl {in_ctl}"
    )
    assert on_nav > 4 * on_plain and on_nav > 4 * in_ctl


def test_floats_are_the_boards_float32():
    """The VM's float is IEEE single precision with round-to-nearest on the FPU: products,
    quotients, sums and sqrt equal NumPy's float32 bit for bit (the unix VM's are doubles)."""
    rng = np.random.default_rng(3)
    x = rng.standard_normal(64).astype(np.float32) * np.float32(1e3)
    y = rng.standard_normal(64).astype(np.float32)
    out = guest.run(
        "import array, binascii, math\n"
        f"x = array.array('f', binascii.unhexlify({x.tobytes().hex()!r}))\n"
        f"y = array.array('f', binascii.unhexlify({y.tobytes().hex()!r}))\n"
        "r = array.array('f', bytes(4 * 4 * len(x)))\n"
        "for i in range(len(x)):\n"
        "    r[4 * i] = x[i] * y[i] + y[i]\n"
        "    r[4 * i + 1] = x[i] / y[i]\n"
        "    r[4 * i + 2] = math.sqrt(abs(x[i]))\n"
        "    r[4 * i + 3] = (x[i] - y[i]) * 0.5\n"
        "print('R', binascii.hexlify(bytes(r)).decode())\n"
    )
    got = np.frombuffer(bytes.fromhex(out.split("R ")[1].split()[0]), "<f4").reshape(-1, 4)
    want = np.stack(
        [x * y + y, x / y, np.sqrt(np.abs(x)), (x - y) * np.float32(0.5)], axis=1
    ).astype(np.float32)
    assert got.tobytes() == want.tobytes()


def test_the_emulated_board_shadows_the_builtin_modules():
    out = guest.run(
        "import time, machine, sys\n"
        "b = sys.implementation._build\n"
        "print(hasattr(time, 'now_us'), hasattr(machine, 'fire_timers'), b)\n"
    )
    assert out.split()[-3:] == ["True", "True", "M4F_INS"]


def test_frames_and_extended_frames_equal_the_model_byte_for_byte(quick):
    stim, r = quick
    assert r.runtime == "m4f" and r.run_time_zeroed
    assert r.frame.counts == (6000, 6000) and r.ext.counts == (300, 300)
    assert r.identical, r.summary()
    fw = r.firmware_run
    # not vacuous: the firmware navigated for more than half the run
    assert np.sum(fw.per_tick["state"] == 2) > 3000
    # ...and only the run-time counters differ in the raw streams
    assert stream.without_run_time(fw.out) == r.out_firmware
    assert "PARITY: identical" in r.summary() and "gc_runs" in r.summary()


def test_every_tick_is_counted_and_the_emulation_is_set_apart(quick):
    stim, r = quick
    t = r.firmware_run.per_tick
    assert len(t) == len(stim)
    fw = t["instr"].astype(np.int64) - t["emu_instr"]
    assert (fw > 20_000).all()  # a tick runs Python: tens of thousands of instructions at least
    # every tick reads the IMU through the emulated SPI bus: emulation in every tick
    assert (t["emu_instr"] > 1_000).all() and (t["emu_instr"] < t["instr"]).all()
    collecting = t["collected"] > 0
    assert collecting.sum() == r.firmware_run.stats["app_gc_runs"]
    assert (t["alloc_bytes"][collecting] < 0).all()  # a collection frees more than a tick takes
    assert (t["alloc_bytes"][~collecting] >= 0).all()


def test_alignment_allocates_only_at_fixes_and_less_than_the_app_assumes(quick):
    """With the native kernels an aligning tick runs Python only when a fix is screened, and
    a fix with a course boxes no float there (fix_check's bits, not the floats): only the
    first stable fix allocates (the origin), at most _STEP_BYTES. The navigator asks for room
    before such a step, and the app counts the steps against the room its last heap check
    found and checks again only when they may have used it up (app.py). Before the bits,
    every aligning fix allocated 32 bytes."""
    from common.firmware_env import import_module

    t = quick[1].firmware_run.per_tick
    aligning = t["state"] == 1
    assert aligning.sum() > 2000
    alloc = np.where(aligning & (t["collected"] == 0), t["alloc_bytes"], 0).astype(np.int64)
    allocating = np.nonzero(alloc)[0]
    assert len(allocating) == 1, allocating  # the origin's fix
    worst = int(alloc.max())
    assert 100 < worst <= import_module("app")._STEP_BYTES, worst


def test_a_navigating_tick_allocates_nothing_on_the_board(quick):
    """The allocation proof on the emulated Cortex-M4F with the armv7emsp native kernels: the
    bytes every tick allocated (gc.mem_alloc before and after, exact to the byte when no
    collection runs in between) are 0 in every tick that ends navigating, the one that starts
    it from the receiver's course included (the nav_restart kernel): IMU read, NMEA parsing,
    fix delivery and screening, the filter, the frame and the extended frame; and the app
    never collects garbage while navigating."""
    stim, r = quick
    fw = r.firmware_run
    assert fw.stats["kernels"] == "native"
    t = fw.per_tick
    navigating = t["state"] == 2
    assert navigating.sum() > 3000  # not vacuous: 16 s of navigation, 16 fixes, 160 ext frames
    assert np.count_nonzero(t["alloc_bytes"][navigating]) == 0
    assert t["collected"][navigating].sum() == 0


def test_the_resets_of_a_walk_allocate_nothing_on_the_board(tmp_path):
    """25 s of walk_real on the emulated Cortex-M4F: navigating from 12.3 s (from the receiver's
    course), then the yaw estimator resets the heading twice while the walker turns
    (nav_align._course_start and _gsf_reset, the nav_restart kernel); no navigating tick
    allocates, the start and the resets included, and no collection runs. Their Python
    references allocated ~2 KB a reset, and 300 s of the walk collected the heap 5 times
    while navigating (docs/native.md)."""
    stim = board_input.simulate("walk_real", 25.0, seed=0).stimulus
    fw = m4f.run(stim, tmp_path)
    t = fw.per_tick
    navigating = t["state"] == 2
    assert navigating.sum() > 2000 and fw.stats["nav_resets"] >= 2
    assert np.count_nonzero(t["alloc_bytes"][navigating]) == 0
    assert t["collected"][t["state"] == 2].sum() == 0


def test_the_status_page_equals_the_model_byte_for_byte():
    """16 s of quick_start (navigating from 12.3 s) with the display setting on: what the
    firmware sent to the screen's UART, the start page and 155 ticks' turns, equals the model's
    byte for byte (model/display.py; parity compares it with the frames), the marks say which
    tick sent what, and the navigating ticks, the page's turns among them, allocate nothing on
    the board either. No screen answers in the guest: the page counts no OK and no fault. The
    cost of a turn is printed with -s."""
    stim = board_input.simulate("quick_start", 16.0, seed=0).stimulus
    r = parity.compare(stim, {"display": 1}, runtime="m4f")
    assert r.identical, r.summary()
    assert "display: identical" in r.summary()
    fw = r.firmware_run
    t = fw.per_tick
    assert fw.display == r.display_model and len(fw.display) > 4000
    start = fw.stats["display_start_bytes"]
    assert fw.display[:start].startswith(b"SBC(0);CLS(0);") and fw.display[:start].endswith(b"\r\n")
    wrote = np.flatnonzero(t["display_bytes"])
    assert fw.display_marks[0] == (-1, start) and len(fw.display_marks) == len(wrote) + 1
    assert [k for k, _ in fw.display_marks[1:]] == wrote.tolist()
    assert fw.display_marks[-1][1] == len(fw.display)
    assert ((wrote + 1) % 8 == 3).all()  # a turn every 8 ticks (App.ticks is k + 1)
    s = fw.stats
    assert s["display_batches"] == fw.display.count(b"\r\n") > 20
    assert s["display_oks"] == s["display_missed"] == s["display_tx_overflow"] == 0
    navigating = np.zeros(len(t), bool)
    navigating[1:] = (t["state"][1:] == 2) & (t["state"][:-1] == 2)
    turn = (np.arange(len(t)) + 1) % 8 == 3
    assert (navigating & turn).sum() > 80 and np.isin(wrote, np.flatnonzero(navigating)).sum() > 40
    assert np.count_nonzero(t["alloc_bytes"][navigating]) == 0
    fwi = t["instr"].astype(np.int64) - t["emu_instr"]
    plain = navigating & ~turn & (t["display_bytes"] == 0)
    sent = navigating & (t["display_bytes"] > 2)
    print(
        f"navigating tick, median instructions: {np.median(fwi[plain]):.0f} without a turn, "
        f"{np.median(fwi[navigating & turn]):.0f} with one, {np.median(fwi[sent]):.0f} with a "
        f"field sent ({np.median(t['display_bytes'][sent]):.0f} bytes)"
    )


def test_the_firmware_gets_the_boards_heap(quick):
    s = quick[1].firmware_run.stats
    # the free heap of a board whose heap region is the image's, less MicroPython's own
    assert abs(s["free_at_start"] - s["board_free_at_start"]) <= 16
    usable = s["heap_total_bytes"] * m4f_build.BOARD_HEAP_BYTES // m4f_build.GC_HEAP_BYTES
    assert s["board_free_at_start"] == usable - s["system_bytes"]
    assert 0 < s["system_bytes"] < 4096
    assert 0 <= s["ballast_bytes"] < 512  # the reserve fits the emulator: little to scan
    assert s["driver_alloc_bytes"] == 0 and s["float32"] and s["bytes_per_block"] == 16


def test_runs_are_deterministic(tmp_path):
    stim = board_input.simulate("static", 2.0, seed=1).stimulus
    a = m4f.run(stim, tmp_path / "a")
    b = m4f.run(stim, tmp_path / "b")
    assert a.out == b.out
    # Everything but the instruction counts repeats exactly. A count is read from the 25 MHz
    # timer, one step per 40 instructions, whose phase against the instructions can differ
    # between two QEMU runs (seen in full test runs): each reading may then move by one step,
    # so a tick by at most 40 and the running sum too (a phase shift, not a cost change).
    instr = ("instr", "emu_instr")
    others = [n for n in a.per_tick.dtype.names if n not in instr]
    assert np.array_equal(a.per_tick[others], b.per_tick[others])
    for name in instr:
        d = a.per_tick[name].astype(np.int64) - b.per_tick[name]
        assert np.abs(d).max() <= 40 and np.abs(np.cumsum(d)).max() <= 40


PADDING_SETUP = """
def _padding_setup():
    pad = bytearray({n})
    def report():
        return [("padding", len(pad))]
    return report, 0
"""


def test_a_navigating_tick_costs_the_same_wherever_the_heap_put_things(tmp_path):
    """What the heap held before the firmware started (here a bytearray of 16 or 2,000 bytes,
    kept) moves every object the firmware makes. A per-tick Python frame too large for the C
    stack is allocated on the heap at each call, and that search costs what the heap's layout
    says (tests/runtimes/test_frames.py); with none, a plain navigating tick (no fix, no
    extended frame: the median) costs the same to the counter's step, and the mean barely
    moves (the rare event ticks still run Python that allocates). Left out: the tick that
    starts navigation (the alignment's last Python, which allocates)."""
    stim = board_input.simulate("quick_start", 16.0, seed=0).stimulus
    costs = []
    for n in (16, 2000):
        src = PADDING_SETUP.format(n=n).replace("\n", "\r\n")
        r = m4f.run(stim, tmp_path / str(n), guest_setup=(src, "_padding_setup"))
        assert dict(r.stats["report"])["padding"] == n
        t = r.per_tick
        nav = np.flatnonzero(t["state"] == 2)[1:]  # the first starts navigation
        assert len(nav) > 400
        costs.append((t["instr"] - t["emu_instr"])[nav].astype(np.int64))
    a, b = costs
    assert abs(np.median(a) - np.median(b)) <= 80
    assert abs(a.mean() - b.mean()) < 0.02 * a.mean()


def test_the_runs_metrics_carry_the_board_cost(quick):
    stim, r = quick
    fw = r.firmware_run
    decoded = stream.decode(fw.out)

    class Track:  # firmware_metrics wants the track's alignment time, states, health, causes
        align_time_s = None
        state = health = causes = np.zeros(0, int)

    acc = dict.fromkeys(
        ("horiz_rms_m", "vert_rms_m", "vel_rms_m_s", "roll_rms_deg", "pitch_rms_deg",
         "yaw_rms_deg", "horiz_rms_gnss_m", "horiz_max_m", "vel_rms_gnss_m_s",
         "pos_3sigma_coverage", "pos_nees_h"),
    )  # fmt: skip
    acc["outages"] = []
    m = firmware_metrics(fw, decoded, Track(), acc, stim.duration_s)
    nav = m["board_cost"]["phases"]["navigating"]
    fi = nav["firmware_instr"]
    assert fi["p50"] <= fi["p99"] <= fi["max"] and nav["ticks"] > 3000
    assert m["board_heap"]["app_gc_runs"] == fw.stats["app_gc_runs"]
    text = "\n".join(board_cost.lines(m["board_cost"]))
    assert "navigating" in text and "instructions per tick" in text and "MHz" in text


def test_a_firmware_error_names_the_tick_and_a_driver_error_is_an_emulator_error(tmp_path):
    elf = m4f_build.build(progress=None)
    call = (
        "import feed, emulate_m4f\r\n"
        "feed.firmware_error(7, ValueError('boom'), emulate_m4f.exit_firmware_error)\r\n"
    )
    out, rc, _ = m4f._execute(elf, call, tmp_path, None, 60, 10)
    assert rc == m4f.EXIT_FIRMWARE_ERROR and out.error_tick == 7
    assert any("ValueError: boom" in line for line in out.error_lines)
    out, rc, _ = m4f._execute(elf, "raise OSError(5)\r\n", tmp_path, None, 60, 10)
    assert rc == m4f.EXIT_DRIVER_ERROR
    assert any("OSError" in line for line in out.other)
    # a driver that raises inside main ends the run too, even with the heap left full (here
    # its setup fills it for good: the REPL could not compile its next command)
    full = (
        "_x = []\r\ndef _fill():\r\n n = 4096\r\n while n:\r\n  try:\r\n"
        "   _x.append(bytearray(n))\r\n  except MemoryError:\r\n   n //= 2\r\n"
        " raise MemoryError\r\n"
    )
    stim = board_input.simulate("static", 1.0, seed=0).stimulus
    with pytest.raises(EmulatorError, match=r"exit status 4[\s\S]*MemoryError"):
        m4f.run(stim, tmp_path / "m", guest_setup=(full, "_fill"), timeout_s=60)
    stim = board_input.simulate("static", 60.0, seed=0).stimulus
    with pytest.raises(EmulatorError, match=r"did not finish within 1 s") as e:
        m4f.run(stim, tmp_path / "t", timeout_s=1)
    assert not isinstance(e.value, FirmwareError)


def test_the_registry_offers_it_for_parity_only_where_bits_match():
    rt = runtimes.get("m4f")
    assert rt.bit_exact and rt.counts_instructions and rt.own_run_time
    assert parity.bit_exact_runtimes() == ("cpython", "m4f", "f411")
    with pytest.raises(EmulatorError, match="bit-exact runtime"):
        parity.compare(board_input.simulate("static", 0.1).stimulus, runtime="mpy_unix")


def test_no_fused_multiply_add_in_the_build():
    """common.toolchain.C_FLOAT_FLAGS (-ffp-contract=off): without it GCC fuses a*b + c into one
    vfma.f32, rounding once where the float32 contract rounds twice (300 of them otherwise)."""
    elf = m4f_build.build(progress=None)
    assert toolchain.fused_multiply_adds(elf) == []
