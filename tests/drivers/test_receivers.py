"""Every common receiver kind completes its epochs without configuration: the 20
gpsd regression logs (the NMEA data set, INDEX.md) as they are (GGA+RMC(+VTG) receivers,
several talkers), and receiver kinds derived from them here, line by line, honestly: what a
receiver configured that way would have printed of the same seconds.

    gga_rmc       the log as recorded
    rmc_only      GGA and VTG lines dropped
    gga_only      RMC and VTG lines dropped
    gga_vtg       RMC lines dropped (VTG instead of RMC; u-blox prints VTG before GGA)
    alternate     GGA in even epochs, RMC in odd ones (seconds at 1 Hz), VTG dropped
    rmc_10th      GGA every epoch, RMC in every tenth only, VTG dropped
    talker_XX     every sentence's talker rewritten to XX (IN GQ QZ GA GB BD), checksum
                  recomputed as old ^ old talker ^ new talker (a damaged line stays damaged)

Bytes are fed with a clock: each second's group of lines (from a GGA/RMC with a new UTC
time) starts at its UTC step after the last (200 ms .. 1 s) and its bytes arrive at 0.1 ms
each, which is what places a VTG that precedes its GGA in the next epoch.

A fix is delivered when an epoch completes with a position, quality > 0 and no impossible
field (what app.py hands the navigator). The reference of a derived log is the fixes of the
sentences kept: the UTC seconds with a kept GGA of quality 1-5, or (no GGA kept) an RMC with
status A and mode A/D/R/F/P, both with a position (gpsd reports such a second as a 2D/3D
TPV). For the logs as recorded, gpsd's own count is checked too: the UTC seconds with a TPV
of mode >= 2 in the .chk.
"""

import collections
import functools
import re

import numpy as np
import pytest

from common.firmware_env import REPO_DIR
from drivers import gnss, gnss_kern

NMEA_DIR = REPO_DIR.parent / "shared" / "data" / "nmea"
LOGS = sorted(p.name[:-4] for p in NMEA_DIR.glob("*.log"))
needs_logs = pytest.mark.skipif(not LOGS, reason=f"no NMEA logs in {NMEA_DIR}")
ADDR = re.compile(rb"^\$([A-Z]{2})(GGA|RMC|VTG|GSA),")
MASK = 2**30 - 1


def _hms_ms(field):
    """ms of day of an hhmmss[.sss] field, None if it is not one."""
    m = re.match(rb"^(\d\d)(\d\d)(\d\d)(\.\d+)?$", field)
    if not m:
        return None
    h, mi, s = int(m[1]), int(m[2]), int(m[3])
    return ((h * 60 + mi) * 60 + s) * 1000 + int(float(m[4] or b"0") * 1000)


class Line:
    """A log line: its bytes, type (GGA/RMC/VTG/GSA or None), UTC ms (GGA/RMC), arrival."""

    def __init__(self, data):
        self.data = data
        # the sentence from its '$' (beidou-bd has a line starting with a space, ublox-8 one
        # after binary UBX bytes)
        sent = data[max(data.rfind(b"$"), 0) :]
        m = ADDR.match(sent)
        self.talker = m[1] if m else None
        self.kind = m[2].decode() if m else None
        self.utc = None
        if self.kind in ("GGA", "RMC"):
            self.utc = _hms_ms(sent.split(b",")[1].split(b"*")[0])
        self.t_us = 0


@functools.cache
def log_lines(name):
    """The log's lines (comments dropped, as gpsfake does) with arrival times."""
    raw = (NMEA_DIR / f"{name}.log").read_bytes().splitlines(keepends=True)
    lines = [Line(x) for x in raw if not x.startswith(b"#")]
    start, key, off = 0, None, 0
    for ln in lines:
        if ln.utc is not None and ln.utc != key:
            step = 1000 if key is None else (ln.utc - key) % 86400000
            start += 1000 * (step if 200 <= step <= 1000 else 1000)
            key, off = ln.utc, 20000  # the group starts 20 ms after its second
        ln.t_us = start + off + 100 * len(ln.data)
        off += 100 * len(ln.data)
    return lines


