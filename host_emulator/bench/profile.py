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

# (module, class or None, attribute names): what is wrapped, besides every navk function
TARGETS = (
    ("app", "App", ("service", "_gnss_read", "_deliver_fix", "_fix_fields", "_fix_tick",
                    "_send_frame", "_send_ext")),
    ("drivers.bmi055", "BMI055", ("read",)),
    ("drivers.gnss", "Nmea", ("feed", "_end")),
    ("nav_align", "Alignment", ("_align_fix", "_level", "_track", "_start_navigation",
                                "_gsf_align", "_gsf_reset", "_gsf_turn", "_yaw_now")),
    ("nav", "Navigator", ("imu_counts", "_reset_event", "gnss_fix", "_take_fix", "_tick", "gnss",
                          "_navigate", "_nav_fix",
                          "_schedule", "_start_queued_fix", "_inject", "_align",
                          "_still_update", "_fix_usable", "_reanchor", "_update_health",
                          "_fault_reset", "_restart", "_gsf_watch", "_gsf_step", "_apply_dx")),
    ("nav_aid", "Aiding", ("_start_gnss_update", "_start_zupt", "_start_nhc", "_reset_to_gnss",
                           "_lever_n", "_sigma_h", "_sigma_v")),
    ("eskf", "Eskf", ("work", "diagonal_ok", "start_propagation", "start_update", "add_scalar")),
    ("ins", "Ins", ("take_dvn", "slow_update", "shift_origin")),
    ("records", "ExtFrame", ("pack",)),
    ("records", "RawRecord", ("pack",)),
    ("frame", None, ("pack_fields",)),
    ("nav", None, ("nav_frame",)),
    ("geo", "LocalFrame", ("to_enu", "to_e7", "set_origin")),
)  # fmt: skip

# The kernels the firmware calls from Python when they are native (the others run inside
# nav_tick, where no wrapper sees them; a wrapper costs ~140 bytes of the board's heap)
KERNELS = ("nav_tick", "nav_frame", "ext_pack", "gnss_fix", "fix_usable", "geo_enu", "euler",
           "nav_start", "bmi055_decode", "gnss_rows", "zupt_rows", "nhc_rows",
           "nmea_scan", "gsf_step", "inject")  # fmt: skip

# The wrappers' room: the profile runs on a build whose GC heap is this much larger, so the
# firmware still gets the board's heap (the wrappers took the room of its largest buffer)
WRAPPER_HEAP_BYTES = 16 * 1024

# The guest's setup (emulate_m4f.main's SETUP): wraps, then returns the report function.
GUEST = r"""
def _profile_setup():
    import gc
    import m4f
    ic = m4f.icount
    em = m4f.emu_total
    keys = []
    cnt = [0] * 256  # instructions, calls of wrapper j at 2j, 2j + 1: one list, not one each
    on = [ALL_TICKS]
    ticks = [0]

    def wrap(owner, name, key):
        # collected first, so the wrappers pack at the bottom of the heap instead of being
        # spread over it by the garbage in between (the firmware then lacks a large block)
        gc.collect()
        f = getattr(owner, name)  # a name that is gone stops the profile (AttributeError)
        j = 2 * len(keys)
        keys.append(key)

        def w(*args):
            if on[0]:
                c0 = ic()
                e0 = em()
                r = f(*args)
                cnt[j] += ((ic() - c0) & 0x3FFFFFFF) - ((em() - e0) & 0x3FFFFFFF)
                cnt[j + 1] += 1
                return r
            return f(*args)

        setattr(owner, name, w)

    try:
        import navk
        for name in KERNELS:
            wrap(navk, name, "navk." + name)
    except ImportError:
        pass
    for mod, cls, names in TARGETS:
        m = __import__(mod)
        for part in mod.split(".")[1:]:
            m = getattr(m, part)
        owner = getattr(m, cls) if cls else m
        for n in names:
            wrap(owner, n, (cls or mod) + "." + n)
    import app
    import nav
    service = app.App.service
    calib = [0, 0]

    # what a wrapper adds to its caller: a wrapped no-op call less a plain one
    def nop():
        return None

    class Probe:
        pass

    Probe.f = nop
    on0 = on[0]
    on[0] = True
    wrap(Probe, "f", "_probe")
    wrapped = Probe.f
    c0 = ic()
    for _ in range(50):
        nop()
    c1 = ic()
    for _ in range(50):
        wrapped()
    c2 = ic()
    calib[0] = (((c2 - c1) & 0x3FFFFFFF) - ((c1 - c0) & 0x3FFFFFFF)) // 50
    on[0] = on0
    keys.pop()
    cnt[2 * len(keys)] = cnt[2 * len(keys) + 1] = 0

    def counted_service(self):
        if not ALL_TICKS:
            on[0] = self.nav.state == nav.NAVIGATING
        if on[0]:
            ticks[0] += 1
        service(self)
        # the wrappers' argument tuples are garbage the app does not expect (it checks the
        # heap once a second while navigating): collected here, outside every count
        if gc.mem_free() < 16384:
            gc.collect()

    app.App.service = counted_service

    def report():
        yield "ticks", ticks[0]
        yield "wrapper_instr", calib[0]
        for j, key in enumerate(keys):
            yield key, [cnt[2 * j], cnt[2 * j + 1]]

    gc.collect()
    gc.collect()
    return report
"""


def guest_setup(all_ticks):
    """MicroPython source defining `_profile_setup` for emulate_m4f.main's SETUP."""
    targets = repr(tuple((m, c, tuple(n)) for m, c, n in TARGETS))
    return (
        f"TARGETS = {targets}\nKERNELS = {KERNELS!r}\nALL_TICKS = {bool(all_ticks)}\n"
        + GUEST.strip("\n")
        + "\n"
    ).replace("\n", "\r\n")


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
                         guest_setup=(guest_setup(a.all_ticks), "_profile_setup"),
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
