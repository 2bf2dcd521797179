"""`machine` as the stm32 port has it: the arguments its C takes, derived from the vendored
MicroPython v1.28.0 source (common.toolchain.micropython_dir()), against the emulated board's
stand-in (host_emulator/emulated_board/mpy/machine.py) and the firmware's own calls.

- The port's tables: every `static const mp_arg_t allowed_args[] = {...}` that machine.UART,
  SPI (hardware SPI), Pin (init, irq), Timer (the soft timer) and WDT parse with
  mp_arg_parse_all (py/argcheck.c), read from their C with the `#if`s evaluated for the
  STM32F411 (the family and part macros of the image's boards, tools/image/boards; other
  configuration macros from the port's headers). An argument is positional-allowed unless
  MP_ARG_KW_ONLY, required if MP_ARG_REQUIRED. What each constructor does before its table
  (an id taken positionally; the table parsed only when more is given) is checked as anchors
  in the same C, so a port that changes shape fails here rather than passing on stale tables.
  A table that cannot be parsed fails loudly (ApiSourceError), never yields nothing.
- The stand-in: its own tables equal these; it takes each argument the port takes, where the
  port takes it (positionally or by keyword), and refuses with the port's TypeError an unknown
  keyword (`txbuf`), a keyword-only argument given positionally and a missing required one;
  its constants are the F4 HAL's; the port's ValueErrors for refused values; the same in the
  MicroPython VM.
- The firmware: firmware/board.py, firmware/app.py and firmware/drivers/*.py, read with `ast`:
  every call of a machine constructor, of `.init(`/`.irq(` on an object one of them made, and
  of machine's functions passes only what the port takes (`check_calls`; the check that
  catches `machine.UART(1, baudrate=9600, txbuf=512)`).
"""

import ast
import functools
import inspect
import re
import sys
from dataclasses import dataclass

import pytest

from common import toolchain
from common.firmware_env import FIRMWARE_DIR, REPO_DIR
from host_emulator.emulated_board import MPY_DIR, install_machine
from host_emulator.runtimes.mpy_unix import vm as mpvm

SRC = toolchain.micropython_dir()
PROJECT_BOARDS = REPO_DIR / "tools" / "image" / "boards"

ARG_KINDS = {"MP_ARG_INT": "int", "MP_ARG_OBJ": "obj", "MP_ARG_BOOL": "bool"}
ARG_FLAGS = {"MP_ARG_REQUIRED", "MP_ARG_KW_ONLY"}


class ApiSourceError(Exception):
    """The port's C is not in the shape this test reads: fix the reader, do not skip."""


@dataclass(frozen=True)
class Arg:
    name: str
    kind: str  # int, obj, bool
    required: bool
    kw_only: bool

    def __str__(self):
        flags = ("required " if self.required else "") + ("kw-only" if self.kw_only else "pos")
        return f"{self.name} ({self.kind}, {flags})"


@dataclass(frozen=True)
class Call:
    """How a constructor or method takes its arguments: `lead` positional-only arguments
    ((name, required)) before the table, which, if `when_more`, is parsed only when more than
    the lead is given (UART(id), Pin(id) and Timer(-1) return without configuring)."""

    table: tuple
    lead: tuple = ()
    when_more: bool = False

    def names(self):
        return [a.name for a in self.table]


# ---- the port's C ------------------------------------------------------------------------


def _read(rel):
    path = SRC / rel
    if not path.is_file():
        raise ApiSourceError(f"{path} missing")
    return path.read_text()


def _squash(text):
    return re.sub(r"\s+", " ", text)


def _block(text, start, what):
    """The text between the brace at `start` and its match."""
    if text[start] != "{":
        raise ApiSourceError(f"{what}: no opening brace")
    depth = 0
    for i in range(start, len(text)):
        depth += {"{": 1, "}": -1}.get(text[i], 0)
        if depth == 0:
            return text[start + 1 : i]
    raise ApiSourceError(f"{what}: unbalanced braces")


def function_body(rel, func):
    """The body of C function `func` in SRC/rel."""
    text = _read(rel)
    found = list(re.finditer(rf"\b{func}\s*\([^;{{)]*\)\s*\{{", text))
    if len(found) != 1:
        raise ApiSourceError(f"{rel}: {len(found)} definitions of {func}()")
    return _block(text, found[0].end() - 1, f"{rel}:{func}")


def target_config():
    """(macros defined, {macro: value}) of the F411 image: the family and part of every board
    in tools/image/boards (they must agree), e.g. STM32F4 and STM32F411xE."""
    parts = set()
    for mk in sorted(PROJECT_BOARDS.glob("*/mpconfigboard.mk")):
        text = mk.read_text()
        for inc in re.findall(r"^include\s+(\S+)", text, re.M):  # make runs in ports/stm32
            text += (SRC / "ports" / "stm32" / inc).read_text()
        series = re.search(r"^MCU_SERIES\s*=\s*(\w+)", text, re.M)
        mcu = re.search(r"^CMSIS_MCU\s*=\s*(\w+)", text, re.M)
        if not series or not mcu:
            raise ApiSourceError(f"{mk}: no MCU_SERIES/CMSIS_MCU")
        parts.add(("STM32" + series.group(1).upper(), mcu.group(1)))
    if not parts:
        raise ApiSourceError(f"no boards in {PROJECT_BOARDS}")
    if len(parts) != 1:
        raise ApiSourceError(f"the image's boards are not one MCU: {sorted(parts)}")
    return set(parts.pop())


