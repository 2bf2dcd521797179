"""Faults a board meets, injected into a stimulus where the firmware meets them: the BMI055's
data registers, the GNSS UART's bytes and the PPS edges. The unmodified firmware then
runs on any runtime as on a board with that fault.

A fault is written `KIND@T0+DURATION[:PARAM]` (seconds from the start of the stimulus; PARAM as
the kind says), e.g. `imu-zeros@300+1` or `gyro-bias@300+60:1`. `parse` reads one, `apply`
returns a new stimulus with faults applied, in the order given; ticks T0 .. T0 + DURATION are
affected (the stimulus' tick is 5 ms). The kinds (KINDS: the text of `--fault help`):

IMU (both dies' data registers; counts at the stimulus' configured ranges):
- imu-stuck: every register keeps the value of T0's sample (new-data flags included);
- imu-silent: neither die answers (a broken SPI line or a dead chip: reads give the bus' idle
  0xFF, the chip IDs too); a per-tick flag of the stimulus that each runtime's driver applies;
- imu-zeros, imu-ones: every data register reads 0x00 or 0xFF;
- gyro-over, accel-over: every axis at the positive end of its range (over-range);
- gyro-vibe, accel-vibe: every axis at alternately the positive and the negative end, tick by
  tick (a vibration beyond the range);
- gyro-bias:PARAM: PARAM deg/s added to every gyro axis (default 1);
- accel-bias:PARAM: PARAM m/s^2 added to every accel axis (default 0.5);
- accel-scale:PARAM: every accel count times PARAM (default 1.05).
GNSS:
- gnss-loss: no byte arrives (the receiver silent); PPS edges go on;
- uart-corrupt:PARAM: each byte has a bit flipped with probability PARAM (default 0.01;
  which bit and which bytes from `seed`);
- pps-missing: no PPS edge;
- pps-spurious: an extra PPS edge half-way between the receiver's;
- gnss-jump:PARAM, gnss-height:PARAM: the sentences' positions PARAM m north (default 100), their
  GGA heights PARAM m higher (default 100);
- gnss-speed:PARAM, gnss-course:PARAM, gnss-quality:PARAM, gnss-hdop:PARAM: those fields set to
  PARAM (m/s, deg, GGA quality, HDOP; defaults 1000, 400, 6, 0), physically absurd or unusable;
- gnss-late:PARAM: the bytes arrive PARAM s late (default 1.4), those after them in order;
- gnss-clock:PARAM: the sentences' times of day PARAM s later (default -18: a receiver that
  steps from GPS time to UTC; the date is left, the firmware does not use it, so a week
  rollover changes nothing it reads);
- gnss-frozen: every sentence repeats the position, height, speed and course of the first
  sentence of its kind in the interval (a receiver that keeps sending its last solution);
- gnss-pole: the sentences' latitudes exactly 90 deg N.
A field fault edits every sentence that starts within the interval and has the field (a no-fix
sentence's empty fields stay empty; a course is set wherever there is a speed), with its
checksum made anew (a sentence whose checksum was already wrong is left as it is); the edited
bytes take the ticks of the original's, aligned at its end (it completes when the original did).

Board:
- stall: the board busy (a long interrupt, a flash write): the loop does not run over the
  interval, while the tick timer and the PPS interrupt do and GNSS bytes fill the UART's ring;
  a per-tick flag of the stimulus that each runtime applies. At most STALL_MAX_S. The board's
  watchdog (50 ms, firmware/board.py) resets it after a much shorter stall, which no runtime
  emulates: the runtimes run longer ones as survived, the navigator stepping through at most
  app._CATCH_UP_MAX (10) of the missed ticks (docs/health.md, the watchdog).
"""

from dataclasses import dataclass

import numpy as np

from common.errors import EmulatorError
from common.proto import stimulus as stim_mod
from host_emulator.sim import imu as imu_mod
from host_emulator.sim import nmea

GYRO_MAX, GYRO_MIN = 32767, -32768  # int16 counts
ACCEL_MAX, ACCEL_MIN = 2047, -2048  # 12-bit counts

