"""What a tick costs the board, from the m4f runtime's per-tick counts (runtimes/m4f: the
unmodified app loop on an emulated Cortex-M4F, instructions counted to 40).

Per phase (aligning, navigating: the navigation state after the tick):
- firmware instructions per tick (executed minus those spent in the emulated peripherals,
  which on the board are C drivers and hardware): mean, p50, p99, max;
- the emulation's own instructions (reported, never counted as firmware);
- garbage collection: how many ticks ran the app's gc.collect() (firmware/app.py's low-water
  rule), every how many ticks, and what one costs (the collecting ticks' mean minus the other
  ticks' mean, same phase);
- bytes allocated per tick (ticks without a collection; one 16-byte block per boxed float);
- time per tick at CLOCK_HZ for each CPI (cycles per instruction, docs/benchmarks/cpi.md) and
  the share of ticks that would overrun the 5 ms tick.

Not counted (so the times are a floor): interrupt entry and exit, the real peripherals'
drivers (SPI and UART transfers in C, DMA), and flash wait states beyond what the CPI holds.
"""

import json
import pathlib

import numpy as np

PHASES = {1: "aligning", 2: "navigating"}
# the m4f run's heap and start-up figures (FirmwareRun.stats keys) a report quotes
HEAP_KEYS = ("free_at_start", "live_after_start", "system_bytes", "emulator_bytes",
             "ballast_bytes", "startup_instructions", "app_gc_runs")  # fmt: skip
CLOCK_HZ = 100e6  # the F411's maximum; the WEACT_F411_BLACKPILL image runs at 96 MHz
CPI_FILE = pathlib.Path(__file__).resolve().parents[2] / "docs" / "benchmarks" / "cpi.json"
# Until docs/benchmarks/cpi.json exists (make cpi): the range of docs/requirements.md, time budget
CPI_FALLBACK = {
    "cpi_low": 1.65,
    "cpi_central": 2.05,
    "cpi_high": 2.43,
    "source": "docs/requirements.md, time budget",
}


def cpi_range():
    """(low, central, high, source) of MicroPython's cycles per instruction on an STM32F4."""
    c = CPI_FALLBACK
    if CPI_FILE.exists():
        try:
            c = json.loads(CPI_FILE.read_text())["summary"]
            c = {**c, "source": "docs/benchmarks/cpi.md"}
        except (ValueError, KeyError):
            c = CPI_FALLBACK
    return c["cpi_low"], c["cpi_central"], c["cpi_high"], c["source"]


# instructions: the p99 and max per tick of docs/requirements.md, time budget
OVER_LINES = (50_000, 100_000)


def _stats(x):
    if not len(x):
        return None
    return {
        "mean": float(np.mean(x)),
        "p50": float(np.percentile(x, 50)),
        "p99": float(np.percentile(x, 99)),
        "max": int(np.max(x)),
    }


def summary(per_tick, tick_us=5000, clock_hz=CLOCK_HZ):
    """The cost figures of a run (a dict, JSON-ready) from FirmwareRun.per_tick."""
    fw = per_tick["instr"].astype(np.int64) - per_tick["emu_instr"]
    emu = per_tick["emu_instr"].astype(np.int64)
    collected = per_tick["collected"] > 0
    low, central, high, source = cpi_range()
    budget_instr = {c: tick_us * 1e-6 * clock_hz / c for c in (low, central, high)}
    out = {
        "clock_hz": clock_hz,
        "cpi": {"low": low, "central": central, "high": high, "source": source},
        "phases": {},
    }
    for state, name in PHASES.items():
        m = per_tick["state"] == state
        if not m.any():
            continue
        f = fw[m]
        c = collected[m]
        quiet = f[~c]
        ph = {
            "ticks": int(m.sum()),
            "firmware_instr": _stats(f),
            "firmware_instr_without_gc": _stats(quiet),
            "emulation_instr": _stats(emu[m]),
            "gc_collections": int(c.sum()),
            "ticks_per_collection": float(m.sum() / c.sum()) if c.any() else None,
            "gc_collect_instr": float(np.mean(f[c]) - np.mean(quiet))
            if c.any() and len(quiet)
            else None,
            "alloc_bytes_per_tick": _stats(per_tick["alloc_bytes"][m][~c]),
            # ticks beyond the p99 and max budget lines (docs/requirements.md, time budget)
            "ticks_over": {f"{t}": int(np.sum(f > t)) for t in OVER_LINES},
            "time_ms": {},
        }
        for cpi in (low, central, high):
            to_ms = cpi / clock_hz * 1e3
            ph["time_ms"][f"{cpi:g}"] = {
                "mean": ph["firmware_instr"]["mean"] * to_ms,
                "p99": ph["firmware_instr"]["p99"] * to_ms,
                "max": ph["firmware_instr"]["max"] * to_ms,
                "overrun_share": float(np.mean(f > budget_instr[cpi])),
                "overrun_ticks": int(np.sum(f > budget_instr[cpi])),
            }
        out["phases"][name] = ph
    return out


def lines(s):
    """A few lines for a console or a report."""
    low, central, high = s["cpi"]["low"], s["cpi"]["central"], s["cpi"]["high"]
    mhz = s["clock_hz"] / 1e6
    out = []
    for name, ph in s["phases"].items():
        fi = ph["firmware_instr"]
        t = ph["time_ms"][f"{central:g}"]
        gc = (
            f"gc.collect every {ph['ticks_per_collection']:.0f} ticks, "
            f"~{ph['gc_collect_instr']:,.0f} instructions each"
            if ph["gc_collections"] and ph["gc_collect_instr"] is not None
            else "no gc.collect"
        )
        out.append(
            f"{name} ({ph['ticks']} ticks): {fi['mean']:,.0f} instructions per tick mean, p99 "
            f"{fi['p99']:,.0f}, max {fi['max']:,} (emulation excluded: "
            f"{ph['emulation_instr']['mean']:,.0f} mean); {gc}"
        )
        shares = " / ".join(
            f"{100 * ph['time_ms'][f'{c:g}']['overrun_share']:.1f} %" for c in (low, central, high)
        )
        out.append(
            f"  at {mhz:g} MHz, CPI {central:g} ({low:g}-{high:g}): {t['mean']:.2f} ms mean, "
            f"p99 {t['p99']:.2f} ms of the 5 ms tick; overruns {shares} of ticks"
        )
    return out
