"""CPI of MicroPython on an STM32F4: published perf_bench cycles over counted instructions.

The emulated Cortex-M4F (runtimes/m4f) counts instructions, not cycles. To turn its counts into
time on the board, this divides cycles measured on a real STM32F4 by the instructions the same
work takes on the emulated one:

- cycles: MicroPython's tests/perf_bench times on a NUCLEO-F401RE at 84 MHz, published in
  micropython/micropython pull request #18069 ("stm32: Change flash latency for NUCLEO-F401RE.",
  yn386, 2025-09-14), with N=84 M=80, at 5 flash wait states ("before") and at 2 ("after");
  stored as data with their source in perf_bench_f401.json; cycles = us x 84.
- instructions: the same benchmarks (the vendored MicroPython's tests/perf_bench, v1.28.0) with
  the same N and M, run as run-perfbench.py runs them on a board: the benchmark's source, then
  benchrun.py, then `bm_run(84, 80)`, sent as one script through the raw REPL of a freshly
  started board and compiled there. benchrun.py times exactly `run()` (the benchmark's timed
  function, bm_setup() having run before it and result() after it) with `time.ticks_us()`;
  here `time` is replaced, for that script only, by an object whose ticks_us is
  `m4f.icount` (instructions executed, to 40), so the same line measures instructions.
  The board averages 8 such runs; the count is deterministic (with QEMU's SysTick stopped:
  see SHIM), so each benchmark runs twice and the two counts must agree to the counter's 40
  instructions.
- the heap: the garbage collector's work is part of both measurements, so the count is taken
  on a build whose GC heap is the F401 image's, F401_GC_HEAP_BYTES (the same interpreter,
  options and firmware; only MICROPY_HEAP_SIZE differs: build.build_dir). Each benchmark is
  also counted once on the default build (a 113,848-byte heap) to show how much that matters,
  and what one collection costs is measured in another run.

CPI at the F411's 3 wait states (what it needs at 96-100 MHz, between the two published
settings) is interpolated linearly in wait states, per benchmark: a flash access missing the
ART accelerator's cache costs one cycle per wait state, so the stall cycles per instruction
grow in proportion to them.

`calibrate(progress=None)` returns a dict whose keys are stable (a bench-board command reads
them, or docs/benchmarks/cpi.json, which holds the same dict; KEYS, ROW_KEYS and SUMMARY_KEYS
name them and tests/bench/test_cpi.py holds cpi.json to them):

    rows: one dict per measured benchmark, in the published table's order:
        name                        perf_bench file without .py, e.g. "bm_chaos"
        instructions                counted instructions of run() on the F401-heap build
        instructions_runs           [first, second] count (agree to resolution_instructions)
        instructions_default_heap   the count on the default build (GC_HEAP_BYTES heap)
        gc_collect_instructions     one gc.collect() after the benchmark on the F401-sized heap
                                    (a run of its own): what a collection more or less in run()
                                    would change in `instructions`
        norm, result                what benchrun printed besides the time (as on the board)
        expected_result             the benchmark's .exp, else CPython's result (run-perfbench's
                                    truth); result == expected_result is checked
        us_before, us_after         published times, microseconds (5 and 2 wait states)
        cycles_before, cycles_after us x cpu_hz / 1e6
        cpi_before, cpi_after       cycles / instructions
        cpi_f411                    interpolated at f411_wait_states (3)
    summary:
        cpi_low, cpi_high           lowest and highest per-benchmark CPI at either latency
        cpi_central                 median over benchmarks of cpi_f411
        how                         {cpi_low, cpi_high, cpi_central}: how each was chosen
        before, after, f411         {wait_states, min, median, max} of cpi_before/after/f411
        benchmarks                  number of rows
    skipped: {perf_bench name: why it was not measured}
    params {N, M}, cpu_hz, wait_states {before, after}, f411_wait_states,
    gc_heap_bytes, default_gc_heap_bytes, resolution_instructions, source (the PR's),
    board, micropython (version of the tree), toolchain {gcc, qemu}

`python -m host_emulator cpi` (make cpi) runs it, prints the table and writes
docs/benchmarks/cpi.md and cpi.json (`--no-write`: print only).
"""

import json
import pathlib
import statistics
import subprocess
import sys
import textwrap
import time

