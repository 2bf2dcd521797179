"""The bindings of the native kernels, generated from their one header (firmware/native/navk.h).

    prototypes(text, natmod=False) -> [Prototype]  the exported functions (named navk_*) of a
                                       header; natmod: those of a MicroPython native module
    micropython_module(protos) -> str  the C of the MicroPython native module `navk`
    cdef(protos) -> str                the declarations cffi compiles the CPython module from

What the header may hold: comments, preprocessor lines, and declarations ending in `;` (static
inline definitions are skipped). Every function whose name starts with `navk_` is exported,
named without the prefix (`navk_add` -> `navk.add`); it takes only the types of BUFFERS and
SCALARS below and returns void, int32_t or float. Anything else in an exported prototype is an
error naming it (nothing is hand-written per function, so nothing may be guessed). Between
`#ifndef NAVK_NATMOD` and its `#endif` (not nested) are the host's kernels: the CPython build
binds them, a MicroPython native module (built with -DNAVK_NATMOD) has them not, since the board
loads its module's code into its heap.

The MicroPython wrappers are lean on purpose (a navigating tick of the board has 30,000
instructions): a buffer argument is one call of the runtime's get_buffer plus a typecode and a
length check, a small int is unboxed inline, and the result is None, an int or a float object.
"""

import dataclasses
import re

MODULE = "navk"
PREFIX = "navk_"


@dataclasses.dataclass(frozen=True)
class Buffer:
    """A buffer argument: what C sees, what MicroPython gives (array typecodes) and NumPy."""

    ctype: str  # the element type in C
    typecodes: tuple  # MicroPython buffer typecodes accepted (1: bytearray's)
    python: str  # what to pass, for error messages
    dtype: str  # NumPy dtype (CPython)
    itemsize: int


BUFFERS = {
    "float": Buffer("float", ("f",), "array('f')", "float32", 4),
    "int32_t": Buffer("int32_t", ("i",), "array('i')", "int32", 4),
    "int16_t": Buffer("int16_t", ("h",), "array('h')", "int16", 2),
    "uint8_t": Buffer("uint8_t", ("B", 1), "bytearray or array('B')", "uint8", 1),
}
SCALARS = ("int32_t", "float")
RETURNS = ("void", "int32_t", "float")


class HeaderError(ValueError):
    """navk.h holds a prototype the generator cannot bind; the message names it."""


@dataclasses.dataclass(frozen=True)
class Param:
    name: str
    base: str  # float, int32_t, int16_t, uint8_t
    pointer: bool
    const: bool

    @property
    def ctype(self):
        if not self.pointer:
            return self.base
        return ("const " if self.const else "") + self.base + " *"

    @property
    def buffer(self):
        return BUFFERS[self.base] if self.pointer else None


@dataclasses.dataclass(frozen=True)
class Prototype:
    ret: str
    cname: str
    params: tuple

    @property
    def name(self):
        """The Python name: the C name without navk_."""
        return self.cname[len(PREFIX) :]

    def declaration(self):
        args = ", ".join(f"{p.ctype}{'' if p.pointer else ' '}{p.name}" for p in self.params)
        return f"{self.ret} {self.cname}({args or 'void'});"


HOST_ONLY = re.compile(r"^[ \t]*#ifndef[ \t]+NAVK_NATMOD\b.*?^[ \t]*#endif[^\n]*", re.M | re.S)


def _strip(text):
    """The header without comments and preprocessor lines (line continuations included)."""
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)
    text = re.sub(r"//[^\n]*", " ", text)
    text = re.sub(r"\\\n", " ", text)
    return "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))


def _statements(text):
    """Top-level declarations (text before each `;`), skipping braced bodies."""
    out, cur, depth = [], [], 0
    for ch in text:
        if ch == "{":
            depth += 1
            if depth == 1:
                cur = []  # a definition (static inline ...): not a declaration
            continue
        if ch == "}":
            depth -= 1
            continue
        if depth:
            continue
        if ch == ";":
            out.append(" ".join("".join(cur).split()))
            cur = []
        else:
            cur.append(ch)
    return [s for s in out if s]


_PROTO = re.compile(r"^(?P<ret>[\w\s]+?)\s*\b(?P<name>\w+)\s*\((?P<params>.*)\)$")
_PARAM = re.compile(r"^(?P<const>const\s+)?(?P<base>\w+)\s*(?P<ptr>\*)?\s*(?P<name>\w+)$")


