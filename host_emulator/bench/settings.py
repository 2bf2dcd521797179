"""`python -m host_emulator bench-settings` (`make bench-settings`): the board settings that
still navigate, the source of firmware/lib/config.py's range table.

Every float setting of that table, and the int settings that change the navigation, one at a
time: values across the range the table allowed before this benchmark narrowed it (SWEEPS: both
ends, the default, 1 and 3 per decade between, then REFINE_ROUNDS rounds of a value between the
last that passes and the first that fails), each applied as a board applies it: written into
the emulated board's ins.cfg by proto/config.py `from_values` (the path of `replay --set`), so
the unmodified firmware loads the float32 the board would hold, and run on the CPython runtime
over urban_drive (the car profile) and walk (the board in hand, the handheld profile), the
whole of each (SCENARIOS), seed 0 (--seeds).

A value passes when every run of it navigates within the board spec (SPEC: eval/report.py's
and eval/demo.py's figures; a figure the default misses on a scenario: within RELATIVE times
the default's), reaches the navigating state at most NAV_LATE_S after the default does, keeps
every float of its track finite and sends at most RELATIVE times as many frames TRUST_M off
without health 2 as the default. A setting's allowed range: the widest run of passing values
around its default (Plan.allowed; the range table's row: table_row).

How a value is applied (Sweep.how):
  value   the setting itself
  xyz     a calibration bias, the value on every axis; the simulated sensor keeps its own
          errors, so the value is a calibration error on top of them
  diag    a calibration matrix, the value on the diagonal (a scale error) and 0 off it
  lever   the lever arm, the value on every axis, the simulated antenna there too
  mount   mount_ypr_deg, the value as yaw, pitch and roll, the simulated sensor's axes turned
          by it (its counts rotated through the firmware's own rot.euler_to_dcm)
  stamp   gnss_stamp_lag_s, the simulated receiver's fixes that late
  gga     the value, every run (the default's too) with a receiver that prints GGA and GSA
          only: the settings of the heading from the track, unused while RMC gives a course
lever, mount and stamp (MATCHED) describe an installation or a receiver a board may have: the
simulation is given it, so the sweep asks whether the firmware navigates with it when told.

A value outside the firmware's range table of today is run with the table widened to the
swept range for that run (in the worker, whose firmware `config` module both from_values and
the firmware's start-up read; the run checks the firmware loaded it), so the report keeps what
the refused values measured.

Writes docs/benchmarks/settings.md and settings.json. `--quick`: the ends and the default
only, the first SCENARIOS seconds (tests/bench/test_settings.py); `--only NAME`: those settings.
"""

import contextlib
import dataclasses
import decimal
import functools
import json
import math
import pathlib
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from common.errors import EmulatorError
from host_emulator import args as cli_args
from host_emulator.bench import outputs
from host_emulator.bench.faults import TRUST_M
from host_emulator.bench.navigation import SCENARIO_PROFILES

DEFAULT_OUT = pathlib.Path("docs/benchmarks/settings.md")
# scenario: run seconds (full: the whole scenario, its outages included; quick)
SCENARIOS = {"urban_drive": (600.0, 150.0), "walk": (300.0, 100.0)}
SEEDS = (0,)
# the board spec (eval/report.py, eval/demo.py): metric -> (limit, what, short name, unit)
SPEC = {
    "horiz_rms_m": (3.0, "horizontal position RMS", "horiz", "m"),
    "vel_rms_m_s": (0.05, "velocity RMS", "vel", "m/s"),
    "roll_rms_deg": (0.5, "roll RMS", "roll", "deg"),
    "pitch_rms_deg": (0.5, "pitch RMS", "pitch", "deg"),
    "yaw_rms_deg": (3.0, "yaw RMS", "yaw", "deg"),
}
RELATIVE = 1.5  # a figure the default misses: this many times the default's at most
# Every run sends its 52-byte frame only with the extended frame (every ext_every_ticks, 20 by
# default): the score reads the track there alone, the navigation is the same bit for bit
# (tests/bench/test_settings.py), and decoding a frame per tick would cost more than the run.
FRAMES = {"output_every_ticks": 20}
# The offsets of a BMI055 (firmware/lib/config.py's comments, the datasheet's; sim/imu.py's
# uncalibrated part: 0.2-1 deg/s, 10-50 mg): a right calibration bias is one of them, which no
# sweep of a simulated sensor can tell from a wrong one (the sweep: how far off it may be)
SENSOR_OFFSET = {"gyro_bias0": (175, 10000, "1 deg/s"), "accel_bias0": (7, 10, "70 mg")}
# ... and of its scale factors (3x sim/imu.py's 0.3 % 1-sigma), which a calibration matrix's
# diagonal undoes
SENSOR_SCALE = (1, 100, "1 %")
NAV_LATE_S = 30.0  # navigating at most this much later than the default run
REFINE_ROUNDS = 2  # rounds of a value between the last that passes and the first that fails
GGA_ONLY = ("GGA", "GSA")
MATCHED = ("lever", "mount", "stamp")  # the simulation has the value too (Sweep.how)


