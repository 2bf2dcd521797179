"""The board formats written once in common/proto against what they must agree with:
the frame's field table against the contract in docs/requirements.md, output frame (parsed from the
document, not retyped), the firmware's packers (firmware/lib/records.py) against the record layouts,
the CRC against crcmod's independent CRC-32, the host's tick arithmetic against the MicroPython
side's (emulated_board/mpy/time.py)."""

import importlib.util
import re
from array import array

import crcmod.predefined
import numpy as np
import pytest

import f32
from common.firmware_env import REPO_DIR
from common.proto import frame as frame_schema
from common.proto import records as rec_schema
from common.proto.crc import crc32
from common.proto.ticks import TICKS_PERIOD, ticks_diff
from host_emulator.emulated_board import MPY_DIR

REQUIREMENTS = REPO_DIR / "docs" / "requirements.md"
# the contract itself, outside the repository (the design notes the checks beyond it read)
DESIGN_NOTES = REPO_DIR.parent / "shared" / "DESIGN.md"
_CODES = {"int16": "h", "int32": "i", "u8": "B"}


def _table(text):
    """The '| bytes | field | scale |' rows of a frame table, as written."""
    return re.findall(r"^\| \d+(?:-\d+)? \| [^|]+ \| [^|]+ \|$", text, re.M)


def _contract_section():
    text = REQUIREMENTS.read_text()
    start = text.index("### Output frame (contract)")
    return text[start : text.index("\n### ", start + 1)]


def _design_rows():
    """(first byte, last byte, struct code, scale per unit or None) of each row of the frame
    table in docs/requirements.md, output frame (contract)."""
    rows = []
    for m in re.finditer(
        r"^\| (\d+)(?:-(\d+))? \| ([^|]+) \| ([^|]+) \|$", _contract_section(), re.M
    ):
        first, last = int(m[1]), int(m[2] or m[1])
        kind = re.search(r"\((int16|int32|u8)\)", m[3])
        code = _CODES[kind[1]] if kind else "B"  # header, counter: bytes
        scale = re.match(r"([\d.e]+) per ", m[4])
        rows.append((first, last, code, float(scale[1]) if scale else None))
    return rows


def test_the_repositorys_frame_table_is_the_contracts():
    """docs/requirements.md carries the contract's frame table row for row (the design notes'
    section 6, outside the repository: compared where they are, as on the CI machine)."""
    if not DESIGN_NOTES.exists():
        pytest.skip(f"the design notes are not at {DESIGN_NOTES}")
    notes = DESIGN_NOTES.read_text()
    section = notes[notes.index("## 6.") : notes.index("## 7.")]
    assert _table(_contract_section()) == _table(section) != []


def _effective_scale(f):
    return 1e7 if f.unit == "1e-7 deg" else f.scale  # lat/lon: integers in 1e-7 deg


def test_the_frame_table_is_the_design_contract():
    rows = _design_rows()
    assert rows[0][:2] == (0, 1) and rows[-1][:2] == (51, 51) and len(rows) == 16
    covered = []
    for first, last, code, scale in rows:
        inside = [f for f in frame_schema.FIELDS if first <= frame_schema.OFFSETS[f.name] <= last]
        assert inside and {f.code for f in inside} == {code}, (first, inside)
        size = {"B": 1, "h": 2, "i": 4}[code]
        assert len(inside) * size == last - first + 1
        if scale is not None:
            assert {_effective_scale(f) for f in inside} == {scale}, (first, inside)
        covered += inside
    assert covered == list(frame_schema.FIELDS)
    assert frame_schema.STRUCT.size == frame_schema.FRAME_LEN == 52