from common import toolchain
from common.errors import EmulatorError
from host_emulator import args as cli_args
from host_emulator.bench import outputs
from host_emulator.runtimes.m4f import build as m4f_build
from host_emulator.runtimes.m4f import guest

HERE = pathlib.Path(__file__).resolve().parent
PUBLISHED = HERE / "perf_bench_f401.json"
DOCS = HERE.parents[1] / "docs" / "benchmarks"

# The NUCLEO-F401RE image's GC heap: _heap_end - _heap_start of MicroPython v1.28.0's stm32
# port built for a board configured as NUCLEO_F401RE (UART REPL, no USB): the 80 KB RAM of
# boards/stm32f401xe.ld (96 KB less the 16 KB filesystem cache) less the 16 KB stack, the
# 8-byte _estack_reserve and 3,628 bytes of .data and .bss. (Measured once from such a build;
# the vendored tree has no F401 CMSIS headers, so it was compiled as STM32F411xE with the
# F401's linker script, which changes neither .bss nor the heap.)
F401_GC_HEAP_BYTES = 61_900
F411_WAIT_STATES = 3  # RM0383: 3 wait states for 90-100 MHz at 2.7-3.6 V
RESOLUTION = 40  # m4f.INSTR_PER_COUNT: the counter's step
TIMEOUT_S = 300
# The keys of calibrate()'s dict (and cpi.json): stable, described in the module docstring.
KEYS = (
    "rows", "summary", "skipped", "params", "cpu_hz", "wait_states", "f411_wait_states",
    "gc_heap_bytes", "default_gc_heap_bytes", "resolution_instructions", "source", "board",
    "micropython", "toolchain",
)  # fmt: skip
ROW_KEYS = (
    "name", "instructions", "instructions_runs", "instructions_default_heap",
    "gc_collect_instructions", "norm", "result", "expected_result", "us_before", "us_after",
    "cycles_before", "cycles_after", "cpi_before", "cpi_after", "cpi_f411",
)  # fmt: skip
SUMMARY_KEYS = (
    "cpi_low", "cpi_high", "cpi_central", "how", "before", "after", "f411", "benchmarks",
)  # fmt: skip

# Run before the benchmark, in a namespace of its own so that the script's globals are what
# they would be without it (a name added and deleted would leave a deleted slot in the dict):
# - benchrun.py imports ticks_us and ticks_diff from `time`: for this script `time` is an
#   object whose ticks_us counts instructions;
# - QEMU's SysTick (the qemu port's 1 ms tick, every 10**6 instructions) is stopped: where its
#   interrupt lands depends on when the host delivered the pasted script, and the registers
#   it stacks, left below the stack pointer, can later be seen by the garbage collector's
#   conservative scan: with it running, two runs differ by up to a few thousand instructions.
SHIM = """exec('''
import sys, uctypes, m4f
uctypes.struct(0xE000E010, {"csr": 0 | uctypes.UINT32}).csr = 0
class IcountTime:
    ticks_us = m4f.icount
    @staticmethod
    def ticks_diff(a, b):
        return (a - b) & 0x3FFFFFFF
sys.modules["time"] = IcountTime
from time import ticks_us
assert ticks_us is m4f.icount
''', {})
"""


def perf_bench_dir():
    return toolchain.micropython_dir() / "tests" / "perf_bench"


def load_published(path=PUBLISHED):
    """The published figures (perf_bench_f401.json), checked; EmulatorError saying what is
    wrong with them."""
    path = pathlib.Path(path)
    try:
        data = json.loads(path.read_text())
    except OSError as e:
        raise EmulatorError(f"cannot read the published figures {path}: {e.strerror}") from None
    except ValueError as e:
        raise EmulatorError(f"{path} is not JSON: {e}") from None
    try:
        n, m = int(data["params"]["N"]), int(data["params"]["M"])
        hz = float(data["cpu_hz"])
        ws = {k: int(data["runs"][k]["wait_states"]) for k in ("before", "after")}
        benchmarks = data["benchmarks"]
        data["source"]["pull_request"]
        if not benchmarks:
            raise ValueError("no benchmarks")
        for name, b in benchmarks.items():
            for key in ("us_before", "us_after"):
                if not float(b[key]) > 0:
                    raise ValueError(f"{name}: {key} must be positive")
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        what = f"missing {e}" if isinstance(e, KeyError) else str(e)
        raise EmulatorError(f"{path}: not the published figures' layout ({what})") from None
    if not (n > 0 and m > 0 and hz > 0 and ws["before"] != ws["after"]):
        raise EmulatorError(f"{path}: N, M and cpu_hz must be positive, the wait states differ")
    return data


