"""Board benchmark: `python -m host_emulator bench-board [--scenario S] [--duration S]
[--out FILE] [--jobs N]` (make bench-board).

Runs the unmodified app loop on the emulated Cortex-M4F (runtimes/m4f) over a whole simulated
drive, once with the default configuration, once with coning on and 2 filter slices per tick,
and once with a 10 Hz receiver (at 115200 baud: the filter then runs 4 slices per tick), and
over a hand-held walk (walk_real, 300 s: a walk's resets, which a drive seldom has), and
writes what a tick costs the board's CPU (eval/board_cost.py: instructions per tick
by phase, the emulation set apart, garbage collection, time per tick at 100 MHz for the CPI
range, overruns) together with the heap, the start-up and the firmware image's budget, to
FILE (default docs/benchmarks/board.md; the numbers in a .json and a plot beside it).

Beside it, the image itself on the emulated STM32F411 (runtimes/f411) over the same drive,
raw-input records off and on, with the 10 Hz receiver, with the screen's status page (the
display setting on, the UsartGPU on USART6), and over the walk: the time each tick takes at
the image's 96 MHz, the port's drivers, interrupts and DMA included (eval/board_time.py), and
what a turn of the page costs, tick by tick against the run without it.

The emulated Cortex-M4F runs at about 3x real time, the emulated STM32F411 at 1.1-1.7x (two
runs at a time), so the default (urban_drive, 600 s, and the walk: nine runs on two processes)
takes about twenty minutes (18 min at 5be7785). It is a
benchmark: the design budget (docs/requirements.md, time budget: p99 <= 50,000 and max <=
100,000 instructions per tick, no gc.collect while navigating) and the image's targets (a
navigating tick at most 2.0 ms at p99 and 3.5 ms at most, no tick late or missed) are reported
against, not asserted.
"""

import json
import pathlib
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from common.errors import EmulatorError
from common.firmware_env import REPO_DIR
from host_emulator import args as cli_args
from host_emulator.bench import figures, outputs
from host_emulator.eval import board_cost
from host_emulator.runtimes.m4f import build as m4f_build

# label, the board settings over the defaults, the simulated receiver (sim/gnss.py GnssModel
# fields over its defaults: a 10 Hz receiver needs more than 9600 baud)[, a scenario of its own
# instead of the bench's, over its default duration unless --duration says]
_10_HZ = {"rate_hz": 10, "baud": 115200}
WALK = "walk_real"
VARIANTS = (
    ("default (coning off, 1 slice per tick)", {}, {}),
    ("coning on, 2 slices per tick", {"coning": 1, "slices_per_tick": 2}, {}),
    ("default, a 10 Hz receiver", {}, _10_HZ),
    ("default, a hand-held walk (walk_real)", {}, {}, WALK),
)
# the image itself on the emulated STM32F411 (runtimes/f411): the default configuration with
# the raw-input records off and on (the output's heaviest load), with a 10 Hz receiver, and
# with the screen's status page (compared tick by tick with the first: page_lines)
TWIN_VARIANTS = (
    ("image, raw_record off", {}, {}),
    ("image, raw_record on", {"raw_record": 1}, {}),
    ("image, a 10 Hz receiver", {}, _10_HZ),
    ("image, the screen's status page", {"display": 1}, {}),
    ("image, a hand-held walk (walk_real)", {}, {}, WALK),
)
# each configuration's short name in board.json ("id"), by which docs quote its figures
# (bench/figures.py: twin.<id>.*, m4f.<id>.*)
IDS = {
    "default (coning off, 1 slice per tick)": "default",
    "coning on, 2 slices per tick": "coning",
    "default, a 10 Hz receiver": "10hz",
    "image, raw_record off": "off",
    "image, raw_record on": "raw",
    "image, a 10 Hz receiver": "10hz",
    "image, the screen's status page": "page",
    "default, a hand-held walk (walk_real)": "walk",
    "image, a hand-held walk (walk_real)": "walk",
}
# the f411 runtime's figures of the screen (runtimes/f411/world.py Screen.stats)
SCREEN_KEYS = ("display_bytes", "display_batches", "display_oks", "display_missed",
               "display_cause_frames", "display_rx_lost")  # fmt: skip
