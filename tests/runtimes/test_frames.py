"""A navigating tick calls no Python function whose frame MicroPython puts on the heap.

MicroPython keeps a bytecode function's frame (its locals, arguments and value stack: n_state
words, plus its exception stack) on the C stack up to VM_MAX_STATE_ON_STACK = 11 words
(py/objfun.c); a larger frame is allocated on the GC heap and freed at every call. Nothing is
left allocated, so the allocation proofs cannot see it, and `micropython.heap_lock()` makes the
VM fall back to the C stack silently; but every such call searches the heap for free blocks, a
cost of thousands of instructions that depends on where the free blocks lie: on the emulated
Cortex-M4F the same navigating tick then cost more or less depending on what the heap held
before the firmware started (docs/native.md). So every function of the default
configuration's navigating tick is held to 11 words here, read from what mpy-cross compiles for
the board (mpy-tool's prelude), and so is the tick where navigation starts.
"""

import importlib.util
import subprocess
import sys

import pytest

from common import toolchain
from common.firmware_env import FIRMWARE_DIR

VM_MAX_STATE_ON_STACK_WORDS = 11  # py/objfun.c: sizeof(mp_uint_t) * 11
EXC_STACK_WORDS = 3  # mp_exc_stack_t: handler, val_sp, prev_exc

# (file under firmware/, qualified name): what a navigating tick calls in Python, kernels
# native (re-anchoring and resets, rarer than once a minute, are left out)
PER_TICK = (
    ("app.py", "App.service"),
    ("app.py", "App._gnss_read"),
    ("app.py", "App._send_frame"),
    ("app.py", "App._send_ext"),
    ("app.py", "App._send_ext_state"),
    ("lib/nav.py", "Navigator.imu_counts"),
    ("lib/records.py", "ExtFrame.pack"),
    ("drivers/bmi055.py", "BMI055.read"),
    # the fix path, once a second: the epoch's sentence, its delivery and screening
    ("app.py", "App._deliver_fix"),
    ("app.py", "App._fix_fields"),
    ("app.py", "App._no_fix"),
    ("app.py", "App._fix_tick"),
    ("app.py", "App._late_s"),
    ("app.py", "App._pps_seen"),
    ("lib/nav.py", "Navigator.gnss_fix"),
    ("lib/nav.py", "Navigator._take_fix"),
    ("lib/nav.py", "Navigator._reset_event"),
    ("lib/nav.py", "Navigator._nav_fix"),
    ("lib/nav.py", "Navigator._fix_usable"),
    ("lib/geo.py", "LocalFrame.to_enu"),
    ("drivers/gnss.py", "Nmea.feed"),
    ("drivers/gnss.py", "Nmea.rejected"),
    ("drivers/gnss.py", "Nmea._end"),
    ("drivers/gnss.py", "Nmea._gga"),
    ("drivers/gnss.py", "Nmea._rmc"),
    ("drivers/gnss.py", "Nmea._vtg"),
    ("drivers/gnss.py", "Nmea._gsa"),
    ("drivers/gnss.py", "Nmea._epoch_time"),
    ("drivers/gnss.py", "Nmea._speed"),
    ("drivers/gnss.py", "Nmea._complete"),
    # the tick that starts navigation, from the receiver's course, the track or the yaw
    # estimator (whose step is every aligning fix's once levelled)
    ("lib/nav_align.py", "Alignment._align_fix"),
    ("lib/nav_align.py", "Alignment._gsf_align"),
    ("lib/nav_align.py", "Alignment._gsf_start"),
    ("lib/nav_align.py", "Alignment._gsf_speed"),
    ("lib/nav_align.py", "Alignment._track"),
    ("lib/nav_align.py", "Alignment._track_window"),
    ("lib/nav_align.py", "Alignment._start_navigation"),
    # the status page's turn, every 8th tick with the display setting on (docs/display.md)
    ("board.py", "_Chars.write_n"),
    ("lib/status_page.py", "StatusPage.turn"),
    ("lib/status_page.py", "StatusPage._make"),
    ("lib/status_page.py", "StatusPage._unchanged"),
    ("lib/status_page.py", "StatusPage._same"),
    ("lib/status_page.py", "StatusPage._fix"),
    ("lib/status_page.py", "StatusPage._angle"),
    ("lib/status_page.py", "StatusPage._speed"),
    ("lib/status_page.py", "StatusPage._motion"),
    ("lib/status_page.py", "StatusPage._health"),
    ("lib/status_page.py", "StatusPage._cause"),
    ("lib/status_page.py", "StatusPage._draw"),
    ("lib/status_page.py", "StatusPage._send"),
    ("lib/status_page.py", "StatusPage._end"),
    ("lib/status_page.py", "_sign"),
    ("lib/status_page.py", "_put"),
    ("lib/status_page.py", "_two"),
    ("lib/status_page.py", "_dec"),
    ("lib/status_page.py", "_i16"),
    ("lib/status_page.py", "_i32"),
    ("lib/status_page.py", "_clamp"),
    ("lib/status_page.py", "var_cm2"),
    ("lib/status_page.py", "isqrt"),
    ("lib/status_page.py", "first_cause"),
    ("lib/status_page.py", "_bits"),
)


