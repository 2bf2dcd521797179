"""The settings benchmark's page (docs/benchmarks/settings.md) from a finished sweep
(settings.py's Plan): the criterion, the range table with what passes and why the next value
fails, and each setting's values with their figures and verdicts."""

from host_emulator.bench.faults import TRUST_M
from host_emulator.bench.navigation import SCENARIO_PROFILES
from host_emulator.bench.settings import (
    _BY_NAME,
    NAV_LATE_S,
    RELATIVE,
    SCENARIOS,
    SENSOR_OFFSET,
    SENSOR_SCALE,
    SPEC,
    _fig,
    _firmware_config,
    limits,
    setting_values,
    table_row,
)


def _cell(runs):
    """horiz m, vel m/s, roll/pitch/yaw deg, navigating s: the worst seed's."""
    rs = [r for r, _why in runs]
    if any("error" in r for r in rs):
        return "-"

    def worst(k):
        v = [r[k] for r in rs]
        return None if any(x is None for x in v) else max(v)

    att = "/".join(f"{worst(k):.2f}" if worst(k) is not None else "-"
                   for k in ("roll_rms_deg", "pitch_rms_deg", "yaw_rms_deg"))  # fmt: skip
    h, v, t = worst("horiz_rms_m"), worst("vel_rms_m_s"), worst("align_time_s")
    return (f"{_fig(h)} | {'-' if v is None else f'{v:.3f}'} | {att} | "
            f"{'-' if t is None else f'{t:.0f}'}")  # fmt: skip


def _value_text(plan, name, v):
    defs = plan.defaults[name]
    tags = [sc.split("_")[0] for sc, d in defs.items() if d == v]
    if tags:
        return f"{v:.4g} (default{'' if len(tags) == len(defs) else ', ' + tags[0]})"
    return f"{v:.4g}"


def _beyond(plan, name, allowed):
    """(below, above): the first value past each end of the allowed range and why it fails."""
    vals = plan.values[name]
    out = []
    for k in (vals.index(allowed[0]) - 1, vals.index(allowed[1]) + 1):
        if not 0 <= k < len(vals):
            out.append("the end of the sweep")
            continue
        why = [f"{sc} " + ", ".join(list(dict.fromkeys(w for _r, ws in rs for w in ws))[:2])
               for sc, rs in plan.row(name, vals[k]).items()
               if any(ws for _r, ws in rs)]  # fmt: skip
        out.append(f"{vals[k]:.4g}: " + "; ".join(why))
    return out


HOW = {
    "value": "the value",
    "xyz": "on every axis (a calibration error)",
    "diag": "on the diagonal (a scale error)",
    "lever": "on every axis, the antenna there",
    "mount": "as yaw, pitch, roll, the sensor turned so",
    "stamp": "the fixes that late",
    "gga": "the value, a GGA-only receiver",
}


def markdown(plan, cmd, wall_s):
    """The report, and {setting: {"allowed", "table_row"}}."""
    scs = list(SCENARIOS)
    runs = ", ".join(f"{sc} ({SCENARIO_PROFILES[sc]} profile, {plan.run_s(sc):g} s)" for sc in scs)
    lines = [
        "# Board settings benchmark",
        "",
        f"`{cmd}`: every float setting of firmware/lib/config.py's range table and the int "
        "settings that change the navigation, one at a time, over the range the table allowed "
        "before this benchmark narrowed it; each value written into the emulated board's "
        "ins.cfg (proto/config.py `from_values`, as `replay --set` does: the float32 the board "
        "would hold) and run through the unmodified firmware on the CPython runtime over "
        f"{runs}, seed{'s' if len(plan.seeds) > 1 else ''} {', '.join(map(str, plan.seeds))}. "
        "How each setting is applied and why: host_emulator/bench/settings.py.",
        "",
        *_criterion(plan),
        *_ranges(plan),
        "## Per setting",
        "",
        "The figures of each value (the worst seed's; nav s: navigating after power-on) and "
        "its verdict. *refused*: outside the firmware's range table now (run with the table "
        "widened to the swept range).",
        "",
    ]
    for name in [s.name for s in plan.sweeps] + list(plan.ints):
        lines += _setting(plan, name)
    lines += [
        f"Benchmark wall time: {wall_s / 60:.1f} min ({len(plan.results)} firmware runs).",
        "",
    ]
    return "\n".join(lines), plan.ranges()