@dataclasses.dataclass(frozen=True)
class Sweep:
    """A setting and its values: lo..hi (integers over den) the range swept, the firmware's
    before this benchmark; log: values a factor apart from the default (else offsets from it);
    first: the smallest value of a range open at lo (log), the smallest offset (else)."""

    name: str
    lo: int
    hi: int
    den: int
    log: bool
    first: float
    how: str = "value"
    values: tuple = ()  # given values instead of the generated ones (with the ends)


SWEEPS = (
    Sweep("gyro_bias0", -35, 35, 100, False, 0.003, "xyz"),  # rad/s
    Sweep("accel_bias0", -2, 2, 1, False, 0.03, "xyz"),  # m/s^2
    Sweep("gyro_matrix", -2, 2, 1, False, 0.03, "diag"),
    Sweep("accel_matrix", -2, 2, 1, False, 0.03, "diag"),
    Sweep("lever_b_m", -10, 10, 1, False, 0.3, "lever"),
    Sweep("mount_ypr_deg", -180, 180, 1, False, 30.0, "mount", (-90.0, 30.0, 90.0)),
    Sweep("gyro_arw", 0, 5, 100, True, 1e-5),
    Sweep("accel_vrw", 0, 5, 10, True, 1e-4),
    Sweep("gyro_bias_sigma", 0, 1, 10, True, 1e-6),
    Sweep("accel_bias_sigma", 0, 1, 1, True, 1e-4),
    Sweep("gnss_hdop_max", 0, 50, 1, True, 0.01),
    Sweep("gate_sigma", 1, 100, 1, True, 1.0),
    Sweep("gnss_uere_m", 0, 100, 1, True, 0.001),
    Sweep("still_gyro", 0, 2, 10, True, 1e-4),
    Sweep("still_accel", 0, 5, 1, True, 1e-3),
    Sweep("heading_speed_m_s", 1, 300, 10, True, 0.1),
    Sweep("track_min_m", 1, 200, 1, True, 1.0, "gga"),
    Sweep("track_max_s", 1, 120, 1, True, 1.0, "gga"),
    Sweep("gnss_stamp_lag_s", 0, 3, 10, False, 0.01, "stamp"),
)
# int settings that change the navigation: every value they may take (validate's own rules,
# not the range table: reported, not narrowed here). The sensor ranges and baud rates are the
# hardware's (a replay derives them from the data), not a choice that could navigate worse.
INT_SWEEPS = {
    "profile": (0, 1),
    "slices_per_tick": (1, 2, 3, 4),
    "coning": (0, 1),
    "gnss_need_speed": (0, 1, 2),
    "gnss_lag_learn": (0, 1),
}
_BY_NAME = {s.name: s for s in SWEEPS}


def _dec(x):
    return decimal.Decimal(repr(float(x)))


def _nice(x, digits=1):
    """x rounded to `digits` significant digits (a decimal as a float)."""
    return float(f"{x:.{digits - 1}e}")


def _steps(start, stop):
    """1 and 3 times the powers of ten from start to stop (both > 0), ascending."""
    out = []
    k = math.floor(math.log10(start)) - 1
    while 10.0**k <= stop * 10:
        for m in (1, 3):
            v = float(f"{m}e{k}")
            if start <= v <= stop:
                out.append(v)
        k += 1
    return out


