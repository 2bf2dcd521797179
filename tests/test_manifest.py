"""firmware/manifest.py, the freeze list, read by MicroPython's own manifest runner
(tools/manifestfile.py of the vendored v1.28.0 tree; MICROPY_DIR= points at another checkout):
it lists every firmware file but main.py and the Python reference kernels (lib/nav_kern.py,
lib/yaw_gsf.py, drivers/gnss_kern.py: the board runs navk), under the names the board imports
them by; included with reference_kernels=True (the emulated Cortex-M4F's manifest) it lists
those too.
The firmware runs from that layout in the MicroPython VM with the native kernels and nothing
else on its path, and without them it says in one line why it cannot start."""

import importlib.util
import os
import shutil

import pytest

from common import native
from common.firmware_env import FIRMWARE_DIR, REPO_DIR, import_module
from host_emulator.runtimes.mpy_unix import vm as mpvm

MICROPY_DIR = os.environ.get("MICROPY_DIR") or str(REPO_DIR.parent / "shared/vendor/micropython")
REFERENCE_KERNELS = {"lib/nav_kern.py": "nav_kern.py", "lib/yaw_gsf.py": "yaw_gsf.py",
                     "drivers/gnss_kern.py": "drivers/gnss_kern.py"}  # fmt: skip


def _frozen(**options):
    """[(source path, frozen name)] of the manifest, as makemanifest.py would freeze them."""
    path = os.path.join(MICROPY_DIR, "tools", "manifestfile.py")
    assert os.path.exists(path), f"MicroPython's tools/manifestfile.py not found ({MICROPY_DIR})"
    spec = importlib.util.spec_from_file_location("manifestfile", path)
    mf = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mf)
    m = mf.ManifestFile(mf.MODE_FREEZE, {"MPY_DIR": MICROPY_DIR, "MPY_LIB_DIR": None})
    m.include(str(FIRMWARE_DIR / "manifest.py"), **options)
    return [(r.full_path, r.target_path) for r in m.files()]


@pytest.fixture(scope="module")
def frozen():
    return _frozen()


def _firmware_files():
    """{source path: frozen name} of every firmware file but main.py."""
    want = {}
    for p in FIRMWARE_DIR.rglob("*.py"):
        rel = p.relative_to(FIRMWARE_DIR).as_posix()
        if rel in ("main.py", "manifest.py") or "__pycache__" in rel:
            continue
        want[p.resolve().as_posix()] = rel.removeprefix("lib/")  # lib/ is on sys.path
    return want


def test_every_firmware_file_but_main_and_the_reference_kernels_is_frozen(frozen):
    want = _firmware_files()
    kernels = {(FIRMWARE_DIR / rel).resolve().as_posix() for rel in REFERENCE_KERNELS}
    got = {os.path.realpath(src): name for src, name in frozen}
    assert got == {src: name for src, name in want.items() if src not in kernels}
    assert len({name for _, name in frozen}) == len(frozen)  # no two modules one name
    # in an order of the manifest's, not the filesystem's (the order numbers the qstrs)
    names = [name for _, name in frozen]
    drivers = sorted(n for n in names if n.startswith("drivers/"))
    assert names == ["app.py", "board.py"] + drivers + sorted(set(names[2:]) - set(drivers))


def test_with_the_reference_kernels_every_firmware_file_but_main_is_frozen():
    got = {os.path.realpath(src): name for src, name in _frozen(reference_kernels=True)}
    assert got == _firmware_files()
    assert set(REFERENCE_KERNELS.values()) <= set(got.values())


def _layout(frozen, tmp_path):
    for src, name in frozen:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, tmp_path / name)


_START = (
    "import app, board, nav, config, records\nfrom drivers import bmi055, gnss\n"
    "n = nav.Navigator(__import__('navcfg').NavConfig('car'))\n"
    "print('ok', n.state, app.__name__, bmi055.__name__, __import__('kern').describe())\n"
)


def test_the_firmware_runs_from_the_frozen_layout_with_its_native_kernels(frozen, tmp_path):
    _layout(frozen, tmp_path)
    lib = native.natmod("x64").parent  # navk.mpy for the unix VM, where a board has lib/navk.mpy
    out = mpvm.run(f"import sys\nsys.path[:] = [{str(tmp_path)!r}, {str(lib)!r}]\n" + _START)
    want = f"ok 1 app drivers.bmi055 kernels: native (navk abi {import_module('kern').ABI})"
    assert out.strip().splitlines()[-1] == want


def test_without_navk_main_says_in_one_line_why_it_cannot_start(frozen, tmp_path):
    """A board whose /flash lacks lib/navk.mpy: no Python kernels to fall back to, so main.py
    prints one line and returns to the REPL (no traceback, no loop)."""
    _layout(frozen, tmp_path)
    (tmp_path / "main.py").write_text((FIRMWARE_DIR / "main.py").read_text())
    out = mpvm.run(
        f"import sys\nsys.path[:] = [{str(tmp_path)!r}]\n"
        "import board\nboard.maintenance_start = lambda: False\n"  # the VM has no RTC register
        "import main\nprint('back at the REPL')\n"
    )
    lines = out.strip().splitlines()
    assert lines == [
        "ins: cannot start: no kernels: navk not found, and this image carries no Python "
        "kernels (no module named 'gnss_kern'): put lib/navk.mpy on /flash (make deploy "
        "PORT=...)",
        "back at the REPL",
    ]
