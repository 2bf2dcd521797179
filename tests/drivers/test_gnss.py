"""firmware/drivers/gnss.py: the NMEA driver against 20 real receiver logs, two oracles (gpsd's
accepted-sentence echo and TPV reports in the .chk files; pynmea2's field parse), edge cases,
and on the MicroPython VM: same integers as on CPython, no allocation under heap_lock, and
every stored integer a board small int (|x| < 2**30; the 64-bit VM cannot show this itself).

The logs are read from ../shared/data/nmea (gpsd regression suite, see its INDEX.md). Lines
starting with '#' are log comments (gpsfake skips them too); everything else is fed as UART
bytes in random chunk sizes through a 128-byte buffer, as `uart.readinto` would deliver it.
"""

import collections
import functools
import json
import random
import re
import sys
from decimal import ROUND_HALF_UP, Decimal
from fractions import Fraction

import pynmea2
import pytest

from common.firmware_env import REPO_DIR
from drivers import gnss, gnss_kern
from host_emulator.runtimes.mpy_unix import vm as mpvm

NMEA_DIR = REPO_DIR.parent / "shared" / "data" / "nmea"
LOGS = sorted(p.name[:-4] for p in NMEA_DIR.glob("*.log"))
needs_logs = pytest.mark.skipif(not LOGS, reason=f"no NMEA logs in {NMEA_DIR}")
TYPES = {b"GGA": gnss.GGA, b"RMC": gnss.RMC, b"VTG": gnss.VTG, b"GSA": gnss.GSA}
TALKERS = {bytes((a, b)) for a in range(65, 91) for b in range(65, 91) if a != 80}  # not P
SMALL = 2**30  # MicroPython small ints on a 32-bit board: -2**30 <= x < 2**30

ATTRS = {
    gnss.GGA: (
        "gga_utc_ms gga_lat_e7 gga_lon_deg gga_lon_frac_e7 gga_pos_ok gga_quality gga_nsat "
        "gga_hdop_x100 gga_alt_mm gga_alt_ok gga_sep_mm gga_sep_ok"
    ).split(),
    gnss.RMC: (
        "rmc_utc_ms rmc_status rmc_lat_e7 rmc_lon_deg rmc_lon_frac_e7 rmc_pos_ok "
        "rmc_speed_mm_s rmc_course_cdeg rmc_date rmc_mode"
    ).split(),
    gnss.VTG: "vtg_course_cdeg vtg_speed_mm_s vtg_mode".split(),
    gnss.GSA: "gsa_mode gsa_fix gsa_nsv gsa_pdop_x100 gsa_hdop_x100 gsa_vdop_x100".split(),
}
EPOCH = (
    "epoch_utc_ms epoch_lat_e7 epoch_lon_deg epoch_lon_frac_e7 epoch_pos_ok epoch_alt_mm "
    "epoch_alt_ok epoch_sep_mm epoch_sep_ok epoch_quality epoch_nsat epoch_hdop_x100 "
    "epoch_speed_mm_s epoch_course_cdeg"
).split()
COUNTERS = (
    "n_gga n_rmc n_vtg n_gsa n_ignored n_bad_csum n_no_csum n_malformed n_overlong "
    "n_collided n_bad_field n_epochs n_epochs_dropped"
).split()


def check_small_ints(p):
    """Every int the driver holds (attributes, and the bytes of its buffers trivially) is a
    board small int."""
    for name, v in vars(p).items():
        if isinstance(v, int) and not name.startswith("rec_"):
            assert -SMALL <= v < SMALL, (name, v)


DAMAGED_SPEED = -1  # Recorder.rec_sequence: an RMC or VTG rejected for its checksum


class Recorder(gnss.Nmea):
    """The driver, plus a record of every line it finished (test only)."""

    def __init__(self, **kw):
        super().__init__(**kw)
        self.rec_accepted = []  # (kind, line, {attr: value})
        self.rec_sequence = []  # rec_accepted plus (DAMAGED_SPEED, line, {}), in order
        self.rec_good = []  # every line with a good checksum (accepted or ignored)
        self.rec_epochs = []  # ({epoch attr: value}, line that completed it)
        self.rec_events = []  # [kind, values...] of sentences and [0, values...] of epochs

    def _end(self, r):
        seq, ign, ep = self.seq, self.n_ignored, self.n_epochs
        super()._end(r)
        check_small_ints(self)
        line = bytes(self._line[: self.line_length()])
        if self.seq != seq:
            snap = {a: getattr(self, a) for a in ATTRS[self.last]}
            self.rec_accepted.append((self.last, line, snap))
            self.rec_sequence.append((self.last, line, snap))
            self.rec_events.append([self.last] + [snap[a] for a in ATTRS[self.last]])
        elif r == 9 and re.match(rb"[A-OQ-Z][A-Z](RMC|VTG),", line):  # gnss._NR_BAD_CSUM
            self.rec_sequence.append((DAMAGED_SPEED, line, {}))
        if self.seq != seq or self.n_ignored != ign:
            self.rec_good.append(line)
        if self.n_epochs != ep:
            self.rec_epochs.append(({a: getattr(self, a) for a in EPOCH}, line))
            self.rec_events.append([0] + [getattr(self, a) for a in EPOCH])


def strip_comments(data):
    return b"".join(x for x in data.splitlines(keepends=True) if not x.startswith(b"#"))


@functools.cache
def log_bytes(name):
    return strip_comments((NMEA_DIR / f"{name}.log").read_bytes())


def feed_chunks(p, data, seed, max_chunk=100, check=True):
    """Feed like the app: uart.readinto(buf) of random sizes (often 1), then feed(buf, n)."""
    rng = random.Random(seed)
    buf = bytearray(128)
    i = 0
    while i < len(data):
        n = min(rng.choice((1, 1, 2, 3, rng.randint(1, max_chunk))), len(data) - i)
        buf[:n] = data[i : i + n]
        p.feed(buf, n)
        if check:
            check_small_ints(p)
        i += n
    return p


@functools.cache
def run_log(name):
    return feed_chunks(Recorder(), log_bytes(name), seed=name)


@functools.cache
def chk_lines(name):
    """gpsd's echo (every sentence it accepted, without '$') and its JSON reports, in order."""
    out = []
    for x in (NMEA_DIR / f"{name}.log.chk").read_bytes().splitlines():
        if x.startswith(b"$"):
            out.append(("nmea", x[1:]))
        elif x.startswith(b"{"):
            out.append(("json", json.loads(x)))
    return out


def known_type(line):
    return line[2:5] in TYPES and line[:2] in TALKERS and line[5:6] == b","


# ---- expected results per log -----------------------------------------------------------