def config_value(name):
    """A configuration macro's integer value for the image: a project board's definition (all
    must agree) or else the port's default (`#define NAME (n)` in its config headers)."""
    pattern = re.compile(rf"^\s*#define\s+{name}\s+\(?\s*(\d+)\s*\)?\s*$", re.M)
    values = set()
    for header in PROJECT_BOARDS.glob("*/mpconfigboard.h"):
        values.update(int(v) for v in pattern.findall(header.read_text()))
    if not values:
        for rel in ("ports/stm32/mpconfigboard_common.h", "ports/stm32/mpconfigport.h"):
            values.update(int(v) for v in pattern.findall(_read(rel)))
    if len(values) != 1:
        raise ApiSourceError(f"configuration macro {name}: values {sorted(values)}")
    return values.pop()


_COND_TOKEN = re.compile(r"\s*(defined\s*\(\s*\w+\s*\)|defined\s+\w+|\|\||&&|!|\(|\)|\w+)")


def eval_condition(cond, defined):
    """A preprocessor condition (`defined(X)`, configuration macros, !, &&, ||, parentheses)
    for the target whose macros are `defined`. A family or part macro (STM32...) not in
    `defined` is undefined; any other macro must resolve (config_value) or this fails."""
    out = []
    pos = 0
    cond = cond.split("//")[0].strip()
    while pos < len(cond):
        m = _COND_TOKEN.match(cond, pos)
        if not m:
            raise ApiSourceError(f"#if {cond!r}: cannot read at {cond[pos:]!r}")
        tok = m.group(1)
        pos = m.end()
        if tok.startswith("defined"):
            name = re.search(r"(\w+)\s*\)?$", tok).group(1)
            if name not in defined and not name.startswith("STM32"):
                raise ApiSourceError(f"#if {cond!r}: is {name} defined for the F411?")
            out.append(str(name in defined))
        elif tok in ("||", "&&", "!"):
            out.append({"||": " or ", "&&": " and ", "!": " not "}[tok])
        elif tok in "()" or tok.isdigit():
            out.append(tok)
        else:
            out.append(str(config_value(tok)))
    return bool(eval("".join(out), {"__builtins__": {}}))  # only the tokens above


_ENTRY = re.compile(
    r"^\{\s*MP_QSTR_(\w+)\s*,\s*([A-Z_|\s]+?)\s*(?:,\s*\{.*\}\s*)?\}\s*,?\s*(?://.*)?$"
)


def parse_allowed_args(rel, func, defined=None):
    """The `allowed_args[]` table of function `func` in SRC/rel, for the target (`defined`:
    target_config() unless given), as Args in the C's order."""
    defined = target_config() if defined is None else defined
    body = function_body(rel, func)
    m = re.search(r"allowed_args\[\]\s*=\s*\{", body)
    if not m:
        raise ApiSourceError(f"{rel}:{func}: no allowed_args[] table")
    table = _block(body, m.end() - 1, f"{rel}:{func} allowed_args")
    args = []
    stack = []  # per open #if: [this branch taken, some branch taken]
    for raw in table.splitlines():
        line = raw.strip()
        if not line or line.startswith("//"):
            continue
        d = re.match(r"#\s*(ifdef|ifndef|if|elif|else|endif)\b\s*(.*)", line)
        if d:
            kw, cond = d.groups()
            if kw in ("ifdef", "ifndef"):
                cond = f"{'!' if kw == 'ifndef' else ''}defined({cond.split()[0]})"
                kw = "if"
            if kw == "if":
                take = eval_condition(cond, defined)
                stack.append([take, take])
            elif not stack:
                raise ApiSourceError(f"{rel}:{func}: #{kw} without #if")
            elif kw == "elif":
                take = not stack[-1][1] and eval_condition(cond, defined)
                stack[-1] = [take, stack[-1][1] or take]
            elif kw == "else":
                stack[-1] = [not stack[-1][1], True]
            else:
                stack.pop()
            continue
        e = _ENTRY.match(line)
        if not e:
            raise ApiSourceError(f"{rel}:{func}: cannot read table line {line!r}")
        if not all(taken for taken, _ in stack):
            continue
        flags = {f.strip() for f in e.group(2).split("|")}
        kinds = flags & set(ARG_KINDS)
        if len(kinds) != 1 or flags - set(ARG_KINDS) - ARG_FLAGS:
            raise ApiSourceError(f"{rel}:{func}: flags of {e.group(1)}: {e.group(2)!r}")
        args.append(
            Arg(e.group(1), ARG_KINDS[kinds.pop()], "MP_ARG_REQUIRED" in flags,
                "MP_ARG_KW_ONLY" in flags)
        )  # fmt: skip
    if stack:
        raise ApiSourceError(f"{rel}:{func}: unterminated #if")
    if not args:
        raise ApiSourceError(f"{rel}:{func}: an empty table")
    return tuple(args)


def _anchor(rel, func, *snippets):
    """Fail unless function `func` of SRC/rel says each snippet (whitespace aside)."""
    body = _squash(function_body(rel, func))
    for s in snippets:
        if _squash(s) not in body:
            raise ApiSourceError(f"{rel}:{func} no longer says {s!r}: re-read it")