def _close(a, b):
    """a and b (same sign, not 0) within a factor 1.25 of each other."""
    return a * b > 0 and max(a / b, b / a) <= 1.25


def grid(sw, defaults, quick=False):
    """The sweep's values, ascending: the ends (sw.first instead of an end the table refuses),
    the defaults (one per scenario's profile), and between them 1 and 3 per decade (log: the
    values; else: the offsets from the default, both ways) or sw.values, leaving out a step
    within a factor 1.25 of an end or a default; quick: the ends and the defaults alone."""
    lo, hi = sw.lo / sw.den, sw.hi / sw.den
    d = defaults[0]
    if sw.log:
        ends = [sw.first if sw.first > lo else lo, hi]
        between = _steps(ends[0], hi)
        near = [*ends, *defaults]
    else:
        ends = [lo, hi]
        steps = _steps(sw.first, max(hi - d, d - lo))
        between = list(sw.values) or [float(_dec(d) + k * _dec(s)) for s in steps for k in (-1, 1)]
        near = [e - d for e in ends]
    out = set(ends) | set(defaults)
    for v in [] if quick else between:
        if lo <= v <= hi and not any(_close(v if sw.log else v - d, n) for n in near):
            out.add(v)
    return sorted(out)


def defaults_of(name):
    """The setting's default per scenario ({scenario: value}): the element a sweep sets (a
    vector's, a matrix's diagonal: 1 for identity), for the scenario's profile."""
    config = _firmware_config()
    out = {}
    for scenario in SCENARIOS:
        cfg = config.BoardConfig(1 if SCENARIO_PROFILES[scenario] == "handheld" else 0)
        v = getattr(cfg, name)
        out[scenario] = 1.0 if v is None else float(v[0] if isinstance(v, list) else v)
    return out


def _firmware_config():
    from common import firmware_env

    firmware_env.install()
    import config  # the firmware's (firmware/lib/config.py)

    return config


def setting_values(sw, value):
    """{name: value} of the board configuration for a swept value."""
    if sw.how in ("xyz", "lever", "mount"):
        return {sw.name: [value] * 3}
    if sw.how == "diag":
        return {sw.name: [value if i % 4 == 0 else 0.0 for i in range(9)]}
    return {sw.name: value}


@contextlib.contextmanager
def _swept_range(sw):
    """The firmware's range table with sw's row widened to the swept range while a run of it
    loads its configuration (the firmware's `config` module of this process)."""
    config = _firmware_config()
    table = config._RANGES
    config._RANGES = tuple(
        (r[0], min(r[1] * sw.den, sw.lo * r[3]), max(r[2] * sw.den, sw.hi * r[3]),
         r[3] * sw.den, r[4], r[5] and r[1] * sw.den <= sw.lo * r[3])
        if sw is not None and r[0] == sw.name else r
        for r in table
    )  # fmt: skip
    try:
        yield
    finally:
        config._RANGES = table


@functools.lru_cache(maxsize=4)
def _plain_simulation(scenario, run_s, seed, receiver):
    from host_emulator.sim import board_input
    from host_emulator.sim import gnss as sim_gnss

    model = sim_gnss.GnssModel(sentences=receiver) if receiver else None
    return board_input.simulate(scenario, run_s, seed, gnss_model=model)


def simulation(scenario, run_s, seed, sw=None, value=None):
    """The board's input for a run: the scenario's simulation, with the installation a
    matched sweep's value describes (lever, mount, stamp) and the receiver a gga sweep has."""
    how = sw.how if sw is not None else "value"
    if how not in ("lever", "mount", "stamp"):
        return _plain_simulation(scenario, run_s, seed, GGA_ONLY if how == "gga" else None)
    from host_emulator.sim import board_input
    from host_emulator.sim import gnss as sim_gnss

    if how != "mount":
        field = {"lever": ("lever_b_m", (value,) * 3), "stamp": ("stamp_lag_s", value)}[how]
        model = sim_gnss.GnssModel(**dict([field]))
        return board_input.simulate(scenario, run_s, seed, gnss_model=model)
    sim = _plain_simulation(scenario, run_s, seed, None)
    imu = _mounted(sim.imu, value)
    stim, damaged = board_input.to_stimulus(sim.truth, imu, sim.gnss, _sim_header(sim), seed)
    return dataclasses.replace(sim, imu=imu, stimulus=stim, damaged_sentences=damaged)