# Exact counters after the whole log: accepted GGA, RMC, VTG, GSA; ignored (other types,
# good checksum); rejected: bad checksum, no checksum, malformed, overlong, collided, bad
# field; epochs completed and dropped (a GGA or RMC whose second never got what the receiver
# sends: the GGA, or the speed sentence, test_receivers.py). Where each
# rejection comes from (the lines are listed by the framing reference in test_framing_*):
EXPECTED = {
    "GPSmap-76S": (12, 12, 11, 12, 104, 0, 0, 0, 0, 0, 0, 12, 0),  # clean; 1 VTG missing
    "beidou-bd": (10, 10, 0, 20, 39, 0, 0, 0, 0, 0, 0, 10, 0),  # GN/GP/BD talkers, BDGSA
    # GN/GL GSA; the first RMC's GGA came before the log started: dropped
    "bu353-glonass": (18, 19, 0, 38, 37, 0, 0, 0, 0, 0, 0, 18, 1),
    # 1 GPGSV with a bad checksum (INDEX: "1 bad-checksum GSV")
    "com-1289": (14, 14, 0, 14, 55, 1, 0, 0, 0, 0, 0, 14, 0),
    # all 23 GGA have bad checksums (INDEX): an RMC-only receiver to the parser, learned in
    # two epochs (dropped), then 21 epochs from the RMC
    "firefly-II": (0, 23, 0, 0, 23, 23, 0, 0, 0, 0, 0, 21, 2),
    # cold boot through a simulator, many damaged lines: 30 bad checksums (garbled bodies such
    # as "$GPN,..." and "$GP,00,..." with the original checksum); 4 without '*' ($PLCS, and
    # 3 truncated fragments); 5 malformed (a run of NUL bytes inside an RMC, and 4 lines where
    # '*1E' is followed by the rest of another sentence); 2 overlong (two GSV fragments glued
    # to other sentences, > 100 characters); 5 collided (3 x "$GPGSA...*1E$GPRMC" without
    # CR/LF, 2 GSV fragments cut by '$'). The epoch of 00:03:43 is dropped: this receiver
    # prints RMC first, and the damaged RMC after its GGA reads 00:03:44, the next one's.
    # At the cold boot RMCs come without GGA: learned RMC-only (2 dropped), 7 no-fix epochs
    # from RMC status V more than GGA+RMC would complete.
    "gp-320fw-2019-04-07-coldboot": (10, 16, 10, 13, 42, 30, 4, 5, 2, 5, 0, 16, 3),
    # the partial last sentence (INDEX) ends in CR LF without '*'
    "holux-gm-210": (11, 11, 0, 11, 6, 0, 1, 0, 0, 0, 0, 11, 0),
    "mt3339": (30, 30, 0, 30, 48, 0, 0, 0, 0, 0, 0, 30, 0),
    # 3 $POLYN lines without checksum (INDEX); 11 $PMTKCHN of ~200 characters are overlong
    "mtk-3301": (11, 11, 11, 3, 9, 0, 3, 0, 11, 0, 0, 11, 0),
    "myguide-3100": (13, 13, 0, 13, 61, 0, 0, 0, 0, 0, 0, 13, 0),  # empty GGA quality field
    "neo-m8n": (23, 23, 23, 44, 180, 0, 0, 0, 0, 0, 0, 23, 0),
    "nmea-fuzzy-cases": (14, 14, 0, 0, 0, 0, 0, 0, 0, 0, 0, 14, 0),  # 8 minute decimals
    # 5 Hz; the log ends after a GGA whose RMC never came: 150 GGA, 149 epochs; the first
    # RMC's GGA came before the log started: dropped
    "quectel-l76k-nmea": (150, 150, 150, 450, 1380, 0, 0, 0, 0, 0, 0, 149, 1),
    # 8 epochs of signal loss print GGA/RMC without time: they form no epoch (42 - 8 = 34)
    "quectel": (42, 42, 42, 42, 144, 0, 0, 0, 0, 0, 0, 34, 0),
    # "$GPGGA,030130$GPGLL,..." (INDEX: unterminated GGA collided with GLL)
    "triton400": (4, 4, 0, 3, 17, 0, 0, 0, 0, 1, 0, 4, 0),
    # binary UBX before the first sentence is skipped; the incomplete last line has no '*'
    "ublox-8": (72, 72, 72, 144, 648, 0, 1, 0, 0, 0, 0, 72, 0),
    "ublox-lea-4h": (14, 14, 14, 14, 52, 0, 0, 0, 0, 0, 0, 14, 0),
    # a gap in the log (08:37:36 -> 08:55:15): the GGA of 08:55:15 has no RMC of its second,
    # and the first RMC's GGA came before the log started: 2 dropped
    "ublox-lea-5h": (18, 19, 18, 18, 91, 0, 0, 0, 0, 0, 0, 17, 2),
    # the log starts with the GGA of 00:19:01 whose RMC came before the start of the log
    "ublox-lea-5q": (9, 9, 9, 9, 27, 0, 0, 0, 0, 0, 0, 8, 1),
    "ublox-neo-m9n-nmea": (61, 61, 61, 244, 976, 0, 0, 0, 0, 0, 0, 61, 0),
}

# Sentences gpsd echoed that we do not accept, or the reverse, for ALL sentence types (the
# GGA/RMC/VTG/GSA subset agrees exactly on every log, see test_accepted_*_match_gpsd):
# (gpsd only, ours only) counts with the reason.
GPSD_DIFFERENCES = {
    # gpsd accepts the MTK channel-status sentences of ~200 characters; our line buffer stops
    # at MAXLEN = 100 (NMEA-0183 allows 82 with $ and CR LF). They are ignored types anyway.
    "mtk-3301": (11, 0),
}


def test_the_logs_are_all_there():
    assert len(LOGS) == 20 and set(LOGS) == set(EXPECTED)


# ---- framing and counts -----------------------------------------------------------------


def reference_framing(data):
    """An independent statement of the framing rules over the whole byte string (regexes, no
    state machine): the kind of every '$'-started candidate."""
    kinds = []
    for m in re.finditer(rb"\$([^$\r\n]*)(?=([$\r\n]|\Z))", data):
        body, term = m.group(1), m.group(2)
        bad = [i for i, c in enumerate(body) if c < 32 or c > 126]
        if bad and bad[0] <= gnss.MAXLEN:
            kinds.append("n_malformed")
        elif len(body) > gnss.MAXLEN:
            kinds.append("n_overlong")
        elif term == b"$":
            kinds.append("n_collided")
        elif term == b"":
            kinds.append("pending")
        elif b"*" not in body:
            kinds.append("n_no_csum")
        else:
            s = body.index(b"*")
            if not re.fullmatch(rb"[0-9A-Fa-f]{2}", body[s + 1 :]):
                kinds.append("n_malformed")
            elif functools.reduce(lambda a, c: a ^ c, body[:s], 0) != int(body[s + 1 :], 16):
                kinds.append("n_bad_csum")
            else:
                kinds.append("good")
    return collections.Counter(kinds)


@needs_logs
@pytest.mark.parametrize("name", LOGS)
def test_counts_per_log(name):
    p = run_log(name)
    assert tuple(getattr(p, c) for c in COUNTERS) == EXPECTED[name]
    ref = reference_framing(log_bytes(name))
    for c in ("n_malformed", "n_overlong", "n_collided", "n_no_csum", "n_bad_csum"):
        assert getattr(p, c) == ref[c], c
    assert ref["good"] == p.n_gga + p.n_rmc + p.n_vtg + p.n_gsa + p.n_ignored + p.n_bad_field
    assert p.seq == len(p.rec_accepted) == sum(EXPECTED[name][:4])


@needs_logs
@pytest.mark.parametrize("name", ["gp-320fw-2019-04-07-coldboot", "triton400", "ublox-8"])
def test_chunking_does_not_matter(name):
    """Byte by byte, in one call, and in random chunks: the same sentences and counters."""
    data = log_bytes(name)
    a = feed_chunks(Recorder(), data, seed=1, max_chunk=1, check=False)
    b = Recorder()
    b.feed(data, len(data))
    c = run_log(name)
    for p in (a, b):
        assert p.rec_accepted == c.rec_accepted
        assert p.rec_epochs == c.rec_epochs
        assert [getattr(p, x) for x in COUNTERS] == [getattr(c, x) for x in COUNTERS]


# ---- oracle 1: gpsd ---------------------------------------------------------------------


@needs_logs
@pytest.mark.parametrize("name", LOGS)
def test_accepted_gga_rmc_vtg_gsa_match_gpsd_echo(name):
    """Same GGA/RMC/VTG/GSA lines, same order, as gpsd echoed (it drops bad checksums)."""
    ours = [line for _, line, _ in run_log(name).rec_accepted]
    gpsd = [x for kind, x in chk_lines(name) if kind == "nmea" and known_type(x)]
    assert ours == gpsd
    assert len(ours) == sum(EXPECTED[name][:4])


@needs_logs
@pytest.mark.parametrize("name", LOGS)
def test_all_good_sentences_match_gpsd_echo_but_documented(name):
    ours = collections.Counter(run_log(name).rec_good)
    gpsd = collections.Counter(x for kind, x in chk_lines(name) if kind == "nmea")
    only_gpsd, only_ours = gpsd - ours, ours - gpsd
    assert (sum(only_gpsd.values()), sum(only_ours.values())) == GPSD_DIFFERENCES.get(name, (0, 0))
    if name == "mtk-3301":
        assert all(x.startswith(b"PMTKCHN,") and len(x) > gnss.MAXLEN for x in only_gpsd)