def _retalk(ln, talker):
    """The line with its talker replaced and the checksum moved by the same XOR."""
    d = ln.data
    star = d.rfind(b"*")
    if not ln.talker or star < 0 or len(d) < star + 3:
        return ln
    try:
        ck = int(d[star + 1 : star + 3], 16)
    except ValueError:
        return ln
    i = d.rfind(b"$")
    ck ^= d[i + 1] ^ d[i + 2] ^ talker[0] ^ talker[1]
    new = Line(d[: i + 1] + talker + d[i + 3 : star + 1] + b"%02X" % ck + d[star + 3 :])
    new.t_us = ln.t_us
    return new


@functools.cache
def epoch_index(name):
    """UTC ms -> ordinal of its epoch in the log (alternate, rmc_10th: epochs, which are
    seconds at 1 Hz)."""
    out = {}
    for ln in log_lines(name):
        if ln.utc is not None and ln.utc not in out:
            out[ln.utc] = len(out)
    return out


def derive(name, kind):
    """The lines a receiver of this kind would have printed (see the module doc)."""
    lines = log_lines(name)
    if kind == "gga_rmc":
        return lines
    if kind.startswith("talker_"):
        t = kind[-2:].encode()
        return [_retalk(ln, t) for ln in lines]
    ix = epoch_index(name)

    def nth(ln, n, r):  # a GGA/RMC of the r-th epoch of each n
        return ln.utc is not None and ix[ln.utc] % n == r

    keep = {
        "rmc_only": lambda ln: ln.kind not in ("GGA", "VTG"),
        "gga_only": lambda ln: ln.kind not in ("RMC", "VTG"),
        "gga_vtg": lambda ln: ln.kind != "RMC",
        "alternate": lambda ln: (
            ln.kind not in ("GGA", "RMC", "VTG")
            or ln.kind == "GGA"
            and nth(ln, 2, 0)
            or ln.kind == "RMC"
            and nth(ln, 2, 1)
        ),
        "rmc_10th": lambda ln: ln.kind not in ("RMC", "VTG") or ln.kind == "RMC" and nth(ln, 10, 0),
    }[kind]
    return [ln for ln in lines if keep(ln)]


class Clock:
    """time.ticks_us / ticks_diff of the board, at the arrival time of the line fed."""

    def __init__(self):
        self.t = 0

    def ticks_us(self):
        return self.t & MASK

    @staticmethod
    def ticks_diff(a, b):
        return ((a - b + 2**29) & MASK) - 2**29


class Rec(gnss.Nmea):
    def __init__(self, **kw):
        super().__init__(**kw)
        self.fixes = []  # (utc, has height, speed) of the delivered fixes
        self.epochs = []  # the line that completed each epoch

    def _end(self, r):
        n = self.n_epochs
        super()._end(r)
        if self.n_epochs != n:
            self.epochs.append(bytes(self._line[: self.line_length()]))
            if self.epoch_pos_ok and self.epoch_quality > 0 and not self.epoch_bad:
                self.fixes.append((self.epoch_utc_ms, self.epoch_alt_ok, self.epoch_speed_mm_s))


def run(lines, monkeypatch, **kw):
    clock = Clock()
    monkeypatch.setattr(gnss, "_ticks_us", clock.ticks_us)
    monkeypatch.setattr(gnss, "_ticks_diff", clock.ticks_diff)
    p = Rec(**kw)
    for ln in lines:
        clock.t = ln.t_us
        p.feed(ln.data, len(ln.data))
    return p


def _good(d):
    """The checksum of a line is right."""
    star = d.rfind(b"*")
    if not d.startswith(b"$") or star < 0:
        return False
    x = 0
    for c in d[1:star]:
        x ^= c
    return d[star + 1 : star + 3].upper() == b"%02X" % x