def _source(name):
    path = perf_bench_dir() / f"{name}.py"
    try:
        return path.read_text()
    except OSError:
        raise EmulatorError(
            f"{name}.py is not in {perf_bench_dir()}: a MicroPython tree "
            "with tests/perf_bench is needed (MICROPY_DIR)"
        ) from None


def script(name, n, m):
    """What run-perfbench sends the board for one benchmark: its source, benchrun.py, the
    call (here behind SHIM)."""
    return _source(name) + _source("benchrun") + f"bm_run({n}, {m})\n"


# After bm_run, in a namespace of its own: what one full collection costs on this heap with the
# benchmark's module loaded (how much a collection more or less would change the count). Only in
# a run of its own: any code added to the script takes heap, and on the F401-sized heap a few
# hundred bytes less can bring a collection more into run().
GC_PROBE = """exec('''
import gc, m4f
t0 = m4f.icount()
gc.collect()
print("gc", (m4f.icount() - t0) & 0x3FFFFFFF)
''', {})
"""


def _parse(name, text):
    """(time, norm, result) from benchrun's line: the last one not from GC_PROBE."""
    lines = [x for x in text.strip().splitlines() if x and not x.startswith("gc ")]
    line = lines[-1] if lines else ""
    parts = line.split(None, 2)
    if len(parts) < 3 or "SKIP" in line:
        raise EmulatorError(f"{name} printed no time on the emulated Cortex-M4F: {text.strip()!r}")
    try:
        return int(parts[0]), int(parts[1]), parts[2].strip()
    except ValueError:
        raise EmulatorError(f"{name}: cannot read benchrun's line {line!r}") from None


def count(name, n, m, gc_heap_bytes=F401_GC_HEAP_BYTES, gc_probe=False):
    """One run of a benchmark on a freshly started emulated Cortex-M4F with a GC heap of
    gc_heap_bytes (None: the default build's): {instructions (of run()), norm, result,
    gc_collect_instructions (one gc.collect() afterwards, with gc_probe; else None)}."""
    code = SHIM + script(name, n, m) + (GC_PROBE if gc_probe else "")
    try:
        out = guest.run(code, TIMEOUT_S, gc_heap_bytes=gc_heap_bytes)
    except AssertionError as e:
        raise EmulatorError(f"{name} failed on the emulated Cortex-M4F: {e}") from None
    except subprocess.TimeoutExpired:
        raise EmulatorError(f"{name} did not finish within {TIMEOUT_S} s") from None
    instr, norm, result = _parse(name, out)
    gc_lines = [x for x in out.splitlines() if x.startswith("gc ")]
    if gc_probe and not gc_lines:
        raise EmulatorError(f"{name}: no garbage collection measured: {out.strip()!r}")
    return {
        "instructions": instr,
        "norm": norm,
        "result": result,
        "gc_collect_instructions": int(gc_lines[-1].split()[1]) if gc_probe else None,
    }


def expected_result(name, n, m):
    """What run-perfbench checks the board's result against: the .exp file if the benchmark
    has one, else the result CPython gives for the same script."""
    exp = perf_bench_dir() / f"{name}.py.exp"
    if exp.exists():
        return exp.read_text().strip()
    proc = subprocess.run(
        [sys.executable, "-c", script(name, n, m)], capture_output=True, text=True,
        timeout=TIMEOUT_S,
    )  # fmt: skip
    if proc.returncode != 0:
        raise EmulatorError(f"{name} failed on CPython (the truth):\n{proc.stderr[-800:]}")
    return _parse(name, proc.stdout)[2]


def interpolate(cpi_a, ws_a, cpi_b, ws_b, ws):
    """CPI at `ws` wait states on the line through (ws_a, cpi_a) and (ws_b, cpi_b)."""
    return cpi_a + (cpi_b - cpi_a) * (ws - ws_a) / (ws_b - ws_a)


def skipped(published):
    """Every perf_bench benchmark not measured, with the reason."""
    reasons = dict(published.get("absent", {}))
    out = {}
    for path in sorted(perf_bench_dir().glob("*.py")):
        name = path.stem
        if name == "benchrun" or name in published["benchmarks"]:
            continue
        out[name] = reasons.get(
            name,
            "not in the retrieved part of the published table (its stored copy ends after "
            "core_import_mpy_multi.py), so there is nothing to divide",
        )
        if name.startswith("viper_"):
            out[name] += "; and a viper benchmark times native code, not the interpreter"
    return out