# status_page: a turn every 8 ticks at the app's ticks 3 mod 8, the batch's end at 107 mod 128
# (tick k runs with the app's ticks k + 1)
PAGE_SLOT, PAGE_PHASE, PAGE_ROUND, PAGE_END = 8, 3, 128, 107
# a tick whose garbage collector ran (a collection, or a long search for a free block): more
# instructions in gc_* than the hard interrupts' gc_lock/gc_unlock (10 a tick) and a small
# allocation take; page_cost leaves these ticks out
GC_TICK_INSTR = 5_000
# each variant's configuration in `make bench-nav` (docs/benchmarks/navigation.json), whose
# accuracy the report sets beside the cost
NAV_PROFILES = {
    "default (coning off, 1 slice per tick)": "car",
    "coning on, 2 slices per tick": "car, coning on, 2 slices per tick",
    "default, a 10 Hz receiver": "rate: 10 Hz",
}
NAV_JSON = REPO_DIR / "docs" / "benchmarks" / "navigation.json"
# A whole app tick once navigating (docs/requirements.md: the time budget's p99 and max, the
# project targets' mean, 0.6 ms at CPI 2.05 and 100 MHz, and no overrun at the high CPI)
BUDGET = {"mean": 30_000, "p99": 50_000, "max": 100_000}
DEFAULT_OUT = REPO_DIR / "docs" / "benchmarks" / "board.md"


def _run_runtime(runtime, label, overrides, receiver, scenario, duration):
    """(stimulus, FirmwareRun) of one configuration on `runtime` with the receiver's GnssModel
    fields, progress every 10 %; or (stimulus, the error's message): what the board would do
    is a finding."""
    from host_emulator import runtimes
    from host_emulator.sim import board_input
    from host_emulator.sim import gnss as sim_gnss

    model = sim_gnss.GnssModel(**receiver) if receiver else None
    stim = board_input.simulate(scenario, duration, 0, gnss_model=model).stimulus
    t = time.perf_counter()
    last = [-1]

    def progress(k, n):
        decile = 10 * k // n
        if decile > last[0]:
            last[0] = decile
            print(f"  {label}: {100 * k // n:3d} % ({time.perf_counter() - t:.0f} s)", flush=True)

    try:
        with tempfile.TemporaryDirectory(prefix="bench-board-") as d:
            return stim, runtimes.get(runtime).run(stim, pathlib.Path(d), overrides, progress)
    except EmulatorError as e:
        print(f"  {label}: failed: {e}", flush=True)
        return stim, str(e)


def _one(task):
    """One variant on the m4f runtime: (label, overrides, receiver, scenario, duration) ->
    result dict."""
    label, overrides, receiver, scenario, duration = task
    stim, fw = _run_runtime("m4f", label, overrides, receiver, scenario, duration)
    if isinstance(fw, str):  # e.g. a firmware exception on the board's heap
        return {"label": label, "overrides": overrides, "receiver": receiver, "error": fw}
    return {
        "label": label,
        "id": IDS[label],
        "overrides": overrides,
        "receiver": receiver,
        "scenario": scenario,
        "duration_s": duration,
        "ticks": fw.ticks,
        "wall_s": fw.wall_s,
        "cost": board_cost.summary(fw.per_tick, stim.tick_us),
        "heap": {k: fw.stats[k] for k in board_cost.HEAP_KEYS},  # fmt: skip
        "overruns_reported": fw.stats["overruns"],
        "per_tick_fw": (fw.per_tick["instr"].astype(np.int64) - fw.per_tick["emu_instr"]).tolist(),
        "per_tick_state": fw.per_tick["state"].tolist(),
        "per_tick_collected": fw.per_tick["collected"].tolist(),
    }


def _one_twin(task):
    """One configuration on the f411 runtime (the image on the emulated STM32F411)."""
    label, overrides, receiver, scenario, duration = task
    from host_emulator.eval import board_time

    stim, fw = _run_runtime("f411", label, overrides, receiver, scenario, duration)
    if isinstance(fw, str):  # e.g. the chip reset by its watchdog
        return {"label": label, "overrides": overrides, "receiver": receiver, "error": fw,
                "twin": True}  # fmt: skip
    states = board_time.states(fw.out, fw.ticks)
    hz = fw.stats["hclk_hz"]
    return {
        "label": label,
        "id": IDS[label],
        "overrides": overrides,
        "receiver": receiver,
        "scenario": scenario,
        "duration_s": duration,
        "twin": True,
        "ticks": fw.ticks,
        "wall_s": fw.wall_s,
        "time": board_time.summary(fw.per_tick, states, hz, fw.stats["cpi"], stim.tick_us),
        "run": {k: fw.stats.get(k) for k in board_time.RUN_KEYS},
        "screen": {k: fw.stats[k] for k in SCREEN_KEYS if k in fw.stats},
        "per_tick_busy_ms": (fw.per_tick["busy_cycles"] * 1000.0 / hz).round(4).tolist(),
        "per_tick_gc": (fw.per_tick["gc_instr"] > GC_TICK_INSTR).tolist(),
        "per_tick_state": states.tolist(),
    }


def _run_task(task):
    return _one_twin(task[1:]) if task[0] == "f411" else _one(task[1:])