def _fun_obj_arity(rel, name):
    """n of MP_DEFINE_CONST_FUN_OBJ_n(name_obj, ...) in SRC/rel: a fixed positional count."""
    m = re.search(rf"MP_DEFINE_CONST_FUN_OBJ_(\d)\(\s*{name}_obj\b", _read(rel))
    if not m:
        raise ApiSourceError(f"{rel}: no MP_DEFINE_CONST_FUN_OBJ_n for {name}")
    return int(m.group(1))


def port_api():
    """{(class, method): Call} and {function: positional count}, from the port's C."""
    uart = "ports/stm32/machine_uart.c"
    spi = "ports/stm32/machine_spi.c"
    pin = "ports/stm32/pin.c"
    timer = "extmod/machine_timer.c"
    wdt = "extmod/machine_wdt.c"
    uart_init = parse_allowed_args(uart, "mp_machine_uart_init_helper")
    _anchor(
        uart,
        "mp_machine_uart_make_new",
        "mp_arg_check_num(n_args, n_kw, 1,",
        "if (n_args > 1 || n_kw > 0) {",
        "mp_machine_uart_init_helper(self, n_args - 1, args + 1, &kw_args);",
    )
    _anchor(
        "extmod/machine_uart.c",
        "machine_uart_init",
        "mp_machine_uart_init_helper(MP_OBJ_TO_PTR(args[0]), n_args - 1, args + 1, kw_args)",
    )
    spi_new = parse_allowed_args(spi, "machine_hard_spi_make_new")
    # SPI() with no positional argument is the legacy SoftSPI construction (extmod/modmachine.h),
    # whose table has no id: the id is positional only, whatever the hard SPI's table says
    _anchor(
        spi,
        "machine_hard_spi_make_new",
        "MP_MACHINE_SPI_CHECK_FOR_LEGACY_SOFTSPI_CONSTRUCTION(n_args, n_kw, all_args);",
    )
    if "if (n_args == 0 || all_args[0] == MP_OBJ_NEW_SMALL_INT(-1))" not in _squash(
        _read("extmod/modmachine.h")
    ) or spi_new[0] != Arg("id", "obj", True, False):
        raise ApiSourceError("SPI's id is no longer what this test reads")
    pin_init = parse_allowed_args(pin, "pin_obj_init_helper")
    _anchor(
        pin,
        "mp_pin_make_new",
        "mp_arg_check_num(n_args, n_kw, 1,",
        "if (n_args > 1 || n_kw > 0) {",
        "pin_obj_init_helper(pin, n_args - 1, args + 1, &kw_args);",
    )
    _anchor(
        pin,
        "pin_obj_init",
        "pin_obj_init_helper(MP_OBJ_TO_PTR(args[0]), n_args - 1, args + 1, kw_args)",
    )
    _anchor(pin, "pin_irq", "mp_arg_parse_all(n_args - 1, pos_args + 1, kw_args,")
    # machine.Timer is extmod's soft timer, machine.WDT extmod's over the port's IWDG code
    if config_value("MICROPY_PY_MACHINE_TIMER") != 1 or (
        '#define MICROPY_PY_MACHINE_WDT_INCLUDEFILE "ports/stm32/machine_wdt.c"'
        not in _read("ports/stm32/mpconfigport.h")
    ):
        raise ApiSourceError("machine.Timer/WDT are no longer extmod's in the stm32 port")
    timer_init = parse_allowed_args(timer, "machine_timer_init_helper")
    _anchor(
        timer,
        "machine_timer_make_new",
        "if (n_args > 0) { id = mp_obj_get_int(args[0]); --n_args; ++args; }",
        "if (n_args > 0 || n_kw > 0) {",
        "machine_timer_init_helper(self, n_args, args, &kw_args);",
    )
    _anchor(
        timer,
        "machine_timer_init",
        "machine_timer_init_helper(self, n_args - 1, args + 1, kw_args);",
    )
    _anchor(wdt, "machine_wdt_make_new", "mp_arg_parse_all_kw_array(n_args, n_kw, all_args,")
    calls = {
        ("UART", "__new__"): Call(uart_init, lead=(("id", True),), when_more=True),
        ("UART", "init"): Call(uart_init),
        ("SPI", "__new__"): Call(spi_new[1:], lead=(("id", True),)),
        ("SPI", "init"): Call(parse_allowed_args(spi, "machine_hard_spi_init")),
        ("Pin", "__new__"): Call(pin_init, lead=(("id", True),), when_more=True),
        ("Pin", "init"): Call(pin_init),
        ("Pin", "irq"): Call(parse_allowed_args(pin, "pin_irq")),
        ("Timer", "__new__"): Call(timer_init, lead=(("id", False),), when_more=True),
        ("Timer", "init"): Call(timer_init),
        ("WDT", "__new__"): Call(parse_allowed_args(wdt, "machine_wdt_make_new")),
    }
    functions = {
        f: _fun_obj_arity("extmod/modmachine.c", f"machine_{f}")
        for f in ("idle", "disable_irq", "enable_irq")
    }
    return calls, functions


def format_api(calls, functions):
    """The derived tables as text (print it: `print(format_api(*port_api()))`)."""
    lines = []
    for (cls, meth), call in calls.items():
        lead = [f"{n} (positional only{', required' if r else ''})" for n, r in call.lead]
        more = " [table only when more is given]" if call.when_more else ""
        lines.append(f"{cls}.{meth}: " + ", ".join(lead + [str(a) for a in call.table]) + more)
    for f, n in functions.items():
        lines.append(f"{f}: {n} positional argument(s), no keywords")
    return "\n".join(lines)