def _tool_version(cmd):
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=30).stdout
    except OSError:
        return None
    return out.splitlines()[0].strip() if out else None


def _stats(values, wait_states):
    return {
        "wait_states": wait_states,
        "min": round(min(values), 4),
        "median": round(statistics.median(values), 4),
        "max": round(max(values), 4),
    }


def _truthful(run, truth, name):
    if run["result"] != truth:
        raise EmulatorError(
            f"{name}: the emulated Cortex-M4F's result {run['result']!r} is not the truth "
            f"{truth!r}: it did not do the benchmark's work"
        )
    return run


def _row(name, pub, first, second, probed):
    """A benchmark's row from its two counts on the F401-sized heap, a third run measuring a
    collection there, and the published times."""
    n, m = int(pub["params"]["N"]), int(pub["params"]["M"])
    i1, i2 = first["instructions"], second["instructions"]
    if abs(i1 - i2) > RESOLUTION or first["result"] != second["result"]:
        raise EmulatorError(
            f"{name}: two runs disagree ({i1} and {i2} instructions, results "
            f"{first['result']!r} and {second['result']!r}): the count is not reproducible"
        )
    truth = expected_result(name, n, m)
    _truthful(first, truth, name)
    _truthful(probed, truth, name)
    hz = float(pub["cpu_hz"])
    ws_b = int(pub["runs"]["before"]["wait_states"])
    ws_a = int(pub["runs"]["after"]["wait_states"])
    us_b = float(pub["benchmarks"][name]["us_before"])
    us_a = float(pub["benchmarks"][name]["us_after"])
    cpi_b, cpi_a = us_b * hz / 1e6 / i1, us_a * hz / 1e6 / i1
    return {
        "name": name,
        "instructions": i1,
        "instructions_runs": [i1, i2],
        "instructions_default_heap": None,  # filled in by calibrate
        "gc_collect_instructions": probed["gc_collect_instructions"],
        "norm": first["norm"],
        "result": first["result"],
        "expected_result": truth,
        "us_before": us_b,
        "us_after": us_a,
        "cycles_before": round(us_b * hz / 1e6, 2),
        "cycles_after": round(us_a * hz / 1e6, 2),
        "cpi_before": round(cpi_b, 4),
        "cpi_after": round(cpi_a, 4),
        "cpi_f411": round(interpolate(cpi_a, ws_a, cpi_b, ws_b, F411_WAIT_STATES), 4),
    }