# kind -> (default PARAM or None when it takes none, what it does)
KINDS = {
    "imu-stuck": (None, "both dies' registers keep T0's sample"),
    "imu-silent": (None, "both dies stop answering (SPI reads the bus' idle 0xFF)"),
    "imu-zeros": (None, "every data register reads 0x00"),
    "imu-ones": (None, "every data register reads 0xFF"),
    "gyro-over": (None, "every gyro axis at the positive end of its range"),
    "accel-over": (None, "every accel axis at the positive end of its range"),
    "gyro-vibe": (None, "every gyro axis alternately at either end of its range"),
    "accel-vibe": (None, "every accel axis alternately at either end of its range"),
    "gyro-bias": (1.0, "PARAM deg/s added to every gyro axis"),
    "accel-bias": (0.5, "PARAM m/s^2 added to every accel axis"),
    "accel-scale": (1.05, "every accel count times PARAM"),
    "gnss-loss": (None, "no GNSS byte arrives (PPS goes on)"),
    "uart-corrupt": (0.01, "a bit flipped in each GNSS byte with probability PARAM"),
    "pps-missing": (None, "no PPS edge"),
    "pps-spurious": (None, "an extra PPS edge half-way between the receiver's"),
    "gnss-jump": (100.0, "GGA/RMC positions PARAM m north of the truth's fixes"),
    "gnss-height": (100.0, "GGA heights PARAM m higher"),
    "gnss-speed": (1000.0, "RMC/VTG speed PARAM m/s"),
    "gnss-course": (400.0, "RMC/VTG course PARAM deg"),
    "gnss-quality": (6.0, "GGA fix quality PARAM (6: dead reckoning, 8: simulation)"),
    "gnss-hdop": (0.0, "GGA HDOP PARAM"),
    "gnss-late": (1.4, "GNSS bytes arrive PARAM s late (later ones wait behind them)"),
    "gnss-clock": (-18.0, "GGA/RMC times of day PARAM s later (-18: GPS time to UTC)"),
    "gnss-frozen": (None, "GGA/RMC/VTG repeat the interval's first position and motion"),
    "gnss-pole": (None, "GGA/RMC latitudes exactly 90 deg N"),
    "stall": (None, "the board busy: the loop does not run (the timer and interrupts do)"),
}
# the longest stall run (as if survived). It was set against a 1 s watchdog; the board's is now
# 50 ms (firmware/board.py), so a stall of nearly that or more would reset the board, which no
# runtime emulates: this bound, and bench/faults.py's 0.2 s case, are still to come down to it
STALL_MAX_S = 0.5
# the NMEA field faults: sentence edits (_edit)
_FIELD_KINDS = ("gnss-jump", "gnss-height", "gnss-speed", "gnss-course", "gnss-quality",
                "gnss-hdop", "gnss-clock", "gnss-frozen", "gnss-pole")  # fmt: skip
# the fields gnss-frozen repeats, by sentence: (first, last) field index
_FROZEN_FIELDS = {"GGA": (2, 11), "RMC": (3, 8), "VTG": (1, 8)}
M_PER_DEG_LAT = 111194.93  # a degree of latitude on a 6,371 km sphere (a jump, not geodesy)


class FaultError(EmulatorError):
    """A fault that cannot be applied as written, with what is wrong."""


@dataclass(frozen=True)
class Fault:
    kind: str
    t0_s: float
    duration_s: float
    param: float | None = None

    def __str__(self):
        p = "" if self.param is None else f":{self.param:g}"
        return f"{self.kind}@{self.t0_s:g}+{self.duration_s:g}{p}"


def describe():
    """The kinds, one line each (for `--fault help` and errors)."""
    lines = []
    for kind, (default, what) in KINDS.items():
        form = kind if default is None else f"{kind}:PARAM"
        extra = "" if default is None else f" (default {default:g})"
        lines.append(f"  {form:18} {what}{extra}")
    return "\n".join(lines)


def parse(spec):
    """A Fault from `KIND@T0+DURATION[:PARAM]`; FaultError saying what is wrong."""
    form = "KIND@T0+DURATION[:PARAM], e.g. imu-zeros@300+1 or gyro-bias@300+60:1"
    text = spec.strip()
    kind, at, rest = text.partition("@")
    if not at:
        raise FaultError(f"fault {spec!r}: expected {form}")
    kind = kind.strip().lower()
    if kind not in KINDS:
        raise FaultError(f"fault {spec!r}: unknown kind {kind!r}; the kinds:\n{describe()}")
    when, _, param = rest.partition(":")
    t0, plus, dur = when.partition("+")
    if not plus:
        raise FaultError(f"fault {spec!r}: expected {form}")
    t0_s = _number(spec, t0, "T0")
    duration_s = _number(spec, dur, "DURATION")
    if t0_s < 0 or duration_s <= 0:
        raise FaultError(f"fault {spec!r}: T0 must be 0 or more and DURATION more than 0")
    default = KINDS[kind][0]
    if kind == "stall" and duration_s > STALL_MAX_S:
        raise FaultError(f"fault {spec!r}: a stall of more than {STALL_MAX_S:g} s is beyond "
                         f"the board's watchdog timeout (50 ms), a reset the emulator does "
                         f"not model")  # fmt: skip
    if default is None:
        if param:
            raise FaultError(f"fault {spec!r}: {kind} takes no PARAM")
        return Fault(kind, t0_s, duration_s)
    value = _number(spec, param, "PARAM") if param else default
    if kind == "uart-corrupt" and not 0 < value <= 1:
        raise FaultError(f"fault {spec!r}: PARAM is a probability, more than 0 and at most 1")
    if kind == "accel-scale" and not value > 0:
        raise FaultError(f"fault {spec!r}: PARAM is a scale factor, more than 0")
    return Fault(kind, t0_s, duration_s, value)