def _sim_header(sim):
    h = sim.stimulus.header
    return {k: h[k] for k in ("scenario", "seed", "duration_s")}


def _mounted(imu, deg):
    """The IMU's counts from a sensor whose axes are turned by mount_ypr_deg = (deg, deg, deg)
    against the body: x_sensor = C^T x_body, C the firmware's own rot.euler_to_dcm (what
    config._apply_mounting composes into the calibration), rounded and held to the registers."""
    _firmware_config()
    import f32
    import rot

    ypr, c = f32.zeros(3), f32.zeros(9)
    for i in range(3):
        ypr[i] = math.radians(deg)
    rot.euler_to_dcm(c, ypr)
    c = np.asarray([float(x) for x in c]).reshape(3, 3)

    def turn(counts):
        info = np.iinfo(counts.dtype)
        return np.clip(np.rint(counts @ c), info.min, info.max).astype(counts.dtype)

    return dataclasses.replace(imu, gyro_counts=turn(imu.gyro_counts),
                               accel_counts=turn(imu.accel_counts))  # fmt: skip


def run(task):
    """One firmware run: (scenario, run_s, seed, setting name or None, value) -> its figures,
    or what went wrong ("error")."""
    scenario, run_s, seed, name, value = task
    from host_emulator.eval import evaluate, scenario_run

    sw = _BY_NAME.get(name)
    if name is None:  # a default run ("gga": with the GGA-only receiver)
        sim = _plain_simulation(scenario, run_s, seed, GGA_ONLY if value == "gga" else None)
    else:
        sim = simulation(scenario, run_s, seed, sw, value)
    overrides = dict(FRAMES)
    if sw is None and name is not None:  # an int setting
        overrides[name] = int(value)
    elif sw is not None:
        overrides.update(setting_values(sw, value))
    row = {"scenario": scenario, "seed": seed, "setting": name, "value": value}
    with tempfile.TemporaryDirectory(prefix="ins-settings-") as tmp:
        path = pathlib.Path(tmp) / "stimulus.bin"
        sim.stimulus.write(path)
        try:
            with _swept_range(sw):
                fw = scenario_run.run_firmware("cpython", path, overrides=overrides)
        except Exception as e:  # the firmware raised, refused the value: a result of the sweep
            return {**row, "error": f"{type(e).__name__}: {e}".splitlines()[0]}
        if fw.stats.get("config_status") != 0:
            return {**row, "error": "the firmware did not load the configuration: "
                    + "; ".join(fw.console[:1])}  # fmt: skip
        m, tr, err = scenario_run.evaluate_run(sim, fw, sim.stimulus, tmp, "cpython")
    h = np.hypot(err.dp[:, 0], err.dp[:, 1])
    over = (h > TRUST_M) | (np.abs(err.dp[:, 2]) > TRUST_M)
    health = tr.health[tr.state == evaluate.NAVIGATING][: err.t_s.size]
    t_nav = tr.t_s[tr.state == evaluate.NAVIGATING]
    arrays = (tr.p_n, tr.v_n, tr.ypr, tr.sigma, tr.bg, tr.ba)
    return {
        **row,
        **{k: m[k] for k in (*SPEC, "vert_rms_m", "wall_s")},
        # the first extended frame in the navigating state (frames come with them alone)
        "align_time_s": float(t_nav[0]) if t_nav.size else None,
        "finite": bool(all(np.isfinite(a).all() for a in arrays)),
        "untrusted_over_10m": int((over & (health < 2)).sum()),
    }


def _key(r):
    return (r["scenario"], r["seed"], r["setting"], r["value"])


def limits(base):
    """{metric: (limit, how)} of a scenario from its default's runs: the spec's figure, or
    RELATIVE times the default's (its worst seed) where the default misses it."""
    out = {}
    for k, (spec, *_what) in SPEC.items():
        worst = max(r[k] for r in base)
        out[k] = (spec, "spec") if worst <= spec else (RELATIVE * worst, f"{RELATIVE:g}x default")
    return out