def calibrate(progress=None, published=None):
    """Measure and divide; the dict described in the module docstring. progress(message) is
    called before each step. EmulatorError if the board cannot be built, a benchmark fails or
    gives another result than the truth, or two runs disagree."""
    say = progress or (lambda message: None)
    pub = load_published(published or PUBLISHED)
    n, m = int(pub["params"]["N"]), int(pub["params"]["M"])
    ws_b = int(pub["runs"]["before"]["wait_states"])
    ws_a = int(pub["runs"]["after"]["wait_states"])
    names = list(pub["benchmarks"])
    for name in names:
        _source(name)  # all present before anything runs
    if not (m4f_build.firmware_elf(F401_GC_HEAP_BYTES)).exists():
        say(f"building the emulated Cortex-M4F with a {F401_GC_HEAP_BYTES} B GC heap (once; ~40 s)")
    m4f_build.build(progress=None, gc_heap_bytes=F401_GC_HEAP_BYTES)
    if not m4f_build.firmware_elf().exists():
        say("building the emulated Cortex-M4F (once; ~40 s)")
    m4f_build.build(progress=None)
    rows = []
    for i, name in enumerate(names, 1):
        say(f"[{i}/{len(names)}] {name}: counting (twice, a collection, the default heap)")
        first, second = count(name, n, m), count(name, n, m)
        rows.append(_row(name, pub, first, second, count(name, n, m, gc_probe=True)))
        rows[-1]["instructions_default_heap"] = _truthful(
            count(name, n, m, gc_heap_bytes=None), rows[-1]["expected_result"], name
        )["instructions"]
    before = [r["cpi_before"] for r in rows]
    after = [r["cpi_after"] for r in rows]
    f411 = [r["cpi_f411"] for r in rows]
    both = before + after
    summary = {
        "cpi_low": round(min(both), 4),
        "cpi_high": round(max(both), 4),
        "cpi_central": round(statistics.median(f411), 4),
        "how": {
            "cpi_low": f"the lowest per-benchmark CPI at either published latency ({ws_a} or "
            f"{ws_b} wait states)",
            "cpi_high": f"the highest per-benchmark CPI at either published latency ({ws_a} or "
            f"{ws_b} wait states)",
            "cpi_central": f"the median over the {len(rows)} benchmarks of the CPI interpolated "
            f"linearly in wait states to the F411's {F411_WAIT_STATES} (at 96-100 MHz)",
        },
        "before": _stats(before, ws_b),
        "after": _stats(after, ws_a),
        "f411": _stats(f411, F411_WAIT_STATES),
        "benchmarks": len(rows),
    }
    return {
        "rows": rows,
        "summary": summary,
        "skipped": skipped(pub),
        "params": {"N": n, "M": m},
        "cpu_hz": float(pub["cpu_hz"]),
        "wait_states": {"before": ws_b, "after": ws_a},
        "f411_wait_states": F411_WAIT_STATES,
        "gc_heap_bytes": F401_GC_HEAP_BYTES,
        "default_gc_heap_bytes": m4f_build.GC_HEAP_BYTES,
        "resolution_instructions": RESOLUTION,
        "source": pub["source"],
        "board": pub.get("board"),
        "micropython": ".".join(map(str, toolchain.micropython_version())),
        "toolchain": {
            "gcc": _tool_version(["arm-none-eabi-gcc", "--version"]),
            "qemu": _tool_version(["qemu-system-arm", "--version"]),
        },
    }


