"""Fixtures of the emulated STM32F411's tests: bare-metal programs (programs.c) compiled with
Debian's arm-none-eabi-gcc (never skipped: without it the tests fail, as CI must), and a chip
that runs one."""

import pathlib
import subprocess

import pytest

from common import toolchain
from host_emulator.f411 import boards
from host_emulator.f411.chip import F411
from host_emulator.f411.image import Image

HERE = pathlib.Path(__file__).parent
_built = {}


def build_program(name, out_dir):
    """programs.c with -DPROGRAM_<name>: (bin, elf) paths."""
    if name in _built:
        return _built[name]
    toolchain.ensure()
    tree = toolchain.micropython_dir()
    elf = out_dir / f"{name}.elf"
    binf = out_dir / f"{name}.bin"
    cmd = [
        "arm-none-eabi-gcc", "-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16",
        "-mfloat-abi=hard", "-O1", "-g0", "-ffreestanding", "-nostdlib", "-nostartfiles",
        "-DSTM32F411xE", f"-DPROGRAM_{name}", f"-I{tree / 'lib' / 'cmsis' / 'inc'}",
        f"-I{tree / 'lib' / 'stm32lib' / 'CMSIS' / 'STM32F4xx' / 'Include'}",
        "-T", str(HERE / "programs.ld"), "-o", str(elf), str(HERE / "programs.c"),
    ]  # fmt: skip
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    subprocess.run(["arm-none-eabi-objcopy", "-O", "binary", str(elf), str(binf)], check=True)
    _built[name] = (binf, elf)
    return _built[name]


@pytest.fixture(scope="session")
def programs_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("f411-programs")


@pytest.fixture
def chip_for(programs_dir):
    """chip_for(name) -> an F411 (NUCLEO wiring) reset into program `name`."""

    def make(name, board="NUCLEO_F411RE"):
        binf, elf = build_program(name, programs_dir)
        return F411(boards.get(board), Image(binf, elf))

    return make


def word(chip, name, index=0):
    """A 32-bit global of the program (data[index], result, ...)."""
    addr = chip.image.address(name)
    return chip.read_word(addr + 4 * index)


def run_until_done(chip, limit_ms=100):
    """Run until the program sets `done` (or the limit of board time passes)."""
    addr = chip.image.address("done")
    end = chip.clock.now() + chip.clock.cycles_for_us(limit_ms * 1000)
    while chip.clock.now() < end:
        chip.run(min(end, chip.clock.now() + chip.clock.cycles_for_us(1000)),
                 lambda: chip.read_word(addr) != 0)  # fmt: skip
        if chip.read_word(addr):
            return True
    return False