# ---- the firmware's calls ------------------------------------------------------------------


def check_calls(source, filename="<source>", api=None):
    """Problems (strings "file:line: ...") of the machine calls in Python `source` against the
    port's tables, and the (class, method) or function of every call checked. Checked: machine
    constructors (`machine.UART(...)`, `from machine import UART`), `.init(`/`.irq(` on a name
    or attribute that a constructor call is assigned to anywhere in the source (or on the call
    itself), and machine's functions. A machine call the tables do not cover is a problem."""
    calls, functions = api or API
    tree = ast.parse(source, filename)
    module_names = set()  # names bound to the machine module
    class_names = {}  # local name -> machine class
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name == "machine":
                    module_names.add(a.asname or "machine")
        elif isinstance(node, ast.ImportFrom) and node.module == "machine":
            for a in node.names:
                class_names[a.asname or a.name] = a.name

    def machine_attr(func):
        """The machine attribute a call's callee names, or None."""
        if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):
            if func.value.id in module_names:
                return func.attr
        if isinstance(func, ast.Name):
            return class_names.get(func.id)
        return None

    classes = {c for c, _ in calls}
    made = {}  # expression text -> machine class of the object assigned to it
    for node in ast.walk(tree):
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and isinstance(node.value, ast.Call):
            cls = machine_attr(node.value.func)
            if cls in classes:
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                for t in targets:
                    made.setdefault(ast.unparse(t), set()).add(cls)

    problems = []
    checked = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        where = f"{filename}:{node.lineno}"
        name = machine_attr(node.func)
        key = None
        if name in classes:
            key = (name, "__new__")
        elif name is not None:
            if name not in functions:
                problems.append(f"{where}: machine.{name}() is not in the tables derived here")
                continue
            checked.append(name)
            if node.keywords:
                problems.append(f"{where}: machine.{name}() takes no keywords")
            if len(node.args) != functions[name]:
                problems.append(
                    f"{where}: machine.{name}() takes {functions[name]} positional "
                    f"argument(s), given {len(node.args)}"
                )
            continue
        elif isinstance(node.func, ast.Attribute) and node.func.attr in ("init", "irq"):
            obj = node.func.value
            owners = made.get(ast.unparse(obj), set())
            if isinstance(obj, ast.Call) and machine_attr(obj.func) in classes:
                owners = {machine_attr(obj.func)}
            owners = {c for c in owners if (c, node.func.attr) in calls}
            if len(owners) > 1:
                problems.append(f"{where}: {ast.unparse(obj)} is one of {sorted(owners)}")
            if len(owners) == 1:
                key = (owners.pop(), node.func.attr)
        if key is None:
            continue
        checked.append(key)
        problems.extend(f"{where}: {p}" for p in _check_call(key, calls[key], node))
    return problems, checked


def _check_call(key, call, node):
    what = f"machine.{key[0]}" + ("" if key[1] == "__new__" else f".{key[1]}")
    if any(isinstance(a, ast.Starred) for a in node.args) or any(
        k.arg is None for k in node.keywords
    ):
        return [f"{what}(): *args/**kwargs cannot be checked"]
    problems = []
    n_pos = len(node.args)
    n_lead = min(n_pos, len(call.lead))
    rest = n_pos - n_lead
    keywords = [k.arg for k in node.keywords]
    for name, required in call.lead[n_pos:]:
        if name in keywords:
            problems.append(f"{what}(): {name} is positional only")
        elif required:
            problems.append(f"{what}(): {name} is required, positionally")
    keywords = [k for k in keywords if k not in [n for n, _ in call.lead]]
    if call.when_more and rest == 0 and not keywords:
        return problems  # nothing to configure: the table is not parsed
    table = call.table
    for i in range(rest):
        if i >= len(table) or table[i].kw_only:
            problems.append(f"{what}(): positional argument {n_lead + i + 1} is not taken "
                            "positionally (extra positional arguments given)")  # fmt: skip
            break
    names = call.names()
    for k in keywords:
        if k not in names:
            problems.append(f"{what}(): keyword {k!r} is not taken by the port "
                            f"(extra keyword arguments given; it takes {names})")  # fmt: skip
        elif names.index(k) < rest:
            problems.append(f"{what}(): {k!r} given both positionally and by keyword")
    for i, a in enumerate(table):
        if a.required and i >= rest and a.name not in keywords:
            problems.append(f"{what}(): {a.name!r} argument required")
    return problems


def firmware_sources():
    files = [FIRMWARE_DIR / "board.py", FIRMWARE_DIR / "app.py"]
    files += sorted((FIRMWARE_DIR / "drivers").glob("*.py"))
    return files


API = port_api()


# ---- the derived tables --------------------------------------------------------------------


def test_the_tables_are_read_from_the_port_and_the_f411_build():
    calls, functions = API
    assert target_config() == {"STM32F4", "STM32F411xE"}
    uart = calls[("UART", "init")]
    assert uart.names()[:4] == ["baudrate", "bits", "parity", "stop"]
    assert "rxbuf" in uart.names() and "txbuf" not in uart.names()
    assert "invert" not in uart.names()  # #if defined(STM32H7)
    h7 = parse_allowed_args("ports/stm32/machine_uart.c", "mp_machine_uart_init_helper",
                            defined={"STM32H7"})  # fmt: skip
    assert [a.name for a in h7] == uart.names() + ["invert"]  # the #if is evaluated, not skipped
    assert calls[("Pin", "init")].names() == ["mode", "pull", "af", "value", "alt"]
    assert calls[("Timer", "init")].names()[-1] == "hard"
    assert functions == {"idle": 0, "disable_irq": 0, "enable_irq": 1}