def reference(lines):
    """The UTC ms of the seconds whose kept sentences give a fix (module doc)."""
    gga, rmc = set(), set()
    for ln in lines:
        d = ln.data[ln.data.rfind(b"$") :].strip()
        if ln.utc is None or not _good(d):
            continue
        f = d.split(b"*")[0].split(b",")
        if ln.kind == "GGA" and len(f) >= 10 and f[2] and f[4] and f[6] in b"12345" and f[6]:
            gga.add(ln.utc)
        elif ln.kind == "RMC" and len(f) >= 10 and f[2] == b"A" and f[3] and f[5]:
            if len(f) <= 12 or f[12] in (b"", b"A", b"D", b"R", b"F", b"P"):
                rmc.add(ln.utc)
    return gga | {t for t in rmc if t not in gga}


@functools.cache
def gpsd_fixes(name):
    """The UTC seconds (ms of day of the echoed GGA/RMC before it) of gpsd's mode >= 2 TPVs."""
    out, key = set(), None
    for x in (NMEA_DIR / f"{name}.log.chk").read_bytes().splitlines():
        ln = Line(x)
        if ln.utc is not None:
            key = ln.utc
        elif x.startswith(b'{"class":"TPV"') and re.search(rb'"mode":[23]', x) and key:
            out.add(key)
    return out


@functools.cache
def cut_epochs(name):
    """UTC ms of the epochs the recording cut: the first and the last, and those either side
    of a gap of more than 2 s (ublox-lea-5h: 08:37:36 -> 08:55:15). A GGA+RMC receiver's
    epoch there may lack the sentence printed before the recording started or after it
    stopped."""
    keys = list(epoch_index(name))
    out = {keys[0], keys[-1]} if keys else set()
    for a, b in zip(keys, keys[1:], strict=False):
        if not 0 < (b - a) % 86400000 <= 2000:
            out |= {a, b}
    return out


# Epochs a kind loses while the parser learns what the receiver sends (gnss.py "Epochs"):
# two for a receiver lacking GGA or the speed sentence, four for alternate epochs (each kind
# misses every other epoch: two misses in four take four epochs), none for GGA+RMC
LEARNING = {
    "gga_rmc": 0,
    "rmc_only": 2,
    "gga_only": 2,
    "gga_vtg": 2,
    "alternate": 4,
    "rmc_10th": 2,
    **{f"talker_{t}": 0 for t in ("IN", "GQ", "QZ", "GA", "GB", "BD")},
}
# ... and logs that are another kind already: firefly-II's GGA all have bad checksums (INDEX),
# so as recorded it is an RMC-only receiver; the cold boot's garbled lines lose GGA and RMC
# at random (gp-320fw: 41 bad checksums), which the learning follows
LEARNING_LOG = {"firefly-II": 2, "gp-320fw-2019-04-07-coldboot": 2}


@needs_logs
@pytest.mark.parametrize("kind", list(LEARNING))
def test_fixes_delivered_per_receiver_kind(kind, monkeypatch):
    """Per log: never a fix the kept sentences do not give; every fix they give but those of
    the learning epochs (at the log's start, LEARNING) and of the epochs the recording cut.
    The totals over the 20 logs are docs/gnss.md's table."""
    delivered = reference_total = 0
    for name in LOGS:
        lines = derive(name, kind)
        p = run(lines, monkeypatch)
        got = [f[0] for f in p.fixes]
        ref = sorted(reference(lines))
        assert len(got) == len(set(got)), name  # one fix per epoch
        assert set(got) <= set(ref), (name, set(got) - set(ref))
        learn = max(LEARNING[kind], LEARNING_LOG.get(name, 0))
        missing = [i for i, t in enumerate(ref) if t not in got and t not in cut_epochs(name)]
        assert len(missing) <= learn and all(i <= learn for i in missing), (name, missing)
        delivered += len(got)
        reference_total += len(ref)
    assert (delivered, reference_total) == FIGURES[kind]