def tasks(scenario, duration, default_duration):
    """The runs: (runtime, label, overrides, receiver, scenario, duration) of every variant,
    the image's first (the longest runs); default_duration(name): a scenario's own."""
    out = []
    for runtime, variants in (("f411", TWIN_VARIANTS), ("m4f", VARIANTS)):
        for label, overrides, receiver, *own in variants:
            name = own[0] if own else scenario
            out.append((runtime, label, overrides, receiver, name,
                        duration or default_duration(name)))  # fmt: skip
    return out


def _other_scenarios(runs, scenario):
    """'; the walk's rows over walk_real (300 s, seed 0)' for the runs over another scenario."""
    other = sorted({(r["scenario"], r["duration_s"]) for r in runs
                    if r.get("scenario", scenario) != scenario})  # fmt: skip
    return "".join(f"; the rows that name {name} over it ({dur:g} s, seed 0)"
                   for name, dur in other)  # fmt: skip


def image_budget():
    """(the firmware image's budget lines, None), building it if needed (tools/image, cached:
    seconds), or (None, the reason) if it cannot be built here."""
    try:
        from common import toolchain
        from tools.image import budget, build

        report = build.build(build.DEFAULT_BOARD, log=lambda *_: None)
    except (ImportError, toolchain.ToolchainError, build.ImageError) as e:
        return None, str(e)
    lines = [f"{report['board']} ({report['description']}), MicroPython {report['micropython']}:"]
    lines += budget.report_lines(report["figures"])
    return lines, None


def _per_tick_figure(results, path, key, scale, ylabel, xlabel, title, decorate):
    """One panel per run: results[i][key] per tick (x scale), aligning and navigating ticks in
    their colours; decorate(ax, run) adds the run's lines."""
    if not results:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(results), 1, figsize=(10, 3.2 * len(results)), sharex=True)
    axes = np.atleast_1d(axes)
    for ax, r in zip(axes, results, strict=True):
        y = np.array(r[key]) * scale
        state = np.array(r["per_tick_state"])
        t = np.arange(len(y)) * 0.005
        for s, name, color in ((1, "aligning", "C1"), (2, "navigating", "C0")):
            m = state == s
            ax.plot(t[m], y[m], ".", ms=1, color=color, label=name)
        decorate(ax, r, t, y)
        ax.set_ylabel(ylabel)
        ax.set_title(r["label"])
        ax.legend(loc="upper right", markerscale=6, fontsize=8)
    axes[-1].set_xlabel(xlabel)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _plot(results, path):
    def decorate(ax, r, t, y):
        gc = np.array(r["per_tick_collected"]) > 0
        ax.plot(t[gc], y[gc], ".", ms=2, color="C3", label="tick with gc.collect")
        ax.axhline(BUDGET["p99"] / 1e3, color="k", ls="--", lw=0.8, label="budget p99 50k")

    _per_tick_figure(results, path, "per_tick_fw", 1e-3, "thousand instructions",
                     "time since power-on, s",
                     "Firmware instructions per 5 ms tick on the emulated Cortex-M4F",
                     decorate)  # fmt: skip


def _plot_twin(results, path):
    from host_emulator.eval import board_time

    def decorate(ax, r, t, y):
        for key, ls in (("p99", "--"), ("max", ":")):
            v = board_time.TARGET_MS[key]
            ax.axhline(v, color="k", ls=ls, lw=0.8, label=f"target {key} {v:g} ms")
        ax.axhline(5.0, color="C3", lw=0.8, label="the 5 ms tick")

    _per_tick_figure(results, path, "per_tick_busy_ms", 1.0, "ms", "time since the first tick, s",
                     "Busy time per 5 ms tick of the image on the emulated STM32F411 (96 MHz)",
                     decorate)  # fmt: skip