def test_an_unreadable_table_fails_loudly(tmp_path, monkeypatch):
    """A line the reader does not know, a condition on a macro it cannot resolve: errors."""
    src = tmp_path / "x.c"
    src.write_text(
        "void f(void) {\n static const mp_arg_t allowed_args[] = {\n"
        "  { MP_QSTR_a, MP_ARG_INT, {.u_int = 0} },\n  ARGS_FROM_A_MACRO\n };\n}\n"
        "void g(void) {\n static const mp_arg_t allowed_args[] = {\n"
        "  #if SOME_UNKNOWN_OPTION\n  { MP_QSTR_b, MP_ARG_OBJ },\n  #endif\n };\n}\n"
        "void h(void) {\n mp_arg_parse_all(n_args, args, kw, 0, NULL, vals);\n}\n"
    )
    (tmp_path / "ports" / "stm32").mkdir(parents=True)
    for header in ("mpconfigboard_common.h", "mpconfigport.h"):
        (tmp_path / "ports" / "stm32" / header).write_text("")
    monkeypatch.setattr(sys.modules[__name__], "SRC", tmp_path)
    f411 = {"STM32F4", "STM32F411xE"}
    with pytest.raises(ApiSourceError, match="ARGS_FROM_A_MACRO"):
        parse_allowed_args("x.c", "f", f411)
    with pytest.raises(ApiSourceError, match="SOME_UNKNOWN_OPTION"):
        parse_allowed_args("x.c", "g", f411)
    with pytest.raises(ApiSourceError, match="no allowed_args"):
        parse_allowed_args("x.c", "h", f411)
    with pytest.raises(ApiSourceError, match="0 definitions"):
        parse_allowed_args("x.c", "gone", f411)


# ---- the stand-in --------------------------------------------------------------------------


@pytest.fixture
def machine():
    m = install_machine()
    m.power_on()
    return m


def _samples(m):
    """A value each argument takes, per call; None marks an argument the port takes but whose
    use it refuses with ValueError (SPI's sck/mosi/miso: 'not implemented')."""
    uart = {"baudrate": 9600, "bits": 8, "parity": None, "stop": 1, "flow": 0, "timeout": 0,
            "timeout_char": 0, "rxbuf": 64, "read_buf_len": 64}  # fmt: skip
    spi = {"baudrate": 4_000_000, "polarity": 0, "phase": 0, "bits": 8, "firstbit": m.SPI.MSB}
    pin = {"mode": m.Pin.OUT, "pull": m.Pin.PULL_UP, "af": -1, "value": 1, "alt": -1}
    timer = {"mode": m.Timer.PERIODIC, "callback": lambda t: None, "period": 5,
             "tick_hz": 1000, "freq": 200, "hard": True}  # fmt: skip
    return {
        ("UART", "__new__"): uart,
        ("UART", "init"): uart,
        ("SPI", "__new__"): {**spi, "sck": None, "mosi": None, "miso": None},
        ("SPI", "init"): spi,
        ("Pin", "__new__"): pin,
        ("Pin", "init"): pin,
        ("Pin", "irq"): {"handler": lambda p: None, "trigger": m.Pin.IRQ_RISING, "hard": True},
        ("Timer", "__new__"): timer,
        ("Timer", "init"): timer,
        ("WDT", "__new__"): {"id": 0, "timeout": 1000},
    }


LEAD = {"UART": (2,), "SPI": (1,), "Pin": ("B0",), "Timer": (-1,), "WDT": ()}


def _caller(m, key):
    """f(*args, **kwargs): the stand-in's constructor (after the lead) or method."""
    cls, meth = key
    if meth == "__new__":
        return lambda *a, **k: getattr(m, cls)(*LEAD[cls], *a, **k)
    if cls == "Pin":
        obj = m.Pin("B0", m.Pin.IN)
    elif cls == "Timer":
        obj = m.Timer(-1)
    else:
        obj = getattr(m, cls)(*LEAD[cls], baudrate=9600)
    return getattr(obj, meth)


STANDIN_TABLES = {  # where the stand-in keeps its copy of each table
    ("UART", "init"): "UART._INIT",
    ("SPI", "init"): "_SPI_INIT",
    ("Pin", "init"): "Pin._INIT",
    ("Pin", "irq"): "Pin._IRQ",
    ("Timer", "init"): "Timer._INIT",
    ("WDT", "__new__"): "WDT._NEW",
}


def test_the_stand_ins_tables_are_the_ports(machine):
    """The stand-in's own copies of the tables: the port's names, kinds and flags in order."""
    calls, _ = API
    flags = {"int": machine._INT, "obj": machine._OBJ, "bool": machine._BOOL}
    for key, path in STANDIN_TABLES.items():
        want = [(a.name, flags[a.kind] | (a.required and machine._REQUIRED)
                 | (a.kw_only and machine._KW_ONLY)) for a in calls[key].table]  # fmt: skip
        table = functools.reduce(getattr, path.split("."), machine)
        assert [(n, f) for n, f, _ in table] == want, key
    spi = [(n, f) for n, f, _ in machine._SPI_NEW]
    assert spi[0] == ("id", machine._REQUIRED | machine._OBJ)
    assert [n for n, _ in spi[1:]] == calls[("SPI", "__new__")].names()


