"""Board benchmark: `python -m host_emulator bench-board [--scenario S] [--duration S]
[--out FILE] [--jobs N]` (make bench-board).

Runs the unmodified app loop on the emulated Cortex-M4F (runtimes/m4f) over a whole simulated
drive, once with the default configuration and once with coning on and 2 filter slices per
tick, and writes what a tick costs the board's CPU (bench/board_cost.py: instructions per tick
by phase, the emulation set apart, garbage collection, time per tick at 100 MHz for the CPI
range, overruns) together with the heap, the start-up and the firmware image's budget, to
FILE (default docs/benchmarks/board.md; the numbers in a .json and a plot beside it).

The emulated board runs at about real time, so the default (urban_drive, 600 s, two
configurations on two processes) takes about 11 minutes. It is a benchmark: the design budget
(DESIGN.md 4: p99 <= 50,000 and max <= 100,000 instructions per tick, no gc.collect while
navigating) is reported against, not asserted.
"""

import json
import pathlib
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from host_emulator import args as cli_args
from host_emulator.bench import board_cost
from host_emulator.errors import EmulatorError
from host_emulator.firmware_env import REPO_DIR
from host_emulator.runtimes.m4f import build as m4f_build

VARIANTS = (
    ("default (coning off, 1 slice per tick)", {}),
    ("coning on, 2 slices per tick", {"coning": 1, "slices_per_tick": 2}),
)
# each variant's configuration in `make bench-nav` (docs/benchmarks/navigation.json), whose
# accuracy the report sets beside the cost
NAV_PROFILES = {
    "default (coning off, 1 slice per tick)": "car",
    "coning on, 2 slices per tick": "car, coning on, 2 slices per tick",
}
NAV_JSON = REPO_DIR / "docs" / "benchmarks" / "navigation.json"
# A whole app tick once navigating: p99 and max from DESIGN.md 4, the mean and no overrun at
# the high CPI from issue 15 (0.6 ms mean at CPI 2.05 and 100 MHz)
BUDGET = {"mean": 30_000, "p99": 50_000, "max": 100_000}
DEFAULT_OUT = REPO_DIR / "docs" / "benchmarks" / "board.md"


def _one(task):
    """One variant on the m4f runtime: (label, overrides, scenario, duration) -> result dict."""
    label, overrides, scenario, duration = task
    from host_emulator.runtimes import m4f
    from host_emulator.sim import board_input

    stim = board_input.simulate(scenario, duration, 0).stimulus
    t = time.perf_counter()
    last = [-1]

    def progress(k, n):
        decile = 10 * k // n
        if decile > last[0]:
            last[0] = decile
            print(f"  {label}: {100 * k // n:3d} % ({time.perf_counter() - t:.0f} s)", flush=True)

    try:
        with tempfile.TemporaryDirectory(prefix="bench-board-") as d:
            fw = m4f.run(stim, pathlib.Path(d), overrides, progress)
    except EmulatorError as e:  # a firmware exception on the board's heap is a finding
        print(f"  {label}: failed: {e}", flush=True)
        return {"label": label, "overrides": overrides, "error": str(e)}
    return {
        "label": label,
        "overrides": overrides,
        "ticks": fw.ticks,
        "wall_s": fw.wall_s,
        "cost": board_cost.summary(fw.per_tick, stim.tick_us),
        "heap": {k: fw.stats[k] for k in board_cost.HEAP_KEYS},  # fmt: skip
        "overruns_reported": fw.stats["overruns"],
        "per_tick_fw": (fw.per_tick["instr"].astype(np.int64) - fw.per_tick["emu_instr"]).tolist(),
        "per_tick_state": fw.per_tick["state"].tolist(),
        "per_tick_collected": fw.per_tick["collected"].tolist(),
    }


def image_budget():
    """(the firmware image's budget lines, None), building it if needed (tools/image, cached:
    seconds), or (None, the reason) if it cannot be built here."""
    try:
        from tools import toolchain
        from tools.image import budget, build

        report = build.build(build.DEFAULT_BOARD, log=lambda *_: None)
    except (ImportError, toolchain.ToolchainError, build.ImageError) as e:
        return None, str(e)
    lines = [f"{report['board']} ({report['description']}), MicroPython {report['micropython']}:"]
    lines += budget.report_lines(report["figures"])
    return lines, None


def _plot(results, path):
    if not results:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(results), 1, figsize=(10, 3.2 * len(results)), sharex=True)
    axes = np.atleast_1d(axes)
    for ax, r in zip(axes, results, strict=True):
        fw = np.array(r["per_tick_fw"]) / 1e3
        state = np.array(r["per_tick_state"])
        t = np.arange(len(fw)) * 0.005
        for s, name, color in ((1, "aligning", "C1"), (2, "navigating", "C0")):
            m = state == s
            ax.plot(t[m], fw[m], ".", ms=1, color=color, label=name)
        gc = np.array(r["per_tick_collected"]) > 0
        ax.plot(t[gc], fw[gc], ".", ms=2, color="C3", label="tick with gc.collect")
        ax.axhline(BUDGET["p99"] / 1e3, color="k", ls="--", lw=0.8, label="budget p99 50k")
        ax.set_ylabel("thousand instructions")
        ax.set_title(r["label"])
        ax.legend(loc="upper right", markerscale=6, fontsize=8)
    axes[-1].set_xlabel("time since power-on, s")
    fig.suptitle("Firmware instructions per 5 ms tick on the emulated Cortex-M4F")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


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
    rows = []
    for r in results:
        acc = accuracy(nav_json, NAV_PROFILES.get(r["label"], ""))
        nav = r["cost"]["phases"].get("navigating")
        if acc is None or nav is None:
            continue
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
        f"mean of {acc['seeds']} seeds, the firmware's float32 navigator on CPython, the board's "
        "bits); cost: navigating instructions per tick of this run.",
        "",
        "| configuration | horiz RMS m | vel RMS m/s | yaw RMS deg | end of outages m | "
        "mean / p99 instructions |",
        "|---|---|---|---|---|---|",
        *rows,
        "",
        "A faster GNSS update is the receiver's rate (1 Hz in the scenarios), not a setting "
        "of the firmware: not measured here.",
    ]


