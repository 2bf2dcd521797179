"""The profiler's guest side (host_emulator/bench/profile.py): frozen into the emulated
Cortex-M4F's build, so its code is in flash as the firmware's is, not in the heap the run
measures. emulate_m4f.main calls setup(...) before the firmware starts (its SETUP argument):
every function named is wrapped by a counter of the instructions it executes (m4f.icount, the
emulated peripherals' own taken out) and of its calls; the report it returns yields
(name, value) pairs at the end of the run."""

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


def setup(all_ticks):
    """Wrap; (report, firmware_bytes) as emulate_m4f.main wants of its SETUP."""
    import gc

    import m4f

    ic = m4f.icount
    em = m4f.emu_total
    keys = []
    cnt = [0] * 256  # instructions, calls of wrapper j at 2j, 2j + 1: one list, not one each
    on = [all_ticks]
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

    # what the firmware's modules hold is the firmware's (on the board it comes out of the
    # heap the firmware starts with): measured apart from the wrappers, which are the
    # emulator's. navk's are wrapped before anything imports it (the firmware binds its
    # functions by name), the classes' after their modules are imported.
    gc.collect()
    a0 = gc.mem_alloc()
    try:
        import navk
    except ImportError:
        navk = None
    gc.collect()
    firmware_bytes = gc.mem_alloc() - a0
    if navk is not None:
        for name in KERNELS:
            wrap(navk, name, "navk." + name)
    gc.collect()
    a0 = gc.mem_alloc()
    for mod, _, _ in TARGETS:
        __import__(mod)
    import app
    import nav

    gc.collect()
    firmware_bytes += gc.mem_alloc() - a0
    for mod, cls, names in TARGETS:
        m = __import__(mod)
        for part in mod.split(".")[1:]:
            m = getattr(m, part)
        owner = getattr(m, cls) if cls else m
        for n in names:
            wrap(owner, n, (cls or mod) + "." + n)
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
        if not all_ticks:
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
    return report, firmware_bytes
