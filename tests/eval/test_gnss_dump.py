"""`python -m host_emulator gnss-dump FILE [--json]` (host_emulator/eval/gnss_dump.py): one line
per accepted sentence, matching the driver's own records; counters on stderr; a clear error
for an unreadable file."""

import json
import subprocess
import sys

import pytest

from common.firmware_env import REPO_DIR
from drivers import gnss
from host_emulator.eval import gnss_dump

NMEA_DIR = REPO_DIR.parent / "shared" / "data" / "nmea"
needs_logs = pytest.mark.skipif(not NMEA_DIR.is_dir(), reason=f"no NMEA logs in {NMEA_DIR}")
LOG = "quectel"  # southern and eastern hemisphere, empty fields, VTG, GSA
ATTRS = {
    gnss.GGA: "gga_utc_ms gga_lat_e7 gga_lon_deg gga_lon_frac_e7 gga_pos_ok gga_quality",
    gnss.RMC: "rmc_speed_mm_s",
    gnss.VTG: "vtg_course_cdeg",
    gnss.GSA: "gsa_fix",
}


class Recorder(gnss.Nmea):
    """The driver, recording what it accepted at each line end (independent of the tool's
    byte-by-byte feeding)."""

    def __init__(self):
        super().__init__()
        self.rec_accepted = []

    def _end(self, r):
        seq = self.seq
        super()._end(r)
        if self.seq != seq:
            snap = {a: getattr(self, a) for a in ATTRS[self.last].split()}
            self.rec_accepted.append((self.last, bytes(self._line[: self.line_length()]), snap))


def driver_records(name):
    p = Recorder()
    lines = (NMEA_DIR / f"{name}.log").read_bytes().splitlines(keepends=True)
    data = b"".join(x for x in lines if not x.startswith(b"#"))
    p.feed(data, len(data))
    return p


@needs_logs
def test_text_lines_match_the_driver(capsys):
    assert gnss_dump.main([str(NMEA_DIR / f"{LOG}.log")]) == 0
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert lines[0] == "# " + " ".join(gnss_dump.COLUMNS)
    p = driver_records(LOG)
    assert len(lines) - 1 == len(p.rec_accepted) == 168
    for line, (kind, _, s) in zip(lines[1:], p.rec_accepted, strict=True):
        cols = dict(zip(gnss_dump.COLUMNS, line.split(), strict=True))
        assert cols["type"] == gnss_dump.NAMES[kind]
        if kind == gnss.GGA:
            assert cols["utc_s"] == (
                "-" if s["gga_utc_ms"] < 0 else f"{s['gga_utc_ms'] / 1000:.3f}"
            )
            if s["gga_pos_ok"]:
                assert int(cols["lat_e7"]) == s["gga_lat_e7"]
                assert int(cols["lon_e7"]) == s["gga_lon_deg"] * 10**7 + s["gga_lon_frac_e7"]
            assert cols["quality"] == str(s["gga_quality"])
        elif kind == gnss.RMC and s["rmc_speed_mm_s"] >= 0:
            assert cols["speed_m_s"] == f"{s['rmc_speed_mm_s'] / 1000:.3f}"
        elif kind == gnss.VTG and s["vtg_course_cdeg"] >= 0:
            assert cols["course_deg"] == f"{s['vtg_course_cdeg'] / 100:.2f}"
    first = lines[1].split()
    assert first == "GGA 8421.000 -367459895 1747345477 56.100 1 7 1.10 - - 1".split()
    assert err.strip() == (
        "gnss-dump: accepted GGA 42 RMC 42 VTG 42 GSA 42, ignored 144, rejected 0 "
        "(bad checksum 0, no checksum 0, malformed 0, overlong 0, collided 0, bad field 0), "
        "epochs 34 (dropped 0)"
    )


@needs_logs
def test_json_lines(capsys):
    assert gnss_dump.main([str(NMEA_DIR / "gp-320fw-2019-04-07-coldboot.log"), "--json"]) == 0
    out, err = capsys.readouterr()
    rows = [json.loads(x) for x in out.splitlines()]
    p = driver_records("gp-320fw-2019-04-07-coldboot")
    assert [r["type"] for r in rows] == [gnss_dump.NAMES[k] for k, _, _ in p.rec_accepted]
    assert rows[0] == {
        "type": "VTG",
        "utc_s": None,
        "lat_e7": None,
        "lon_e7": None,
        "alt_m": None,
        "quality": None,
        "nsat": None,
        "hdop": None,
        "speed_m_s": 0.028,  # 0.1 km/h
        "course_deg": 0.0,
        "valid": 1,
        "lat_deg": None,
        "lon_deg": None,
    }
    gga = next(r for r in rows if r["type"] == "GGA" and r["lat_e7"] is not None)
    assert gga["lat_deg"] == gga["lat_e7"] / 1e7 and gga["lon_deg"] == gga["lon_e7"] / 1e7
    assert all(not isinstance(v, str) for r in rows for k, v in r.items() if k != "type")
    assert "rejected 46 (bad checksum 30, no checksum 4, malformed 5, overlong 2" in err


def test_unreadable_file_is_a_clear_error(tmp_path):
    missing = tmp_path / "nope.log"
    proc = subprocess.run(
        [sys.executable, "-m", "host_emulator", "gnss-dump", str(missing)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 1 and proc.stdout == ""
    assert proc.stderr == f"gnss-dump: cannot read {missing}: No such file or directory\n"
    assert gnss_dump.main([str(tmp_path)]) == 1  # a directory


def test_raw_keeps_comment_lines(tmp_path, capsys):
    f = tmp_path / "c.log"
    f.write_bytes(b"# $GPVTG,,T,,M,0.117,N,0.216,K,A*21\r\n")
    assert gnss_dump.main([str(f)]) == 1
    assert "empty once its '#' comment lines are skipped" in capsys.readouterr().err
    assert gnss_dump.main([str(f), "--raw"]) == 0
    assert capsys.readouterr().out.splitlines()[1:] == ["VTG - - - - - - - 0.060 - 1"]


@pytest.mark.parametrize("v, d, s", [(0, 3, "0.000"), (-56100, 3, "-56.100"), (5, 2, "0.05")])
def test_fixed_point_text(v, d, s):
    assert gnss_dump._fixed(v, d) == s


def test_a_file_that_is_not_nmea_says_so(tmp_path, capsys):
    """A binary log, a text file without sentences and an empty file: exit 1 and one line
    saying what the file is, not a count of rejected sentences with status 0."""
    import random

    (tmp_path / "ubx.bin").write_bytes(bytes(random.Random(2).randrange(256) for _ in range(9000)))
    (tmp_path / "notes.txt").write_bytes(b"lat,lon\n34.1,108.9\n" * 50)
    (tmp_path / "empty.log").write_bytes(b"")
    for name, what in (
        ("ubx.bin", "is not an NMEA log: 9000 bytes of binary data"),
        ("notes.txt", "is not an NMEA log: 950 bytes of text, but no NMEA sentence"),
        ("empty.log", "empty.log is empty"),
    ):
        assert gnss_dump.main([str(tmp_path / name)]) == 1
        out, err = capsys.readouterr()
        assert out == "" and what in err and err.count("\n") == 1, err