FIGURES = {  # kind: (fixes delivered, fixes of the sentences kept) over the 20 logs
    "gga_rmc": (475, 484),
    "rmc_only": (456, 481),
    "gga_only": (433, 457),
    "gga_vtg": (440, 457),
    "alternate": (422, 470),
    "rmc_10th": (434, 462),
    "talker_IN": (475, 484),
    "talker_GQ": (475, 484),
    "talker_QZ": (475, 484),
    "talker_GA": (475, 484),
    "talker_GB": (475, 484),
    "talker_BD": (475, 484),
}

# gpsd's fixes (UTC seconds with a TPV of mode >= 2) against ours on the logs as recorded:
# (gpsd's only, ours only) with the reason; every other log agrees second for second
GPSD_DIFFERENCES = {
    "GPSmap-76S": (1, 0),  # GGA quality 8 (simulator): epoch_bad, not a fix for us
    # the first RMC, whose GGA came before the recording started (gpsd reports the RMC)
    "bu353-glonass": (1, 0),
    "quectel-l76k-nmea": (1, 0),
    "firefly-II": (2, 0),  # no GGA (bad checksums): the two epochs that learn RMC only
    "gp-320fw-2019-04-07-coldboot": (1, 0),  # 00:03:43: its RMC is damaged, its GGA waits
    "mtk-3301": (1, 0),  # gpsd's mode 2 from a GGA of quality 0 (3 satellites)
    "myguide-3100": (2, 0),  # gpsd's mode 2 from GGAs with an empty quality field
    # the last epoch: gpsd reports a cycle when the next one starts, and the log ends first
    "neo-m8n": (0, 1),
    "ublox-lea-4h": (0, 1),
    # the GGA after the gap (08:55:15, its RMC cut) and the last RMC (08:55:20, its GGA cut)
    "ublox-lea-5h": (2, 0),
}


@needs_logs
def test_fixes_against_gpsd_on_the_logs_as_recorded(monkeypatch):
    gpsd_total = ours_total = 0
    for name in LOGS:
        ours = {f[0] for f in run(log_lines(name), monkeypatch).fixes}
        gpsd = gpsd_fixes(name)
        diff = (len(gpsd - ours), len(ours - gpsd))
        assert diff == GPSD_DIFFERENCES.get(name, (0, 0)), (name, diff)
        gpsd_total += len(gpsd)
        ours_total += len(ours)
    assert (ours_total, gpsd_total) == (475, 484)


@needs_logs
def test_a_gga_rmc_receiver_completes_as_with_need_speed_1(monkeypatch):
    """On every log but the two that are another kind as recorded (LEARNING_LOG), the learned
    epochs are those of the old rule (gnss_need_speed 1): the same epochs, completed by the
    same sentence."""
    for name in LOGS:
        if name in LEARNING_LOG:
            continue
        auto = run(log_lines(name), monkeypatch)
        forced = run(log_lines(name), monkeypatch, need_speed=1)
        assert auto.epochs == forced.epochs and auto.fixes == forced.fixes, name


@needs_logs
def test_what_the_old_rule_delivered_and_the_overrides(monkeypatch):
    """gnss_need_speed 1 (the old default) delivers nothing from RMC-only, GGA-only and
    alternate-epoch receivers and only every tenth epoch with RMC every tenth; 0 (the old
    GGA-only setting) delivers every GGA, without the speed of a GGA+RMC receiver whose RMC
    comes after the GGA (neo-m8n: RMC VTG GGA, so it has it; mt3339: GGA GSA RMC)."""
    counts = collections.Counter()
    for name in LOGS:
        for kind in ("rmc_only", "gga_only", "alternate", "rmc_10th"):
            counts[kind] += len(run(derive(name, kind), monkeypatch, need_speed=1).fixes)
    assert counts == {"rmc_only": 0, "gga_only": 0, "alternate": 0, "rmc_10th": 49}
    for name, with_speed in (("neo-m8n", 23), ("mt3339", 0)):
        p = run(log_lines(name), monkeypatch, need_speed=0)
        assert len(p.fixes) == len(reference(log_lines(name)))
        assert sum(f[2] >= 0 for f in p.fixes) == with_speed, name