def _mpy_tool():
    tree = toolchain.micropython_dir()
    sys.path.insert(0, str(tree / "py"))  # mpy-tool imports makeqstrdata
    try:
        spec = importlib.util.spec_from_file_location("mpy_tool", tree / "tools" / "mpy-tool.py")
        tool = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(tool)
    finally:
        sys.path.remove(str(tree / "py"))
    tool.global_qstrs = tool.GlobalQStrList()
    return tool


def frame_words(source, tmp_path):
    """{qualified name: frame words} of every function in a source file (a path under
    firmware/, or any path), as compiled for the board (armv7emsp)."""
    source = FIRMWARE_DIR / source
    out = tmp_path / (source.stem + ".mpy")
    subprocess.run(
        [str(toolchain.mpy_cross()), "-march=armv7emsp", "-o", str(out), str(source)], check=True
    )
    tool = _mpy_tool()
    words = {}

    def walk(rc, prefix):
        name = rc.simple_name.str
        qual = f"{prefix}.{name}" if prefix else name
        if hasattr(rc, "prelude_signature"):
            n_state, n_exc = rc.prelude_signature[0], rc.prelude_signature[1]
            words[qual] = n_state + EXC_STACK_WORDS * n_exc
        for child in rc.children:
            walk(child, "" if name == "<module>" else qual)

    walk(tool.read_mpy(str(out)).raw_code, "")
    return words


@pytest.fixture(scope="module")
def compiled(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("frames")
    return {path: frame_words(path, tmp) for path in {p for p, _ in PER_TICK}}


@pytest.mark.parametrize("path, name", PER_TICK)
def test_a_per_tick_function_keeps_its_frame_on_the_c_stack(compiled, path, name):
    words = compiled[path]
    assert name in words, f"{path} has no {name}: update PER_TICK"
    assert words[name] <= VM_MAX_STATE_ON_STACK_WORDS, (
        f"{path} {name}: a frame of {words[name]} words is allocated on the heap at every call"
    )


def test_the_reading_counts_locals_stack_and_exception_handlers(tmp_path):
    """Frames of known size: n_state is the locals (arguments included) plus the deepest value
    stack; a try block adds an exception-stack entry."""
    src = tmp_path / "sizes.py"
    src.write_text(
        "def small(a):\n"
        "    return a\n"
        "def many(a, b, c, d, e, f, g, h, i, j, k, l):\n"
        "    return a\n"
        "def guarded(a):\n"
        "    try:\n"
        "        return a\n"
        "    except ValueError:\n"
        "        return None\n"
    )
    words = frame_words(src, tmp_path)
    assert words["small"] <= 2
    assert words["many"] >= 13 > VM_MAX_STATE_ON_STACK_WORDS
    assert words["guarded"] >= words["small"] + EXC_STACK_WORDS