@needs_logs
def test_fixes_match_gpsd_tpv_reports():
    """Where gpsd printed a TPV right after a GGA/RMC: lat/lon within its 1e-9 deg printing
    (|ours - tpv * 1e7| <= 0.505), altitude to the mm, fix status. gpsd's mode is its own
    inference (e.g. mtk-3301 reports mode 2 for a GGA of quality 0 with 3 satellites, and
    myguide-3100 mode 2 with an empty quality), so only fixes we call valid are checked."""
    compared = collections.Counter()
    status = {2: 2, 4: 3, 5: 4, 6: 5, 8: 8}  # GGA quality -> TPV status (absent: 1)
    for name in LOGS:
        recs = {line: (kind, snap) for kind, line, snap in run_log(name).rec_accepted}
        chk = chk_lines(name)
        for (k1, x), (k2, tpv) in zip(chk, chk[1:], strict=False):
            if k1 != "nmea" or k2 != "json" or tpv["class"] != "TPV" or x not in recs:
                continue
            kind, s = recs[x]
            if kind not in (gnss.GGA, gnss.RMC):
                continue
            if kind == gnss.GGA and s["gga_pos_ok"] and s["gga_quality"] > 0:
                lat, lon = s["gga_lat_e7"], s["gga_lon_deg"] * 10**7 + s["gga_lon_frac_e7"]
                assert tpv["mode"] >= 2 and tpv.get("status", 1) == status.get(
                    s["gga_quality"], 1
                ), (name, x)
                assert s["gga_alt_mm"] == round(tpv["altMSL"] * 1000), (name, x)
            elif kind == gnss.RMC and s["rmc_pos_ok"] and s["rmc_status"] == ord("A"):
                lat, lon = s["rmc_lat_e7"], s["rmc_lon_deg"] * 10**7 + s["rmc_lon_frac_e7"]
                assert tpv["mode"] >= 2
            else:  # no fix, empty quality, status V: gpsd never claims 3D from it
                assert tpv["mode"] <= 2 or "lat" not in tpv, (name, x)
                compared["invalid"] += 1
                continue
            assert abs(lat - tpv["lat"] * 1e7) <= 0.505, (name, x, lat, tpv["lat"])
            assert abs(lon - tpv["lon"] * 1e7) <= 0.505, (name, x, lon, tpv["lon"])
            compared[kind] += 1
    assert compared == {gnss.GGA: 55, gnss.RMC: 80, "invalid": 102}


# ---- oracle 2: pynmea2 ------------------------------------------------------------------


def units(text, k):
    """Exact: the decimal text times 10**k, rounded half away from zero (None if empty)."""
    if text == "":
        return None
    return int(Decimal(text).scaleb(k).quantize(Decimal(1), rounding=ROUND_HALF_UP))


def exact_e7(dm, hemi):
    """Exact lat/lon of ddmm.mmm text in 1e-7 deg, rounded half away from zero."""
    i = dm.index(".") if "." in dm else len(dm)
    v = (Fraction(int(dm[: i - 2])) + Fraction(Decimal(dm[i - 2 :])) / 60) * 10**7
    r = int(v + Fraction(1, 2))  # v >= 0: floor(v + 1/2)
    return -r if hemi in "SW" else r


def check_float_deg(ours, deg):
    """pynmea2's float degrees (float(d) + float(m) / 60): ours is its correct rounding, except
    within 1e-6 units of a tie, where float error decides which way (then |ours - v| <= 0.5 +
    1e-6). Returns "tie" for those, "exact" otherwise."""
    v = deg * 1e7
    frac = abs(v - int(v))
    if abs(frac - 0.5) > 1e-6:
        assert ours == round(v), (ours, v)
        return "exact"
    assert abs(ours - v) <= 0.5 + 1e-6
    return "tie"


def check_ms(ours, t):
    """pynmea2 computes microseconds as int(float(".sss") * 1e6), which can be 1 us low
    (".004" -> 3999 us); our ms truncate the decimals."""
    if t is None:
        assert ours == -1
        return
    us = t.microsecond
    assert ours == ((t.hour * 60 + t.minute) * 60 + t.second) * 1000 + (us + 1) // 1000


def check_pos(s, prefix, msg, counts):
    if not s[prefix + "pos_ok"]:
        # empty, out of range or a bad hemisphere letter
        bad_hemi = msg.lat_dir not in ("N", "S") or msg.lon_dir not in ("E", "W")
        assert msg.lat == "" or msg.lon == "" or bad_hemi
        return
    lat = s[prefix + "lat_e7"]
    lon = s[prefix + "lon_deg"] * 10**7 + s[prefix + "lon_frac_e7"]
    assert abs(s[prefix + "lon_frac_e7"]) < 10**7
    assert s[prefix + "lon_deg"] * s[prefix + "lon_frac_e7"] >= 0  # same sign
    assert lat == exact_e7(msg.lat, msg.lat_dir)
    assert lon == exact_e7(msg.lon, msg.lon_dir)
    counts["pos"] += 1
    counts[check_float_deg(lat, msg.latitude)] += 1
    counts[check_float_deg(lon, msg.longitude)] += 1


def opt(v):
    return None if v == -1 else v


def char(v):
    return "" if v == 0 else chr(v)


def check_against_pynmea2(kind, line, s, counts):
    msg = pynmea2.parse("$" + line.decode("ascii"), check=True)
    if kind == gnss.GGA:
        check_ms(s["gga_utc_ms"], msg.timestamp)
        check_pos(s, "gga_", msg, counts)
        assert opt(s["gga_quality"]) == msg.gps_qual
        assert opt(s["gga_nsat"]) == (int(msg.num_sats) if msg.num_sats else None)
        assert opt(s["gga_hdop_x100"]) == units(msg.horizontal_dil, 2)
        if msg.altitude is None:
            assert not s["gga_alt_ok"]
        else:
            assert s["gga_alt_ok"] and s["gga_alt_mm"] == units(msg.data[8], 3)
            assert abs(s["gga_alt_mm"] - msg.altitude * 1000) <= 0.5 + 1e-6
        assert (s["gga_sep_mm"] if s["gga_sep_ok"] else None) == units(msg.geo_sep, 3)
    elif kind == gnss.RMC:
        check_ms(s["rmc_utc_ms"], msg.timestamp)
        assert char(s["rmc_status"]) == msg.status
        check_pos(s, "rmc_", msg, counts)
        kn = msg.spd_over_grnd
        if kn is None:
            assert s["rmc_speed_mm_s"] == -1
        else:  # knots -> mm/s exactly from the digits, and within 0.5 of pynmea2's float
            exact = Fraction(Decimal(msg.data[6])) * Fraction(1852000, 3600)
            assert s["rmc_speed_mm_s"] == int(exact + Fraction(1, 2))
            assert abs(s["rmc_speed_mm_s"] - kn * 1852000 / 3600) <= 0.5 + 1e-6
        course = msg.true_course
        assert opt(s["rmc_course_cdeg"]) == units(msg.data[7], 2)
        assert course is None or abs(s["rmc_course_cdeg"] - course * 100) <= 0.5 + 1e-6
        d = msg.datestamp
        if d is None or isinstance(d, str):
            assert s["rmc_date"] == -1
        else:
            assert s["rmc_date"] == (d.year % 100) * 10000 + d.month * 100 + d.day
        assert char(s["rmc_mode"]) == (msg.mode_indicator or "")
    elif kind == gnss.VTG:
        assert opt(s["vtg_course_cdeg"]) == units(msg.data[0], 2)
        assert msg.true_track is None or abs(s["vtg_course_cdeg"] - msg.true_track * 100) <= 0.5
        if msg.spd_over_grnd_kmph is not None:
            exact = Fraction(Decimal(msg.data[6])) * Fraction(1000000, 3600)
            assert s["vtg_speed_mm_s"] == int(exact + Fraction(1, 2))
            assert abs(s["vtg_speed_mm_s"] - msg.spd_over_grnd_kmph / 3.6 * 1000) <= 0.5 + 1e-6
        elif msg.spd_over_grnd_kts is not None:
            exact = Fraction(msg.spd_over_grnd_kts) * Fraction(1852000, 3600)
            assert s["vtg_speed_mm_s"] == int(exact + Fraction(1, 2))
        else:
            assert s["vtg_speed_mm_s"] == -1
        assert char(s["vtg_mode"]) == (msg.faa_mode or "")
    else:
        assert char(s["gsa_mode"]) == msg.mode
        assert opt(s["gsa_fix"]) == units(msg.mode_fix_type, 0)
        assert s["gsa_nsv"] == sum(1 for i in range(1, 13) if getattr(msg, f"sv_id{i:02d}"))
        assert opt(s["gsa_pdop_x100"]) == units(msg.pdop, 2)
        assert opt(s["gsa_hdop_x100"]) == units(msg.hdop, 2)
        assert opt(s["gsa_vdop_x100"]) == units(msg.vdop, 2)
    counts[kind] += 1