def table(result):
    """The per-benchmark table (markdown) and the summary lines."""
    ws = result["wait_states"]
    f = result["f411_wait_states"]
    lines = [
        f"| benchmark | instructions | F401 us, {ws['before']} WS | F401 us, {ws['after']} WS "
        f"| CPI, {ws['before']} WS | CPI, {ws['after']} WS | CPI, {f} WS (interpolated) "
        f"| one gc.collect() "
        f"| instructions, default heap ({result['default_gc_heap_bytes']:,} B) |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in result["rows"]:
        d = r["instructions_default_heap"] / r["instructions"] - 1
        lines.append(
            f"| {r['name']} | {r['instructions']:,} | {r['us_before']:,.2f} | "
            f"{r['us_after']:,.2f} | {r['cpi_before']:.3f} | {r['cpi_after']:.3f} | "
            f"{r['cpi_f411']:.3f} | {r['gc_collect_instructions']:,} "
            f"({100 * r['gc_collect_instructions'] / r['instructions']:.1f} %) | "
            f"{r['instructions_default_heap']:,} ({100 * d:+.1f} %) |"
        )
    s = result["summary"]
    lines += [
        "",
        f"CPI range {s['cpi_low']:.2f}-{s['cpi_high']:.2f}, central {s['cpi_central']:.2f} "
        f"({s['benchmarks']} benchmarks). Median CPI at {s['before']['wait_states']} wait "
        f"states {s['before']['median']:.2f} ({s['before']['min']:.2f}-"
        f"{s['before']['max']:.2f}), at {s['after']['wait_states']} "
        f"{s['after']['median']:.2f} ({s['after']['min']:.2f}-{s['after']['max']:.2f}), "
        f"interpolated at {f} {s['f411']['median']:.2f} ({s['f411']['min']:.2f}-"
        f"{s['f411']['max']:.2f}).",
    ]
    return "\n".join(lines)


def _reflow(text, width=100):
    """Paragraphs and list items filled to `width`; headings and tables as they are."""
    out = []
    for block in text.strip("\n").split("\n\n"):
        if block.startswith(("#", "|")):
            out.append(block)
            continue
        items, cur = [], []
        for line in block.split("\n"):
            if line.startswith("- ") and cur:
                items.append(cur)
                cur = []
            cur.append(line.strip())
        items.append(cur)
        filled = []
        for item in items:
            bullet = item[0].startswith("- ")
            filled.append(
                textwrap.fill(
                    " ".join(item),
                    width,
                    subsequent_indent="  " if bullet else "",
                    break_long_words=False,
                    break_on_hyphens=False,
                )  # fmt: skip
            )
        out.append("\n".join(filled))
    return "\n\n".join(out) + "\n"


def report(result):
    """docs/benchmarks/cpi.md: how the cycles and the instructions were measured, the table,
    the summary and the skipped benchmarks, how the emulated build differs from the F401's."""
    return _reflow(
        _method_text(result)
        + f"## Per benchmark\n\n{table(result)}\n\n"
        + _summary_text(result)
        + _build_text(result)
    )


def _method_text(result):
    """cpi.md's title and its account of the cycles, the instructions and the heap."""
    src = result["source"]
    n, m = result["params"]["N"], result["params"]["M"]
    mhz = result["cpu_hz"] / 1e6
    ws = result["wait_states"]
    heap = result["gc_heap_bytes"]
    gc_share = [r["gc_collect_instructions"] / r["instructions"] for r in result["rows"]]
    return f"""
# CPI of MicroPython on an STM32F4 (calibration of the instruction counts)

Generated by `make cpi` (`python -m host_emulator cpi`, host_emulator/bench/cpi.py). The
emulated Cortex-M4F (`--runtime m4f`) counts instructions; this gives the cycles per
instruction that turn them into time on the board.

**Cycles** are MicroPython's perf_bench times on a {result["board"]} at {mhz:g} MHz, published
by {src["author"]} on {src["date"]} in [{src["repository"]} pull request
#{src["pull_request"]}]({src["url"]}) ("{src["title"]}"): `run-perfbench.py` with N={n} M={m},
each time the mean of 8 runs, **before** the PR at {ws["before"]} flash wait states (the
port's default, FLASH_LATENCY_5) and **after** it at {ws["after"]} (FLASH_LATENCY_2).
Cycles = us x {mhz:g}. The figures and their source are in
host_emulator/bench/perf_bench_f401.json; the stored copy of the PR they were read from ends
in the middle of the table, so only its first {len(result["rows"])} rows are used.

**Instructions** are those of the same benchmarks (tests/perf_bench of the MicroPython
v{result["micropython"]} tree the emulated board is built from) with the same N and M, run as
run-perfbench runs them on a board: the benchmark's source, benchrun.py and `bm_run({n}, {m})`
as one script through the raw REPL of a freshly started board, compiled there. benchrun.py
times `run()` alone (the benchmark's setup before it, its result after it) with
`time.ticks_us()`; for this script `time.ticks_us` is `m4f.icount`, the instructions executed
(to {result["resolution_instructions"]} instructions), so the same two lines count
instructions. Each benchmark ran twice on the same build and the two counts agree to the
counter's resolution; each result equals run-perfbench's truth (the .exp file, else
CPython's result for the same script).

**The heap.** The garbage collector's work is in both measurements, so the instructions are
counted on a build whose GC heap is the F401 image's, {heap:,} B (the 80 KB of RAM of
stm32f401xe.ld less the 16 KB stack and 3.6 KB of .data and .bss of a v1.28.0 image built as
NUCLEO_F401RE), and otherwise the same as the default one. The last column is the count on the
default build ({result["default_gc_heap_bytes"]:,} B heap): the difference is what the
collections the smaller heap adds cost. How many collections fall inside `run()` depends on
what the heap holds when it starts: a few hundred bytes less free can add one, so each count
is uncertain by about one collection, the `one gc.collect()` column ({100 * min(gc_share):.1f}
to {100 * max(gc_share):.1f} % of the count; measured after the benchmark in a run of its own),
and so is its CPI.

"""


def _summary_text(result):
    """cpi.md's summary (the CPI range and the central value) and its skipped benchmarks."""
    s = result["summary"]
    mhz = result["cpu_hz"] / 1e6
    ws = result["wait_states"]
    by_reason = {}
    for name, why in result["skipped"].items():
        by_reason.setdefault(why, []).append(name)
    skipped_lines = "\n".join(f"- {', '.join(names)}: {why}." for why, names in by_reason.items())
    return f"""## Summary

- **cpi_low = {s["cpi_low"]:.2f}, cpi_high = {s["cpi_high"]:.2f}**: the lowest and the
  highest per-benchmark CPI at either published latency ({ws["after"]} or {ws["before"]} wait
  states).
- **cpi_central = {s["cpi_central"]:.2f}**: {s["how"]["cpi_central"]}. A flash access that
  misses the ART accelerator's cache costs one cycle per wait state, so CPI is taken as linear
  in wait states between the two published settings. The F411 needs
  {result["f411_wait_states"]} wait states above 90 MHz (RM0383, 2.7-3.6 V), so at its 96-100
  MHz; the F401 needs 2 at {mhz:g} MHz (the "after" setting), and "before" ran with 5.
- Time on the board = instructions x CPI / clock: at 100 MHz and CPI {s["cpi_central"]:.2f},
  10,000 instructions take {10_000 * s["cpi_central"] / 100:.0f} us.

## Skipped benchmarks

{skipped_lines}

"""


def _build_text(result):
    """cpi.md's comparison of the emulated build with the F401's firmware."""
    tc = result["toolchain"]
    return f"""## How the emulated build differs from the F401's

The interpreter is the same C (py/, extmod/) with the same options: the qemu port at
MICROPY_CONFIG_ROM_LEVEL_EXTRA_FEATURES like the stm32 port, computed goto (our board sets it
as the stm32 port does), -Os everywhere and -O3 for py/vm.c and py/gc.c (py/py.mk, both
ports), float32 on the single-precision FPU, object representation A. Comparing every
MICROPY_* macro of the two ports as configured (v1.28.0, the stm32 port for
WEACT_F411_BLACKPILL and the qemu port for our M4F_INS; NUCLEO_F401RE's board files set no
interpreter option), what can change these counts is:

- MICROPY_MEM_STATS = 1 and MICROPY_MALLOC_USES_ALLOCATED_SIZE = 1 in the qemu port (0 in the
  stm32 port): a few more instructions for each heap allocation and free (byte counters, sizes
  passed on), so allocation-heavy benchmarks count slightly more here and their CPI comes out
  slightly low;
- MICROPY_GC_STACK_ENTRY_TYPE: uint16_t in the stm32 port, size_t here (the collector's mark
  stack; the same work);
- the heap: sized as the F401's (above), but what the two firmwares allocate before the
  script is not the same (the board mounts its flash filesystem, for one);
- not options, and not ours to match: the PR measured a development version of September
  2025 (between v1.26 and v1.27), this is v{result["micropython"]}; its compiler is not
  stated, this one is {tc["gcc"]}; the board also took its 1 ms SysTick interrupt (of the
  order of 0.1 % of the cycles), which the emulated board has stopped while it counts (where
  that interrupt lands depends on when the host delivered the script, and with it running two
  runs differed by up to a few thousand instructions).

Emulator: {tc["qemu"]}, `-icount shift=0`.
"""


def write(result, out_dir=DOCS):
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "cpi.md").write_text(report(result))
    (out_dir / "cpi.json").write_text(json.dumps(result, indent=1) + "\n")
    return out_dir / "cpi.md", out_dir / "cpi.json"


