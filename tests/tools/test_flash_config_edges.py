"""`python -m tools.flash config set` and the firmware's own `config.load` accept exactly the same
values at every edge of every setting's range.

The host tool parses a decimal text into a Python double and writes a float32; the board reads
that float32 back. Each float setting (every entry of config._RANGES, and gnss_latency_s) is
walked at both ends of its range: the decimal text of the end (what a user types), the float32
end and its float32 neighbours just inside and just outside (numpy.nextafter on float32), and the
doubles just beside the decimal end (they round to the float32 end: the host must judge the value
it writes, not the one typed). A vector takes the value in one element at a time, the others at
their defaults. Each int setting is probed at every edge of its rule (_INT_EDGES).

Host side: tools.flash's main(["config", "set", "--file", ...]) in this process. Board side:
firmware/lib/config.load on the file: the tool's file when it accepted the value, else the file
another writer would make (config.encode without validation), which the board must then refuse.
Accepted by the tool <=> load() says OK and holds that value, on CPython (the firmware's float32
model, tests/conftest.py) and in the MicroPython unix VM.
"""

import contextlib
import io
import json
import struct

import numpy as np
import pytest

import config  # firmware/lib/config.py (tests/conftest.py installs the firmware environment)
from host_emulator.runtimes.mpy_unix import vm as mpvm
from tools.flash.__main__ import main

# (name, low, high, den, low refused, high refused): the float settings' ranges; gnss_latency_s
# has its own rule, [0, 1) s, outside _RANGES
_FLOAT_RANGES = [
    (name, lo, hi, den, open_low, False) for name, lo, hi, den, _unit, open_low in config._RANGES
] + [("gnss_latency_s", 0, 1, 1, False, True)]

# The int settings' edges, as validate() states them: the members of a set or the ends of a
# range (each tried with its neighbours, and int32's own ends too)
_INT_EDGES = {
    "profile": (0, 1),
    "gyro_range_dps": config._GYRO_RANGES,
    "accel_range_g": config._ACCEL_RANGES,
    "output_every_ticks": (1, 200),
    "output_baud": config._BAUDS,
    "ext_every_ticks": (0, 2000),
    "raw_record": (0, 1),
    "gnss_baud": config._BAUDS,
    "gnss_need_speed": (0, 2),
    "coning": (0, 1),
    "slices_per_tick": (1, 4),
    "gnss_lag_learn": (0, 1),
    "display": (0, 1),
    "display_baud": config._BAUDS,  # 38400 and up
    "display_w": (220, 480),
    "display_h": (176, 320),
    "display_fg": (0, 255),
    "display_bg": (0, 255),
    "display_warn": (0, 255),
    "display_fault": (0, 255),
}
_INT_NAMES = [row[1] for row in config._SCHEMA if row[2] == config._INT]


def _unique(items):
    return list(dict.fromkeys(items))


def _float_texts(lo, hi, den):
    """The texts to try at both ends of lo/den .. hi/den: the decimal a user types, the float32
    end and its float32 neighbours, the doubles beside the decimal end."""
    texts = []
    for end in (lo, hi):
        e = np.float32(end) / np.float32(den)  # the float32 end (f32.ratio)
        d = end / den  # the double a user's decimal gives
        texts.append(config._dec(end, den))
        for v in (np.nextafter(e, np.float32(-np.inf)), e, np.nextafter(e, np.float32(np.inf))):
            texts.append(repr(float(v)))
        texts += [repr(float(np.nextafter(d, -np.inf))), repr(float(np.nextafter(d, np.inf)))]
    return _unique(texts)


def _default_elements(name):
    value = getattr(config.BoardConfig(), name)
    if value is None:  # a calibration matrix: identity
        return [1.0 if i % 4 == 0 else 0.0 for i in range(9)]
    return [float(x) for x in value]


def _cases():
    """(setting, element index or None, value's text) of every edge to try."""
    cases = []
    for name, lo, hi, den, _open_low, _open_high in _FLOAT_RANGES:
        value = getattr(config.BoardConfig(), name)
        n = 1 if value is not None and not isinstance(value, list) else len(_default_elements(name))
        for text in _float_texts(lo, hi, den):
            for i in range(n) if n > 1 else (None,):
                cases.append((name, i, text))
    for name in _INT_NAMES:
        probes = {v + d for v in _INT_EDGES[name] for d in (-1, 0, 1)} | {-(2**31), 2**31 - 1}
        cases += [(name, None, str(v)) for v in sorted(probes)]
    return cases