@needs_logs
def test_fields_match_pynmea2():
    """Every accepted GGA/RMC/VTG/GSA of every log, field by field. Exact integers are
    computed from the digits pynmea2 split out (Decimal/Fraction); its floats (lat/lon, alt,
    speeds, courses) must round to ours (tolerances in the check_* docstrings)."""
    counts = collections.Counter()
    for name in LOGS:
        for kind, line, snap in run_log(name).rec_accepted:
            check_against_pynmea2(kind, line, snap, counts)
    assert counts[gnss.GGA] == sum(e[0] for e in EXPECTED.values()) == 536
    assert counts[gnss.RMC] == sum(e[1] for e in EXPECTED.values()) == 567
    assert counts[gnss.VTG] == sum(e[2] for e in EXPECTED.values()) == 421
    assert counts[gnss.GSA] == sum(e[3] for e in EXPECTED.values()) == 1122
    assert counts["pos"] == 1029
    # Exact ties in the digits: 6 minute decimals make minutes * 1e7 / 60 = m_e6 / 6, a tie
    # when m_e6 = 3 mod 6 (quectel: 3644.759379 S, 17444.072853 E, ...; mtk-3301:
    # 5212.978993 N, ...). We round them half away from zero (the exact oracle above agrees);
    # pynmea2's float lands within 1e-7 units either side. All other values: same integer.
    assert counts["tie"] == 28 and counts["exact"] == 2 * 1029 - 28


# ---- epochs -----------------------------------------------------------------------------


RMC_QUALITY = {"D": 2, "R": 4, "F": 5, "E": 6, "M": 7, "S": 8, "N": 0}  # else 1 (status A)


def reference_epochs(accepted, need_speed=gnss.AUTO):
    """The epoch rule restated over the accepted sentences (one burst each, so every VTG is
    within its window): key = UTC of GGA/RMC (VTG joins the latest key; no time: no epoch).
    Of the last four keyed epochs, a GGA (a speed sentence) is expected unless two or more
    lacked it (need_speed 1: both always; 0: a GGA always, the speed never). Complete at the
    first moment the key has its GGA, or an RMC and GGA is not expected, and a speed sentence
    or speed is not expected: the GGA's fix, else the RMC's (no height, nsat, HDOP); speed
    from RMC with status A or VTG with mode != N, else -1. A speed sentence damaged on the line
    (DAMAGED_SPEED, rejected for its checksum; an RMC whose time still reads as another
    epoch's excepted) counts as one without a speed."""
    out = []
    hist = collections.deque(maxlen=4)  # (had a GGA, had a speed sentence) of past epochs
    key, gga, rmc, spd, done = None, None, None, None, False
    for kind, line, s in accepted:
        if kind in (gnss.GGA, gnss.RMC):
            t = s["gga_utc_ms" if kind == gnss.GGA else "rmc_utc_ms"]
            if t != key:
                if key is not None and key >= 0 and need_speed == gnss.AUTO:
                    hist.append((gga is not None, spd is not None))
                key, gga, rmc, spd, done = t, None, None, None, False
            if t < 0:
                continue
            if kind == gnss.GGA:
                gga = s
            else:
                rmc = s
                ok = s["rmc_status"] == ord("A")
                spd = (s["rmc_speed_mm_s"], s["rmc_course_cdeg"]) if ok else (-1, -1)
        elif kind == gnss.VTG and key is not None and key >= 0:
            ok = s["vtg_mode"] != ord("N")
            spd = (s["vtg_speed_mm_s"], s["vtg_course_cdeg"]) if ok else (-1, -1)
        elif kind == DAMAGED_SPEED and key is not None and key >= 0 and not done:
            t = re.match(rb"..RMC,(\d\d)(\d\d)(\d\d)(\.\d*)?,", line)
            h, m, sec = (int(x) for x in t.groups()[:3]) if t else (99, 0, 0)
            if (
                h > 23
                or m > 59
                or sec > 59
                or key
                == (h * 3600 + m * 60 + sec) * 1000
                + round(float(b"0" + (t.group(4) or b"")) * 1000)
            ):  # an RMC's time, where it still reads as one, is the epoch's
                spd = (-1, -1)
        want_gga = sum(not g for g, _ in hist) < 2
        want_spd = need_speed == 1 or need_speed == gnss.AUTO and sum(not v for _, v in hist) < 2
        if not done and (gga or rmc and not want_gga) and (spd or not want_spd):
            done = True
            if gga:
                ep = {"epoch_" + a[4:]: v for a, v in gga.items()}
            else:
                q = 0
                if rmc["rmc_status"] == ord("A"):
                    q = RMC_QUALITY.get(chr(rmc["rmc_mode"]) if rmc["rmc_mode"] else "", 1)
                ep = {"epoch_" + a[4:]: rmc[a] for a in ATTRS[gnss.RMC][:6] if "status" not in a}
                ep.update(epoch_alt_mm=0, epoch_alt_ok=0, epoch_sep_mm=0, epoch_sep_ok=0)
                ep.update(epoch_quality=q, epoch_nsat=-1, epoch_hdop_x100=-1)
            ep["epoch_speed_mm_s"], ep["epoch_course_cdeg"] = spd or (-1, -1)
            out.append((ep, line))
    return out


@needs_logs
@pytest.mark.parametrize("name", LOGS)
def test_epochs_follow_the_rule(name):
    p = run_log(name)
    assert p.rec_epochs == reference_epochs(p.rec_sequence)
    for ep, _ in p.rec_epochs:  # every completed epoch carries a time
        assert ep["epoch_utc_ms"] >= 0


@needs_logs
def test_epoch_order_variants():
    """u-blox completes at GGA (RMC VTG GGA), holux at RMC (GGA RMC), quectel at VTG (GGA VTG
    RMC); speed from the same second; need_speed=False completes at the GGA."""
    last = {n: run_log(n).rec_epochs[0][1][2:5] for n in ("neo-m8n", "holux-gm-210", "quectel")}
    assert last == {"neo-m8n": b"GGA", "holux-gm-210": b"RMC", "quectel": b"VTG"}
    data = log_bytes("quectel")
    p = feed_chunks(Recorder(need_speed=False), data, seed=2)
    assert p.rec_epochs == reference_epochs(p.rec_sequence, need_speed=False)
    assert p.n_epochs == 34 and all(line[2:5] == b"GGA" for _, line in p.rec_epochs)
    ep = run_log("neo-m8n").rec_epochs[0][0]
    assert ep["epoch_utc_ms"] == (17 * 3600 + 19 * 60 + 26) * 1000
    assert ep["epoch_speed_mm_s"] == 60  # VTG 0.216 km/h (the RMC before: 0.117 kn = 60.2)


# ---- unit tests: edge cases -------------------------------------------------------------


def sentence(body, check=None, end=b"\r\n"):
    """'$' body '*' checksum end, the checksum computed unless given."""
    body = body.encode() if isinstance(body, str) else body
    if check is None:
        check = b"%02X" % functools.reduce(lambda a, c: a ^ c, body, 0)
    return b"$" + body + b"*" + check + end


def fed(*chunks, **kw):
    p = gnss.Nmea(**kw)
    for c in chunks:
        p.feed(c, len(c))
        check_small_ints(p)
    return p


GGA_BODY = "GPGGA,123519.25,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"
RMC_BODY = "GPRMC,123519.25,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W"
VTG_BODY = "GPVTG,054.7,T,034.4,M,005.5,N,010.2,K,A"
GSA_BODY = "GNGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1,1"


def test_a_typical_epoch():
    p = fed(sentence(RMC_BODY) + sentence(VTG_BODY) + sentence(GGA_BODY) + sentence(GSA_BODY))
    assert (p.n_gga, p.n_rmc, p.n_vtg, p.n_gsa, p.rejected(), p.n_ignored) == (1, 1, 1, 1, 0, 0)
    assert p.gga_utc_ms == 45319250 and p.gga_quality == 1 and p.gga_nsat == 8
    assert p.gga_lat_e7 == 481173000  # 48 + 7.038/60 deg
    assert (p.gga_lon_deg, p.gga_lon_frac_e7) == (11, 5166667)  # 31/60 = .516666.. -> 67
    assert p.gga_lon_e7() == 115166667
    assert p.gga_hdop_x100 == 90 and p.gga_alt_mm == 545400 and p.gga_sep_mm == 46900
    assert p.rmc_speed_mm_s == 11524  # 22.4 kn = 11.5235.. m/s
    assert p.rmc_course_cdeg == 8440 and p.rmc_date == 940323 and p.rmc_status == ord("A")
    assert p.vtg_speed_mm_s == 2833 and p.vtg_course_cdeg == 5470  # 10.2 km/h
    assert (p.gsa_mode, p.gsa_fix, p.gsa_nsv) == (ord("A"), 3, 5)
    assert (p.gsa_pdop_x100, p.gsa_hdop_x100, p.gsa_vdop_x100) == (250, 130, 210)
    assert p.epoch_ready == 1 and p.n_epochs == 1 and p.gga_seen == 1
    assert p.epoch_speed_mm_s == 2833 and p.epoch_course_cdeg == 5470  # VTG came last
    assert p.talker == 0x474E and p.last == gnss.GSA and p.seq == 4


