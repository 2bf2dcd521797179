"""The private consts a firmware module repeats from the module that owns them, generated.

MicroPython inlines a `const()` whose name starts with an underscore where the module uses it,
and the name exists nowhere else: it costs no global and no dict entry on the board, but a
module that indexes another module's buffers cannot import it. So nav_kern.py, nav_aid.py and
nav_align.py, which index the Navigator's buffers that nav.py lays out, repeat the indices
they use. The repeated lines sit between two marker lines in each module and are written from
the owner's source by `python -m common.native.layout` (with layout.h and tuning.h): never by
hand. A name qualifies when the module uses it (a NAME token outside the block: docstrings and
comments do not count) and the owner defines it as an int const(), as `_NAME` or as the public
`NAME` (then copied as `_NAME`: a public const is a global). The lines keep the owner's order
and its literal (hex stays hex); the owner's comments say what each one is.
"""

import io
import re
import tokenize

from common.firmware_env import FIRMWARE_DIR

# (module that repeats, module that owns), as the firmware imports them
COPIES = (
    ("nav_kern", "nav"),
    ("nav_aid", "nav"),
    ("nav_align", "nav"),
    ("drivers.gnss_kern", "drivers.gnss"),
)

_BEGIN = "# ---- {owner}'s consts used here: `python -m common.native.layout` writes them ----"
_END = "# ---- end of {owner}'s consts ----"
_INT_CONST = re.compile(r"^(_?[A-Z][A-Z0-9_]*) = const\((-?(?:0x[0-9A-Fa-f]+|\d+)|[A-Z_]\w*)\)")
_TOP_ASSIGN = re.compile(r"^([A-Za-z_]\w*)\s*=")


class CopyError(ValueError):
    """A module without its markers, or one that defines by hand a name the owner has."""


def _path(module):
    if "." in module:  # a package's (drivers.gnss)
        return FIRMWARE_DIR.joinpath(*module.split(".")).with_suffix(".py")
    return FIRMWARE_DIR / "lib" / (module + ".py")


def _file(module):
    return module.rsplit(".", 1)[-1] + ".py"


def owner_consts(owner):
    """{name: literal} of the owner's int consts, in source order (a const defined as another
    one, `_FS = const(MAXLEN)`, takes its literal)."""
    out = {}
    for line in _path(owner).read_text().splitlines():
        m = _INT_CONST.match(line)
        if m:
            literal = m.group(2)
            if literal[0].isalpha() or literal[0] == "_":
                if literal not in out:
                    raise CopyError(f"{_file(owner)}: {line!r}: {literal} is no const above it")
                literal = out[literal]
            out[m.group(1)] = literal
        elif re.match(r"_?[A-Z][A-Z0-9_]* = const\($", line):
            raise CopyError(f"{_file(owner)}: {line!r}: write a const on one line")
    return out


def _split(text, module, owner):
    """(before, block, after) of a module's text around its marker lines."""
    begin, end = _BEGIN.format(owner=_file(owner)), _END.format(owner=_file(owner))
    lines = text.splitlines(keepends=True)
    marks = [i for i, s in enumerate(lines) if s.rstrip("\n") in (begin, end)]
    if len(marks) != 2 or lines[marks[0]].rstrip("\n") != begin:
        raise CopyError(f"{_file(module)}: needs the lines {begin!r} and {end!r}")
    i, j = marks
    return "".join(lines[: i + 1]), "".join(lines[i + 1 : j]), "".join(lines[j:])


def _used_names(code):
    toks = tokenize.generate_tokens(io.StringIO(code).readline)
    return {t.string for t in toks if t.type == tokenize.NAME}


def generate(module, owner):
    """The module's text with its block rewritten from the owner's consts."""
    text = _path(module).read_text()
    before, _, after = _split(text, module, owner)
    code = before + after
    consts = owner_consts(owner)
    own = {m.group(1) for s in code.splitlines() if (m := _TOP_ASSIGN.match(s))}
    twice = sorted(own & {n if n.startswith("_") else "_" + n for n in consts})
    if twice:
        raise CopyError(
            f"{_file(module)} defines {', '.join(twice)} by hand: {_file(owner)} owns "
            "them (delete them; the block copies what is used)"
        )
    used = _used_names(code)
    rows = []
    for name, literal in consts.items():
        local = name if name.startswith("_") else "_" + name
        if local in used and local not in own:
            rows.append(f"{local} = const({literal})\n")
    return before + "".join(rows) + after


def generated():
    """{path: text} of every module that repeats consts."""
    return {_path(module): generate(module, owner) for module, owner in COPIES}
