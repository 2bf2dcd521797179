"""The constants the native kernels share with the firmware's Python, generated from it.

    python -m common.native.layout          rewrite firmware/native/layout.h and tuning.h, and
                                            the const blocks of const_copies.py
    python -m common.native.layout --check  exit 1, naming the files, if one is stale

Every number the C and the Python sides both use is written once, in the Python module that
owns it (a `const()`, a plain int, or a float32 from the seam: `f32.f32`, `f32.ratio`,
`f32.from_bits`), and reaches C only through the two headers this writes:

    layout.h   the integers: buffer layouts (indices, lengths), flag bits, result codes
    tuning.h   the float32 constants of the kernels' arithmetic (fmath's, limits, weights,
               clips), as F32_BITS of their bit patterns: fmath32.h defines it and includes
               tuning.h, so a kernel that includes fmath32.h has both

A block below names a module and the names it takes from it, as exact names or prefixes
("_C_*"); a C name is the block's tag plus the Python name without its leading underscore
(nav's `_C_TICK` is `C_TICK`, gnss's `MAXLEN` with tag NMEA_ is `NMEA_MAXLEN`). Values are
the CPython values of the modules as firmware_env imports them; names keep the module's source
order; an int written in hex there is hex here, a negative one in parentheses.
tests/native/test_layout.py fails when a header is not what this writes.
"""

import argparse
import fnmatch
import re
import sys
import textwrap

import numpy as np

from common.firmware_env import FIRMWARE_DIR, import_module, install, use_kernels
from common.native import const_copies

NATIVE_DIR = FIRMWARE_DIR / "native"

# (module, what the block is, tag, names): the names in the module's source order
LAYOUT = (
    ("ins", "the state buffer Ins.x", "", ("X_*", "NX")),
    ("eskf", "the float buffer Eskf.e, the job's scalars at e[E_S], the int buffer Eskf.i, "
     "the error-state indices and the job codes", "",
     ("N", "IX_*", "MAX_*", "IDLE", "PROPAGATING", "UPDATING", "_S_*", "E_*", "NE", "I_*",
      "NI")),
    ("nav", "the calibration buffer Navigator._cal and its flags", "",
     ("_CAL_*", "_NCAL")),
    ("nav", "the standstill detector Navigator._st, its parameters _stp and its flags", "",
     ("_ST_*", "_STP_*", "_NSTP", "_STILL_*")),
    ("nav", "the aiding parameters Navigator._aid", "", ("_AID_*", "_NAID")),
    ("nav", "a fix in ints (Navigator.fix_in), fix_check's bits, the pending fix "
     "Navigator._fx", "", ("FI_*", "NFI", "_FC_*", "_FX_*")),
    ("nav_aid", "the fix of the running GNSS update, Navigator._used; how long a jumped "
     "receiver may be refused, the tick a reset is held until", "",
     ("_US_*", "_STEP_HOLD_S", "UNCONFIRMED")),
    ("nav", "the control state Navigator.ctl, its option bits, the filter jobs, nav_tick's "
     "events, the IMU status bits, health's causes and the states", "",
     ("ALIGNING", "NAVIGATING", "RING", "IMU_*", "CAUSE_*", "_JOB_*", "_C_*", "_NC",
      "_OPT_*", "_EV_*", "_RESTART_*", "_DRIFT_*")),
    ("nav", "the navigator's float buffers in one, Navigator.mem, and the parts of it with "
     "indices of their own (the aiding watch, the receiver's unseen error, the lag search)",
     "", ("_M_*", "_NM", "_BW_N", "_AW_*", "_INFLATE_*", "_CN_*", "_NCN", "_LS_*", "_NLS")),
    ("frame", "the frame's length and byte offsets, the int fields of App._fields and the "
     "frame's scales", "", ("FRAME_LEN", "_FB_*", "F_*", "NF", "_GYRO_FRAME_X100", "_ACCEL_FRAME")),
    ("records", "the extended frame and the raw-input record: lengths and int fields", "",
     ("EXT_*", "RAW_*", "EF_*", "NEF", "RF_*", "NRF")),
    ("geo", "the origin's coefficients LocalFrame.coef", "GEO_", ("*",)),
    ("drivers.bmi055", "the counts that mean over range", "BMI055_", ("*_SAT_*",)),
    ("drivers.gnss", "the NMEA parser's line buffer, number codes and sentence formatters",
     "NMEA_", ("MAXLEN", "_MAXF", "_EMPTY", "_BAD", "_CAP", "_FMT_*")),
    ("drivers.gnss", "the parser's int buffer Nmea._s (framing state, the sentence's fields: "
     "NS_A..NS_F per type, as gnss.py lists) and nmea_scan's results", "",
     ("_NS_*", "_NR_*")),
    ("drivers.uart_dma", "the DMA transmitter's state DmaTx._tx", "", ("TX_*", "NTX")),
    ("status_page", "text_num's forms of a number", "", ("TN_*",)),
    ("yaw_gsf", "the yaw estimator's bank at Navigator.mem[M_GSF], a hypothesis in it, "
     "gsf_step's bits, P's yaw variance in Navigator.mem", "",
     ("GSF_*", "_H_*", "_NH", "_NST", "_G_*", "NG", "_P_YAW")),
    ("kern", "the native module's ABI, which kern.py checks", "NAVK_", ("ABI",)),
)  # fmt: skip

