"""common/native/bindings.py: navk.h's prototypes -> the MicroPython module's C and cffi's cdef.

The generator takes the header's navk_* prototypes (comments, preprocessor lines and static
definitions skipped), refuses any type it cannot bind (naming the prototype), and writes one
wrapper per kernel: fixed-arity function objects up to 3 arguments, VAR_BETWEEN(n, n) above.
"""

import pathlib

import pytest

from common import native
from common.native import bindings

SAMPLE = pathlib.Path(__file__).with_name("sample")


def protos_of(text):
    return bindings.prototypes(text)


def test_the_sample_header_gives_every_kernel_in_order():
    protos = bindings.prototypes((SAMPLE / "navk.h").read_text())
    names = [p.name for p in protos]
    assert names == [
        "abi", "neg", "hypot", "sqrt_n", "add", "madd", "dot", "sum16", "scale16", "xor",
        "icum", "args12",
    ]  # fmt: skip
    assert "private" not in names  # static inline: internal
    by = {p.name: p for p in protos}
    assert by["abi"].params == () and by["abi"].ret == "int32_t"
    assert by["dot"].ret == "float"
    a12 = by["args12"]
    assert [(p.base, p.pointer, p.const) for p in a12.params] == [
        ("float", True, True), ("float", True, False), ("int32_t", True, True),
        ("int32_t", True, False), ("int16_t", True, True), ("int16_t", True, False),
        ("uint8_t", True, True), ("uint8_t", True, False), ("int32_t", False, False),
        ("float", False, False), ("int32_t", False, False), ("float", False, False),
    ]  # fmt: skip


def test_the_firmware_header_parses():
    protos = native.prototypes()
    names = [p.name for p in protos]
    assert names[:2] == ["abi", "add"]
    assert len(set(names)) == len(names)


def test_multi_line_prototypes_comments_and_macros():
    protos = protos_of(
        "/* c */\n#define X 1\n#if X\n// line\n#endif\n"
        "void navk_f(float *out,\n           const float *a, // a\n int32_t n);\n"
        "typedef int navk_t;\nint other(int x);\n"
        "static inline float navk_g(float x) { return x; }\n"
    )
    assert [p.declaration() for p in protos] == [
        "void navk_f(float *out, const float *a, int32_t n);"
    ]


@pytest.mark.parametrize(
    "decl, says",
    [
        ("void navk_f(double *x);", "buffers are"),
        ("void navk_f(int x);", "scalars are"),
        ("void navk_f(const int32_t n);", "scalars are"),
        ("double navk_f(void);", "returns 'double'"),
        ("void navk_f(float *x, float *x);", "repeats"),
        ("void navk_f(float x[3]);", "cannot bind"),
        ("void navk_f(void); void navk_f(void);", "declared twice"),
        ("int other(void);", "no navk_* prototype"),
    ],
)
def test_what_cannot_be_bound_is_an_error_naming_it(decl, says):
    with pytest.raises(bindings.HeaderError) as e:
        protos_of(decl)
    assert says in str(e.value)
    if "navk_f" in decl:
        assert "navk_f" in str(e.value)


def test_the_micropython_module():
    protos = bindings.prototypes((SAMPLE / "navk.h").read_text())
    c = bindings.micropython_module(protos)
    assert '#include "py/dynruntime.h"' in c and '#include "navk.h"' in c
    assert "static MP_DEFINE_CONST_FUN_OBJ_0(mod_abi_obj, mod_abi);" in c
    assert "static MP_DEFINE_CONST_FUN_OBJ_1(mod_neg_obj, mod_neg);" in c
    assert "static MP_DEFINE_CONST_FUN_OBJ_2(mod_hypot_obj, mod_hypot);" in c
    assert "static MP_DEFINE_CONST_FUN_OBJ_3(mod_sqrt_n_obj, mod_sqrt_n);" in c
    assert "MP_DEFINE_CONST_FUN_OBJ_VAR_BETWEEN(mod_add_obj, 4, 4, mod_add);" in c
    assert "MP_DEFINE_CONST_FUN_OBJ_VAR_BETWEEN(mod_args12_obj, 12, 12, mod_args12);" in c
    # buffers: const -> read, else read-write; int32 and float scalars; results
    assert "navk_add(NAVK_FLOAT_RW(args[0]), NAVK_FLOAT_RO(args[1]), NAVK_FLOAT_RO(args[2])" in c
    assert "mp_obj_get_float_to_f(a0), mp_obj_get_float_to_f(a1)" in c
    assert "return mp_obj_new_float_from_f(navk_dot(" in c
    assert "return mp_obj_new_int(navk_abi());" in c
    assert "navk_icum(NAVK_INT32_T_RW(a0), NAVK_INT32_T_RO(a1), navk_int(a2));" in c
    typecodes = {
        "NAVK_FLOAT_RW": "'f', 'f', 4",
        "NAVK_INT32_T_RO": "'i', 'i', 4",
        "NAVK_INT16_T_RW": "'h', 'h', 2",
        "NAVK_UINT8_T_RO": "'B', 1, 1",  # 1: bytearray's typecode
    }
    lines = c.splitlines()
    for macro, tc in typecodes.items():
        assert any(x.startswith(f"#define {macro}(o)") and tc in x for x in lines), macro
    for p in protos:
        assert f"mp_store_global(MP_QSTR_{p.name}, MP_OBJ_FROM_PTR(&mod_{p.name}_obj));" in c


def test_the_cdef_is_the_prototypes():
    protos = bindings.prototypes((SAMPLE / "navk.h").read_text())
    cdef = bindings.cdef(protos)
    assert cdef.splitlines()[0] == "int32_t navk_abi(void);"
    assert "float navk_hypot(float x, float y);" in cdef
    assert "#" not in cdef and "static" not in cdef and "/*" not in cdef
    import cffi

    cffi.FFI().cdef(cdef)  # parses


def test_a_native_module_leaves_the_hosts_kernels_out():
    """Between `#ifndef NAVK_NATMOD` and `#endif`: bound on CPython, not in a MicroPython
    module (the board's holds its code in its heap)."""
    text = (
        "void navk_a(float *o);\n#ifndef NAVK_NATMOD\nvoid navk_b(float *o);\n#endif\n"
        "void navk_c(float *o);\n"
    )
    assert [p.name for p in bindings.prototypes(text)] == ["a", "b", "c"]
    assert [p.name for p in bindings.prototypes(text, natmod=True)] == ["a", "c"]
    host = {p.name for p in native.prototypes()} - {p.name for p in native.prototypes(natmod=True)}
    assert host == {"sin_n", "cos_n", "asin_n", "atan2_n"}