def _overruns(t):
    """A table cell: the overrunning ticks at one CPI and their share ("0" when none: a rare
    one, like a collection's tick, is not hidden by rounding)."""
    n = t["overrun_ticks"]
    return f"{n} ({100 * t['overrun_share']:.3g} %)" if n else "0"


def markdown(results, scenario, duration, budget, budget_why, cmd, nav_json=NAV_JSON):
    low, central, high, source = board_cost.cpi_range()
    lines = [
        "# What a tick costs the board",
        "",
        f"Measured by `{cmd}` (docs regenerate with `make bench-board`): the unmodified app loop "
        f"(`firmware/app.py`: IMU read, NMEA, navigator, frames, watchdog, its own garbage "
        f"collection) on the emulated Cortex-M4F (`--runtime m4f`: MicroPython v1.28.0 built "
        f"for QEMU's mps2-an386 with the STM32F411's float32 hard-float settings, the firmware "
        f"frozen as in the image, instructions counted with `-icount shift=0`), over "
        f"{scenario} ({duration:g} s, seed 0), with the board's heap.",
        "",
        "Firmware instructions per tick exclude the emulated peripherals (Python standing in "
        "for the board's C drivers and hardware; their own count is shown); the firmware's "
        "calls into them are counted at the cost of a C method call (it holds each through "
        "`m4f.Periph`, docs/emulator.md). Time per tick "
        f"= instructions x CPI / 100 MHz, CPI {low:g} / {central:g} / {high:g} ({source}); "
        "a tick overruns when that exceeds 5 ms. Not counted, so the times are a floor: "
        "interrupt entry and exit, the C drivers of SPI and the UARTs, DMA.",
        "",
        f"Budget, a whole app tick once navigating: mean <= {BUDGET['mean']:,} (issue 15), "
        f"p99 <= {BUDGET['p99']:,}, max <= {BUDGET['max']:,} instructions (DESIGN.md 4), no "
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
            fi = ph["firmware_instr"]
            t = ph["time_ms"]
            gc = (
                f"{ph['gc_collections']} (every {ph['ticks_per_collection']:.0f} ticks)"
                if ph["gc_collections"]
                else "0"
            )
            one = f"{ph['gc_collect_instr']:,.0f}" if ph["gc_collect_instr"] is not None else "-"
            shares = " / ".join(_overruns(t[f"{c:g}"]) for c in (low, central, high))
            lines.append(
                f"| {r['label']} | {phase} | {ph['ticks']} | {fi['mean']:,.0f} | "
                f"{fi['p50']:,.0f} | {fi['p99']:,.0f} | {fi['max']:,} | "
                f"{ph['emulation_instr']['mean']:,.0f} | {gc} | {one} | "
                f"{t[f'{central:g}']['mean']:.1f} / {t[f'{central:g}']['p99']:.1f} | {shares} |"
            )
    for r in failed:
        lines += ["", f"**{r['label']}: the run failed:**", "", "```", r["error"], "```"]
    if not results:
        return "\n".join(lines)
    nav = results[0]["cost"]["phases"].get("navigating")
    lines += ["", "![instructions per tick](board_ticks.png)", "", "## Against the budget", ""]
    if nav:
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
        lines.append(
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
    else:
        lines.append("The firmware never navigated in this run: no navigating figures.")
    lines += accuracy_cost_lines(results, nav_json)
    h = results[0]["heap"]
    own_live = h["live_after_start"] - h["emulator_bytes"] - h["ballast_bytes"] - h["system_bytes"]
    lines += [
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
        "## Firmware image",
        "",
    ]
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
    return "\n".join(lines)


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
        from host_emulator.runtimes.m4f import build as m4f_build
        from host_emulator.sim import trajectory

        m4f_build.build()  # once, before the parallel runs
        dur = duration or trajectory.SCENARIOS[args.scenario].default_duration_s
        print(f"bench-board: {args.scenario} {dur:g} s on the emulated Cortex-M4F, "
              f"{len(VARIANTS)} configurations (about real time each)")  # fmt: skip
        tasks = [(label, ov, args.scenario, dur) for label, ov in VARIANTS]
        with ProcessPoolExecutor(max_workers=min(args.jobs, len(tasks))) as ex:
            results = list(ex.map(_one, tasks))
        budget, why = image_budget()
        cmd = "python -m host_emulator bench-board" + (f" --scenario {args.scenario}"
              if args.scenario != "urban_drive" else "") + (f" --duration {dur:g}"
              if duration else "")  # fmt: skip
        out = pathlib.Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        text = markdown(results, args.scenario, dur, budget, why, cmd)
        out.write_text(text)
        _plot([r for r in results if "error" not in r], out.with_name("board_ticks.png"))
        slim = [{k: v for k, v in r.items() if not k.startswith("per_tick")} for r in results]
        out.with_suffix(".json").write_text(
            json.dumps(
                {"scenario": args.scenario, "duration_s": dur, "results": slim, "image": budget},
                indent=2,
            )
            + "\n"  # fmt: skip
        )
        print(text)
        print(f"wrote {out}, {out.with_suffix('.json')}, {out.with_name('board_ticks.png')}")
        return 0

    return cli_args.run_reporting(command)