def test_a_frame_encodes_and_decodes_to_its_physical_values():
    b = frame_schema.encode(
        300, gyro_x=1311, accel_z=16383, lat_e7=-338688000, height_dm=-120, nav_state=2,
        yaw_cdeg=-17999, vel_n_cm_s=32766, pos_e_cm=-2147480, pos_u_dm=-32767, pps=1,
    )  # fmt: skip
    assert frame_schema.is_valid(b) and b[:3] == b"\xeb\x90\x2c"
    d = frame_schema.decode(b)
    assert d["counter"] == 44 and d["gyro_dps"] == [1311 / 131.07, 0.0, 0.0]
    assert d["accel_g"][2] == 1.0 and d["lat_e7"] == -338688000 and d["height_m"] == -12.0
    assert d["yaw_deg"] == -179.99 and d["vel_enu_m_s"] == [0.0, 327.66, 0.0]
    assert d["pos_enu_m"] == [-21474.8, 0.0, -3276.7] and d["pps"] == 1 and d["raw"] == b
    assert not frame_schema.is_valid(b[:-1] + bytes([b[-1] ^ 1]))
    with pytest.raises(KeyError, match="not frame fields"):
        frame_schema.encode(0, yaw=1)


def _firmware_ext(counter, tick):
    """The firmware's extended frame of a made-up navigator state (float32 bits kept)."""
    import ins
    import records

    rng = np.random.default_rng(counter)
    p = f32.zeros(225)
    p[:] = rng.normal(size=225).astype(np.float32)
    p[16] = np.float32(np.nan)  # a NaN variance: its bits must survive
    x, coef, cv = f32.zeros(ins.NX), f32.zeros(12), f32.zeros(2)
    for b in (x, coef, cv):
        b[:] = rng.normal(size=len(b)).astype(np.float32)
    e = records.ExtFrame(cv)
    e.fields[:] = array("i", (counter, 1, 2, 3, 5, 70000, 1234, 65535, 7, -338688000, -151,
                              -2093000, tick, 0xCBC5))  # fmt: skip
    e.pack(p, x, coef)
    ref = bytearray(records.EXT_LEN)  # the Python reference of the (native) kernel
    records._ext_pack_py(ref, e.fields, p, x, coef, cv)
    assert ref == e.data
    bg, ba, pos = (x[i : i + 3] for i in (ins.X_BG, ins.X_BA, ins.X_P))
    # the diagonal as sent: the position's three with the unseen GNSS variances added
    diag = np.diagonal(np.asarray(p).reshape(15, 15)).copy()
    diag[0:3] = diag[0:3] + np.array([cv[0], cv[0], cv[1]], np.float32)
    assert diag[0] != p[0] and diag[2] != p[32]  # the random cv is not 0
    return bytes(e.data), diag, bg, ba, pos, coef


def test_the_firmwares_extended_frame_is_the_record_layout():
    import geo
    import records

    data, p, bg, ba, pos, coef = _firmware_ext(9, 0x3FFFFFFF)
    assert len(data) == rec_schema.EXT_LEN == records.EXT_LEN and rec_schema.crc_ok(data)
    d = rec_schema.decode_ext(data)
    assert (d["counter"], d["health"], d["nav_state"], d["config_status"], d["flags"]) == (
        9, 1, 2, 3, 5,
    )  # fmt: skip
    assert (d["worst_tick_us"], d["mean_tick_us"], d["overruns"], d["gc_runs"]) == (
        65535, 1234, 65535, 7,
    )  # fmt: skip
    assert (d["origin_lat_e7"], d["origin_lon_e7"], d["tick"]) == (
        -338688000,
        -1512093000,
        2**30 - 1,
    )
    assert d["p_diag"][0] == float(p[0]) and np.isnan(d["p_diag"][1])
    assert d["causes"] == 0xCBC5
    assert rec_schema.cause_names(0xCBC5) == [
        "imu_saturated", "imu_dead", "gnss_rejects", "gnss_bad_data", "reset_to_gnss",
        "uncertain", "gnss_late", "config_defaults", "overrun",
    ]  # fmt: skip
    assert rec_schema.cause_names(0x100001) == ["imu_saturated", "0x100000"]  # a bit not known
    fields = dict(d, p_diag=p, gyro_bias_rad_s=bg,
                  accel_bias_m_s2=ba, pos_enu_m=pos, origin_h_m=coef[geo.H0])  # fmt: skip
    assert rec_schema.encode_ext(9, fields) == data  # the NaN's bits included
    # an older firmware's frame, without the causes, still decodes
    old = data[: rec_schema.EXT_LEN_V1 - 4]
    old = rec_schema.seal(bytes([*old[:2], old[2] - 4, *old[3:]]))
    assert rec_schema.length_ok(old) and rec_schema.crc_ok(old)
    d_old = rec_schema.decode_ext(old)
    assert d_old["causes"] is None and d_old["origin_h_m"] == d["origin_h_m"]
    assert d_old["tick"] == d["tick"] and d_old["health"] == d["health"]