@pytest.mark.parametrize(
    "gga, bit",
    [
        (GGA_BODY, 0),
        (GGA_BODY.replace(",1,08,", ",9,08,"), gnss.BAD_QUALITY),  # no NMEA quality above 8
        (GGA_BODY.replace(",1,08,", ",6,08,"), gnss.BAD_QUALITY),  # estimated
        (GGA_BODY.replace(",46.9,M", ",250.0,M"), gnss.BAD_GEOID),  # the geoid: -107..+86 m
        (GGA_BODY.replace(",46.9,M", ",-200.1,M"), gnss.BAD_GEOID),
        (GGA_BODY.replace(",46.9,M", ",-106.5,M"), 0),
        (GGA_BODY.replace(",1,08,", ",1,120,"), gnss.BAD_NSAT),  # GGA's field has two digits
        (GGA_BODY.replace(",1,08,", ",1,99,"), 0),
        (GGA_BODY.replace("123519.25", "235960.5"), 0),  # a leap second
    ],
)
def test_fields_no_receiver_can_report_make_the_fix_unusable(gga, bit):
    """Fuzzed NMEA once reached the app as fixes: a geoid separation of 200 m and more, a
    quality above 8, more than 99 satellites. Each is now a BAD_* bit of the epoch, which the
    app does not use. (A time that is no time of day is no time: such an epoch is never
    released, test_a_second_60_is_a_leap_second_at_23_59_only.)"""
    p = fed(sentence(gga) + sentence(RMC_BODY.replace("123519.25", gga.split(",")[1])))
    assert p.n_epochs == 1 and p.epoch_pos_ok == 1
    assert p.epoch_bad == bit and p.n_epochs_bad == (1 if bit else 0)


def test_nul_bytes_garbage_and_binary_between_sentences():
    junk = bytes(20) + b"\xb5\x62\x01\x07\x5c\x00" + bytes(range(256)).replace(b"$", b"")
    p = fed(junk + sentence(GGA_BODY) + bytes(5) + b"\xff\xfe" + sentence(RMC_BODY) + junk)
    assert (p.n_gga, p.n_rmc, p.rejected()) == (1, 1, 0)


def test_nul_or_binary_inside_a_sentence_rejects_it():
    s = sentence(GGA_BODY)
    p = fed(s[:20] + b"\x00" + s[20:] + s[:30] + b"\xb5" + s[30:] + s)
    assert (p.n_gga, p.n_malformed) == (1, 2)


def test_a_sentence_split_across_feeds():
    s = sentence(GGA_BODY) + sentence(RMC_BODY)
    for cut in range(1, len(s)):
        p = fed(s[:cut], s[cut:])
        assert (p.n_gga, p.n_rmc, p.epoch_ready) == (1, 1, 1), cut
    p = fed(*[s[i : i + 1] for i in range(len(s))])
    assert (p.n_gga, p.n_rmc) == (1, 1)


def test_feed_reads_only_n_bytes_of_the_buffer():
    buf = bytearray(sentence(GGA_BODY))
    p = fed()
    p.feed(buf, len(buf) - 1)  # LF missing, CR present: the sentence is complete at CR
    assert p.n_gga == 1
    p = fed()
    p.feed(buf, len(buf) - 2)  # no CR/LF yet
    assert p.n_gga == 0
    p.feed(b"\n", 1)
    assert p.n_gga == 1


def test_collision_rejects_the_truncated_sentence():
    s = sentence(GGA_BODY)
    p = fed(s[:25] + s)  # "$GPGGA,123519.25,4807.0$GPGGA,...": the second one survives
    assert (p.n_collided, p.n_gga) == (1, 1)
    p = fed(s[:-2] + s)  # complete, but '$' came before CR/LF
    assert (p.n_collided, p.n_gga) == (1, 1)


def test_overlong_line():
    body = "GPTXT," + "X" * (gnss.MAXLEN - 6 - 3)  # exactly MAXLEN characters with "*hh"
    p = fed(sentence(body))
    assert (p.n_ignored, p.n_overlong) == (1, 0)
    p = fed(sentence(body + "X") + sentence(GGA_BODY))
    assert (p.n_ignored, p.n_overlong, p.n_gga) == (0, 1, 1)
    p = fed(b"$" + b"A" * 1000 + sentence(GGA_BODY))  # a '$' ends an overlong run cleanly
    assert (p.n_overlong, p.n_collided, p.n_gga) == (1, 0, 1)


def test_missing_and_broken_checksums():
    s = sentence(GGA_BODY)
    p = fed(b"$" + GGA_BODY.encode() + b"\r\n")
    assert (p.n_no_csum, p.n_gga) == (1, 0)
    p = fed(s.replace(b"*", b"*0"))  # three characters after '*'
    p.feed(s[:-3] + b"\r\n", len(s) - 1)  # one character after '*'
    p.feed(s[:-4] + b"G5\r\n", len(s))  # not hex
    assert (p.n_malformed, p.n_gga) == (3, 0)
    bad = sentence(GGA_BODY, check=b"%02X" % (int(s[-4:-2], 16) ^ 1))
    p = fed(bad)
    assert (p.n_bad_csum, p.n_gga) == (1, 0)


def test_lowercase_hex_checksum():
    upper = sentence("GNVTG,,T,,M,0.117,N,0.216,K,A")  # neo-m8n.log
    assert upper.endswith(b"*3F\r\n")
    p = fed(upper.replace(b"*3F", b"*3f"))
    assert (p.n_vtg, p.rejected()) == (1, 0)


def test_empty_fields():
    p = fed(sentence("GPGGA,,,,,,,,,,,,,,"))
    assert p.n_gga == 1 and p.gga_utc_ms == -1 and p.gga_pos_ok == 0 and p.gga_quality == -1
    assert (p.gga_nsat, p.gga_hdop_x100, p.gga_alt_ok, p.gga_sep_ok) == (-1, -1, 0, 0)
    p = fed(sentence("GPGGA,105025.80,5612.9999,N,00306.7096,W,,2,60.000,160.002,M,,M,,"))
    assert p.gga_quality == -1 and p.gga_nsat == 2 and p.gga_hdop_x100 == 6000
    assert p.gga_pos_ok and p.gga_alt_mm == 160002 and not p.gga_sep_ok
    p = fed(sentence("GPRMC,,V,,,,,,,,,,N"), sentence("GPVTG,,T,,M,,N,,K,N"))
    assert (p.rmc_status, p.rmc_speed_mm_s, p.rmc_course_cdeg, p.rmc_date) == (86, -1, -1, -1)
    assert (p.vtg_speed_mm_s, p.vtg_course_cdeg, p.vtg_mode) == (-1, -1, ord("N"))
    p = fed(sentence("GPGSA,A,1,,,,,,,,,,,,,,,"))
    assert (p.gsa_fix, p.gsa_nsv, p.gsa_pdop_x100, p.n_gsa) == (1, 0, -1, 1)
    p = fed(sentence("GPVTG,,T,,M,5.5,N,,K"))  # km/h empty: knots used
    assert p.vtg_speed_mm_s == 2829  # 5.5 * 514.44.. = 2829.4


def test_bad_fields_reject_the_sentence_and_keep_the_old_values():
    p = fed(sentence(GGA_BODY))
    for body in (
        GGA_BODY.replace("545.4", "545") + ",X",  # one field too many is fine ...
        GGA_BODY.replace(",1,08,", ",1,0x,"),  # ... a letter in a number is not
        GGA_BODY.replace("123519.25", "12351"),  # time needs 6 digits
        GGA_BODY.replace("4807.038", "48O7.038"),
        GGA_BODY.replace("4807.038", "07.038"),  # minutes need degrees before them
        GGA_BODY.replace("4807.038", "4807.03.8"),
        GGA_BODY.replace("545.4", "1234567890"),  # beyond 1e9 mm
        "GPGGA,123519.25,4807.038,N,01131.000,E,1",  # too few fields
        RMC_BODY.replace("230394", "2303944"),
        GSA_BODY.replace(",2.5,", ",-2.5,"),  # DOPs are not negative
    ):
        p.feed(sentence(body), len(sentence(body)))
    assert p.n_bad_field == 9 and p.n_gga == 2 and p.n_rmc == 0 and p.n_gsa == 0
    assert p.gga_alt_mm == 545000 and p.gga_lat_e7 == 481173000