def verdict(r, base, lim):
    """Why a run fails against its scenario's default run (same seed) and limits: a list of
    short texts, empty when it passes."""
    if "error" in r:
        return [r["error"]]
    if not r["finite"]:
        return ["a non-finite value"]
    if r["align_time_s"] is None:
        return ["never navigates"]
    why = []
    if r["align_time_s"] > base["align_time_s"] + NAV_LATE_S:
        why.append(f"navigating at {r['align_time_s']:.0f} s")
    for k, (limit, _how) in lim.items():
        if r[k] is None or not r[k] <= limit:
            why.append(f"{SPEC[k][2]} {_fig(r[k])} {SPEC[k][3]}")
    if r["untrusted_over_10m"] > RELATIVE * base["untrusted_over_10m"]:
        why.append(f"{r['untrusted_over_10m']} frames > {TRUST_M:g} m not health 2")
    return why


def _fig(x):
    return "-" if x is None else f"{x:.3g}"


def interval(values, passed, start):
    """(i, j): the widest run values[i..j] of passing values around values[start] (None if
    that one fails)."""
    if not passed[start]:
        return None
    i = j = start
    while i > 0 and passed[i - 1]:
        i -= 1
    while j + 1 < len(values) and passed[j + 1]:
        j += 1
    return i, j


def between(sw, default, p, f):
    """A value strictly between a passing p and a failing f (a 1- or 2-digit decimal: log, a
    factor; else an offset from the default), or None."""
    for digits in (1, 2):
        if sw.log:
            v = _nice(math.sqrt(p * f), digits)
        else:
            a, b = abs(p - default), abs(f - default)
            m = _nice(math.sqrt(a * b) if a else b / 3, digits)
            v = float(_dec(default) + (_dec(m) if f > default else -_dec(m)))
        if min(p, f) < v < max(p, f):
            return v
    return None


