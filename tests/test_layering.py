"""Imports run down the layers only. Bottom up:

    firmware/       the board's code: imports nothing of the PC side
    common/         errors, the kernels' builds, the firmware on CPython, the byte formats
    tools/          the board tools: image, flash (deploy, config), monitor
    host_emulator/  devices and inputs, the model, runtimes, evaluation, replay, sessions and
                    the virtual board, benchmarks, the command line

A module may import its own unit (the longest prefix of its name in LAYERS) and units on a
lower layer, never one on its own layer or above; every module of ours must fall in a unit.
Imports inside functions count; tests may import anything."""

import ast

from common.firmware_env import REPO_DIR

# unit (module name prefix) -> layer
LAYERS = {
    "common.errors": 0,
    "common.toolchain": 0,
    "common.progress": 0,  # progress lines that fit the terminal
    "common.native": 1,  # the kernels' builds and their bindings
    "common.firmware_env": 2,  # navk on CPython is the cffi build
    "common.proto": 3,  # the configuration codec is the firmware's own
    "common.native.layout": 4,  # the headers (and the copies), from the firmware's Python
    "common.native.const_copies": 3,  # the consts firmware modules repeat, from the owner
    "common": 5,  # the package's docstring
    "tools.image": 10,
    "tools.flash": 11,  # deploys an image
    "tools.monitor": 12,  # joins a board through tools.flash's maintenance start
    "tools": 13,
    "host_emulator.emulated_board": 20,
    "host_emulator.f411": 20,
    "host_emulator.display": 20,
    "host_emulator.sim": 20,
    "host_emulator.model": 21,
    "host_emulator.runtimes": 22,
    "host_emulator.args": 23,
    "host_emulator.eval": 24,
    "host_emulator.replay": 25,
    "host_emulator.session": 26,
    "host_emulator.virtual_board": 26,
    "host_emulator.bench": 27,
    "host_emulator": 28,  # __main__, the command line
}
OURS = ("common", "tools", "host_emulator")


def unit(module):
    parts = module.split(".")
    for n in range(len(parts), 0, -1):
        name = ".".join(parts[:n])
        if name in LAYERS:
            return name
    return None


def module_name(path):
    parts = list(path.relative_to(REPO_DIR).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports(text):
    """The modules of ours a module's source imports, at any depth of its code."""
    out = set()
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.update(f"{node.module}.{a.name}" for a in node.names)
    return {m for m in out if m.split(".")[0] in OURS}


def sources(*tops):
    """(module name, source text) of every module under the top directories."""
    for top in tops:
        for p in sorted((REPO_DIR / top).rglob("*.py")):
            if "__pycache__" not in p.parts:
                yield module_name(p), p.read_text()


def upward(modules):
    """'module -> imported (why)' for every import that does not run down."""
    bad = []
    for me, text in modules:
        mine = unit(me)
        if mine is None:
            bad.append(f"{me}: in no unit of LAYERS")
            continue
        for target in sorted(imports(text)):
            theirs = unit(target)
            if theirs is None:
                bad.append(f"{me} -> {target}: in no unit of LAYERS")
            elif theirs != mine and LAYERS[theirs] >= LAYERS[mine]:
                bad.append(f"{me} -> {target} (layer {LAYERS[mine]} -> {LAYERS[theirs]})")
    return bad


def test_imports_run_down_the_layers():
    assert upward(sources("common", "tools", "host_emulator")) == []


def test_the_firmware_imports_nothing_of_the_pc_side():
    leaks = [f"{m}: {sorted(imports(t))}" for m, t in sources("firmware") if imports(t)]
    assert leaks == []


def test_an_upward_import_is_reported():
    probe = ("common.proto.probe", "def late():\n    from host_emulator.sim import gnss\n")
    stray = ("scripts.probe", "import common.errors\n")
    same = ("host_emulator.session.probe", "from host_emulator.virtual_board import x\n")
    assert upward([probe, stray, same]) == [
        "common.proto.probe -> host_emulator.sim.gnss (layer 3 -> 20)",
        "scripts.probe: in no unit of LAYERS",
        "host_emulator.session.probe -> host_emulator.virtual_board.x (layer 26 -> 26)",
    ]