@pytest.mark.parametrize("key", sorted(API[0]), ids="{0[0]}.{0[1]}".format)
def test_the_stand_in_takes_what_the_port_takes_and_refuses_the_rest(machine, key):
    """Each argument of the port's table by keyword, the positional ones positionally; one
    positional too many, `txbuf` or an unknown keyword, an argument given twice, a required
    one missing: the port's TypeErrors."""
    call = API[0][key]
    samples = _samples(machine)[key]
    f = _caller(machine, key)
    missing = [a.name for a in call.table if a.name not in samples]
    assert not missing, f"the port takes {missing}: emulate them and give samples here"
    required = {a.name: samples[a.name] for a in call.table if a.required}
    f(**required)
    for a in call.table:  # each by keyword
        if samples[a.name] is None and key[0] == "SPI":
            with pytest.raises(ValueError, match="sck/mosi/miso is not implemented"):
                f(**{**required, a.name: machine.Pin("A5")})
        else:
            f(**{**required, a.name: samples[a.name]})
    n_pos = 0  # the positional prefix, positionally
    while n_pos < len(call.table) and not call.table[n_pos].kw_only:
        n_pos += 1
    prefix = [samples[a.name] for a in call.table[:n_pos]]
    f(*prefix)
    extra = samples[call.table[n_pos].name] if n_pos < len(call.table) else 0
    with pytest.raises(TypeError, match="extra positional arguments given"):
        f(*prefix, extra)
    for bogus in ("txbuf", "no_such_argument"):
        with pytest.raises(TypeError, match="extra keyword arguments given"):
            f(**required, **{bogus: 1})
    if n_pos:
        first = call.table[0].name
        with pytest.raises(TypeError, match="extra keyword arguments given"):  # given twice
            f(samples[first], **{**required, first: samples[first]})
    other = next(a.name for a in call.table if not a.required)  # so that the table is read
    for a in call.table:
        if a.required:
            with pytest.raises(TypeError, match=f"'{a.name}' argument required"):
                f(**{n: v for n, v in required.items() if n != a.name}, **{other: samples[other]})


def test_the_lead_ids_are_positional_only(machine):
    """UART, Pin, SPI and Timer take their id positionally only; UART(id) and Pin(id) alone
    return the part as it is."""
    for cls in ("UART", "Pin"):
        with pytest.raises(TypeError):
            getattr(machine, cls)(id=LEAD[cls][0])
    with pytest.raises(TypeError, match="extra keyword arguments given"):
        machine.SPI(id=1)
    with pytest.raises(TypeError, match="extra keyword arguments given"):
        machine.Timer(id=-1)
    assert machine.UART(2) is machine.uart(2) and machine.uart(2).baudrate == 9600
    assert machine.Pin("B0") is machine.pin("B0")


def test_the_functions_take_what_the_port_takes(machine):
    _, functions = API
    for name, n in functions.items():
        params = inspect.signature(getattr(machine, name)).parameters.values()
        assert [p.kind for p in params] == [inspect.Parameter.POSITIONAL_OR_KEYWORD] * n
        assert all(p.default is inspect.Parameter.empty for p in params), name
    machine.enable_irq(machine.disable_irq())


def test_values_the_port_refuses(machine):
    """The ValueErrors of the port's C for values (ports/stm32/machine_uart.c, pin.c,
    machine_spi.c, extmod/machine_timer.c, ports/stm32/machine_wdt.c)."""
    m = machine
    for bits, parity in ((8, None), (9, None), (7, 0), (8, 1)):
        m.UART(2, 9600, bits, parity)
    for bits, parity in ((7, None), (9, 0), (5, None)):  # no 7-bit words on the F4
        with pytest.raises(ValueError, match="unsupported combination of bits and parity"):
            m.UART(2, 9600, bits, parity)
    u = m.UART(2, 9600, read_buf_len=32)
    assert u.rxbuf == 32 and m.UART(2, 9600, rxbuf=16, read_buf_len=32).rxbuf == 16
    with pytest.raises(ValueError, match="invalid pin mode: 99"):
        m.Pin("B1", 99)
    with pytest.raises(ValueError, match="invalid pin pull: 3"):
        m.Pin("B1", m.Pin.IN, 3)
    with pytest.raises(ValueError, match="invalid pin af: -1"):
        m.Pin("B1", m.Pin.ALT)  # an alternate function needs its number
    with pytest.raises(ValueError, match="invalid pin af: 3"):
        m.Pin("B1", m.Pin.ALT, alt=3)  # not an F411 AF by the HAL's IS_GPIO_AF
    m.Pin("B1", m.Pin.ALT, alt=7)
    m.Pin("B1", m.Pin.ALT_OPEN_DRAIN, None, 4)
    assert m.Pin("B1", m.Pin.OUT, value=None).value() == 0  # value is its truth
    with pytest.raises(ValueError, match="sck/mosi/miso"):
        m.SPI(1, sck=m.Pin("A5"))
    with pytest.raises(ValueError, match="Timer doesn't exist"):
        m.Timer(0)
    with pytest.raises(ValueError, match="period too large"):
        m.Timer(-1, period=0x40000000, callback=print)
    assert m.Timer(-1, freq=200, callback=print).period_ms == 5
    assert m.Timer(-1, freq=5000, callback=print).period_ms == 1
    assert m.Timer(-1, period=3, tick_hz=1, callback=print).period_ms == 3000
    with pytest.raises(ValueError, match=r"WDT\(1\) doesn't exist"):
        m.WDT(1)
    with pytest.raises(ValueError, match="WDT timeout too short"):
        m.WDT(timeout=0)
    with pytest.raises(ValueError, match="WDT timeout too long"):
        m.WDT(timeout=32768)
    assert m.WDT(0, 32767).timeout_ms == 32767 and m.WDT(timeout=1).timeout_ms == 1
    with pytest.raises(TypeError, match="can't convert to int"):
        m.UART(2, 9600.0)


