"""The native kernels and the Python modules agree on every buffer layout: each `#define` of
firmware/native/layout.h equals the constant of the Python module it repeats."""

import re

import pytest

from host_emulator.firmware_env import FIRMWARE_DIR, import_module

LAYOUT_H = FIRMWARE_DIR / "native" / "layout.h"

# C name prefix -> (module, Python name for the rest of the C name); first match wins
RULES = (
    ("CAL_HAS_", None, None),  # flags, checked below
    ("X_", "ins", "X_"),
    ("NX", "ins", "NX"),
    ("S_", "eskf", "_"),
    ("E_", "eskf", "E_"),
    ("I_", "eskf", "I_"),
    ("IX_", "eskf", "IX_"),
    ("NE", "eskf", "NE"),
    ("NI", "eskf", "NI"),
    ("N", "eskf", "N"),
    ("MAX_", "eskf", "MAX_"),
    ("IDLE", "eskf", "IDLE"),
    ("PROPAGATING", "eskf", "PROPAGATING"),
    ("UPDATING", "eskf", "UPDATING"),
    ("CAL_", "nav", "_CAL_"),
    ("NCAL", "nav", "_NCAL"),
    ("C_", "nav", "_C_"),
    ("NC", "nav", "_NC"),
    ("CN_", "nav", "_CN_"),
    ("NCN", "nav", "_NCN"),
    ("LS_", "nav", "_LS_"),
    ("NLS", "nav", "_NLS"),
    ("M_", "nav", "_M_"),
    ("NM", "nav", "_NM"),
    ("OPT_", "nav", "_OPT_"),
    ("JOB_", "nav", "_JOB_"),
    ("EV_", "nav", "_EV_"),
    ("ALIGNING", "nav", "ALIGNING"),
    ("NAVIGATING", "nav", "NAVIGATING"),
    ("RING", "nav", "RING"),
    ("STP_", "nav", "_STP_"),
    ("NSTP", "nav", "_NSTP"),
    ("STILL_", "nav", "_STILL_"),
    ("ST_", "nav", "_ST_"),
    ("AID_", "nav", "_AID_"),
    ("AW_", "nav", "_AW_"),
    ("INFLATE_", "nav", "_INFLATE_"),
    ("NAID", "nav", "_NAID"),
    ("FX_", "nav", "_FX_"),
    ("FI_", "nav", "FI_"),
    ("NFI", "nav", "NFI"),
    ("FC_", "nav", "_FC_"),
    ("US_", "nav_aid", "_US_"),
    ("F_", "frame", "F_"),
    ("NF", "frame", "NF"),
    ("EF_", "records", "EF_"),
    ("NEF", "records", "NEF"),
    ("RF_", "records", "RF_"),
    ("NRF", "records", "NRF"),
    ("GEO_", "geo", ""),
    ("BMI055_", "drivers.bmi055", ""),
    ("NMEA_MAXLEN", "drivers.gnss", "MAXLEN"),
    ("NMEA_MAXF", "drivers.gnss", "_MAXF"),
    ("NS_", "drivers.gnss", "_NS_"),
    ("NR_", "drivers.gnss", "_NR_"),
)


def defines():
    out = {}
    for m in re.finditer(r"^#define\s+([A-Z][A-Z0-9_]*)\s+(-?\d+)\b", LAYOUT_H.read_text(), re.M):
        out[m.group(1)] = int(m.group(2))
    return out


def python_name(c_name):
    for prefix, module, replacement in RULES:
        exact = not prefix.endswith("_")
        if (exact and c_name == prefix) or (not exact and c_name.startswith(prefix)):
            if module is None:
                return None, None
            return module, replacement + c_name[len(prefix) :] if not exact else replacement
    raise AssertionError(f"layout.h: {c_name} has no Python counterpart in RULES")


@pytest.mark.parametrize("c_name", sorted(defines()))
def test_layout_constant_equals_python(c_name):
    module, name = python_name(c_name)
    if module is None:
        return
    value = getattr(import_module(module), name)
    assert defines()[c_name] == value, f"layout.h {c_name} = {defines()[c_name]}, {module}.{name}"


def test_layout_has_every_block():
    # the calibration flags are literals in nav.Navigator._set_calibration (bit 0, bit 1)
    d = defines()
    assert (d["CAL_HAS_GM"], d["CAL_HAS_AM"]) == (1, 2)
    assert len(d) > 100
