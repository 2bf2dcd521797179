"""The numbers the native kernels share with the firmware's Python are written once: layout.h
and tuning.h are what common/native/layout.py generates from the Python modules, and no C file
defines a number of its own under a name the Python side also has."""

import re

import numpy as np
import pytest

from common.firmware_env import FIRMWARE_DIR, import_module
from common.native import layout

NATIVE = FIRMWARE_DIR / "native"


def defines(text):
    """{name: value text} of a C text's object-like #defines with a value."""
    return dict(re.findall(r"^#define[ \t]+([A-Z][A-Z0-9_]*)[ \t]+(\S[^/\n]*?)\s*(?:/\*.*)?$",
                           text, re.M))  # fmt: skip


def test_the_generated_headers_are_what_the_generator_writes():
    assert layout.stale() == [], "run `python -m common.native.layout` and commit the headers"


def test_the_headers_hold_the_python_values():
    """Spot checks through an independent reading: an index, a negative hex code, a flag, a
    float32 by its bits."""
    ints = defines((NATIVE / "layout.h").read_text())
    nav = import_module("nav")
    gnss = import_module("drivers.gnss")
    assert int(ints["C_INFLATE"]) == nav._C_INFLATE
    assert ints["NMEA_BAD"] == "(-0x3FFFFFFF)" and gnss._BAD == -0x3FFFFFFF
    assert ints["CAUSE_FAULTS"] == hex(nav.CAUSE_FAULTS).upper().replace("0X", "0x")
    assert int(ints["CAL_HAS_AM"]) == nav._CAL_HAS_AM == 2
    floats = defines((NATIVE / "tuning.h").read_text())
    bits = int(np.array(import_module("nav_align").MIN_LEVEL_F).view(np.uint32))
    assert floats["MIN_LEVEL_F"] == f"F32_BITS(0x{bits:08X})"


def test_no_kernel_defines_a_number_the_python_side_holds():
    """A #define in a .c or a hand-written header whose name, without a prefix the generator
    adds, is a Python constant of the firmware would be a second copy of it."""
    python = set()
    for module, *_ in layout.LAYOUT + layout.TUNING:
        python.update(name.lstrip("_") for name, _ in layout._names(layout._module_path(module)))
    generated = {"layout.h", "tuning.h"}
    copies = []
    for path in sorted(NATIVE.glob("*.[ch]")):
        if path.name in generated:
            continue
        for name in defines(path.read_text()):
            bare = re.sub(r"^(NMEA_|GEO_|BMI055_|NAVK_|FM_)", "", name)
            if name in python or bare in python:
                copies.append(f"{path.name}: {name}")
    assert copies == []


def test_a_stale_header_is_reported(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(layout, "NATIVE_DIR", tmp_path)
    (tmp_path / "layout.h").write_text("/* old */\n")
    assert layout.main(["--check"]) == 1
    err = capsys.readouterr().err
    assert "layout.h is stale" in err and "tuning.h is stale" in err
    assert layout.main([]) == 0 and layout.main(["--check"]) == 0


def test_a_pattern_that_selects_nothing_is_an_error(monkeypatch):
    monkeypatch.setattr(layout, "LAYOUT", (("ins", "x", "", ("NO_SUCH_*",)),))
    with pytest.raises(layout.LayoutError, match="NO_SUCH_"):
        layout.headers()