def test_short_but_complete_sentences():
    """Older receivers: RMC without the magnetic variation fields, GGA ending at altitude."""
    p = fed(sentence("GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394"))
    assert p.n_rmc == 1 and p.rmc_date == 940323 and p.rmc_mode == 0
    p = fed(sentence("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4"))
    assert p.n_gga == 1 and p.gga_alt_mm == 545400 and p.gga_sep_ok == 0
    p = fed(sentence("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9"))
    assert (p.n_gga, p.n_bad_field) == (0, 1)


def test_out_of_range_values_are_marked_invalid_not_rejected():
    p = fed(sentence(GGA_BODY.replace("123519.25", "243000").replace("4807.038,N", "9100.0,N")))
    assert p.n_gga == 1 and p.gga_utc_ms == -1 and p.gga_pos_ok == 0
    p = fed(sentence(GGA_BODY.replace("01131.000,E", "18000.001,E")))
    assert p.gga_pos_ok == 0
    p = fed(sentence(GGA_BODY.replace(",N,", ",X,")))
    assert p.gga_pos_ok == 0
    p = fed(sentence(RMC_BODY.replace("230394", "320394")))
    assert p.n_rmc == 1 and p.rmc_date == -1


def test_a_second_60_is_a_leap_second_at_23_59_only():
    """24:00:00.999 in a fuzzed log was 23:59:60.999 read naively; second 60 of any other minute
    is no time at all (the Python reference and nmea.c alike, test_the_native_scan_...)."""
    for t, ms in (("235960.999", 86400999), ("123460", -1), ("000060", -1), ("240000", -1)):
        p = fed(sentence(GGA_BODY.replace("123519.25", t)))
        assert p.n_gga == 1 and p.gga_utc_ms == ms, t


def test_hemispheres_and_longitude_halves():
    p = fed(sentence("GPGGA,000000,3644.759368,S,17444.072860,W,1,07,1.1,-56.1,M,-37.0,M,,"))
    assert p.gga_lat_e7 == -367459895  # 36.74598946.. S
    assert (p.gga_lon_deg, p.gga_lon_frac_e7) == (-174, -7345477)  # 174.734547666.. W
    assert p.gga_lon_e7() == -1747345477 and gnss.lon_e7(-174, -7345477) == -1747345477
    assert p.gga_alt_mm == -56100 and p.gga_sep_mm == -37000
    p = fed(sentence("GPGGA,000000,0000.0000,N,10856.4000,E,1,07,1.1,400,M,-29,M,,"))
    assert p.gga_lat_e7 == 0 and (p.gga_lon_deg, p.gga_lon_frac_e7) == (108, 9400000)
    assert p.gga_lon_e7() == 1089400000 >= 2**30  # the combined value needs a long int
    p = fed(sentence("GPGGA,000000,0000.0001,S,00000.0001,W,1,07,1.1,0,M,0,M,,"))
    assert p.gga_lat_e7 == -17 and (p.gga_lon_deg, p.gga_lon_frac_e7) == (0, -17)
    p = fed(sentence("GPGGA,000000,8960.000000,N,17959.9999999,W,0,0,,137,M,13,M,,"))
    assert p.gga_lat_e7 == 900000000 and (p.gga_lon_deg, p.gga_lon_frac_e7) == (-180, 0)


@pytest.mark.parametrize("seed", range(3))
def test_lat_lon_rounding_of_any_number_of_minute_decimals(seed):
    """Exact round half away from zero of deg + min / 60 (Fraction), including ties (minutes
    whose 1e7/60 multiple ends in .5 exactly) and 0 to 12 decimals."""
    rng = random.Random(seed)
    cases = ["4807", "4807.", "0000.000000000000", "4800.0000030", "4800.0000090"]
    cases += ["17959.99999997", "17959.99999996", "00000.0000003"]
    for _ in range(200):
        nd = rng.randint(0, 12)
        mm = f"{rng.randint(0, 59):02d}" + ("." + "".join(rng.choices("0123456789", k=nd)))
        cases.append(f"{rng.randint(0, 89):02d}{mm}")
        cases.append(f"{rng.randint(0, 179):03d}{mm}")
    ties = 0
    for dm in cases:
        for hemi_lat, hemi_lon in (("N", "E"), ("S", "W")):
            lat = dm if len(dm.split(".")[0]) == 4 else "0000"
            p = fed(sentence(f"GPGGA,000000,{lat},{hemi_lat},{dm},{hemi_lon},1,5,1,0,M,0,M,,"))
            assert p.n_gga == 1 and p.gga_pos_ok, dm
            assert p.gga_lon_e7() == exact_e7(dm, hemi_lon), dm
            assert p.gga_lat_e7 == exact_e7(lat, hemi_lat), dm
        v = Fraction(Decimal(dm[-2:] if "." not in dm else dm[dm.index(".") - 2 :])) * 10**7 / 60
        ties += v.denominator == 2
    assert ties >= 2  # "4800.0000030" and "4800.0000090" are exact ties: 0.5 and 1.5 e-7 deg


def test_midnight_and_end_of_day_times():
    for t, ms in (("000000", 0), ("000000.000", 0), ("235959.999", 86399999)):
        p = fed(sentence(GGA_BODY.replace("123519.25", t)))
        assert p.gga_utc_ms == ms
    p = fed(sentence(GGA_BODY.replace("123519.25", "235959.9999")))  # decimals truncate
    assert p.gga_utc_ms == 86399999
    p = fed(sentence(GGA_BODY.replace("123519.25", "235960")))  # a leap second
    assert p.gga_utc_ms == 86400000


def test_ignored_types_and_talkers():
    p = fed(
        sentence("GPGSV,1,1,00"),
        sentence("GPGLL,4807.038,N,01131.000,E,123519,A,A"),
        sentence("GPZDA,201530.00,04,07,2002,00,00"),
        sentence("GPTXT,01,01,02,ANTENNA OK"),
        sentence("PUBX,00,1"),
        sentence("PGGGA" + GGA_BODY[5:]),  # P: proprietary, not a talker
        sentence("gpGGA" + GGA_BODY[5:]),  # talkers are capitals
        sentence("G1GGA" + GGA_BODY[5:]),
        sentence("GPGGAX" + GGA_BODY[5:]),
    )
    assert (p.n_ignored, p.seq, p.rejected()) == (9, 0, 0)
    for talker in ("GP", "GN", "GL", "BD", "GA", "GB", "GQ", "QZ", "GI", "IN", "ZZ"):
        p = fed(sentence(talker + GGA_BODY[2:]))
        assert p.n_gga == 1 and p.talker == (ord(talker[0]) << 8 | ord(talker[1]))


def test_epochs():
    rmc, vtg, gga = sentence(RMC_BODY), sentence(VTG_BODY), sentence(GGA_BODY)
    p = fed(gga)
    assert p.gga_seen == 1 and p.epoch_ready == 0  # waiting for the speed of 12:35:19.25
    p.feed(rmc, len(rmc))
    assert p.epoch_ready == 1 and p.epoch_speed_mm_s == 11524 and p.epoch_course_cdeg == 8440
    p.epoch_ready = 0
    p.feed(vtg, len(vtg))  # same epoch, already handed over
    assert p.epoch_ready == 0 and p.n_epochs == 1
    gga2 = sentence(GGA_BODY.replace("123519.25", "123520.25"))
    gga3 = sentence(GGA_BODY.replace("123519.25", "123521.25"))
    p.feed(gga2 + gga3, 2 * len(gga2))  # 12:35:20 never got its speed: dropped, not late
    assert (p.n_epochs, p.n_epochs_dropped, p.epoch_ready) == (1, 1, 0)
    v_rmc = sentence(RMC_BODY.replace("123519.25", "123521.25").replace(",A,", ",V,"))
    p.feed(v_rmc, len(v_rmc))  # a status-V RMC completes it without a speed
    assert p.epoch_ready == 1 and p.epoch_utc_ms == 45321250 and p.epoch_speed_mm_s == -1
    p = fed(gga, need_speed=False)
    assert p.epoch_ready == 1 and p.epoch_speed_mm_s == -1
    p = fed(sentence("GPGGA,,,,,,0,,,,,,,,"), vtg, sentence("GPRMC,,V,,,,,,,,,,N"))
    assert p.n_epochs == 0 and p.gga_seen == 1  # no time: no epoch