def _param(text, where):
    m = _PARAM.match(text.strip())
    if not m:
        raise HeaderError(f"{where}: cannot bind parameter {text.strip()!r}")
    base, ptr, const = m["base"], bool(m["ptr"]), bool(m["const"])
    if ptr and base not in BUFFERS:
        raise HeaderError(
            f"{where}: parameter {text.strip()!r}: buffers are "
            + ", ".join(f"{b} * / const {b} *" for b in BUFFERS)
        )
    if not ptr and (const or base not in SCALARS):
        raise HeaderError(
            f"{where}: parameter {text.strip()!r}: scalars are {' and '.join(SCALARS)} (not const)"
        )
    return Param(m["name"], base, ptr, const)


def prototypes(text, natmod=False):
    """The exported prototypes of a header's text, in order (natmod: without the host's,
    HOST_ONLY); HeaderError if one cannot be bound or a name repeats."""
    if natmod:
        text = HOST_ONLY.sub("", text)
    protos, seen = [], set()
    for stmt in _statements(_strip(text)):
        m = _PROTO.match(stmt)
        if not m or not m["name"].startswith(PREFIX):
            continue  # not an exported function (a typedef, an internal helper, ...)
        where = m["name"]
        if re.search(r"\bstatic\b", m["ret"]):
            continue  # internal to the C files that include the header
        ret = " ".join(re.sub(r"\bextern\b", " ", m["ret"]).split())
        if ret not in RETURNS:
            raise HeaderError(f"{where}: returns {ret!r}; a kernel returns {', '.join(RETURNS)}")
        params_text = m["params"].strip()
        params = ()
        if params_text not in ("", "void"):
            params = tuple(_param(p, where) for p in params_text.split(","))
        names = [p.name for p in params]
        if len(set(names)) != len(names):
            raise HeaderError(f"{where}: a parameter name repeats")
        if m["name"] in seen:
            raise HeaderError(f"{where}: declared twice")
        seen.add(m["name"])
        protos.append(Prototype(ret, m["name"], params))
    if not protos:
        raise HeaderError("no navk_* prototype found")
    return protos


def cdef(protos):
    """cffi's cdef: the prototypes as plain declarations."""
    return "\n".join(p.declaration() for p in protos) + "\n"


# ---------------------------------------------------------------------------------------------
# The MicroPython native module

_C_HEAD = """\
// Generated by common/native/bindings.py from navk.h: do not edit (it is rebuilt with the module).
// The MicroPython native module `navk`: one function per navk_* prototype, named without the
// prefix. Buffers: one get_buffer call, then the typecode and a length of at least one element
// are checked (TypeError / ValueError); ints are unboxed inline when small.
#include "py/dynruntime.h"
#include "py/objarray.h"
#include "navk.h"

// GCC may turn a loop that clears or copies memory into a call of these, and a kernel may call
// them: the runtime's own, as MicroPython's natmod examples do (no C library is linked).
void *memset(void *s, int c, size_t n) {
    return mp_fun_table.memset_(s, c, n);
}
void *memcpy(void *dst, const void *src, size_t n) {
    return mp_fun_table.memmove_(dst, src, n);
}
void *memmove(void *dst, const void *src, size_t n) {
    return mp_fun_table.memmove_(dst, src, n);
}

// The buffer types whose objects are read directly (py/objarray.h: array, bytearray and
// memoryview are one struct): set when the module is imported (BSS: mpy_ld wants it global).
const mp_obj_type_t *navk_t_array, *navk_t_bytearray, *navk_t_memoryview;

// A buffer of one element type: its address, or TypeError / ValueError. Fast path: an array,
// bytearray or (writable, for a non-const buffer) memoryview of the right typecode, read from
// its struct; anything else goes through the runtime's get_buffer, which raises for
// non-buffers and read-only buffers given as writable ones.
static void *navk_buf(mp_obj_t o, mp_uint_t flags, int tc, int tc2, size_t itemsize,
                      const char *what) {
    if (mp_obj_is_obj(o)) {
        const mp_obj_array_t *a = MP_OBJ_TO_PTR(o);
        const mp_obj_type_t *t = a->base.type;
        int c = a->typecode;
        if ((t == navk_t_array || t == navk_t_bytearray) && (c == tc || c == tc2) && a->len) {
            return a->items;
        }
        if (t == navk_t_memoryview && a->len
            && (c & MP_OBJ_ARRAY_TYPECODE_FLAG_RW || !(flags & MP_BUFFER_WRITE))) {
            c &= ~MP_OBJ_ARRAY_TYPECODE_FLAG_RW;
            if (c == tc || c == tc2) {
                return (uint8_t *)a->items + a->free * itemsize;  // free: memview_offset
            }
        }
    }
    mp_buffer_info_t bi;
    mp_get_buffer_raise(o, &bi, flags);
    if (bi.typecode != tc && bi.typecode != tc2) {
        mp_raise_TypeError(what);
    }
    if (bi.len < itemsize) {
        mp_raise_ValueError(MP_ERROR_TEXT("navk: empty buffer"));
    }
    return bi.buf;
}

// An int32_t argument: a small int is unboxed here; anything else goes through the runtime
// (TypeError unless an int or a bool), and must equal its int32 value (ValueError beyond int32,
// never truncated). On a 32-bit board ints beyond +-2**30 are heap objects and this check makes
// one more: pass such values in an int32 buffer.
static int32_t navk_int_big(mp_obj_t o) {
    mp_int_t v = mp_obj_get_int_truncated(o);
    if (v != (mp_int_t)(int32_t)v
        || !mp_obj_is_true(mp_binary_op(MP_BINARY_OP_EQUAL, o, mp_obj_new_int(v)))) {
        mp_raise_ValueError(MP_ERROR_TEXT("navk: int beyond int32"));
    }
    return (int32_t)v;
}

static inline int32_t navk_int(mp_obj_t o) {
    if (mp_obj_is_small_int(o)) {
        mp_int_t v = MP_OBJ_SMALL_INT_VALUE(o);
        if (sizeof(mp_int_t) == sizeof(int32_t) || v == (mp_int_t)(int32_t)v) {
            return (int32_t)v;
        }
    }
    return navk_int_big(o);
}
"""