def _number(spec, text, name):
    try:
        v = float(text)
    except ValueError:
        raise FaultError(f"fault {spec!r}: {name} {text!r} is not a number") from None
    if not np.isfinite(v):
        raise FaultError(f"fault {spec!r}: {name} must be finite")
    return v


def apply(stim, faults, seed=0):
    """A new Stimulus with `faults` (Fault objects or specs) applied in order; the header
    lists them ("faults"). FaultError if a fault starts after the stimulus ends."""
    faults = [f if isinstance(f, Fault) else parse(f) for f in faults]
    gyro_regs = stim.gyro_regs.copy()
    accel_regs = stim.accel_regs.copy()
    pps = stim.pps_before_us.copy()
    silent = stim.imu_silent.copy()
    stalled = stim.stalled.copy()
    chunks = [stim.uart_bytes[a:b] for a, b in zip(stim.uart_offsets[:-1], stim.uart_offsets[1:],
                                                    strict=True)]  # fmt: skip
    lsb_dps, lsb_g = _imu_lsb(stim.config)
    rng = np.random.default_rng(seed)
    n = len(stim)
    tick_s = stim.tick_us * 1e-6
    for f in faults:
        k0 = int(round(f.t0_s / tick_s))
        if k0 >= n:
            raise FaultError(f"fault {f}: starts at {f.t0_s:g} s, after the stimulus ends "
                             f"({n * tick_s:g} s)")  # fmt: skip
        k1 = min(n, k0 + max(1, int(round(f.duration_s / tick_s))))
        s = slice(k0, k1)
        kind = f.kind
        if kind == "imu-silent":
            silent[s] = True
        elif kind == "stall":
            stalled[s] = True
        elif kind == "imu-stuck":
            gyro_regs[s] = gyro_regs[k0]
            accel_regs[s] = accel_regs[k0]
        elif kind in ("imu-zeros", "imu-ones"):
            v = 0x00 if kind == "imu-zeros" else 0xFF
            gyro_regs[s] = v
            accel_regs[s] = v
        elif kind.startswith("gyro-"):
            _gyro_fault(gyro_regs, k0, k1, f, lsb_dps)
        elif kind.startswith("accel-"):
            _accel_fault(accel_regs, k0, k1, f, lsb_g)
        elif kind == "gnss-loss":
            for k in range(k0, k1):
                chunks[k] = b""
        elif kind == "uart-corrupt":
            _corrupt_bytes(chunks, k0, k1, f.param, rng)
        elif kind == "pps-missing":
            pps[s] = -1
        elif kind == "pps-spurious":  # half a second after each of the receiver's edges
            _spurious_pps(pps, stim.pps_before_us, k0, k1, int(round(0.5 / tick_s)))
        elif kind in _FIELD_KINDS:
            chunks = _edit_sentences(chunks, k0, k1, f)
        elif kind == "gnss-late":
            chunks = _delay(chunks, k0, k1, int(round(f.param / tick_s)))
    offsets = np.zeros(n + 1, np.int64)
    offsets[1:] = np.cumsum([len(c) for c in chunks])
    header = dict(stim.header)
    header["faults"] = list(header.get("faults", [])) + [str(f) for f in faults]
    return stim_mod.Stimulus(header, gyro_regs, accel_regs, stim.temp_raw.copy(), pps, offsets,
                             b"".join(chunks), dict(stim.extra), silent, stalled)  # fmt: skip


def _imu_lsb(cfg):
    """Gyro LSB per deg/s and accel LSB per g of the stimulus' ranges; FaultError if not BMI055."""
    lsb_dps = imu_mod.GYRO_LSB_PER_DPS_BY_RANGE.get(cfg.get("gyro_range_dps", 250))
    lsb_g = imu_mod.ACCEL_LSB_PER_G_BY_RANGE.get(cfg.get("accel_range_g", 2))
    if lsb_dps is None or lsb_g is None:
        raise FaultError(f"the stimulus' IMU ranges ({cfg.get('gyro_range_dps')} deg/s, "
                         f"{cfg.get('accel_range_g')} g) are not the BMI055's")  # fmt: skip
    return lsb_dps, lsb_g