class Plan:
    """The values of each setting and what their runs gave (results keyed by _key)."""

    def __init__(self, quick, only=None, seeds=SEEDS):
        self.quick = quick
        self.seeds = seeds
        self.sweeps = [s for s in SWEEPS if not only or s.name in only]
        self.ints = {k: v for k, v in INT_SWEEPS.items() if not only or k in only}
        self.defaults = {s.name: defaults_of(s.name) for s in self.sweeps}
        self.defaults.update({k: defaults_of(k) for k in self.ints})
        self.values = {
            s.name: grid(s, sorted(set(self.defaults[s.name].values())), quick) for s in self.sweeps
        }
        self.values.update(self.ints)
        self.results = {}

    def run_s(self, scenario):
        return SCENARIOS[scenario][1 if self.quick else 0]

    def base_key(self, name, scenario, seed):
        """The key of the run a value is compared with: the scenario's default run (with the
        GGA-only receiver for a gga sweep)."""
        gga = name in _BY_NAME and _BY_NAME[name].how == "gga"
        return (scenario, seed, None, "gga" if gga else None)

    def same_as_default(self, name, scenario, value):
        sw = _BY_NAME.get(name)
        return value == self.defaults[name][scenario] and (sw is None or sw.how != "lever")

    def key(self, name, scenario, seed, value):
        if self.same_as_default(name, scenario, value):
            return self.base_key(name, scenario, seed)
        return (scenario, seed, name, value)

    def tasks(self):
        """The runs not done yet: the defaults', then every value's on every scenario."""
        keys = {(sc, sd, None, None) for sc in SCENARIOS for sd in self.seeds}
        if any(s.how == "gga" for s in self.sweeps):
            keys |= {(sc, sd, None, "gga") for sc in SCENARIOS for sd in self.seeds}
        for name, values in self.values.items():
            for v in values:
                keys |= {self.key(name, sc, sd, v) for sc in SCENARIOS for sd in self.seeds}
        todo = sorted((k for k in keys if k not in self.results), key=repr)
        todo.sort(key=lambda k: (k[2] is not None, k[0] != "urban_drive"))  # long ones first
        return [(sc, self.run_s(sc), sd, name, v) for sc, sd, name, v in todo]

    def limits(self, name, scenario):
        return limits([self.results[self.base_key(name, scenario, sd)] for sd in self.seeds])

    def row(self, name, value):
        """{scenario: [(run, why), ...]} of one value and whether it passes everywhere."""
        runs = {}
        for sc in SCENARIOS:
            lim = self.limits(name, sc)
            runs[sc] = []
            for sd in self.seeds:
                r = self.results[self.key(name, sc, sd, value)]
                base = self.results[self.base_key(name, sc, sd)]
                runs[sc].append((r, verdict(r, base, lim)))
        return runs

    def passes(self, name, scenario=None):
        """Per value of the setting: every run passes (on `scenario` alone, if given)."""
        out = []
        for v in self.values[name]:
            runs = self.row(name, v)
            out.append(all(not why for sc, rs in runs.items() if scenario in (None, sc)
                           for _r, why in rs))  # fmt: skip
        return out

    def per_scenario(self, name):
        """Whether a value needs to pass on one scenario only: a setting whose default differs
        by profile (the table holds one range for both), and an installation or a receiver a
        board may have (MATCHED: a 3 m lever arm is a car's, not a hand's)."""
        sw = _BY_NAME.get(name)
        return len(set(self.defaults[name].values())) > 1 or (sw and sw.how in MATCHED)

    def allowed(self, name):
        """(lo, hi) of the setting's allowed range, or None when a default fails: the run of
        values passing on every scenario around the default; per_scenario: the union of each
        scenario's run around its own default."""
        vals = self.values[name]
        if not self.per_scenario(name):
            ij = interval(vals, self.passes(name), vals.index(self.defaults[name]["urban_drive"]))
            return None if ij is None else (vals[ij[0]], vals[ij[1]])
        ends = []
        for sc, d in self.defaults[name].items():
            ij = interval(vals, self.passes(name, sc), vals.index(d))
            if ij is None:
                return None
            ends += [vals[ij[0]], vals[ij[1]]]
        return min(ends), max(ends)

    def ranges(self):
        """{setting: {"passing": [lo, hi], "table_row": [lo, hi, den]}} (None: a default
        fails)."""
        out = {}
        for sw in self.sweeps:
            a = self.allowed(sw.name)
            out[sw.name] = {"passing": a and list(a), "table_row": a and list(table_row(sw, a))}
        return out

    def verdicts(self):
        """{setting: [{"value", "pass", "why": {scenario: [why, ...]}}, ...]}."""
        out = {}
        for name, values in self.values.items():
            out[name] = []
            for v in values:
                why = {sc: [w for _r, ws in rs for w in ws] for sc, rs in self.row(name, v).items()}
                out[name].append({"value": v, "pass": not any(why.values()), "why": why})
        return out

    def refine(self):
        """One value between each end of an allowed range and the failing value beyond it."""
        added = 0
        for sw in self.sweeps:
            vals = self.values[sw.name]
            scs = list(SCENARIOS) if self.per_scenario(sw.name) else [None]
            new = set()
            for sc in scs:
                d = self.defaults[sw.name][sc or "urban_drive"]
                ij = interval(vals, self.passes(sw.name, sc), vals.index(d))
                if ij is None:
                    continue
                for i, k in ((ij[0], ij[0] - 1), (ij[1], ij[1] + 1)):
                    v = between(sw, d, vals[i], vals[k]) if 0 <= k < len(vals) else None
                    if v is not None:
                        new.add(v)
            self.values[sw.name] = sorted(set(vals) | new)
            added += len(new)
        return added


def table_row(sw, allowed):
    """(lo, hi, den) of the firmware's range table for an allowed range: integers over a power
    of ten; an end that is not a short decimal (a default's float32) rounded outwards to two
    digits. A matrix's row bounds every element by the largest scale that passes (a rotation's
    elements times it: a mounting in the matrix keeps its -1s and 0s) widened by the sensor's
    own scale error (SENSOR_SCALE: a right matrix undoes it); a bias's: the sensor's offset
    (SENSOR_OFFSET: a right value is it) widened by half the run that passes (how far off a
    right value may be)."""
    lo, hi = allowed
    if sw.how == "diag":
        hi = float(_dec(hi) + _dec(SENSOR_SCALE[0] / SENSOR_SCALE[1]))
        lo = -hi
    elif sw.name in SENSOR_OFFSET:
        num, den, _text = SENSOR_OFFSET[sw.name]
        hi = float(_dec(num / den) + (_dec(hi) - _dec(lo)) / 2)
        lo = -hi
    ends = []
    for x, up in ((lo, False), (hi, True)):
        d = _dec(x)
        if len(d.normalize().as_tuple().digits) > 3:
            step = decimal.Decimal(1).scaleb(d.adjusted() - 1)
            d = d.quantize(step, rounding=decimal.ROUND_CEILING if up else decimal.ROUND_FLOOR)
        ends.append(d)
    den = 10 ** max(0, *(-e.normalize().as_tuple().exponent for e in ends))
    return int(ends[0] * den), int(ends[1] * den), den


