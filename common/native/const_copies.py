"""The private consts a firmware module repeats from the modules that own them, generated.

MicroPython inlines a `const()` whose name starts with an underscore where the module uses it,
and the name exists nowhere else: it costs no global and no dict entry on the board, but a
module that indexes another module's buffers cannot import it. So nav_kern.py, nav_aid.py and
nav_align.py, which index the Navigator's buffers that nav.py lays out, repeat the indices
they use; app.py and status_page.py repeat the output frame's fields and byte offsets
(frame.py), the extended frame's (records.py) and the navigator's (nav.py). The repeated lines
sit between two marker lines per owner in each module and are written from the owner's source
by `python -m common.native.layout` (with layout.h and tuning.h): never by hand. A name
qualifies when the module uses it (a NAME token outside the blocks: docstrings and comments do
not count) and the owner defines it as an int const(), as `_NAME` or as the public `NAME`
(then copied as `_NAME`: a public const is a global); what the owner itself repeats from
another module is not its own. A name two owners define is an error. The lines keep the
owner's order and its literal (hex stays hex); the owner's comments say what each one is.
"""

import io
import re
import tokenize

from common.firmware_env import FIRMWARE_DIR

# (module that repeats, module that owns), as the firmware imports them; a module may repeat
# from several owners, a block each, and a name from only one of them
COPIES = (
    ("nav_kern", "nav"),
    ("nav_aid", "nav"),
    ("nav_aid", "ins"),
    ("nav_align", "nav"),
    ("nav_align", "yaw_gsf"),
    ("nav_align", "eskf"),
    ("nav", "yaw_gsf"),
    ("yaw_gsf", "nav"),
    ("yaw_gsf", "ins"),
    ("yaw_gsf", "eskf"),
    ("drivers.gnss_kern", "drivers.gnss"),
    ("app", "frame"),
    ("app", "records"),
    ("app", "nav"),
    ("app", "geo"),
    ("app", "status_page"),
    ("status_page", "frame"),
    ("status_page", "records"),
    ("status_page", "nav"),
)

_BEGIN = "# ---- {owner}'s consts used here: `python -m common.native.layout` writes them ----"
_END = "# ---- end of {owner}'s consts ----"
_BEGIN_ANY = re.escape(_BEGIN).replace(re.escape("{owner}"), r"\S+")
_END_ANY = re.escape(_END).replace(re.escape("{owner}"), r"\S+")
_INT_CONST = re.compile(r"^(_?[A-Z][A-Z0-9_]*) = const\((-?(?:0x[0-9A-Fa-f]+|\d+)|[A-Z_]\w*)\)")
_TOP_ASSIGN = re.compile(r"^([A-Za-z_]\w*)\s*=")


class CopyError(ValueError):
    """A module without its markers, or one that defines by hand a name the owner has."""


def _path(module):
    if (FIRMWARE_DIR / (module + ".py")).is_file():  # the app's own (app.py)
        return FIRMWARE_DIR / (module + ".py")
    if "." in module:  # a package's (drivers.gnss)
        return FIRMWARE_DIR.joinpath(*module.split(".")).with_suffix(".py")
    return FIRMWARE_DIR / "lib" / (module + ".py")


def _file(module):
    return module.rsplit(".", 1)[-1] + ".py"


def owner_consts(owner):
    """{name: literal} of the owner's int consts, in source order (a const defined as another
    one, `_FS = const(MAXLEN)`, takes its literal); not what it repeats from others."""
    out = {}
    for line in _without_blocks(_path(owner).read_text()).splitlines():
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


def _without_blocks(text):
    """text without every generated block (the marker lines stay): what the module writes."""
    out, inside = [], False
    for line in text.splitlines(keepends=True):
        if inside and re.match(_END_ANY, line):
            inside = False
        if not inside:
            out.append(line)
        if re.match(_BEGIN_ANY, line):
            inside = True
    return "".join(out)


def _used_names(code):
    toks = tokenize.generate_tokens(io.StringIO(code).readline)
    return {t.string for t in toks if t.type == tokenize.NAME}


def generate(module, owner, text=None):
    """The module's text (its file's, or `text`) with its block rewritten from the owner's
    consts."""
    text = _path(module).read_text() if text is None else text
    before, _, after = _split(text, module, owner)
    code = _without_blocks(before + after)
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
    texts = {}
    for module, owner in COPIES:
        texts[module] = generate(module, owner, texts.get(module))
    for module, text in texts.items():
        _check_once(module, text)
    return {_path(module): text for module, text in texts.items()}


def _check_once(module, text):
    """A name in two owners' blocks would be defined twice, maybe with two values."""
    seen = set()
    for line in text.splitlines():
        m = _INT_CONST.match(line)
        if m:
            if m.group(1) in seen:
                raise CopyError(f"{_file(module)}: {m.group(1)} is defined twice")
            seen.add(m.group(1))