def _criterion(plan):
    scs = list(SCENARIOS)
    lines = [
        "## Criterion",
        "",
        "A value passes when on every scenario it navigates within the board spec "
        "(eval/report.py, eval/demo.py) or, for a figure the default itself misses there, "
        f"within {RELATIVE:g}x the default's; reaches the navigating state at most "
        f"{NAV_LATE_S:g} s after the default; keeps its track finite; and sends at most "
        f"{RELATIVE:g}x as many frames more than {TRUST_M:g} m off (horizontally or vertically) "
        "without health 2 as the default. RMS over the navigation phase, outages included:",
        "",
        "| figure | spec | " + " | ".join(f"{sc} default | limit" for sc in scs) + " |",
        "|---|---|" + "---|---|" * len(scs),
    ]
    base = {sc: [plan.results[(sc, sd, None, None)] for sd in plan.seeds] for sc in scs}
    for k, (spec, what, _short, unit) in SPEC.items():
        cells = []
        for sc in scs:
            limit, how = limits(base[sc])[k]
            cells.append(f"{max(r[k] for r in base[sc]):.3g} | {limit:.3g}"
                         + ("" if how == "spec" else f" ({how})"))  # fmt: skip
        lines.append(f"| {what}, {unit} | {spec:g} | " + " | ".join(cells) + " |")
    nav = [f"{max(r['align_time_s'] for r in base[sc]):.1f} s | +{NAV_LATE_S:g} s" for sc in scs]
    lines.append("| navigating after power-on | - | " + " | ".join(nav) + " |")
    frames = [f"{max(r['untrusted_over_10m'] for r in base[sc])} | {RELATIVE:g}x default"
              for sc in scs]  # fmt: skip
    lines += [f"| frames > {TRUST_M:g} m without health 2 | 0 | " + " | ".join(frames) + " |", ""]
    if any(s.how == "gga" for s in plan.sweeps):
        lines += [
            "The settings applied with a GGA-only receiver are held to the default's run with "
            "that receiver (horiz m | vel m/s | roll/pitch/yaw deg | nav s): "
            + "; ".join(_gga_default(plan, sc) for sc in scs) + ".",
            "",
        ]  # fmt: skip
    return lines


def _gga_default(plan, sc):
    rs = [plan.results[(sc, sd, None, "gga")] for sd in plan.seeds]
    lim = ", ".join(f"{SPEC[k][2]} {v[0]:.3g}" for k, v in limits(rs).items())
    return f"{sc} {_cell([(r, []) for r in rs])}, limits {lim}"


def _ranges(plan):
    units = {r[0]: r[4] for r in _firmware_config()._RANGES}
    lines = [
        "## Allowed ranges",
        "",
        "Passing: the widest run of values around the default that pass on both scenarios; "
        "for still_gyro and still_accel (whose default differs by profile) and the settings "
        "that describe the installation or the receiver (the simulation matched to the value), "
        "the union of each scenario's run around its own default: a value must navigate the "
        "carrier it is the default of, or could be right for (a 3 m lever arm is a car's, "
        "not a hand's). Below / above: the first value past it and why it fails. Table row: "
        "the firmware's range table (integers over a power of ten; an end at a default's "
        "float32 rounded outwards to two digits) from the passing run; for the calibrations, "
        "whose right value is the sensor's own error and which a simulated sensor cannot tell "
        "from a wrong one, the BMI055's own error widened by how far off the sweep may be: a "
        "bias's row is the offset ("
        + ", ".join(f"{n} {t}" for n, (_a, _b, t) in SENSOR_OFFSET.items())
        + ") plus half the passing run, a matrix's bounds every element by the largest "
        f"diagonal scale that passes plus the scale error ({SENSOR_SCALE[2]}; an element of a "
        "rotation, a mounting in the matrix, is within 1).",
        "",
        "| setting | applied | swept | passing | below it | above it | table row (lo, hi, den) |",
        "|---|---|---|---|---|---|---|",
    ]
    for sw in plan.sweeps:
        allowed = plan.allowed(sw.name)
        swept = f"{sw.lo / sw.den:g}..{sw.hi / sw.den:g} {units.get(sw.name, '')}".strip()
        head = f"| {sw.name} | {HOW[sw.how]} | {swept} |"
        if allowed is None:
            lines.append(f"{head} **the default fails** | | | |")
            continue
        below, above = _beyond(plan, sw.name, allowed)
        lines.append(f"{head} {allowed[0]:.4g}..{allowed[1]:.4g} | {below} | {above} "
                     f"| {table_row(sw, allowed)} |")  # fmt: skip
    return [*lines, ""]


def _setting(plan, name):
    scs = list(SCENARIOS)
    sw = _BY_NAME.get(name)
    lines = [
        f"### {name}",
        "",
        f"Applied: {HOW[sw.how if sw else 'value']}."
        + ("" if sw else " An int setting: validate()'s own rule, not the range table."),
        "",
        "| value | " + " | ".join(f"{sc} horiz m | vel m/s | r/p/y deg | nav s" for sc in scs)
        + " | verdict |",
        "|---|" + "---|---|---|---|" * len(scs) + "---|",
    ]  # fmt: skip
    for v in plan.values[name]:
        runs = plan.row(name, v)
        refused = sw is not None and _refused(setting_values(sw, v))
        why = [f"{sc}: {', '.join(dict.fromkeys(w for _r, ws in rs for w in ws))}"
               for sc, rs in runs.items() if any(ws for _r, ws in rs)]  # fmt: skip
        lines.append(
            f"| {_value_text(plan, name, v)}{' *refused*' if refused else ''} | "
            + " | ".join(_cell(runs[sc]) for sc in scs)
            + " | " + ("pass" if not why else "**fail** (" + "; ".join(why) + ")") + " |"
        )  # fmt: skip
    return [*lines, ""]


def _refused(values):
    """The firmware's range table of today refuses it (replay/run_config.py `problem`)."""
    from host_emulator.replay import run_config

    return run_config.problem(values) is not None