def damaged(body, i):
    """The sentence of body with character i (0: the first after '$') replaced, its checksum
    that of the original: line noise."""
    good = sentence(body)
    b = bytearray(good)
    b[1 + i] = ord("#") if b[1 + i] != ord("#") else ord("%")
    return bytes(b)


def test_a_damaged_speed_sentence_completes_its_epoch_without_a_speed():
    """GGA first, then the RMC damaged on the line (a byte of its course): the epoch is
    released at it, position without speed, not dropped at the next GGA (it once was: a fix
    lost for every damaged RMC)."""
    gga, rmc, vtg = sentence(GGA_BODY), damaged(RMC_BODY, 48), damaged(VTG_BODY, 20)
    p = fed(gga + rmc)
    assert p.n_bad_csum == 1 and p.epoch_ready == 1 and p.n_epochs_dropped == 0
    assert p.epoch_utc_ms == 45319250 and p.epoch_lat_e7 == 481173000
    assert (p.epoch_speed_mm_s, p.epoch_course_cdeg) == (-1, -1)
    assert fed(gga + vtg).epoch_ready == 1  # a damaged VTG likewise
    # what the parser learned: this receiver sends a speed sentence, so the next epoch waits
    p.feed(sentence(GGA_BODY.replace("123519.25", "123520.25")), len(gga))
    assert p.n_epochs == 1 and p.gga_utc_ms == 45320250


@pytest.mark.parametrize(
    "line, why",
    [
        (damaged(RMC_BODY, 3), "its address no longer reads RMC"),
        (damaged(RMC_BODY, 0), "its talker is not two capitals"),
        (damaged(RMC_BODY.replace("123519.25", "123520.25"), 48), "the next second's RMC"),
        (sentence("GPZDA,123519.25,23,03,1994,00,00"), "a good sentence of another type"),
        (damaged(GSA_BODY, 20), "a damaged GSA"),
    ],
)
def test_a_damaged_line_that_is_not_the_epochs_speed_does_not_complete_it(line, why):
    p = fed(sentence(GGA_BODY) + line)
    assert p.epoch_ready == 0 and p.n_epochs == 0, why


def test_a_damaged_speed_sentence_after_the_window_belongs_to_the_next_group(monkeypatch):
    """A receiver printing VTG first: its damaged VTG 900 ms after the GGA is the next
    second's, and releasing the open epoch then would hand over a 1 s old position."""
    clock = [0]
    monkeypatch.setattr(gnss, "_ticks_us", lambda: clock[0])
    monkeypatch.setattr(gnss, "_ticks_diff", lambda a, b: a - b)
    p = fed(sentence(GGA_BODY))
    vtg = damaged(VTG_BODY, 20)
    clock[0] = 900000
    p.feed(vtg, len(vtg))
    assert p.epoch_ready == 0 and p.n_bad_csum == 1
    p = fed(sentence(GGA_BODY))
    clock[0] = 700000  # within 3/4 of the 1 s period: the epoch's own
    p.feed(vtg, len(vtg))
    assert p.epoch_ready == 1


def test_epoch_copy_is_not_torn_by_later_sentences():
    rmc, gga = sentence(RMC_BODY), sentence(GGA_BODY)
    nxt = sentence(GGA_BODY.replace("123519.25", "123520.25").replace("4807.038", "4808.000"))
    p = fed(rmc + gga + nxt)
    assert p.epoch_lat_e7 == 481173000 and p.gga_lat_e7 == 481333333


class FakeTime:
    """time.ticks_us() of MicroPython, for CPython."""

    t = 0

    @classmethod
    def ticks_us(cls):
        cls.t = (cls.t + 12345) & (2**30 - 1)
        return cls.t


def test_pps_isr_records_ticks_and_a_flag_only(monkeypatch):
    monkeypatch.setattr(gnss, "time", FakeTime)
    p = gnss.Nmea()
    before = dict(vars(p))
    p.pps_isr(None)
    after = dict(vars(p))
    assert {k for k in after if after[k] != before[k]} <= {"pps_us", "pps_flag"}
    assert p.pps_flag == 1 and isinstance(p.pps_us, int)
    p.feed(sentence(RMC_BODY), len(sentence(RMC_BODY)))
    p.feed(sentence(GGA_BODY), len(sentence(GGA_BODY)))
    assert p.epoch_pps_us == p.pps_us
    assert (p.pps_flag_take(), p.pps_flag_take(), p.pps_flag) == (1, 0, 0)
    assert (p.gga_flag_take(), p.gga_flag_take()) == (1, 0)
    assert (p.epoch_take(), p.epoch_take(), p.epoch_ready) == (1, 0, 0)


def test_counters_wrap_as_small_ints():
    p = gnss.Nmea()
    p.n_gga = p.seq = 2**30 - 1
    p.feed(sentence(GGA_BODY), len(sentence(GGA_BODY)))
    assert p.n_gga == 0 and p.seq == 0


def test_stored_ints_stay_small_through_every_function_on_real_logs(monkeypatch):
    """Run-time proof of the 31-bit bound for intermediates too: trace every line of the
    driver's parsing functions (sys.settrace; the Python reference scan, which the native one
    equals: test_the_native_scan_equals_the_python_reference) over the logs with the widest
    numbers and the most damage, and check every int local. The scan's byte loop is checked at
    its return (its locals are indices and bytes)."""
    monkeypatch.setattr(gnss, "_scan", gnss_kern.scan)
    mods = {gnss.__file__, gnss_kern.__file__}
    seen = collections.Counter()

    def local(frame, event, arg):
        for k, v in frame.f_locals.items():
            if type(v) is int:
                assert -SMALL <= v < SMALL, (frame.f_code.co_name, k, v)
                seen["ints"] += 1
        if event == "return" and type(arg) is int:
            assert -SMALL <= arg < SMALL, (frame.f_code.co_name, arg)
        return local

    def tracer(frame, event, arg):
        if frame.f_code.co_filename not in mods:
            return None
        if frame.f_code.co_name == "scan":
            frame.f_trace_lines = False
        return local

    names = ["nmea-fuzzy-cases", "gp-320fw-2019-04-07-coldboot", "quectel", "mtk-3301"]
    datas = [log_bytes(n) for n in names]
    sys.settrace(tracer)
    try:
        for data in datas:
            p = gnss.Nmea()
            p.feed(data, len(data))
    finally:
        sys.settrace(None)
    assert seen["ints"] > 100_000


# ---- the native scan (navk.nmea_scan) against its Python reference ------------------------


def _mutated(data, seed, n):
    """n damaged copies of pieces of data: flipped, dropped and inserted bytes, with the
    characters the framing and the fields care about inserted most often."""
    rng = random.Random(seed)
    special = b"$*,.\r\n-+0123456789NSEWAVK\x00\xff"
    out = []
    for _ in range(n):
        a = rng.randrange(len(data))
        piece = bytearray(data[a : a + rng.randint(20, 600)])
        for _ in range(rng.randint(1, 8)):
            j = rng.randrange(len(piece) + 1)
            op = rng.random()
            if op < 0.4:
                piece.insert(j, rng.choice(special))
            elif op < 0.7 and j < len(piece):
                del piece[j]
            elif j < len(piece):
                piece[j] = rng.randrange(256)
        out.append(bytes(piece))
    return out


def _state(p):
    return (
        p.rec_events,
        [bytes(x) for x in p.rec_good],
        {a: v for a, v in vars(p).items() if a[0] != "_" and not a.startswith("rec_")},
        list(p._s),
        bytes(p._line),
    )


@needs_logs
def test_the_native_scan_equals_the_python_reference(monkeypatch):
    """Every log and 3,000 damaged pieces of them (bytes flipped, dropped, inserted), fed in
    the same random chunks through the native scan and through _scan_py: the same sentences,
    epochs, counters and attributes, and the same parser buffers, byte for byte."""
    import kern

    assert kern.NATIVE and gnss._scan is not gnss_kern.scan
    native = gnss._scan
    data = b"".join(log_bytes(n) for n in LOGS)
    cases = [log_bytes(n) for n in LOGS] + _mutated(data, 11, 3000)
    sentences = 0
    seen = collections.Counter()
    for i, case in enumerate(cases):
        got = []
        for scan in (native, gnss_kern.scan):
            monkeypatch.setattr(gnss, "_scan", scan)
            got.append(_state(feed_chunks(Recorder(), case, seed=i, check=False)))
        assert got[0] == got[1], i
        sentences += len(got[0][1])
        seen.update({c: got[0][2][c] for c in COUNTERS})
    assert sentences > 10_000
    assert min(seen.values()) > 0, seen  # every outcome of a line happened


