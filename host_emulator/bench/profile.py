"""Where a tick goes on the board: `python -m host_emulator profile [--scenario S]
[--duration S] [--kernels native|python] [--all-ticks]`.

Runs the unmodified app loop on the emulated Cortex-M4F (runtimes/m4f) with the firmware's
functions and the native kernels wrapped, before the firmware is imported, by counters
(m4f.icount, the emulated peripherals' instructions taken out), and prints per function: calls
per tick, instructions per call and per tick (inclusive: a caller's figure contains its
callees'). By default only navigating ticks count; --all-ticks counts every tick.

A profile, not the benchmark: each wrapped call costs the wrapper's own instructions (measured
in the guest and printed; a caller's figure holds them once per wrapped callee) and allocates
its argument tuple (collected after the tick, outside the counts); the wrappers live in room
the board does not have (a build with WRAPPER_HEAP_BYTES more heap), so the firmware keeps the
board's heap. `make bench-board` gives the unprofiled figures.
"""

import argparse
import pathlib
import sys
import tempfile

from common.errors import EmulatorError
from host_emulator import args as cli_args

# The wrappers' room: the profile runs on a build whose GC heap is this much larger, so the
# firmware still gets the board's heap (the wrappers took the room of its largest buffer)
WRAPPER_HEAP_BYTES = 32 * 1024


def guest_setup(all_ticks):
    """m4f.run's guest_setup for the frozen profile_guest module (emulated_board/mpy, which
    names what is wrapped): a short command, so the heap MicroPython holds for it is about
    a plain run's."""
    return "import profile_guest\r\n", f"lambda: profile_guest.setup({bool(all_ticks)})"


def profile_of(pairs):
    """The guest's report pairs as {"ticks", "wrapper_instr", "functions": {name: [instr,
    calls]}}."""
    d = dict(pairs)
    return {"ticks": d.pop("ticks"), "wrapper_instr": d.pop("wrapper_instr"), "functions": d}


def table(profile, mean_tick_instr=None):
    """Lines: per function calls/tick, instructions per call and per tick, biggest first."""
    n = profile["ticks"]
    if not n:
        return ["no tick counted (the firmware never navigated: try --all-ticks)"]
    rows = []
    for key, (instr, calls) in profile["functions"].items():
        if calls:
            rows.append((instr / n, key, calls / n, instr / calls))
    rows.sort(reverse=True)
    out = [
        f"{n} ticks counted; a wrapped call adds {profile['wrapper_instr']} instructions to its "
        "caller's figure (included below)",
        f"{'function':34} {'calls/tick':>10} {'instr/call':>11} {'instr/tick':>11}",
    ]
    for per_tick, key, calls, per_call in rows:
        out.append(f"{key:34} {calls:10.3f} {per_call:11,.0f} {per_tick:11,.0f}")
    if mean_tick_instr is not None:
        out.append(f"whole tick, unwrapped counter (emulation excluded): {mean_tick_instr:,.0f}")
    return out


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m host_emulator profile", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("--scenario", default="quick_start", help="simulated scenario (quick_start)")
    p.add_argument("--duration", default="30", help="seconds of the scenario (default 30)")
    cli_args.add_kernels_option(p)
    p.add_argument("--all-ticks", action="store_true", help="count aligning ticks too")
    a = p.parse_args(argv)
    from host_emulator.runtimes import m4f
    from host_emulator.runtimes.m4f import build as m4f_build
    from host_emulator.sim import board_input

    try:
        cli_args.check_scenario(a.scenario)
        a.duration = cli_args.positive(a.duration, "--duration")
        cli_args.check_duration(a.duration)
        stim = board_input.simulate(a.scenario, a.duration, 0).stimulus
        with tempfile.TemporaryDirectory(prefix="profile-") as d:
            fw = m4f.run(stim, pathlib.Path(d), None, None, kernels=a.kernels,
                         guest_setup=guest_setup(a.all_ticks),
                         gc_heap_bytes=m4f_build.GC_HEAP_BYTES + WRAPPER_HEAP_BYTES)  # fmt: skip
    except (EmulatorError, cli_args.UsageError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    t = fw.per_tick
    fw_instr = t["instr"].astype("i8") - t["emu_instr"]
    sel = slice(None) if a.all_ticks else t["state"] == 2
    mean = float(fw_instr[sel].mean()) if fw_instr[sel].size else None
    print(f"{a.scenario}, {a.duration:g} s, emulated Cortex-M4F, kernels {fw.stats['kernels']}")
    for line in table(profile_of(fw.stats["report"]), mean):
        print(line)
    return 0
