"""firmware/manifest.py, the freeze list, read by MicroPython's own manifest runner
(tools/manifestfile.py of the vendored v1.28.0 tree; MICROPY_DIR= points at another checkout):
it lists every firmware file but main.py, under the names the board imports them by, and the
firmware runs from that layout in the MicroPython VM with nothing else on its path."""

import importlib.util
import os
import shutil

import pytest

from common.firmware_env import FIRMWARE_DIR, REPO_DIR
from host_emulator.runtimes.mpy_unix import vm as mpvm

MICROPY_DIR = os.environ.get("MICROPY_DIR") or str(REPO_DIR.parent / "shared/vendor/micropython")


@pytest.fixture(scope="module")
def frozen():
    """[(source path, frozen name)] of the manifest, as makemanifest.py would freeze them."""
    path = os.path.join(MICROPY_DIR, "tools", "manifestfile.py")
    assert os.path.exists(path), f"MicroPython's tools/manifestfile.py not found ({MICROPY_DIR})"
    spec = importlib.util.spec_from_file_location("manifestfile", path)
    mf = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mf)
    m = mf.ManifestFile(mf.MODE_FREEZE, {"MPY_DIR": MICROPY_DIR, "MPY_LIB_DIR": None})
    m.execute(str(FIRMWARE_DIR / "manifest.py"))
    return [(r.full_path, r.target_path) for r in m.files()]


def test_every_firmware_file_but_main_is_frozen_under_its_import_name(frozen):
    want = {}
    for p in FIRMWARE_DIR.rglob("*.py"):
        rel = p.relative_to(FIRMWARE_DIR).as_posix()
        if rel in ("main.py", "manifest.py") or "__pycache__" in rel:
            continue
        want[p.resolve().as_posix()] = rel.removeprefix("lib/")  # lib/ is on sys.path
    got = {os.path.realpath(src): name for src, name in frozen}
    assert got == want
    assert len({name for _, name in frozen}) == len(frozen)  # no two modules one name


def test_the_firmware_runs_from_the_frozen_layout(frozen, tmp_path):
    for src, name in frozen:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, tmp_path / name)
    out = mpvm.run(
        f"import sys\nsys.path[:] = [{str(tmp_path)!r}]\n"
        "import app, board, nav, config, records\nfrom drivers import bmi055, gnss\n"
        "n = nav.Navigator(__import__('navcfg').NavConfig('car'))\n"
        "print('ok', n.state, app.__name__, bmi055.__name__)\n"
    )
    assert out.strip().splitlines()[-1] == "ok 1 app drivers.bmi055"