def execute(plan, jobs, log=print):
    """Run the plan's runs (the refining runs after the first ones) in a process pool."""
    rounds = 0 if plan.quick else REFINE_ROUNDS
    with ProcessPoolExecutor(max_workers=jobs) as ex:
        for r in range(rounds + 1):
            if r:
                log(f"  refining: {plan.refine()} values between a pass and a fail", flush=True)
            tasks = plan.tasks()
            for i, res in enumerate(ex.map(run, tasks)):
                plan.results[_key(res)] = res
                log(f"  {i + 1}/{len(tasks)} {res['scenario']} seed {res['seed']} "
                    f"{res['setting'] or 'default'}={res['value']}: "
                    + (res["error"] if "error" in res else f"horiz {_fig(res['horiz_rms_m'])} m"),
                    flush=True)  # fmt: skip


def _parser():
    p = cli_args.Parser(prog="python -m host_emulator bench-settings",
                        description=__doc__.split("\n\n")[1])  # fmt: skip
    cli_args.add_jobs_option(p)
    p.add_argument("--quick", action="store_true", help="the ends and the defaults, short runs")
    p.add_argument("--seeds", type=int, default=len(SEEDS), help="seeds per value (default 1)")
    p.add_argument("--only", action="append", default=[], metavar="NAME",
                   help="sweep this setting alone (repeatable)")  # fmt: skip
    p.add_argument("--out", default=str(DEFAULT_OUT), help="markdown file (default %(default)s)")
    return p


def main(argv=None):
    try:
        args = _parser().parse_args(argv)
        unknown = [n for n in args.only if n not in _BY_NAME and n not in INT_SWEEPS]
        if unknown:
            raise cli_args.UsageError(f"--only {unknown[0]}: not a swept setting; the settings: "
                                      + ", ".join([*_BY_NAME, *INT_SWEEPS]))  # fmt: skip
        if args.seeds < 1:
            raise cli_args.UsageError("--seeds must be at least 1")
    except (cli_args.UsageError, EmulatorError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2

    def command():
        out = pathlib.Path(args.out)
        outputs.announce("bench-settings", [out, out.with_suffix(".json")])
        t0 = time.perf_counter()
        plan = Plan(args.quick, set(args.only), tuple(range(args.seeds)))
        print(f"bench-settings: {len(plan.sweeps)} float and {len(plan.ints)} int settings on "
              f"{', '.join(SCENARIOS)}, {args.seeds} seed(s), CPython runtime",
              flush=True)  # fmt: skip
        execute(plan, args.jobs)
        cmd = "python -m host_emulator bench-settings" + (" --quick" if args.quick else "")
        cmd += "".join(f" --only {n}" for n in args.only)
        cmd += f" --seeds {args.seeds}" if args.seeds != len(SEEDS) else ""
        from host_emulator.bench.settings_report import markdown  # it reads this module

        text, ranges = markdown(plan, cmd, time.perf_counter() - t0)
        out = pathlib.Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
        raw = {"command": cmd, "scenarios": {sc: plan.run_s(sc) for sc in SCENARIOS},
               "seeds": list(plan.seeds), "ranges": ranges, "verdicts": plan.verdicts(),
               "runs": list(plan.results.values()), "wall_s": time.perf_counter() - t0}  # fmt: skip
        out.with_suffix(".json").write_text(json.dumps(raw, indent=1) + "\n")
        print(text)
        print(f"wrote {out}, {out.with_suffix('.json')}")
        return 0

    return cli_args.run_reporting(command)
