"""How each runtime gives the firmware its kernels: native (`import navk` finds the build for that
runtime; the default) or python (`import navk` raises ImportError, kern.py falls back), and the
clear error when native is asked for and cannot be built.

    CPython   firmware_env.use_kernels(kind) (INS_KERNELS=python for a whole process); the
              cpython runtime's run(..., kernels=...) calls it, re-importing the firmware
    unix VM   MICROPYPATH: the x64 navk.mpy's directory, or nothing (mpy_unix/vm.py env())
    M4F       /flash/lib/navk.mpy on the guest's FAT RAM disk (armv7emsp), or no file
    CLI       run / replay / parity --kernels native|python
"""

import importlib
import sys

import numpy as np
import pytest

from common import firmware_env, native
from common.errors import EmulatorError
from common.firmware_env import navk_host
from host_emulator import __main__ as cli
from host_emulator import runtimes
from host_emulator.eval import parity
from host_emulator.runtimes import cpython
from host_emulator.runtimes.m4f import guest
from host_emulator.runtimes.mpy_unix import vm
from host_emulator.sim import board_input


@pytest.fixture
def restore_kernels():
    before = firmware_env.kernels()
    yield
    firmware_env.use_kernels(before)


def test_cpython_switches_between_native_and_python(restore_kernels):
    assert firmware_env.use_kernels("python") == "python"
    with pytest.raises(ImportError):
        import navk  # noqa: F401
    kern = importlib.import_module("kern")
    assert not kern.NATIVE and "kernels: Python" in kern.describe()
    assert firmware_env.use_kernels("native") == "native"
    assert "kern" not in sys.modules  # the firmware is imported afresh under the new choice
    import navk

    assert navk is navk_host.load() and navk.abi() == importlib.import_module("kern").ABI
    kern = importlib.import_module("kern")
    assert kern.NATIVE
    kept = sys.modules["kern"]
    firmware_env.use_kernels("native")  # no change: nothing re-imported
    assert sys.modules["kern"] is kept
    with pytest.raises(ValueError, match="native or python"):
        firmware_env.use_kernels("fortran")


def test_the_process_default_comes_from_the_environment(monkeypatch):
    monkeypatch.setenv("INS_KERNELS", "python")
    assert firmware_env.default_kernels() == "python" and runtimes.default_kernels() == "python"
    monkeypatch.setenv("INS_KERNELS", "fast")
    with pytest.raises(EmulatorError, match="INS_KERNELS"):
        runtimes.default_kernels()
    monkeypatch.delenv("INS_KERNELS")
    assert runtimes.default_kernels() == "native"


def test_the_cpython_runtime_runs_both_and_they_agree(tmp_path, restore_kernels):
    """One process, both kernels, one after the other: the same frames, bit for bit."""
    stim = board_input.simulate("quick_start", 16.0, seed=0).stimulus
    nat = cpython.run(stim, tmp_path / "n", kernels="native")
    py = cpython.run(stim, tmp_path / "p", kernels="python")
    assert nat.stats["kernels"] == "native" and py.stats["kernels"] == "python"
    assert any("kernels: native" in line for line in nat.console)
    assert any("kernels: Python" in line for line in py.console)
    assert nat.out == py.out and len(nat.out) > 0


def test_a_native_build_that_cannot_be_made_is_a_clear_error(tmp_path, monkeypatch):
    """No C compiler: the run stops saying which package to install (never a silent fallback
    to the Python kernels)."""
    which = native.shutil.which
    monkeypatch.setattr(native.shutil, "which", lambda t: None if "gcc" in t else which(t))
    monkeypatch.setattr(runtimes, "_built", {})
    stim = board_input.simulate("quick_start", 2.0, seed=0).stimulus
    with pytest.raises(EmulatorError, match="gcc not found: install Debian's gcc"):
        runtimes.get("mpy_unix").run(stim, tmp_path / "vm", kernels="native")
    with pytest.raises(EmulatorError, match="gcc-arm-none-eabi"):
        runtimes.get("m4f").run(stim, tmp_path / "m4f", kernels="native")
    monkeypatch.setattr(navk_host, "_module", None)
    monkeypatch.setattr(native, "cffi_dir", lambda *a: tmp_path / "nothing-cached")
    with pytest.raises(EmulatorError, match="CPython.*gcc not found"):
        cpython.run(stim, tmp_path / "cp", kernels="native")
    # the command line says it in one line, exit status 1
    monkeypatch.setattr(sys, "argv", ["x"])
    rc = cli.main(["run", "--stimulus", str(_write(stim, tmp_path)), "--runtime", "mpy_unix",
                   "--kernels", "native", "--out", str(tmp_path / "out"), "--quiet"])  # fmt: skip
    assert rc == 1


def _write(stim, tmp_path):
    p = tmp_path / "stim.bin"
    stim.write(p)
    return p


def test_the_model_has_no_kernels(tmp_path):
    stim = board_input.simulate("quick_start", 2.0, seed=0).stimulus
    with pytest.raises(EmulatorError, match="model runtime has no kernels"):
        runtimes.get("model").run(stim, tmp_path, kernels="native")
    with pytest.raises(EmulatorError, match="unknown kernels"):
        runtimes.get("cpython").run(stim, tmp_path, kernels="asm")


def test_the_vm_finds_navk_only_when_native():
    probe = (
        "try:\n    import navk\n    print('N', navk.abi())\nexcept ImportError:\n    print('P')\n"
    )
    assert vm.run(probe, kernels="python").split() == ["P"]
    assert vm.run(probe, kernels="native").split()[0] == "N"
    env = vm.env("python")
    assert env["MICROPYPATH"] == f".frozen:{vm.SHARED_DIR}"  # no navk there
    assert vm.env("native")["MICROPYPATH"].startswith(str(native.natmod_dir("x64")))


def test_the_m4f_finds_navk_in_flash_lib_only_when_native():
    probe = (
        "import sys\nprint('PATH', sys.path)\n"
        "try:\n    import navk\n    print('N', navk.abi(), navk.__file__)\n"
        "except ImportError:\n    print('P')\n"
    )
    out = guest.run(probe, kernels="python")
    assert "'/flash/lib'" in out and out.split()[-1] == "P"
    out = guest.run(probe, kernels="native")
    assert out.split()[-1] == "/flash/lib/navk.mpy"


def test_the_command_lines_take_kernels(capsys):
    with pytest.raises(SystemExit):
        cli.main(["run", "--scenario", "quick_start", "--out", "x", "--kernels", "asm"])
    assert "invalid choice: 'asm'" in capsys.readouterr().err
    assert parity.main(["--scenario", "quick_start", "--duration", "2", "--kernels", "c"]) == 2
    assert "--kernels" in capsys.readouterr().err


def test_numpy_scalar_ints_pass():
    navk = navk_host.load()
    o, a = np.zeros(3, np.float32), np.ones(3, np.float32)
    navk.add(o, a, a, np.int32(3))
    assert list(o) == [2, 2, 2]
