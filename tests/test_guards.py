"""Static guards of the float32 contract (docs/requirements.md, float32 contract) over every file in
firmware/.

Each rule is a function over source text, so it is tested twice: it must pass on the real
firmware and it must catch a deliberately bad snippet (a guard that matches nothing would
otherwise pass forever).
"""

import ast

import pytest

from common.firmware_env import FIRMWARE_DIR, LIB_DIR

ALLOWED_FLOATS = {0.0, 1.0, 2.0, 0.5}
BANNED_MATH = {"sin", "cos", "tan", "atan", "atan2", "asin", "acos", "exp", "log", "pow"}
BANNED_LIB_IMPORTS = {"machine", "pyb", "numpy"}
SEAM = "f32.py"


def float_literals(src):
    """Decimal float literals other than 0.0, 1.0, 2.0, 0.5 (MicroPython's float32 literal
    parser is not correctly rounded and mpy-cross folds constants in double)."""
    return [
        (n.lineno, n.value)
        for n in ast.walk(ast.parse(src))
        if isinstance(n, ast.Constant)
        and isinstance(n.value, float)
        and n.value not in ALLOWED_FLOATS
    ]


def banned_math(src):
    """math trig/exp/log, by attribute (math.sin) or by name import (from math import sin)."""
    found = []
    for n in ast.walk(ast.parse(src)):
        if (
            isinstance(n, ast.Attribute)
            and isinstance(n.value, ast.Name)
            and n.value.id == "math"
            and n.attr in BANNED_MATH
        ):
            found.append((n.lineno, n.attr))
        if isinstance(n, ast.ImportFrom) and n.module == "math":
            found += [(n.lineno, a.name) for a in n.names if a.name in BANNED_MATH or a.name == "*"]
    return found


def imported_modules(src):
    found = set()
    for n in ast.walk(ast.parse(src)):
        if isinstance(n, ast.Import):
            found |= {a.name.split(".")[0] for a in n.names}
        elif isinstance(n, ast.ImportFrom) and n.module:
            found.add(n.module.split(".")[0])
    return found


def double_escapes(src):
    """Ways a Python double can sneak into desktop arithmetic and break bit parity:
    float() (use f32.f32), ** (powf differs between libms), and int / int true division
    (a double on CPython, a float32 on the board; use f32.ratio)."""
    found = []
    for n in ast.walk(ast.parse(src)):
        if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == "float":
            found.append((n.lineno, "float()"))
        if isinstance(n, ast.BinOp | ast.AugAssign) and isinstance(n.op, ast.Pow):
            found.append((n.lineno, "**"))
        if (
            isinstance(n, ast.BinOp)
            and isinstance(n.op, ast.Div)
            and all(
                isinstance(o, ast.Constant) and isinstance(o.value, int) for o in (n.left, n.right)
            )
        ):
            found.append((n.lineno, "int / int"))
    return found


def firmware_files():
    return sorted(FIRMWARE_DIR.rglob("*.py"))


def lib_files():
    return sorted(LIB_DIR.rglob("*.py"))


def test_firmware_has_the_core_files():
    names = {p.name for p in lib_files()}
    assert {"f32.py", "fmath.py", "mat.py", "rot.py", "geo.py"} <= names


@pytest.mark.parametrize("path", firmware_files(), ids=lambda p: p.name)
def test_no_decimal_float_literals(path):
    assert float_literals(path.read_text()) == []


@pytest.mark.parametrize("path", firmware_files(), ids=lambda p: p.name)
def test_no_math_trig_exp_log(path):
    assert banned_math(path.read_text()) == []


@pytest.mark.parametrize("path", lib_files(), ids=lambda p: p.name)
def test_lib_is_portable(path):
    assert imported_modules(path.read_text()) & BANNED_LIB_IMPORTS == set()


@pytest.mark.parametrize("path", lib_files(), ids=lambda p: p.name)
def test_lib_floats_stay_float32(path):
    src = path.read_text()
    assert double_escapes(src) == []
    if path.name != SEAM:
        assert "math" not in imported_modules(src), "only the seam may import math (sqrt)"


def test_guards_catch_violations():
    bad = (
        "import math\nfrom math import atan2\nimport machine\nfrom numpy import float32\n"
        "x = 0.1 + 1e-3\ny = math.sin(x) + math.exp(x)\nz = float(3) ** 2 + 1 / 3\n"
        "ok = 0.0 + 1.0 + 2.0 + 0.5 + 1 // 3 + 2.0 / 2\n"
    )
    assert [v for _, v in float_literals(bad)] == [0.1, 1e-3]
    assert sorted(v for _, v in banned_math(bad)) == ["atan2", "exp", "sin"]
    assert imported_modules(bad) & BANNED_LIB_IMPORTS == {"machine", "numpy"}
    assert sorted(v for _, v in double_escapes(bad)) == ["**", "float()", "int / int"]
