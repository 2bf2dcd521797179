"""What a tick costs on the emulated STM32F411 (the f411 runtime: the image itself, its C
drivers, interrupts and DMA, on the clock the image sets), from FirmwareRun.per_tick.

Per tick k, from its timer moment T_k to T_(k+1) (runtimes/f411/world.py): busy = T_k to the
loop's return to WFI (the tick's whole work: the timer interrupt, the loop's pass, the port's
drivers, the frames handed to the DMA), late when that ran past T_(k+1); the instructions of
the interval, of which in interrupt handlers and in the port's UART and SPI/DMA code (by C
function name), and the cycles the bus fast-forwarded over polled peripheral flags (a blocking
UART write's spin on TXE is one). The phase of a tick is the navigation state its frame carries.

The targets: a navigating tick of at most 2.0 ms at p99 and 3.5 ms at most, and no tick late or
missed, alignment included (1.5 ms of every tick left for what comes next).
"""

import numpy as np

from common.proto import stream

TARGET_MS = {"p99": 2.0, "max": 3.5}
# the f411 runtime's run figures a report keeps (runtimes/f411/world.py's stats)
RUN_KEYS = ("board", "overruns", "late_ticks", "watchdog_longest_gap_ms", "watchdog_timeout_ms",
            "gnss_rx_lost", "gnss_bytes_compressed", "rs485_muted", "poll_wait_ms_by_peripheral",
            "realtime_factor")  # fmt: skip
PHASES = {1: "aligning", 2: "navigating"}


def _stats(x):
    if not len(x):
        return None
    return {"mean": float(np.mean(x)), "p50": float(np.percentile(x, 50)),
            "p99": float(np.percentile(x, 99)), "max": float(np.max(x))}  # fmt: skip


def states(out, ticks):
    """The navigation state of each tick, from the frames (one per tick, or every n-th)."""
    frames = stream.decode(out).frames
    if not frames:
        return np.zeros(ticks, np.uint8)
    s = np.array([f["nav_state"] for f in frames], np.uint8)
    every = max(1, round(ticks / len(s)))
    return np.repeat(s, every)[:ticks] if len(s) * every >= ticks else np.resize(s, ticks)


def summary(per_tick, tick_states, hz, cpi, tick_us=5000):
    """The figures of a run (JSON-ready)."""
    ms = 1000.0 / hz
    out = {"hclk_hz": hz, "cpi": cpi, "tick_ms": tick_us / 1000, "phases": {}}
    for state, name in PHASES.items():
        m = tick_states == state
        if not m.any():
            continue
        r = per_tick[m]
        busy = r["busy_cycles"] * ms
        out["phases"][name] = {
            "ticks": int(m.sum()),
            "busy_ms": _stats(busy),
            "instr": _stats(r["instr"]),
            "handler_instr": _stats(r["handler_instr"]),
            "uart_instr": _stats(r["uart_instr"]),
            "spi_dma_instr": _stats(r["spi_dma_instr"]),
            "gc_instr": _stats(r["gc_instr"]),
            "poll_wait_ms": _stats(r["poll_wait_cycles"] * ms),
            "exceptions": _stats(r["exceptions"]),
            "late_ticks": int(r["late"].sum()),
            "over_4ms": int(np.sum(busy > 4.0)),
        }
    return out


def lines(s, run=None):
    """A few lines for a console or a report (run: the RUN_KEYS figures)."""
    out = []
    if run:
        out.append(
            f"{run['board']}: {run['overruns']} ticks missed (the firmware's count), "
            f"{run['late_ticks']} late; watchdog fed at most {run['watchdog_longest_gap_ms']:.1f} "
            f"ms apart (timeout {run['watchdog_timeout_ms']:g} ms)"
        )
    for name, ph in s["phases"].items():
        b = ph["busy_ms"]
        # a late tick's busy time is counted up to the next tick's moment (its end merges
        # with the next tick's work): its max is "at least the period"
        top = f">= {s['tick_ms']:g} (late)" if ph["late_ticks"] else f"{b['max']:.2f}"
        out.append(
            f"{name} ({ph['ticks']} ticks): busy {b['mean']:.2f} ms mean, p99 {b['p99']:.2f}, "
            f"max {top} of the {s['tick_ms']:g} ms tick at {s['hclk_hz'] / 1e6:g} MHz, "
            f"CPI {s['cpi']:g}; {ph['late_ticks']} late"
        )
        out.append(
            f"  per tick: {ph['instr']['mean']:,.0f} instructions (interrupts "
            f"{ph['handler_instr']['mean']:,.0f}, UART code {ph['uart_instr']['mean']:,.0f}, "
            f"SPI/DMA code {ph['spi_dma_instr']['mean']:,.0f}), polled waits "
            f"{ph['poll_wait_ms']['mean']:.3f} ms mean"
        )
    return out