# ---- MicroPython VM ---------------------------------------------------------------------

_VM_RECORDER = """
import json
from drivers import gnss, gnss_kern
A = %r
E = %r
class R(gnss.Nmea):
    def __init__(self):
        super().__init__()
        self.out = []
    def _end(self, r):
        s = self.seq
        e = self.n_epochs
        super()._end(r)
        if self.seq != s:
            self.out.append([self.last] + [getattr(self, a) for a in A[str(self.last)]])
        if self.n_epochs != e:
            self.out.append([0] + [getattr(self, a) for a in E])
"""


def vm_sample():
    """A few hundred real sentences: the damaged cold boot, southern/eastern 6-decimal
    positions, 8-decimal RTK positions, an empty quality field, BeiDou."""
    names = ["gp-320fw-2019-04-07-coldboot", "quectel", "nmea-fuzzy-cases", "myguide-3100"]
    return b"".join(log_bytes(n) for n in names + ["beidou-bd", "mtk-3301"])


def host_records(data):
    p = feed_chunks(Recorder(), data, seed=3)
    return p.rec_events, p


@needs_logs
@pytest.mark.parametrize("kernels", ["native", "python"])
def test_vm_parses_real_sentences_like_cpython(kernels):
    data = vm_sample()
    want, p = host_records(data)
    assert len(want) == 458  # 360 sentences and 98 epochs
    attrs = {str(k): v for k, v in ATTRS.items()}
    got = mpvm.run_json(
        _VM_RECORDER % (attrs, EPOCH)
        + f"data = {data!r}\n"
        + "p = R()\nbuf = bytearray(128)\ni = 0\nstep = 1\n"
        + "while i < len(data):\n"
        + "    n = min(step, len(data) - i)\n"
        + "    buf[0:n] = data[i:i + n]\n"
        + "    p.feed(buf, n)\n"
        + "    i += n\n"
        + "    step = step % 97 + 7\n"
        + f"print(json.dumps([p.out, [getattr(p, c) for c in {COUNTERS!r}]]))\n",
        kernels=kernels,
    )
    assert got[0] == want
    assert got[1] == [getattr(p, c) for c in COUNTERS]


_LOCKED_CASES = {
    "gga": sentence(GGA_BODY),
    "rmc_completes_epoch": sentence(RMC_BODY),
    "vtg": sentence(VTG_BODY),
    "gsa": sentence(GSA_BODY),
    "south_west_many_decimals": sentence(
        "GNGGA,132820.60,4134.49821229,S,09345.03351845,W,4,09,1.0,-278.020,M,-31.442,M,7.6,0133"
    ),
    "far_east": sentence("GPRMC,235959.999,A,3415.0000,N,10856.4000,E,1.5,,010125,,,A"),
    "empty_fields": sentence("GPGGA,,,,,,,,,,,,,,") + sentence("GPRMC,,V,,,,,,,,,,N"),
    "ignored": sentence("GPGSV,1,1,00") + sentence("PUBX,00,1"),
    "bad_checksum": sentence(GGA_BODY, check=b"00"),
    "no_checksum": b"$" + GGA_BODY.encode() + b"\r\n",
    "bad_field": sentence(GGA_BODY.replace(",08,", ",0x,")),
    "collision": sentence(GGA_BODY)[:30] + sentence(VTG_BODY),
    "overlong": b"$" + b"7" * 300 + b"\r\n",
    "garbage_nul_binary": bytes(16) + b"\xb5\x62\x01\x07" + bytes(range(1, 128)) + b"\r\n",
    "nul_inside": sentence(GGA_BODY)[:20] + bytes(4) + b"\r\n",
    # an epoch completed by its damaged RMC, the RMC's time readable, then damaged itself
    "damaged_rmc": sentence(GGA_BODY.replace("123519", "123530"))
    + damaged(RMC_BODY.replace("123519", "123530"), 48),
    "damaged_rmc_time": sentence(GGA_BODY.replace("123519", "123531"))
    + damaged(RMC_BODY.replace("123519", "123531"), 8),
}


@pytest.mark.parametrize("kernels", ["native", "python"])
def test_vm_feed_allocates_nothing(kernels):
    """Under micropython.heap_lock() every case runs without MemoryError (_locked) and
    gc.mem_alloc() does not move (_blocks == 0); also a split sentence, a complete epoch
    handed over (GGA after RMC) and the PPS interrupt handler."""
    body = ["import json", "from drivers import gnss", "p = gnss.Nmea()", "res = {}"]
    body.append("buf = bytearray(400)")
    for name, data in _LOCKED_CASES.items():
        assert len(data) <= 400
        body += [
            f"d = {data!r}",
            "buf[0:len(d)] = d",
            "n = len(d)",
            f"res[{name!r}] = [_locked(lambda: p.feed(buf, n)), _blocks(lambda: p.feed(buf, n))]",
        ]
    split = sentence(GGA_BODY.replace("123519.25", "123519.75"))
    body += [
        f"d = {split!r}",
        "a = bytearray(d[:37])",
        "b = bytearray(d[37:])",
        "def split():",
        "    p.feed(a, len(a))",
        "    p.feed(b, len(b))",
        "res['split'] = [_locked(split), _blocks(split)]",
        "res['pps'] = [_locked(lambda: p.pps_isr(None)), _blocks(lambda: p.pps_isr(None))]",
    ]
    # the learned paths: an epoch from an RMC alone (GGA not expected), a VTG after its
    # window held for the next epoch and taken by it (windows forced: no clock to wait for)
    t = 123600
    for name in ("rmc_only", "vtg_first"):
        rmc = sentence(RMC_BODY.replace("123519.25", f"{t}.25"))
        vtg_gga = sentence(VTG_BODY) + sentence(GGA_BODY.replace("123519.25", f"{t + 1}.25"))
        t += 2
        body += [
            f"r = {rmc!r}",
            f"v1 = {vtg_gga[:45]!r}",  # the VTG, through its LF
            f"v2 = {vtg_gga[45:]!r}",
            "def run():",
            "    p._miss_gga = 3" if name == "rmc_only" else "    p._miss_gga = 0",
            "    p.feed(r, len(r))",
            "    p._join_us = -1",
            "    p.feed(v1, len(v1))",
            "    p._join_us = 750000",
            "    p.feed(v2, len(v2))",
            "    p.epoch_ready = 0",
            f"res[{name!r}] = [_locked(run), p.n_epochs]",
        ]
    body += [
        "res['vtg_first'].append(p.epoch_speed_mm_s)",
        "res['counts'] = [p.n_gga, p.n_rmc, p.n_vtg, p.n_gsa, p.n_epochs, p.rejected()]",
        "print(json.dumps(res))",
    ]
    res = mpvm.run_json("\n".join(body), kernels=kernels)
    counts = res.pop("counts")
    rmc_only, vtg_first = res.pop("rmc_only"), res.pop("vtg_first")
    assert rmc_only[0] and vtg_first[0] and vtg_first[2] == 2833  # the VTG's 10.2 km/h
    assert vtg_first[1] == rmc_only[1] + 1  # the GGA's with the VTG (the RMC waited: dropped)
    assert res == {name: [True, 0] for name in [*_LOCKED_CASES, "split", "pps"]}
    # each case ran 3 times; GGA in gga, south_west, empty_fields, split, damaged_rmc,
    # damaged_rmc_time; RMC in rmc_completes_epoch, far_east, empty_fields; VTG in vtg,
    # collision; and one GGA, RMC and VTG in each of rmc_only and vtg_first
    assert counts[:4] == [6 * 3 + 2, 3 * 3 + 2, 2 * 3 + 2, 3]
    assert counts[4] > 0 and counts[5] > 20


def test_vm_catches_an_allocation():
    """The harness is not vacuous: a slice of the line buffer inside feed fails under
    heap_lock."""
    out = mpvm.run_json(
        "import json\nfrom drivers import gnss\n"
        "class Leaky(gnss.Nmea):\n"
        "    def _end(self, r):\n"
        "        self.copy = bytes(self._line[0:self.line_length()])\n"
        "        super()._end(r)\n"
        "p = Leaky()\np.copy = None\n"
        f"d = {sentence(GGA_BODY)!r}\n"
        "e = d[1:2]\n"
        "print(json.dumps([_locked(lambda: p.feed(d, len(d))), _blocks(lambda: p.feed(e, 1))]))"
    )
    assert out == [False, 0]  # a byte outside a sentence reaches no _end: nothing allocated