TUNING = (
    ("fmath", "the float32 sin, cos, atan2 and asin (fmath32.h)", "FM_", ("*",)),
    ("ins", "gravity and the coning terms", "", ("FREE_AIR", "TWELFTH")),
    ("nav_kern", "the watches (drift, suspicion, aiding), the receiver's unseen error, lag and "
     "velocity noise, the frozen receiver, the angle units", "",
     ("_FROZEN_*", "_BW_*", "_BS_*", "_AW_*", "_CN_*", "_VR_*", "_LAG_*", "RAD_PER_CDEG",
      "CDEG_PER_RAD")),
    ("nav_aid", "the screening of fixes", "",
     ("NO_HEIGHT_VAR", "_JUMP_*", "_STEP_*", "_HOLD_K2")),
    ("navcfg", "standard gravity", "", ("G0_M_S2",)),
    ("nav_align", "levelling", "", ("MIN_LEVEL_F",)),
    ("yaw_gsf", "the yaw estimator", "GSF_",
     ("V0_VAR", "V0_CHORD_VAR", "B0_VAR", "W_MIN", "EXP_CUT", "SIXTH", "TWENTYFOURTH",
      "SIXTYFOURTH", "THIRD", "NINE", "FOUR", "INNOV_BAD")),
)  # fmt: skip

# NAME = const(...), NAME = <int>, NAME = f32.<f32|ratio|from_bits>(...), at column 0
_DEF = re.compile(r"^([A-Za-z_]\w*) = (const\(|-?\d|-?0x|(?:f32\.)?(?:f32|ratio|from_bits)\()")


class LayoutError(ValueError):
    """A block that selects nothing, a value of the wrong kind, a C name given twice."""


def _names(path):
    """(name, source text after '=') of the module's top-level constants, in source order."""
    out = []
    for line in path.read_text().splitlines():
        m = _DEF.match(line)
        if m:
            out.append((m.group(1), line[len(m.group(1)) + 3 :]))
    return out


def _module_path(module):
    return FIRMWARE_DIR / (module.replace(".", "/") + ".py") if "." in module else (
        FIRMWARE_DIR / "lib" / (module + ".py")
    )  # fmt: skip


def _int_text(value, src):
    if isinstance(value, bool) or not isinstance(value, int):
        return None
    if re.match(r"(const\()?-?0x", src):
        text = f"-0x{-value:X}" if value < 0 else f"0x{value:X}"
    else:
        text = str(value)
    return f"({text})" if value < 0 else text  # a macro's sign stays its own