def _hal_macros():
    """#define NAME value of the F4 HAL and CMSIS headers, the port's config and soft timer."""
    files = ["lib/stm32lib/STM32F4xx_HAL_Driver/Inc/stm32f4xx_hal_gpio.h",
             "lib/stm32lib/STM32F4xx_HAL_Driver/Inc/stm32f4xx_hal_gpio_ex.h",
             "lib/stm32lib/STM32F4xx_HAL_Driver/Inc/stm32f4xx_hal_spi.h",
             "lib/stm32lib/CMSIS/STM32F4xx/Include/stm32f411xe.h",
             "ports/stm32/mpconfigport.h", "shared/runtime/softtimer.h"]  # fmt: skip
    macros = {}
    for rel in files:
        for name, value in re.findall(r"^\s*#define\s+(\w+)[ \t]+([^\n]*?)\s*(?:/[*/].*)?$",
                                      _read(rel), re.M):  # fmt: skip
            macros.setdefault(name, value)
    return macros


def _value(expr, macros, depth=0):
    """An integer macro expression: literals (U suffixes), casts, names, << | ( )."""
    if depth > 10:
        raise ApiSourceError(f"macro too deep: {expr}")
    expr = re.sub(r"\(\s*uint(?:8|16|32)_t\s*\)", "", expr)
    out = []
    for tok in re.findall(r"0x[0-9A-Fa-f]+|\d+|\w+|<<|[|()]|\S", expr):
        if re.fullmatch(r"0x[0-9A-Fa-f]+|\d+", tok) or tok in ("<<", "|", "(", ")"):
            out.append(tok)
        elif re.fullmatch(r"U|UL", tok):
            continue
        elif tok in macros:
            out.append(str(_value(macros[tok], macros, depth + 1)))
        else:
            raise ApiSourceError(f"cannot evaluate {tok!r} in {expr!r}")
    text = re.sub(r"(0x[0-9A-Fa-f]+|\d+)U(?:L)?\b", r"\1", "".join(out))
    return eval(text, {"__builtins__": {}})  # only the tokens above


def _rom_ints(rel, table):
    """{name: macro} of the MP_ROM_INT constants of a locals table in SRC/rel."""
    m = re.search(rf"\b{table}\[\]\s*=\s*\{{", _read(rel))
    if not m:
        raise ApiSourceError(f"{rel}: no {table}")
    body = _block(_read(rel), m.end() - 1, table)
    return dict(re.findall(r"MP_QSTR_(\w+)\)\s*,\s*MP_ROM_INT\((\w+)\)", body))


def test_the_stand_ins_constants_are_the_hals(machine):
    macros = _hal_macros()
    for cls, rel, table in (("Pin", "ports/stm32/pin.c", "pin_locals_dict_table"),
                            ("SPI", "extmod/machine_spi.c", "machine_spi_locals_dict_table"),
                            ("Timer", "extmod/machine_timer.c",
                             "machine_timer_locals_dict_table")):  # fmt: skip
        port = {n: _value(v, macros) for n, v in _rom_ints(rel, table).items()}
        ours = {n: v for n, v in vars(getattr(machine, cls)).items() if n.isupper() and n[0] != "_"}
        assert ours and {n: port.get(n) for n in ours} == ours, cls
    gpio_ex = _read("lib/stm32lib/STM32F4xx_HAL_Driver/Inc/stm32f4xx_hal_gpio_ex.h")
    f411 = re.search(r"#if defined\(STM32F411xE\)\s*#define IS_GPIO_AF\(AF\)(.*?)#endif",
                     gpio_ex, re.S).group(1)  # fmt: skip
    afs = {_value(n, macros) for n in re.findall(r"GPIO_AF\w+", f411)}
    assert len(afs) > 8
    for af in range(-1, 17):  # pin.c: an alternate function must pass IS_GPIO_AF
        if af in afs:
            machine.Pin("B1", machine.Pin.ALT, alt=af)
        else:
            with pytest.raises(ValueError, match=f"invalid pin af: {af}"):
                machine.Pin("B1", machine.Pin.ALT, alt=af)
    gpio = _read("lib/stm32lib/STM32F4xx_HAL_Driver/Inc/stm32f4xx_hal_gpio.h")
    modes = re.search(r"#define IS_GPIO_MODE\(MODE\)(.*?)\n\s*#define", gpio, re.S).group(1)
    modes = {_value(n, macros) for n in re.findall(r"GPIO_MODE_\w+", modes)}
    assert len(modes) == 12
    for mode in modes | {4, 0x13, 0x10010000, 0x10410000}:  # pin.c: IS_GPIO_MODE
        if mode in modes:
            machine.Pin("B1", mode, alt=5)
        else:
            with pytest.raises(ValueError, match=f"invalid pin mode: {mode}"):
                machine.Pin("B1", mode)