def twin_lines(twin, m4f_results):
    """The section on the image executed on the emulated STM32F411."""
    from host_emulator.eval import board_time

    if not twin:
        return []
    ok = [r for r in twin if "error" not in r]
    cpi = ok[0]["time"]["cpi"] if ok else 0
    lines = [
        "",
        "## The image on the emulated STM32F411",
        "",
        "The same drive on `--runtime f411` (docs/image.md): the image `make image` builds "
        "(WEACT_F411_BLACKPILL), executed instruction by instruction on the emulated STM32F411 "
        "with deploy's main.py, ins.cfg and navk.mpy on its filesystem: MicroPython's own "
        "drivers, interrupts and DMA run as on the board, on the clock the image sets (96 MHz). "
        f"Time = instructions x CPI {cpi:g} (cpi.md's highest) + waits + 12 cycles per "
        "exception entry and return. Busy: from the tick's timer interrupt to the loop's return "
        "to WFI (the IMU read by SPI and DMA, the NMEA bytes, the navigator, the frames handed "
        "to the DMA); late: still busy at the next tick's moment (a tick is missed only when "
        "two periods pass: the firmware's own count). Instructions: everything the core "
        "executed in the tick's 5 ms, of which in interrupt handlers and in the port's UART and "
        "SPI/DMA C code; polled waits: what the core spent spinning on a peripheral's flag.",
        "",
        "| configuration | phase | ticks | busy ms mean | p50 | p99 | max | late | over 4 ms | "
        "instructions mean / p99 | in interrupts | UART code | SPI/DMA code | polled waits ms "
        "mean / max |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in ok:
        for phase, ph in r["time"]["phases"].items():
            b = ph["busy_ms"]
            top = ">= 5 (late)" if ph["late_ticks"] else f"{b['max']:.2f}"
            lines.append(
                f"| {r['label']} | {phase} | {ph['ticks']} | {b['mean']:.2f} | {b['p50']:.2f} | "
                f"{b['p99']:.2f} | {top} | {ph['late_ticks']} | {ph['over_4ms']} | "
                f"{ph['instr']['mean']:,.0f} / {ph['instr']['p99']:,.0f} | "
                f"{ph['handler_instr']['mean']:,.0f} | {ph['uart_instr']['mean']:,.0f} | "
                f"{ph['spi_dma_instr']['mean']:,.0f} | {ph['poll_wait_ms']['mean']:.3f} / "
                f"{ph['poll_wait_ms']['max']:.3f} |"
            )
    for r in twin:
        if "error" in r:
            lines += ["", f"**{r['label']}: the run failed:**", "", "```", r["error"], "```"]
    if not ok:
        return lines
    lines += ["", "![busy time per tick](board_time.png)", "", "### Against the targets", ""]
    lines += [_twin_target_line(r, board_time.TARGET_MS) for r in ok]
    lines += page_lines(ok)
    m4f_nav = [r["cost"]["phases"]["navigating"]["firmware_instr"]["mean"]
               for r in m4f_results if "error" not in r
               and "navigating" in r["cost"]["phases"]][:1]  # fmt: skip
    nav0 = ok[0]["time"]["phases"].get("navigating")
    if m4f_nav and nav0:
        lines += [
            "",
            f"Beside the emulated Cortex-M4F above: a navigating tick of the default "
            f"configuration there counts {m4f_nav[0]:,.0f} firmware instructions (the emulated "
            f"peripherals left out); the image executes {nav0['instr']['mean']:,.0f} in the "
            "tick's 5 ms: the port's C drivers, the interrupts (SysTick every millisecond, the "
            "UART's every character, the DMA's), the loop's wake-ups between ticks and the DMA "
            "transmitter's Python.",
        ]
    lines += ["", "Wall time of the emulation (two runs at a time on this machine's two cores), "
              "and how much faster than the board's own clock it ran: "
              + ", ".join(f"{r['label']} {r['wall_s']:.0f} s" + (
                  f" ({r['run']['realtime_factor']:.2f}x real time)"
                  if r["run"].get("realtime_factor") else "") for r in ok)
              + "."]  # fmt: skip
    return lines


def _twin_target_line(r, t):
    """A twin run's navigating busy time, missed and late ticks and the watchdog's longest gap
    against the image's targets t (eval/board_time.py TARGET_MS)."""
    nav = r["time"]["phases"].get("navigating")
    run = r["run"]
    if nav is None:
        return f"- {r['label']}: never navigated."
    b = nav["busy_ms"]
    met = [b["p99"] <= t["p99"], b["max"] <= t["max"] and not nav["late_ticks"],
           not run["overruns"] and not run["late_ticks"]]  # fmt: skip
    return (
        f"- {r['label']}: navigating busy p99 {b['p99']:.2f} ms (target <= {t['p99']:g}), "
        f"max {b['max']:.2f} ms (<= {t['max']:g}); {run['overruns']} ticks missed and "
        f"{run['late_ticks']} late in the whole run (target 0); the watchdog fed at most "
        f"{run['watchdog_longest_gap_ms']:.1f} ms apart (timeout "
        f"{run['watchdog_timeout_ms']:g} ms). "
        + ("Met." if all(met) else f"Not met ({len(met) - sum(met)} of {len(met)}).")
    )


def page_cost(base_ms, page_ms, gc=None, tick_ms=5.0):
    """What the screen's status page costs, from the busy time per tick (ms) of two runs of
    the same drive, without and with it (gc: ticks where either collected garbage, left
    out). A turn is tick k with k + 1 = PAGE_PHASE mod PAGE_SLOT (the batch's end: k + 1 =
    PAGE_END mod PAGE_ROUND); its cost is its busy time with the page less without."""
    base = np.asarray(base_ms, float)
    page = np.asarray(page_ms, float)
    k = np.arange(len(page))
    keep = ~np.asarray(gc, bool) if gc is not None else np.ones(len(page), bool)
    turn = ((k + 1) % PAGE_SLOT == PAGE_PHASE) & keep
    end = turn & ((k + 1) % PAGE_ROUND == PAGE_END)
    other = ~((k + 1) % PAGE_SLOT == PAGE_PHASE) & keep
    d = (page - base) * 1000.0  # us
    worst = int(k[turn][np.argmax(d[turn])]) if turn.any() else None

    def figures(m):
        if not m.any():
            return None
        x = d[m]
        return {"mean": float(x.mean()), "p99": float(np.percentile(x, 99)),
                "max": float(x.max())}  # fmt: skip

    return {
        "turns": int(turn.sum()),
        "turn_us": figures(turn),
        "end_us": figures(end),
        "other_us_mean": figures(other)["mean"] if other.any() else None,
        "worst_tick": worst,
        "worst_is_end": worst is not None and (worst + 1) % PAGE_ROUND == PAGE_END,
        "turn_busy_ms_max": float(page[turn].max()) if turn.any() else None,
        "turns_over_period": int(np.sum(page[turn] >= tick_ms)),
        "over_period": int(np.sum(page >= tick_ms)),
        "base_over_period": int(np.sum(base >= tick_ms)),
        "gc_ticks_left_out": int((~keep).sum()),
    }


def page_lines(twin):
    """The screen's status page against the first configuration, tick by tick (page_cost),
    for each twin run with the display setting on."""
    base = next((r for r in twin if not r.get("overrides") and not r.get("receiver")), None)
    lines = []
    for r in twin:
        if not (r.get("overrides") or {}).get("display") or base is None:
            continue
        if len(r.get("per_tick_busy_ms", ())) != len(base.get("per_tick_busy_ms", ())):
            continue
        gc = np.logical_or(r["per_tick_gc"], base["per_tick_gc"])
        c = page_cost(base["per_tick_busy_ms"], r["per_tick_busy_ms"], gc)
        if c["turn_us"] is None:
            continue
        sc = r.get("screen", {})
        t, e = c["turn_us"], c["end_us"]
        lines += [
            "",
            f"### {r['label']}",
            "",
            f"The display setting on: the status page (firmware/lib/status_page.py) on the "
            f"emulated UsartGPU on USART6 (the Black Pill's PA11/PA12), its commands handed to "
            f"the UART's DMA, its OKs read at each batch's end. Against {base['label']}, tick by "
            f"tick over the same drive ({c['gc_ticks_left_out']} ticks with a garbage "
            f"collection in either run left out): a turn of the page (every {PAGE_SLOT}th "
            f"tick: one field made and, if it changed, its command queued) costs "
            f"{t['mean']:.0f} us mean, {t['p99']:.0f} us p99, {t['max']:.0f} us at worst (tick "
            f"{c['worst_tick']}"
            + (", a batch's end" if c["worst_is_end"] else "")
            + f"); a batch's end (every {PAGE_ROUND}th tick: the OKs counted, `\\r\\n`) "
            f"{e['mean']:.0f} us mean, {e['max']:.0f} us at most; the other ticks "
            f"{c['other_us_mean']:.0f} us mean (the transmitter's poll before each sleep). "
            "Ticks with a turn: busy at most "
            + (">= 5 ms (late)" if c["turns_over_period"] else f"{c['turn_busy_ms_max']:.2f} ms")
            + f", {c['turns_over_period']} of {c['turns']} at 5 ms or more; in the whole run "
            f"{c['over_period']} ticks at 5 ms or more ({c['base_over_period']} without the "
            "page).",
        ]
        if sc:
            lines += [
                "",
                f"The screen got {sc['display_bytes']:,} bytes in {sc['display_batches']} "
                f"batches and answered {sc['display_oks']}: {sc['display_missed']} missed by "
                f"status_page's rule, {sc['display_cause_frames']} extended frames with the "
                "display cause.",
            ]
    return lines


def _ticks(n):
    return f"{n} tick" if n == 1 else f"{n} ticks"


def accuracy(nav_json, profile, scenario="urban_drive", gnss="white"):
    """Mean accuracy of `profile` over the seeds of `make bench-nav`'s runs in nav_json (a
    path): {"seeds", "horiz_rms_m", "vel_rms_m_s", "yaw_rms_deg", "outage_end_m": [...]}, or
    None when the file or the profile's runs are missing."""
    try:
        runs = json.loads(pathlib.Path(nav_json).read_text())["runs"]
    except (OSError, ValueError, KeyError):
        return None
    rows = [r for k, r in runs.items() if k.split("/", 3)[::2] == [scenario, gnss]
            and k.split("/", 3)[3] == profile]  # fmt: skip
    if not rows:
        return None
    out = {k: float(np.mean([r[k] for r in rows]))
           for k in ("horiz_rms_m", "vel_rms_m_s", "yaw_rms_deg")}  # fmt: skip
    out["seeds"] = len(rows)
    out["outage_end_m"] = np.mean([[o["horiz_err_end_m"] for o in r["outages"]] for r in rows],
                                  axis=0).tolist()  # fmt: skip
    return out


def accuracy_cost_lines(results, nav_json):
    """The section setting each variant's accuracy (bench-nav) beside its navigating cost."""
    lines = ["", "## What the options buy: accuracy against cost", ""]
    rows, seeds = [], None
    for r in results:
        # the walk has no configuration in bench-nav: no accuracy (its cost is above)
        acc = accuracy(nav_json, NAV_PROFILES.get(r["label"], ""))
        nav = r["cost"]["phases"].get("navigating")
        if acc is None or nav is None:
            continue
        seeds = acc["seeds"]
        fi = nav["firmware_instr"]
        outs = " / ".join(f"{v:.2f}" for v in acc["outage_end_m"])
        rows.append(f"| {r['label']} | {acc['horiz_rms_m']:.2f} | {acc['vel_rms_m_s']:.3f} | "
                    f"{acc['yaw_rms_deg']:.2f} | {outs} | {fi['mean']:,.0f} / "
                    f"{fi['p99']:,.0f} |")  # fmt: skip
    if not rows:
        return lines + [f"No accuracy figures for these configurations in {nav_json} "
                        "(`make bench-nav` writes them)."]  # fmt: skip
    return lines + [
        "Accuracy: `make bench-nav` (docs/benchmarks/navigation.md: urban_drive, white GNSS, "
        f"mean of {seeds} seeds, the firmware's float32 navigator on CPython, the board's "
        "bits); cost: navigating instructions per tick of this run.",
        "",
        "| configuration | horiz RMS m | vel RMS m/s | yaw RMS deg | end of outages m | "
        "mean / p99 instructions |",
        "|---|---|---|---|---|---|",
        *rows,
        "",
        "A 10 Hz receiver's accuracy is bench-nav's 10 Hz row (white GNSS, fixes at their "
        "epochs); its cost here includes the 4 filter slices per tick such a rate asks for "
        '(docs/navigation.md, "Receivers faster than 1 Hz") and ten times the NMEA bytes.',
    ]


def _overruns(t):
    """A table cell: the overrunning ticks at one CPI and their share ("0" when none: a rare
    one, like a collection's tick, is not hidden by rounding)."""
    n = t["overrun_ticks"]
    return f"{n} ({100 * t['overrun_share']:.3g} %)" if n else "0"


def markdown(results, scenario, duration, budget, budget_why, cmd, nav_json=NAV_JSON,
             twin=()):  # fmt: skip
    """docs/benchmarks/board.md: instructions per tick by configuration and phase, the
    budget, what the options buy, the image on the emulated STM32F411 (twin), the heap and
    start-up, the image's budget."""
    low, central, high, source = board_cost.cpi_range()
    lines = [
        "# What a tick costs the board",
        "",
        f"Measured by `{cmd}` (docs regenerate with `make bench-board`): the unmodified app loop "
        f"(`firmware/app.py`: IMU read, NMEA, navigator, frames, watchdog, its own garbage "
        f"collection) on the emulated Cortex-M4F (`--runtime m4f`: MicroPython v1.28.0 built "
        f"for QEMU's mps2-an386 with the STM32F411's float32 hard-float settings, the firmware "
        f"frozen as in the image, instructions counted with `-icount shift=0`), over "
        f"{scenario} ({duration:g} s, seed 0){_other_scenarios([*results, *twin], scenario)}, "
        "with the board's heap.",
        "",
        "Firmware instructions per tick exclude the emulated peripherals (Python standing in "
        "for the board's C drivers and hardware; their own count is shown); the firmware's "
        "calls into them are counted at the cost of a C method call (it holds each through "
        "`m4f.Periph`, docs/emulator.md). Time per tick "
        f"= instructions x CPI / 100 MHz, CPI {low:g} / {central:g} / {high:g} ({source}); "
        "a tick overruns when that exceeds 5 ms. Not counted, so the times are a floor: "
        "interrupt entry and exit, the C drivers of SPI and the UARTs, DMA.",
        "",
        f"Budget, a whole app tick once navigating (docs/requirements.md, time budget and project "
        f"targets): mean <= {BUDGET['mean']:,}, p99 <= {BUDGET['p99']:,}, max <= "
        f"{BUDGET['max']:,} instructions, no "
        f"gc.collect() while navigating, and no tick overrunning at CPI {high:g}.",
        "",
        "| configuration | phase | ticks | mean | p50 | p99 | max | emulation mean | "
        "gc.collect | one collect | ms mean / p99 at CPI "
        f"{central:g} | overrunning ticks at CPI {low:g} / {central:g} / {high:g} |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    failed = [r for r in results if "error" in r]
    results = [r for r in results if "error" not in r]
    for r in results:
        for phase, ph in r["cost"]["phases"].items():
            lines.append(_phase_row(r["label"], phase, ph, (low, central, high)))
    for r in failed:
        lines += ["", f"**{r['label']}: the run failed:**", "", "```", r["error"], "```"]
    if not results:
        return "\n".join(lines)
    nav = results[0]["cost"]["phases"].get("navigating")
    lines += ["", "![instructions per tick](board_ticks.png)", "", "## Against the budget", ""]
    lines.append(_budget_line(nav, high))
    lines += accuracy_cost_lines(results, nav_json)
    lines += twin_lines(list(twin), results)
    lines += _heap_lines(results, central)
    lines += _image_lines(budget, budget_why, results)
    return "\n".join(lines)


def _phase_row(label, phase, ph, cpis):
    """The cost table's row of a run's phase; cpis: the CPI range (low, central, high)."""
    low, central, high = cpis
    fi = ph["firmware_instr"]
    t = ph["time_ms"]
    gc = (
        f"{ph['gc_collections']} (every {ph['ticks_per_collection']:.0f} ticks)"
        if ph["gc_collections"]
        else "0"
    )
    one = f"{ph['gc_collect_instr']:,.0f}" if ph["gc_collect_instr"] is not None else "-"
    shares = " / ".join(_overruns(t[f"{c:g}"]) for c in (low, central, high))
    return (
        f"| {label} | {phase} | {ph['ticks']} | {fi['mean']:,.0f} | "
        f"{fi['p50']:,.0f} | {fi['p99']:,.0f} | {fi['max']:,} | "
        f"{ph['emulation_instr']['mean']:,.0f} | {gc} | {one} | "
        f"{t[f'{central:g}']['mean']:.1f} / {t[f'{central:g}']['p99']:.1f} | {shares} |"
    )


def _budget_line(nav, high):
    """The default configuration's navigating figures against BUDGET (nav None: it never
    navigated); high: the CPI the overruns are counted at."""
    if not nav:
        return "The firmware never navigated in this run: no navigating figures."
    fi = nav["firmware_instr"]
    over = nav["time_ms"][f"{high:g}"]["overrun_share"]
    met = [
        fi["mean"] <= BUDGET["mean"],
        fi["p99"] <= BUDGET["p99"],
        fi["max"] <= BUDGET["max"],
        nav["gc_collections"] == 0,
        over == 0,
    ]
    n_over = nav["time_ms"][f"{high:g}"]["overrun_ticks"]
    beyond = nav["ticks_over"]
    return (
        f"Default configuration, navigating: mean {fi['mean']:,.0f} instructions "
        f"({fi['mean'] / BUDGET['mean']:.2f}x the budget), p99 {fi['p99']:,.0f} "
        f"({fi['p99'] / BUDGET['p99']:.2f}x), max {fi['max']:,} "
        f"({fi['max'] / BUDGET['max']:.1f}x; {_ticks(beyond[str(BUDGET['max'])])} over "
        f"{BUDGET['max']:,}, {beyond[str(BUDGET['p99'])]} over {BUDGET['p99']:,}), "
        f"{nav['gc_collections']} gc.collect() in "
        f"{nav['ticks']} navigating ticks (budget 0), {_ticks(n_over)} ({100 * over:.3f} %) "
        f"overrunning at CPI {high:g} (budget 0); mean allocation "
        f"{nav['alloc_bytes_per_tick']['mean']:,.0f} bytes per tick "
        f"({nav['alloc_bytes_per_tick']['mean'] / 16:,.0f} blocks of 16 bytes). "
        + (
            "The budget is met."
            if all(met)
            else f"The budget is not met ({len(met) - sum(met)} of {len(met)} figures)."
        )
    )


def _heap_lines(results, central):
    """The heap and start-up section, from the first run's heap figures (the garbage
    collections: every run's); central: the CPI of the start-up's time."""
    h = results[0]["heap"]
    own_live = h["live_after_start"] - h["emulator_bytes"] - h["ballast_bytes"] - h["system_bytes"]
    return [
        "",
        "## Heap and start-up",
        "",
        f"- Free heap when the firmware starts: {h['free_at_start']:,} bytes: what a board with "
        f"the image's {m4f_build.BOARD_HEAP_BYTES:,}-byte heap has free once MicroPython's own "
        f"start-up objects ({h['system_bytes']:,} bytes here, /flash's FAT object among them) "
        f"are made (the emulated board's {h['emulator_bytes']:,} bytes sit in a reserve of "
        f"the build's heap; a ballast of {h['ballast_bytes']:,} bytes takes what is left of "
        "it).",
        f"- Live after start-up: {own_live:,} bytes of the firmware's own.",
        f"- Start-up (imports of the frozen modules, configuration, BMI055 set-up, the App): "
        f"{h['startup_instructions']:,} instructions "
        f"({h['startup_instructions'] * central / 100e6 * 1e3:.0f} ms at CPI {central:g}).",
        "- Garbage collections by the app's low-water rule: "
        + ", ".join(f"{r['label']}: {r['heap']['app_gc_runs']}" for r in results)
        + ".",
        "",
    ]


def _image_lines(budget, budget_why, results):
    """The firmware image's section (budget: `make image`'s lines, or None and why), and the
    runs' wall time."""
    lines = ["## Firmware image", ""]
    if budget:
        lines += ["`make image` (docs/image.md):", "", "```", *budget, "```"]
    else:
        lines.append(f"Not available here: {budget_why}.")
    lines += [
        "",
        "Wall time of the emulation: "
        + ", ".join(f"{r['label']} {r['wall_s']:.0f} s" for r in results)
        + ".",
        "",
    ]
    return lines


def main(argv=None):
    p = cli_args.Parser(
        prog="python -m host_emulator bench-board", description=__doc__.split("\n\n")[1]
    )
    p.add_argument("--scenario", default="urban_drive", help="simulated scenario (urban_drive)")
    p.add_argument("--duration", default=None, help="seconds (default: the whole scenario)")
    p.add_argument("--out", default=str(DEFAULT_OUT), help="markdown file (default %(default)s)")
    cli_args.add_jobs_option(p)
    try:
        args = p.parse_args(argv)
        duration = None if args.duration is None else cli_args.number(args.duration, "--duration")
        cli_args.check_scenario(args.scenario)
        if duration is not None:
            cli_args.check_duration(duration)
    except (cli_args.UsageError, EmulatorError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2

    def command():
        out = pathlib.Path(args.out)
        outputs.announce("bench-board", [out, out.with_suffix(".json"),
                                         out.with_name("board_ticks.png")])  # fmt: skip
        from host_emulator.runtimes import f411
        from host_emulator.runtimes.m4f import build as m4f_build
        from host_emulator.sim import trajectory

        m4f_build.build()  # once, before the parallel runs
        f411.image_files(f411.DEFAULT_BOARD, print)  # likewise the image

        def default_duration(name):
            return trajectory.SCENARIOS[name].default_duration_s

        dur = duration or default_duration(args.scenario)
        runs = tasks(args.scenario, duration, default_duration)
        print(f"bench-board: {args.scenario} {dur:g} s on the emulated Cortex-M4F, "
              f"{len(VARIANTS)} configurations (about 3x real time each), and the image on the "
              f"emulated STM32F411, {len(TWIN_VARIANTS)} configurations (1.1-1.7x real time "
              f"each); the walk's over {WALK}")  # fmt: skip
        with ProcessPoolExecutor(max_workers=min(args.jobs, len(runs))) as ex:
            done = list(ex.map(_run_task, runs))
        twin = [r for r in done if r.get("twin")]
        results = [r for r in done if not r.get("twin")]
        budget, why = image_budget()
        cmd = "python -m host_emulator bench-board" + (f" --scenario {args.scenario}"
              if args.scenario != "urban_drive" else "") + (f" --duration {dur:g}"
              if duration else "")  # fmt: skip
        out = pathlib.Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        text = markdown(results, args.scenario, dur, budget, why, cmd, twin=twin)
        out.write_text(text)
        _plot([r for r in results if "error" not in r], out.with_name("board_ticks.png"))
        _plot_twin([r for r in twin if "error" not in r], out.with_name("board_time.png"))
        slim = [{k: v for k, v in r.items() if not k.startswith("per_tick")} for r in results]
        twin_slim = [{k: v for k, v in r.items() if not k.startswith("per_tick")} for r in twin]
        out.with_suffix(".json").write_text(
            json.dumps(
                {
                    "scenario": args.scenario,
                    "duration_s": dur,
                    "results": slim,
                    "image_on_f411": twin_slim,
                    "image": budget,
                },
                indent=2,
            )
            + "\n"  # fmt: skip
        )
        print(text)
        print(f"wrote {out}, {out.with_suffix('.json')}, {out.with_name('board_ticks.png')}, "
              f"{out.with_name('board_time.png')}")  # fmt: skip
        if out.resolve() == DEFAULT_OUT.resolve():  # the figures the docs quote from it
            src = figures.Sources(out.with_suffix(".json"))
            changed = figures.write_all(figures.documents(), src)
            print(f"rewrote the figures of {', '.join(changed)}" if changed
                  else "the docs' board figures were current")  # fmt: skip
        return 0

    return cli_args.run_reporting(command)