def _float_text(value):
    """F32_BITS of the float32's bit pattern (fmath32.h: folded at compile time, exact
    whatever the compiler does with decimals, NaN included), its value as a comment."""
    if not isinstance(value, np.float32):
        return None
    bits = int(np.array(value, dtype=np.float32).view(np.uint32))
    big_or_small = value != 0 and not 1e-4 <= abs(value) < 1e7
    fmt = np.format_float_scientific if big_or_small else np.format_float_positional
    return f"F32_BITS(0x{bits:08X}) /* {fmt(value, unique=True)} */"


def _block(module, tag, patterns, kind):
    """[(C name, C value text)] of one block."""
    mod = import_module(module)
    rows = []
    used = set()
    for name, src in _names(_module_path(module)):
        hits = [p for p in patterns if fnmatch.fnmatchcase(name, p)]
        if not hits:
            continue
        value = getattr(mod, name)
        text = _int_text(value, src) if kind == "int" else _float_text(value)
        if text is not None:
            rows.append((tag + name.lstrip("_"), text))
            used.update(hits)
    for p in patterns:
        if p not in used:
            raise LayoutError(f"{module}: no {kind} constant matches {p}")
    return rows


def _comment(text):
    """A C comment of text, wrapped at 96 columns."""
    lines = textwrap.wrap(text, 93)
    out = ["/* " + lines[0]] + [" * " + ln for ln in lines[1:]]
    out[-1] += " */"
    return out


def header(blocks, kind, guard, what):
    """The text of one generated header."""
    install()
    seen = {}
    out = _comment(
        f"{what}. Generated by `python -m common.native.layout` (common/native/layout.py) from "
        "the Python modules each block names: do not edit, change the Python constant and "
        "run it again."
    )
    out += [f"#ifndef {guard}", f"#define {guard}"]
    for module, title, tag, patterns in blocks:
        out.append("")
        out += _comment(f"{module.replace('.', '/')}.py: {title}")
        for c_name, text in _block(module, tag, patterns, kind):
            if c_name in seen:
                raise LayoutError(f"{c_name} comes from {seen[c_name]} and {module}")
            seen[c_name] = module
            out.append(f"#define {c_name} {text}")
    out += ["", f"#endif /* {guard} */", ""]
    return "\n".join(out)


def headers():
    """{path: text} of the generated headers."""
    return {
        NATIVE_DIR / "layout.h": header(
            LAYOUT, "int", "NAVK_LAYOUT_H", "Buffer layouts, flags and codes shared by the "
            "kernels and the firmware's Python"),
        NATIVE_DIR / "tuning.h": header(
            TUNING, "float", "NAVK_TUNING_H", "The float32 constants of the kernels' "
            "arithmetic, each the value of its Python twin's"),
    }  # fmt: skip


def generated():
    """{path: text} of every file this writes: the headers, and the firmware modules' copies of
    another module's private consts (const_copies.py)."""
    return {**headers(), **const_copies.generated()}


def stale():
    """The generated files that differ from what this writes."""
    return [p for p, text in generated().items() if not p.exists() or p.read_text() != text]


def _shown(path):
    return (
        path.relative_to(FIRMWARE_DIR.parent) if path.is_relative_to(FIRMWARE_DIR.parent) else path
    )


def main(argv=None):
    ap = argparse.ArgumentParser(
        prog="python -m common.native.layout",
        description="Write firmware/native/layout.h and tuning.h from the firmware's Python, "
        "and the consts firmware modules repeat from the module that owns them "
        "(common/native/const_copies.py).",
    )
    ap.add_argument("--check", action="store_true", help="only say whether they are stale")
    args = ap.parse_args(argv)
    try:
        if args.check:
            old = stale()
            for p in old:
                print(f"layout: {_shown(p)} is stale", file=sys.stderr)
            return 1 if old else 0
        for p, text in generated().items():
            if not p.exists() or p.read_text() != text:
                p.write_text(text)
                print(f"wrote {_shown(p)}")
    except (LayoutError, const_copies.CopyError) as e:
        print(f"layout: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    use_kernels("python")  # the values need no kernels, and navk may be built from stale ones
    sys.exit(main())