def _buffer_macros():
    lines = []
    for base, b in BUFFERS.items():
        tc = [f"'{t}'" if isinstance(t, str) else str(t) for t in b.typecodes]
        tc2 = tc[1] if len(tc) > 1 else tc[0]
        msg = f'MP_ERROR_TEXT("navk: expected {b.python} for a {base} buffer")'
        for const, flags in ((False, "MP_BUFFER_RW"), (True, "MP_BUFFER_READ")):
            macro = f"NAVK_{base.upper()}_{'RO' if const else 'RW'}"
            cast = f"({'const ' if const else ''}{base} *)"
            lines.append(
                f"#define {macro}(o) ({cast}navk_buf((o), {flags}, {tc[0]}, {tc2}, "
                f"{b.itemsize}, {msg}))"
            )
    return "\n".join(lines) + "\n"


def _arg(p, expr):
    if p.pointer:
        return f"NAVK_{p.base.upper()}_{'RO' if p.const else 'RW'}({expr})"
    if p.base == "int32_t":
        return f"navk_int({expr})"
    return f"mp_obj_get_float_to_f({expr})"


def _wrapper(p):
    n = len(p.params)
    fn = f"mod_{p.name}"
    if n <= 3:
        sig = ", ".join(f"mp_obj_t a{i}" for i in range(n)) or "void"
        exprs = [f"a{i}" for i in range(n)]
        define = f"static MP_DEFINE_CONST_FUN_OBJ_{n}({fn}_obj, {fn});"
    else:
        sig = "size_t n_args, const mp_obj_t *args"
        exprs = [f"args[{i}]" for i in range(n)]
        define = f"static MP_DEFINE_CONST_FUN_OBJ_VAR_BETWEEN({fn}_obj, {n}, {n}, {fn});"
    call = f"{p.cname}({', '.join(_arg(q, e) for q, e in zip(p.params, exprs, strict=True))})"
    body = []
    if n > 3:
        body.append("    (void)n_args;  // the runtime checked the count")
    if p.ret == "void":
        body += [f"    {call};", "    return mp_const_none;"]
    elif p.ret == "int32_t":
        body.append(f"    return mp_obj_new_int({call});")
    else:
        body.append(f"    return mp_obj_new_float_from_f({call});")
    return "\n".join([f"static mp_obj_t {fn}({sig}) {{", *body, "}", define, ""])


def micropython_module(protos):
    """The C source of the native module (compiled with navk.c by py/dynruntime.mk)."""
    parts = [_C_HEAD, _buffer_macros()]
    parts += [_wrapper(p) for p in protos]
    init = [
        "mp_obj_t mpy_init(mp_obj_fun_bc_t *self, size_t n_args, size_t n_kw, mp_obj_t *args) {",
        "    MP_DYNRUNTIME_INIT_ENTRY",
        "    mp_obj_t array = mp_import_name(MP_QSTR_array, mp_const_none,",
        "                                    MP_OBJ_NEW_SMALL_INT(0));",
        "    navk_t_array = MP_OBJ_TO_PTR(mp_load_attr(array, MP_QSTR_array));",
        "    navk_t_bytearray = &mp_type_bytearray;",
        "    navk_t_memoryview = MP_OBJ_TO_PTR(mp_load_global(MP_QSTR_memoryview));",
    ]
    init += [
        f"    mp_store_global(MP_QSTR_{p.name}, MP_OBJ_FROM_PTR(&mod_{p.name}_obj));"
        for p in protos
    ]
    init += ["    MP_DYNRUNTIME_INIT_EXIT", "}", ""]
    parts.append("\n".join(init))
    return "\n".join(parts)