def _gyro_fault(gyro_regs, k0, k1, f, lsb_dps):
    """gyro-over, gyro-vibe or gyro-bias on ticks [k0, k1) of gyro_regs, in place."""
    s = slice(k0, k1)
    g = stim_mod.gyro_counts(gyro_regs[s]).astype(np.int64)
    if f.kind == "gyro-over":
        g[:] = GYRO_MAX
    elif f.kind == "gyro-vibe":
        g[:] = np.where((np.arange(k0, k1) % 2 == 0)[:, None], GYRO_MAX, GYRO_MIN)
    else:  # gyro-bias
        g += int(round(f.param * lsb_dps))
    np.clip(g, GYRO_MIN, GYRO_MAX, out=g)
    gyro_regs[s] = stim_mod.gyro_registers(g)


def _accel_fault(accel_regs, k0, k1, f, lsb_g):
    """accel-over, -vibe, -bias or -scale on ticks [k0, k1) of accel_regs, in place; the
    new-data flags stay as they were."""
    s = slice(k0, k1)
    a = stim_mod.accel_counts(accel_regs[s]).astype(np.int64)
    new_data = accel_regs[s, 0::2] & 1  # each axis' flag, in its LSB register
    if f.kind == "accel-over":
        a[:] = ACCEL_MAX
    elif f.kind == "accel-vibe":
        a[:] = np.where((np.arange(k0, k1) % 2 == 0)[:, None], ACCEL_MAX, ACCEL_MIN)
    elif f.kind == "accel-bias":
        a += int(round(f.param / imu_mod.STANDARD_GRAVITY_M_S2 * lsb_g))
    else:  # accel-scale
        a[:] = np.round(a * f.param).astype(np.int64)
    np.clip(a, ACCEL_MIN, ACCEL_MAX, out=a)
    regs = stim_mod.accel_registers(a)
    regs[:, 0::2] = (regs[:, 0::2] & 0xFE) | new_data
    accel_regs[s] = regs


def _corrupt_bytes(chunks, k0, k1, p, rng):
    """Flip one random bit in each UART byte of ticks [k0, k1) with probability p, in place
    (draws per non-empty tick: which bytes, then which bits)."""
    for k in range(k0, k1):
        if chunks[k]:
            b = np.frombuffer(chunks[k], np.uint8).copy()
            hit = rng.random(len(b)) < p
            b[hit] ^= (1 << rng.integers(0, 8, int(hit.sum()))).astype(np.uint8)
            chunks[k] = b.tobytes()


def _spurious_pps(pps, pps_receiver, k0, k1, half):
    """An extra PPS edge `half` ticks after each of the receiver's edges in [k0, k1), in place
    (where the tick is still in the interval and has no edge)."""
    for k in np.flatnonzero(pps_receiver[k0:k1] >= 0) + k0:
        if k + half < k1 and pps[k + half] < 0:
            pps[k + half] = pps_receiver[k]


def _bytes_and_ticks(chunks):
    data = b"".join(chunks)
    ticks = np.repeat(np.arange(len(chunks)), [len(c) for c in chunks])
    return data, ticks


def _chunks_of(data, ticks, n):
    """Per-tick chunks of a byte stream whose byte i arrives at ticks[i] (non-decreasing);
    bytes at or beyond tick n are dropped (they never arrive in the recording)."""
    keep = ticks < n
    data = bytes(np.frombuffer(data, np.uint8)[keep])
    counts = np.bincount(ticks[keep], minlength=n)
    ends = np.cumsum(counts)
    return [data[e - c : e] for c, e in zip(counts, ends, strict=True)]


def _delay(chunks, k0, k1, d):
    data, ticks = _bytes_and_ticks(chunks)
    late = (ticks >= k0) & (ticks < k1)
    ticks = np.where(late, ticks + d, ticks)
    ticks = np.maximum.accumulate(ticks)  # a FIFO: what follows waits behind the late bytes
    return _chunks_of(data, ticks, len(chunks))


