"""Where the image's bytes go: `python -m tools.image sizes [--board B]` (docs/image.md).

Read from what the last build of the board left in build/image/<board>/obj (make image first):

- the code region by object file: every input section the link kept at an address of the code
  region (FLASH_TEXT of the linker map), summed per object (`py/compile.o`, `frozen_content.o`,
  a HAL file...): what each part of MicroPython costs;
- the frozen firmware module by module: the symbols of frozen_content.o (sized by
  arm-none-eabi-nm) that frozen_content.c defines under each `// frozen module NAME` marker,
  and the rest (its qstr pool, the module-name list) shared;
- the module table (genhdr/moduledefs.h): the built-in modules the image carries.

`--save FILE` keeps the figures as JSON; `--against FILE` prints the difference from such a
file per object and per frozen module: what a change gave, with the build before it saved.
"""

import collections
import json
import re

from tools.image import budget

NM = budget.NM
SHARED = "(shared: qstr pool, names)"


def code_objects(map_text, lo, hi):
    """{object: bytes} of the input sections the link placed in [lo, hi)."""
    start = map_text.find("Linker script and memory map")
    end = map_text.find("Cross Reference Table")
    body = map_text[start : end if end > 0 else None]
    pattern = re.compile(
        r"^\s*(?:\S+\s+)?0x([0-9a-fA-F]+)\s+0x([0-9a-fA-F]+)\s+(\S+\.o|\S+\.a\(\S+\))$",
        re.MULTILINE,
    )
    out = collections.Counter()
    for m in pattern.finditer(body):
        addr, size = int(m.group(1), 16), int(m.group(2), 16)
        if lo <= addr < hi and size:
            name = m.group(3)
            name = name.split("/obj/", 1)[1] if "/obj/" in name else name.rsplit("/", 1)[-1]
            out[name] += size
    return dict(out)


def frozen_modules(c_text, nm_text, total):
    """{frozen module: bytes} from frozen_content.c's markers: the symbols defined under a
    module's marker (sized by nm) and the bytes of its string and bytes constants (in the
    object's merged string section, which has no symbols); the rest of `total` (what the link
    kept of frozen_content.o) is shared: the qstr pool and its strings, the module names."""
    owner = {}
    out = collections.Counter()
    mod = None
    for line in c_text.splitlines():
        m = re.match(r"// frozen module (\S+)", line)
        if m:
            mod = m.group(1)
            continue
        m = re.match(r"^(?:static )?(?:const )?[\w\s]*?\b(\w+)(?:\[\w*\])?\s*=", line)
        if mod and m:
            owner[m.group(1)] = mod
            s = re.search(r"\{\{&mp_type_(?:str|bytes)\}, \d+, (\d+), \(const byte\*\)", line)
            if s:
                out[mod] += int(s.group(1)) + 1
    for line in nm_text.splitlines():
        p = line.split()
        if len(p) == 4 and p[1].isdigit() and p[3].split(".")[0] in owner:
            out[owner[p[3].split(".")[0]]] += int(p[1])
    out[SHARED] = total - sum(out.values())
    return dict(out)


def module_table(header_text):
    """The built-in modules of genhdr/moduledefs.h, sorted."""
    return sorted(set(re.findall(r"MP_ROM_QSTR\(MP_QSTR_(\w+)\)", header_text)))


def measure(obj):
    """The figures of the build in obj/ (a dict)."""
    map_text = (obj / "firmware.map").read_text(errors="replace")
    regions = budget.memory_regions(map_text)
    lo, n = regions["FLASH_TEXT"]
    nm = budget._run([NM, "-S", "-t", "d", str(obj / "frozen_content.o")])
    defs = obj / "genhdr" / "moduledefs.h"
    objects = code_objects(map_text, lo, lo + n)
    return {
        "code_region": [lo, n],
        "objects": objects,
        "frozen": frozen_modules(
            (obj / "frozen_content.c").read_text(), nm, objects.get("frozen_content.o", 0)
        ),  # fmt: skip
        "modules": module_table(defs.read_text()) if defs.is_file() else [],
    }


def _table(counts, top, against=None):
    lines = []
    keys = sorted(counts.keys() | (against or {}).keys(),
                  key=lambda k: (-abs(counts.get(k, 0) - (against or {}).get(k, 0))
                                 if against is not None else -counts.get(k, 0), k))  # fmt: skip
    shown = 0
    for k in keys:
        now = counts.get(k, 0)
        if against is not None:
            d = now - against.get(k, 0)
            if not d:
                continue
            lines.append(f"  {d:+9,} {now:9,}  {k}")
        else:
            lines.append(f"  {now:9,}  {k}")
        shown += 1
        if top and shown >= top:
            break
    return lines


def report(fig, top=40, against=None):
    """The figures as printed lines (differences from `against` when given)."""
    objs, frozen = fig["objects"], fig["frozen"]
    total = sum(objs.values())
    lines = [f"code region from 0x{fig['code_region'][0]:08X}: {total:,} B in input sections"]
    if against is None:
        lines.append(f"by object file (the {top} largest):")
        lines += _table(objs, top)
        lines.append(f"frozen firmware by module ({sum(frozen.values()):,} B):")
        lines += _table(frozen, 0)
        lines.append(f"built-in modules ({len(fig['modules'])}): " + " ".join(fig["modules"]))
        return lines
    before = sum(against["objects"].values())
    lines.append(f"against the saved build: {total - before:+,} B ({before:,} before)")
    lines.append("by object file (change, now):")
    lines += _table(objs, top, against["objects"])
    lines.append("frozen firmware by module (change, now):")
    lines += _table(frozen, 0, against["frozen"])
    gone = sorted(set(against["modules"]) - set(fig["modules"]))
    new = sorted(set(fig["modules"]) - set(against["modules"]))
    lines.append("built-in modules left out: " + (" ".join(gone) or "none")
                 + ("; added: " + " ".join(new) if new else ""))  # fmt: skip
    return lines


def main(board, top=40, save=None, against=None, log=print):
    from tools.image import build

    obj = build.BUILD_ROOT / board / "obj"
    if not (obj / "firmware.map").is_file() or not (obj / "frozen_content.c").is_file():
        raise build.ImageError(f"no build of {board} in {obj}: run `make image BOARD={board}` "
                               "first")  # fmt: skip
    fig = measure(obj)
    old = None
    if against:
        try:
            old = json.loads(open(against).read())
        except (OSError, ValueError) as e:
            raise build.ImageError(f"cannot read {against} ({e}): give a file that `--save` "
                                   "wrote") from None  # fmt: skip
    for line in report(fig, top, old):
        log(line)
    if save:
        with open(save, "w") as f:
            json.dump(fig, f, indent=1)
            f.write("\n")
        log(f"saved to {save}")
    return fig
