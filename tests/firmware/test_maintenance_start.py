"""firmware/main.py's maintenance start (board.maintenance_start: the board tools' marker in
the RTC backup register BKP18R) and the 50 ms watchdog, on CPython with the firmware's own
board.py over the emulated `machine` and a stand-in for the stm32 port's `stm.mem32` with the
chip's rule for the backup domain (a write while PWR_CR.DBP is clear is ignored). The image
itself reads the register on the emulated STM32F411: tests/runtimes/test_f411_maintenance.py."""

import importlib
import sys
import types

import pytest

from common.firmware_env import FIRMWARE_DIR
from host_emulator.emulated_board import install_machine

BKP18R, PWR_CR, DBP, APB1ENR, PWREN = 0x40002898, 0x40007000, 0x100, 0x40023840, 1 << 28
ASKED, ON = 0x2D4D4E54, 0x2D4D4E4F  # tools/flash/maintenance.py (test_maintenance.py)
LINE = (
    "ins: maintenance start (asked by the board tools): loop and watchdog off; Ctrl-D or a "
    "reset starts the firmware"
)


class Mem32:
    """stm.mem32 over BKP18R, PWR_CR and RCC_APB1ENR; `writes` lists (address, value)."""

    def __init__(self, bkp=0, pwr_cr=0x8000, apb1enr=0):
        self.regs = {BKP18R: bkp, PWR_CR: pwr_cr, APB1ENR: apb1enr}
        self.writes = []

    def __getitem__(self, addr):
        return self.regs[addr]

    def __setitem__(self, addr, value):
        self.writes.append((addr, value))
        if addr == BKP18R and not self.regs[PWR_CR] & DBP:
            return  # the backup domain is write-protected
        if addr == PWR_CR and not self.regs[APB1ENR] & PWREN:
            return  # the PWR clock is off
        self.regs[addr] = value


@pytest.fixture
def board():
    machine = install_machine()
    machine.power_on()
    import board

    return importlib.reload(board)


def test_the_marker_makes_a_maintenance_start_and_is_answered(board, capsys):
    mem = Mem32(ASKED)
    assert board.maintenance_start(mem) is True
    assert capsys.readouterr().out == LINE + "\n"  # the console says so, in one line
    # backup-domain access first (PWR clock, DBP), then the answer the tools read back
    assert [a for a, _ in mem.writes] == [APB1ENR, PWR_CR, BKP18R]
    assert mem.regs[BKP18R] == ON and mem.regs[PWR_CR] & DBP


@pytest.mark.parametrize("left", [ON, 0x12345678, ASKED + 1])
def test_a_normal_start_clears_what_the_register_holds(board, left, capsys):
    """The start after a maintenance one (ON), or any value: a normal start that clears it,
    so that a later reset starts normally as well."""
    mem = Mem32(left)
    assert board.maintenance_start(mem) is False
    assert mem.regs[BKP18R] == 0 and capsys.readouterr().out == ""


def test_a_clear_register_is_a_normal_start_that_writes_nothing(board):
    mem = Mem32(0)
    assert board.maintenance_start(mem) is False and mem.writes == []


def test_without_the_stm_module_no_start_is_a_maintenance_one(board, monkeypatch):
    monkeypatch.setitem(sys.modules, "stm", None)  # `import stm` raises ImportError
    assert board.maintenance_start() is False


def test_main_py_in_maintenance_starts_neither_the_loop_nor_the_watchdog(
    board, monkeypatch, capsys
):
    """main.py with the marker set: one console line that says so and how to leave, then the
    REPL (main() returns): no App, no timer, no watchdog."""
    machine = sys.modules["machine"]
    mem = Mem32(ASKED)
    monkeypatch.setitem(sys.modules, "stm", types.SimpleNamespace(mem32=mem))
    monkeypatch.setitem(sys.modules, "app", None)  # importing app would raise ImportError
    exec(compile((FIRMWARE_DIR / "main.py").read_text(), "main.py", "exec"), {})
    out = capsys.readouterr().out
    assert out.splitlines() == [LINE]
    assert "maintenance" in out and "loop and watchdog off" in out
    assert "Ctrl-D or a reset starts the firmware" in out
    assert machine.watchdog is None and machine._timers == []
    assert mem.regs[BKP18R] == ON


def test_the_watchdog_is_50_ms_and_what_derives_from_it(board):
    """50 ms (docs/requirements.md, NFR005): the port takes it (IWDG_PR 0, LSI / 4, and RLR 399:
    50.0 ms at the LSI's 32 kHz), the loop catches up at most that many ticks, the stopped loop's
    timer feeds it four times per timeout."""
    import app

    machine = sys.modules["machine"]
    assert board.WDT_TIMEOUT_MS == 50
    assert app._CATCH_UP_MAX == board.WDT_TIMEOUT_MS * board.TICK_HZ // 1000 == 10
    assert board.WDT_TIMEOUT_MS // (1000 // board._FEED_HZ) == 4
    b = board.Board()
    b.start_watchdog()
    assert machine.watchdog.timeout_ms == 50