VM_SCRIPT = """
import json, machine
import bmi055_model
def err(f):
    try:
        f()
    except Exception as e:
        return [type(e).__name__, str(e)]
    return None
t = [0]
imu = bmi055_model.Bmi055(now_us=lambda: t[0])
imu.gyro.write_reg(0x14, 0xB6)
imu.gyro.deselect()
busy = imu.gyro.busy()
t[0] = 30000
print(json.dumps({
    "txbuf": err(lambda: machine.UART(1, baudrate=460800, txbuf=512)),
    "positional": err(lambda: machine.SPI(1, 4000000, 0)),
    "required": err(lambda: machine.Pin("B0", value=1)),
    "mode": err(lambda: machine.Pin("B0", 7)),
    "timer": err(lambda: machine.Timer(2)),
    "ok": err(lambda: (machine.UART(6, baudrate=9600, rxbuf=1024, timeout=0),
                       machine.Timer(-1, mode=machine.Timer.PERIODIC, freq=200,
                                     callback=print, hard=True),
                       machine.Pin("B0", machine.Pin.IN).irq(
                           trigger=machine.Pin.IRQ_RISING, handler=print, hard=True),
                       machine.WDT(timeout=1000))),
    "same": machine.Bmi055 is bmi055_model.Bmi055,
    "clock": [busy, imu.gyro.busy(), imu.accel.busy()],
}))
"""


def test_in_the_micropython_vm_too():
    """machine.py's argument checks and bmi055_model's clock in the MicroPython VM."""
    r = mpvm.run_json(f"import sys\nsys.path.insert(0, {str(MPY_DIR)!r})\n" + VM_SCRIPT)
    assert r["txbuf"] == ["TypeError", "extra keyword arguments given"]
    assert r["positional"] == ["TypeError", "extra positional arguments given"]
    assert r["required"] == ["TypeError", "'mode' argument required"]
    assert r["mode"] == ["ValueError", "invalid pin mode: 7"]
    assert r["timer"] == ["ValueError", "Timer doesn't exist"]
    assert r["ok"] is None and r["same"] is True
    assert r["clock"] == [True, False, False]  # the die's start-up on the clock it was given


# ---- the firmware's calls ------------------------------------------------------------------


def test_the_firmware_calls_machine_only_as_the_port_takes_it():
    problems, checked = [], []
    for path in firmware_sources():
        p, c = check_calls(path.read_text(), str(path.relative_to(REPO_DIR)))
        problems += p
        checked += c
    assert not problems, "\n".join(problems)
    # not vacuous: board.py's peripherals were found and checked
    assert {("UART", "__new__"), ("SPI", "__new__"), ("Pin", "__new__"), ("Pin", "irq"),
            ("Timer", "__new__"), ("WDT", "__new__")} <= set(checked)  # fmt: skip


@pytest.mark.parametrize(
    "source, reported",
    [
        ("import machine\nmachine.UART(1, baudrate=9600, txbuf=512)\n", "'txbuf'"),
        ("from machine import UART as U\nu = U(2, 9600, txbuf=64)\n", "'txbuf'"),
        ("import machine\nmachine.UART(2, rxbuf=64)\n", "'baudrate' argument required"),
        ("import machine\nmachine.SPI(1, 4000000, 0, 0)\n", "positional argument 3"),
        ("import machine\nmachine.SPI(id=1)\n", "id is positional only"),
        ("import machine as m\nm.Pin('B0', value=1)\n", "'mode' argument required"),
        ("import machine\np = machine.Pin('B0', machine.Pin.IN)\np.irq(handler=f, edge=1)\n",
         "'edge'"),
        ("import machine\nmachine.Pin('B0').irq(f, 1, True, 4)\n", "positional argument 4"),
        ("import machine\nclass B:\n    def go(self):\n        self.t = machine.Timer(-1)\n"
         "        self.t.init(freq=1, txbuf=2)\n", "'txbuf'"),
        ("import machine\nmachine.Timer(-1, 200)\n", "positional argument 2"),
        ("import machine\nmachine.WDT(timeout=1000, window=5)\n", "'window'"),
        ("import machine\nmachine.enable_irq()\n", "takes 1 positional"),
        ("import machine\nmachine.idle(now=True)\n", "takes no keywords"),
        ("import machine\nmachine.UART(1, **opts)\n", "cannot be checked"),
        ("import machine\nmachine.lightsleep(10)\n", "not in the tables"),
    ],
)  # fmt: skip
def test_the_checker_reports_what_the_port_refuses(source, reported):
    problems, _ = check_calls(source)
    assert len(problems) == 1 and reported in problems[0], problems


def test_the_checker_passes_what_the_port_takes():
    source = (
        "import machine\nfrom machine import Pin\n"
        "machine.UART(1)\nmachine.UART(2, 9600, 8, None, 1, rxbuf=64, timeout=0)\n"
        "machine.SPI(1, 4000000, polarity=0, phase=0)\n"
        "p = Pin('B0', Pin.IN, None, value=0)\np.irq(None, Pin.IRQ_RISING, True)\np.init(Pin.OUT)\n"
        "machine.Timer(-1)\nmachine.Timer()\nmachine.WDT(0, 1000)\n"
        "machine.enable_irq(machine.disable_irq())\nmachine.idle()\n"
        "drv.init()\nself.board.irq(handler=1)\n"  # not machine objects: not checked
    )
    problems, checked = check_calls(source)
    assert not problems and len(checked) == 12