def _check_out(out_dir):
    out_dir = pathlib.Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise EmulatorError(f"--out {out_dir} is a file, not a directory")


def main(argv=None):
    p = cli_args.Parser(
        prog="python -m host_emulator cpi",
        description="CPI of MicroPython on an STM32F4: published NUCLEO-F401RE perf_bench "
        "cycles over the instructions the same benchmarks take on the emulated Cortex-M4F "
        "(writes docs/benchmarks/cpi.md and cpi.json)",
    )
    p.add_argument("--no-write", action="store_true", help="print the table, write nothing")
    p.add_argument("--out", default=str(DOCS), help="directory for cpi.md and cpi.json")
    p.add_argument("--published", default=str(PUBLISHED), help="the published figures (JSON)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    try:
        args = p.parse_args(argv)
        load_published(args.published)
        if not args.no_write:
            _check_out(args.out)
    except (cli_args.UsageError, EmulatorError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2

    def command():
        t0 = time.perf_counter()

        def progress(message):
            if not args.quiet:
                print(f"{message} ({time.perf_counter() - t0:.0f} s)", file=sys.stderr,
                      flush=True)  # fmt: skip

        if not args.no_write:
            out = pathlib.Path(args.out)
            outputs.announce("cpi", [out / "cpi.md", out / "cpi.json"], stream=sys.stderr)
        result = calibrate(progress, published=args.published)
        print(table(result))
        if not args.no_write:
            for path in write(result, args.out):
                print(f"wrote {path}")
        return 0

    return cli_args.run_reporting(command)