def _edit_sentences(chunks, k0, k1, fault):
    data, ticks = _bytes_and_ticks(chunks)
    out, out_ticks = [], []
    frozen = {}  # gnss-frozen: the first sentence of each kind in the interval, its fields
    i = 0
    while i < len(data):
        j = data.find(b"$", i)
        if j < 0:
            j = len(data)
        out.append(data[i:j])
        out_ticks.append(ticks[i:j])
        if j == len(data):
            break
        end = data.find(b"\n", j)
        end = len(data) if end < 0 else end + 1
        old = data[j:end]
        new = old
        if k0 <= ticks[j] < k1:
            new = _edit(old, fault, frozen)
        t = ticks[j:end]
        out.append(new)
        # aligned at the end: the edited sentence ends (and completes) when the original did
        out_ticks.append(t[np.clip(np.arange(len(new)) - (len(new) - len(t)), 0, len(t) - 1)])
        i = end
    return _chunks_of(b"".join(out), np.concatenate(out_ticks), len(chunks))


def _edit(raw, fault, frozen):
    """One sentence with the fault's field edited and its checksum anew (unchanged if it is
    not a sentence this fault edits, has no such field, or arrived damaged: a new checksum
    would repair what the receiver, or the simulation of one, sent broken). `frozen` keeps
    gnss-frozen's first fields of each kind of sentence."""
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError:
        return raw
    star = text.find("*")
    if (
        not text.startswith("$")
        or star < 0
        or text[star + 1 : star + 3].upper() != f"{nmea.checksum(text[1:star]):02X}"
    ):
        return raw
    f = text[1:star].split(",")
    kind, v = fault.kind, fault.param
    name = f[0][-3:]
    if kind == "gnss-frozen" and name in _FROZEN_FIELDS:
        a, b = _FROZEN_FIELDS[name]
        if len(f) > b:
            f[a : b + 1] = frozen.setdefault(name, f[a : b + 1])
    elif kind == "gnss-clock" and name in ("GGA", "RMC") and len(f) > 1 and f[1]:
        f[1] = _shifted_time(f[1], v)
    elif kind == "gnss-pole" and name in ("GGA", "RMC"):
        i = 2 if name == "GGA" else 3
        if len(f) > i + 1 and f[i]:
            f[i], f[i + 1] = "90" + _same_decimals(0.0, f[i][2:]).rjust(len(f[i][2:]), "0"), "N"
    elif name == "GGA" and len(f) > 9:
        if kind == "gnss-jump" and f[2]:
            f[2], f[3] = _moved_lat(f[2], f[3], v)
        elif kind == "gnss-height" and f[9]:
            f[9] = _same_decimals(float(f[9]) + v, f[9])
        elif kind == "gnss-quality" and f[6]:
            f[6] = str(int(v))
        elif kind == "gnss-hdop" and f[8]:
            f[8] = f"{v:.2f}"
    elif name == "RMC" and len(f) > 8:
        if kind == "gnss-jump" and f[3]:
            f[3], f[4] = _moved_lat(f[3], f[4], v)
        elif kind == "gnss-speed" and f[7]:
            f[7] = f"{v * nmea.KNOTS_PER_M_S:.3f}"
        elif kind == "gnss-course" and f[7]:  # wherever there is a speed (the course of a
            f[8] = f"{v:.2f}"  # slow receiver is often empty)
    elif name == "VTG" and len(f) > 7:
        if kind == "gnss-speed" and f[5]:
            f[5] = f"{v * nmea.KNOTS_PER_M_S:.3f}"
            f[7] = f"{v * 3.6:.3f}"
        elif kind == "gnss-course" and f[5]:
            f[1] = f"{v:.2f}"
    return nmea.sentence(",".join(f))


def _shifted_time(field, seconds):
    """An NMEA time of day (hhmmss.ss) `seconds` later, around midnight, in the same format."""
    t = int(field[0:2]) * 3600 + int(field[2:4]) * 60 + float(field[4:]) + seconds
    t %= 86400.0
    sec = _same_decimals(t % 60.0, field[4:])
    return f"{int(t // 3600):02d}{int(t // 60) % 60:02d}{sec:0>{len(field[4:])}}"


def _same_decimals(x, like):
    dec = len(like.partition(".")[2])
    return f"{x:.{dec}f}"


def _moved_lat(field, hemi, metres):
    """An NMEA latitude (ddmm.mmmm, N/S) moved `metres` north, in the same format."""
    deg = int(field[:2]) + float(field[2:]) / 60.0
    deg = (deg if hemi == "N" else -deg) + metres / M_PER_DEG_LAT
    a = abs(deg)
    d = int(a)
    minutes = _same_decimals((a - d) * 60.0, field[2:])
    if float(minutes) >= 60.0:  # rounded up to a whole degree
        d += 1
        minutes = _same_decimals(0.0, field[2:])
    width = len(field[2:])
    return f"{d:02d}{minutes:0>{width}}", "N" if deg >= 0 else "S"