def _value(name, index, text):
    """The setting's value (Python numbers) with the text in its element."""
    if index is None:
        return int(text) if name in _INT_NAMES else float(text)
    value = _default_elements(name)
    value[index] = float(text)
    return value


def _argument(name, index, text):
    if index is None:
        return f"{name}={text}"
    value = _default_elements(name)
    return f"{name}=" + ",".join(text if i == index else repr(x) for i, x in enumerate(value))


def _expected(name, index, text):
    """What the board holds once it loaded the value: the int, or the float32's bits."""
    if name in _INT_NAMES:
        return int(text)
    return struct.pack("<f", float(text)).hex()


@pytest.fixture(scope="module")
def edges(tmp_path_factory):
    """[(name, index, text, accepted by the tool, file)]: every case through the tool, and the
    file the board reads (the tool's, or for a value it refused one written without checks)."""
    root = tmp_path_factory.mktemp("edges")
    out = []
    for k, (name, index, text) in enumerate(_cases()):
        path = root / f"{k}.cfg"
        sink = io.StringIO()
        with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
            rc = main(["config", "set", "--file", str(path), _argument(name, index, text)])
        assert rc in (0, 1), (name, index, text, sink.getvalue())
        accepted = rc == 0
        assert accepted == path.exists(), (name, index, text, sink.getvalue())
        if not accepted:
            assert "invalid setting: " in sink.getvalue() and name in sink.getvalue()
            cfg = config.BoardConfig()
            setattr(cfg, name, _value(name, index, text))
            path.write_bytes(config.encode(cfg))  # what another writer would put there
        out.append((name, index, text, accepted, str(path)))
    return out


def _board_value(value, index):
    """A loaded setting's value as _expected gives it (None: an identity matrix)."""
    if value is None:
        return None
    x = value if index is None else value[index]
    return x if isinstance(x, int) else struct.pack("<f", float(x)).hex()


def _disagreements(edges, loaded):
    """The cases where the tool and the board differ: (name, index, text, tool, board)."""
    bad = []
    for (name, index, text, accepted, _path), (status, value) in zip(edges, loaded, strict=True):
        board_ok = status == config.OK and value == _expected(name, index, text)
        if accepted != board_ok:
            tool = "accepted" if accepted else "refused"
            board = config.STATUS_TEXT[status] + ("" if status != config.OK else f" {value}")
            bad.append((name, index, text, tool, board))
    return bad


def test_the_case_table_walks_every_setting():
    assert {case[0] for case in _cases()} == {row[1] for row in config._SCHEMA}
    assert set(_INT_EDGES) == set(_INT_NAMES)


def test_the_board_loads_exactly_what_the_tool_accepts_cpython(edges):
    """The firmware's CPython runtime: its float32 model of the board (f32 = numpy.float32)."""
    loaded = []
    for name, index, _text, _accepted, path in edges:
        cfg, status, _msg = config.load(path)
        loaded.append((status, _board_value(getattr(cfg, name), index)))
    assert _disagreements(edges, loaded) == []
    accepted = [case for case in edges if case[3]]
    assert 0 < len(accepted) < len(edges)  # both verdicts occur
    # the ends a user types are accepted (a low end refused by its rule excepted)
    for name, lo, hi, den, open_low, open_high in _FLOAT_RANGES:
        for end, refused in ((lo, open_low), (hi, open_high)):
            verdicts = {c[3] for c in edges if c[0] == name and c[2] == config._dec(end, den)}
            assert verdicts == {not refused}, (name, end)


def test_the_board_loads_exactly_what_the_tool_accepts_mpy_unix(edges):
    """The firmware's config.py in the real MicroPython VM (its unix port): the same verdicts.
    The VM is a double-precision build, so this does not prove the board's float32 arithmetic
    (the CPython test above models that bit for bit); it proves that the code as MicroPython runs
    it (its struct, array('f') stores, int/float comparisons and start-up of config.py) reaches
    the same verdict, which holds because the rule does no arithmetic on the value: it stores
    the value and the range's ends into a float32 buffer and compares float32 with float32."""
    jobs = [(path, name, index) for name, index, _text, _accepted, path in edges]
    out = mpvm.run(f"""
import json, struct, config
for path, name, index in {jobs!r}:
    cfg, status, msg = config.load(path)
    x = getattr(cfg, name)
    x = x if index is None or x is None else x[index]
    x = x if x is None or isinstance(x, int) else struct.pack('<f', x).hex()
    print(json.dumps([status, x]))
""")  # a line a case: one list of them all is too large for the VM's heap
    loaded = [tuple(json.loads(line)) for line in out.strip().splitlines()[-len(edges) :]]
    assert _disagreements(edges, loaded) == []