def _vtg_mm_s(line):
    """A VTG's speed as the parser takes it: km/h, else knots, to mm/s (gnss_kern._vtg)."""
    f = line.strip().split(b"*")[0].split(b",")
    if f[7]:
        return (round(float(f[7]) * 10**4) + 18) // 36
    return gnss_kern._knots_mm_s(round(float(f[5]) * 10**4))


@needs_logs
@pytest.mark.parametrize("name", ["neo-m8n", "ublox-8", "ublox-neo-m9n-nmea", "quectel"])
def test_what_each_kind_carries(name, monkeypatch):
    """RMC only: speed, no height; GGA only: height, no speed; alternate: each its own; VTG
    instead of RMC: the speed of the fix's own second, also where the VTG comes before the
    GGA (u-blox: VTG(t) GGA(t), which without its window would join the epoch of t - 1)."""
    fx = run(derive(name, "rmc_only"), monkeypatch).fixes
    assert fx and all(not alt and spd >= 0 for _, alt, spd in fx)
    fx = run(derive(name, "gga_only"), monkeypatch).fixes
    assert fx and all(alt and spd < 0 for _, alt, spd in fx)
    fx = run(derive(name, "alternate"), monkeypatch).fixes
    ix = epoch_index(name)
    assert all(
        bool(alt) == (ix[t] % 2 == 0) and (spd >= 0) == (ix[t] % 2 == 1) for t, alt, spd in fx
    )
    # the VTG of each second: the one after that second's first GGA/RMC in the recording
    vtg, key = {}, None
    for ln in log_lines(name):
        if ln.utc is not None:
            key = ln.utc
        elif ln.kind == "VTG" and key is not None and key not in vtg:
            vtg[key] = _vtg_mm_s(ln.data)
    fx = run(derive(name, "gga_vtg"), monkeypatch).fixes
    assert len(fx) >= len(ix) - 3
    assert all(spd == vtg[t] for t, _, spd in fx), [(t, spd, vtg[t]) for t, _, spd in fx]


def test_an_rmc_only_receiver_navigates():
    """End to end on the firmware (cpython runtime) and the model, default settings: a
    simulated receiver printing RMC (and GSA) only gives fixes with speed and course but no
    height. The frame shows height 0 (no GGA ever gave one); the navigator gets
    nav.FI_NO_HEIGHT and corrects east and north only, and its height is its own. Both sides
    agree in every bit."""
    from common.proto import stream
    from host_emulator.eval import evaluate, parity
    from host_emulator.sim import board_input
    from host_emulator.sim import gnss as sim_gnss

    model = sim_gnss.GnssModel(sigma_h_m=1.5, sigma_v_m=3.0, sentences=("RMC", "GSA"))
    sim = board_input.simulate("highway_outage", 50.0, seed=0, gnss_model=model)
    stim = sim.stimulus
    assert b"GGA" not in stim.uart_bytes and b"VTG" not in stim.uart_bytes
    r = parity.compare(stim)
    assert r.identical, r.summary()
    d = stream.decode(r.out_firmware)
    valid = [f for f in d.frames if f["gnss_valid"]]
    assert len(valid) > 40 * 200 and {f["height_m"] for f in valid} == {0.0}
    # navigating from the first course at speed, 34 s (as with GGA + RMC: 34.3 s)
    assert sum(f["nav_state"] == 2 for f in d.frames) > 15 * 200
    o = sim.truth.origin
    tr = evaluate.track(d, stim.tick_us * 1e-6, (o.lat_e7, o.lon_e7, o.h_m))
    t = sim.truth
    err = evaluate.errors(tr, t.t_s, t.p_n, t.v_n, t.ypr)
    late = err.t_s > err.t_s[0] + 2.0  # after the first updates
    # measured 0.79 m east/north; the height is the navigator's own from 0 m (the truth's
    # is 400 m), and reported unknown
    assert evaluate.rms(np.hypot(*err.dp[late, :2].T)) < 1.5
    assert np.all(err.sigma[late, 2] >= 1e4)