def test_the_cause_bits_are_the_firmwares():
    """proto/records.py CAUSES names the bits firmware/lib/nav.py and app.py define."""
    import app
    import nav

    fw = {v: k for k, v in vars(nav).items() if k.startswith("CAUSE_") and k != "CAUSE_FAULTS"}
    fw.update({v: k for k, v in vars(app).items() if k.startswith("CAUSE_")})
    assert sorted(fw) == [bit for bit, _ in rec_schema.CAUSES]
    assert rec_schema.CAUSE_OVERRUN == app.CAUSE_OVERRUN
    two = ("CAUSE_IMU_DEAD", "CAUSE_NUMERIC", "CAUSE_GNSS_REJECTS", "CAUSE_RESET",
           "CAUSE_UNCERTAIN", "CAUSE_DRIFT", "CAUSE_GNSS_IMPLAUSIBLE")  # fmt: skip
    faults = sum(b for b, n in fw.items() if n in two)
    assert nav.CAUSE_FAULTS == faults


@pytest.mark.parametrize("kernel", ["native", "python"])
def test_the_firmwares_raw_record_is_the_record_layout(kernel, monkeypatch):
    """RawRecord.pack, through the native raw_pack (the CRC in C: nothing allocated) and its
    Python reference, gives the record the host's schema encodes."""
    import records

    if kernel == "python":
        monkeypatch.setattr(records, "raw_pack", records._raw_pack_py)
    else:
        assert records.raw_pack is not records._raw_pack_py  # navk's
    r = records.RawRecord()
    for n, sat in ((0, False), (17, True), (records.RAW_MAX_GNSS, False)):
        gnss = bytes(range(n))
        g6, a6 = bytes(range(10, 16)), bytes(range(20, 26))
        f = r.fields
        f[records.RF_COUNTER], f[records.RF_T0_US], f[records.RF_PPS_US] = 200, 0x3FFFFFFF, 12345
        f[records.RF_SATURATED], f[records.RF_N] = int(sat), n
        r.pack(bytearray(g6), bytearray(a6), bytearray(gnss) + bytearray(b"x" * (233 - n)))
        data = bytes(r.data[: r.length])
        assert data == rec_schema.encode_raw(200, 0x3FFFFFFF, 12345, g6, a6, sat, gnss)
        assert rec_schema.length_ok(data) and rec_schema.crc_ok(data)
        d = rec_schema.decode_raw(data)
        assert (d["t0_us"], d["pps_us"], d["saturated"], d["gnss_bytes"]) == (
            0x3FFFFFFF, 12345, int(sat), gnss,
        )  # fmt: skip
    assert rec_schema.RAW_MAX_GNSS == records.RAW_MAX_GNSS
    with pytest.raises(ValueError, match="at most 232"):
        rec_schema.encode_raw(0, 0, 0, g6, a6, False, bytes(233))


def test_the_crc_is_crcmods_crc32():
    crcmod32 = crcmod.predefined.mkCrcFun("crc-32")
    rng = np.random.default_rng(3)
    for n in (0, 1, 7, 132, 4096):
        data = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
        assert crc32(data) == crcmod32(data)
        assert crc32(data[n // 2 :], crc32(data[: n // 2])) == crcmod32(data)


def test_the_host_and_the_vm_tick_arithmetic_agree():
    spec = importlib.util.spec_from_file_location("vm_time", MPY_DIR / "time.py")
    vm_time = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(vm_time)
    rng = np.random.default_rng(4)
    half = TICKS_PERIOD // 2
    values = [0, 1, half - 1, half, half + 1, TICKS_PERIOD - 1, *rng.integers(0, TICKS_PERIOD, 500)]
    for a in values:
        for b in values[:12]:
            assert ticks_diff(a, b) == vm_time.ticks_diff(int(a), int(b)), (a, b)
    assert ticks_diff(3, TICKS_PERIOD - 2) == 5 and ticks_diff(TICKS_PERIOD - 2, 3) == -5
