"""The board tools' maintenance start (tools/flash/maintenance.py) against the scripted board
(tests/tools/fakeboard.py): every command that writes the board's filesystem or restarts it
after a read resets the board into a start with neither the loop nor the watchdog first (the
marker in RTC_BKP18R), writes only then, and ends with a soft reset that starts the firmware
normally; a USB board that leaves and comes back after the reset; a firmware older than the
marker, a board without firmware, one already in maintenance, one that never comes back. End
to end: the virtual board (test_flash_deploy.py) and the image on the emulated STM32F411
(tests/runtimes/test_f411_maintenance.py)."""

import ast

import pytest
from fakeboard import FakeSerial

from common.firmware_env import FIRMWARE_DIR
from tools.flash import deploy
from tools.flash import maintenance as maint
from tools.flash.errors import FlashError, NotResponding, TransferCorrupted

STOPPED = b"ins: stopped (Ctrl-D restarts it)"
CFG = b"INSC a configuration"


def _fake(monkeypatch, fs, **kw):
    kw.setdefault("on_ctrl_c", STOPPED)
    fake = FakeSerial(fs, **kw)

    def open_port(port, baud):
        if fake.gone():
            raise FlashError(f"no serial port {port}.")
        return fake

    monkeypatch.setattr(deploy, "open_port", open_port)
    monkeypatch.setattr(maint, "SETTLE_S", 0.0)
    return fake


def test_the_tools_marker_is_the_firmwares():
    """The tools carry their own copy of firmware/board.py's registers and values (they speak
    to whatever firmware the board runs): the same numbers."""
    tree = ast.parse((FIRMWARE_DIR / "board.py").read_text())
    values = {}
    for node in tree.body:
        if not (isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name)):
            continue
        v = node.value
        if isinstance(v, ast.Call) and getattr(v.func, "id", None) == "const":
            values[node.targets[0].id] = ast.literal_eval(v.args[0])
    tools = {
        "_RTC_BKP18R": maint.RTC_BKP18R,
        "_PWR_CR": maint.PWR_CR,
        "_DBP": maint.DBP,
        "_RCC_APB1ENR": maint.RCC_APB1ENR,
        "_PWREN": maint.PWREN,
        "_MAINT_ASKED": maint.MAINTENANCE_ASKED,
        "_MAINT_ON": maint.MAINTENANCE_ON,
    }
    assert {k: values[k] for k in tools} == tools
    assert maint.RTC_BKP18R == 0x40002800 + 0x50 + 4 * 18  # RM0383: RTC_BKP0R at +0x50
    assert (maint.DBP, maint.PWREN) == (1 << 8, 1 << 28)


def test_config_set_writes_in_maintenance_and_restarts_the_firmware(tmp_path, monkeypatch):
    fake = _fake(monkeypatch, tmp_path, firmware="maintenance")
    lines = []
    deploy.write_config("/dev/fake", 115200, CFG, log=lines.append)
    assert (tmp_path / "ins.cfg").read_bytes() == CFG
    # one reset into maintenance, the write there, then a soft reset: the firmware again
    assert fake.events == [
        ("reset", "maintenance"),
        ("write", "/flash/ins.cfg", "maintenance"),
        ("soft reset", "firmware"),
    ]
    assert fake.backup[18] == 0  # the normal start cleared the marker: a reset starts it too
    assert "resetting the board on /dev/fake into maintenance" in lines[0]
    assert lines[1] == "the board restarted in maintenance: loop and watchdog off"
    # the code that asked: backup-domain access first, then the marker, then the reset
    ask = next(c for c in fake.received if b"machine.reset()" in c).decode()
    assert ask.index("0x40023840") < ask.index("0x40007000") < ask.index("0x40002898")
    assert f"= {maint.MAINTENANCE_ASKED:#x}\nmachine.reset()" in ask


def test_config_get_reads_in_maintenance_and_restarts(tmp_path, monkeypatch):
    (tmp_path / "ins.cfg").write_bytes(CFG)
    fake = _fake(monkeypatch, tmp_path, firmware="maintenance")
    assert deploy.read_config("/dev/fake", 115200, log=lambda _line: None) == CFG
    assert fake.events == [("reset", "maintenance"), ("soft reset", "firmware")]
    assert fake.mode == "running" and fake.backup[18] == 0


def test_a_usb_board_that_leaves_and_comes_back_after_the_reset(tmp_path, monkeypatch):
    """A USB port goes with the reset (before or after the run's acknowledgement) and comes
    back a second later: the tools wait for it, and what the board printed meanwhile is
    lost (a return brings the REPL's prompt)."""
    fake = _fake(monkeypatch, tmp_path, firmware="maintenance", vanish_s=1.0)
    deploy.write_config("/dev/fake", 115200, CFG, log=lambda _line: None)
    assert fake.events[:2] == [("reset", "maintenance"), ("write", "/flash/ins.cfg",
                                                          "maintenance")]  # fmt: skip
    assert fake.resets == 1 and (tmp_path / "ins.cfg").read_bytes() == CFG


def test_a_board_that_never_comes_back_says_what_to_do(tmp_path, monkeypatch):
    fake = _fake(monkeypatch, tmp_path, firmware="maintenance", vanish_s=60.0)
    monkeypatch.setattr(maint, "RESET_WAIT_S", 0.5)
    with pytest.raises(NotResponding, match="did not come back within 0.5 s of its reset"):
        deploy.write_config("/dev/fake", 115200, CFG, log=lambda _line: None)
    assert fake.written == []


def test_an_older_firmware_is_stopped_as_before_and_the_marker_cleared(tmp_path, monkeypatch):
    """A main.py that predates the marker starts its loop after the reset: Ctrl-C stops it
    again and the write goes on, with a warning; the marker does not stay behind to make the
    next firmware's start a maintenance one."""
    fake = _fake(monkeypatch, tmp_path, firmware="old")
    lines = []
    deploy.write_config("/dev/fake", 115200, CFG, log=lines.append)
    assert fake.events[:2] == [("reset", "firmware"), ("write", "/flash/ins.cfg", "firmware")]
    assert fake.backup[18] == 0
    assert any("older than this checkout's" in x and "watchdog runs on" in x for x in lines)


def test_a_board_without_firmware_is_written_after_its_reset(tmp_path, monkeypatch):
    fake = _fake(monkeypatch, tmp_path, firmware="none", on_ctrl_c=b"")
    lines = []
    deploy.write_config("/dev/fake", 115200, CFG, log=lines.append)
    assert fake.events[:2] == [("reset", "repl"), ("write", "/flash/ins.cfg", "repl")]
    assert fake.backup[18] == 0
    assert "the board restarted without starting a firmware (no main.py): no watchdog runs" in lines


def test_a_board_already_in_maintenance_is_not_reset_again(tmp_path, monkeypatch):
    fake = _fake(monkeypatch, tmp_path, firmware="maintenance", on_ctrl_c=b"")
    fake.backup[18] = maint.MAINTENANCE_ON
    fake.mode = "friendly"
    lines = []
    deploy.write_config("/dev/fake", 115200, CFG, log=lines.append)
    assert fake.resets == 0 and fake.events[0][:2] == ("write", "/flash/ins.cfg")
    assert "in maintenance (loop and watchdog off) from an earlier start" in lines[0]


def test_a_board_without_the_stm_module_is_not_reset(tmp_path, monkeypatch):
    """Not the stm32 port (no `stm`): no watchdog to stop, the session goes on at once."""
    fake = _fake(monkeypatch, tmp_path)  # firmware=None: no stm, no machine.reset
    deploy.write_config("/dev/fake", 115200, CFG, log=lambda _line: None)
    assert fake.resets == 0 and fake.written == ["/flash/ins.cfg"]


def test_a_dry_run_leaves_a_stopped_board_in_maintenance_and_says_so(
    tmp_path, monkeypatch, flash_build_dir
):
    """deploy --dry-run reads the board in maintenance: a firmware that was running starts
    again (a soft reset); one that was not stays in maintenance, which deploy says."""
    out = flash_build_dir
    fs = tmp_path / "flash"
    fs.mkdir()
    fake = _fake(monkeypatch, fs, firmware="maintenance")
    result = deploy.deploy(out, "/dev/fake", dry_run=True, log=lambda _line: None, watch_s=2)
    assert result["restarted"] and fake.events == [("reset", "maintenance"),
                                                   ("soft reset", "firmware")]  # fmt: skip
    fake = _fake(monkeypatch, fs, firmware="maintenance", on_ctrl_c=b"")
    fake.mode = "friendly"  # stopped earlier (Ctrl-C at the console)
    lines = []
    result = deploy.deploy(out, "/dev/fake", dry_run=True, log=lines.append, watch_s=2)
    assert not result["restarted"] and fake.events == [("reset", "maintenance")]
    assert "stays in maintenance (its firmware was not running): Ctrl-D or a reset" in lines[-1]


def test_code_that_arrives_corrupted_is_a_corrupted_attempt(tmp_path, monkeypatch):
    """A UART REPL (the NUCLEO's) loses the characters that come while a flash erase stalls
    the CPU, which the tools' writes set off: a file chunk that reaches the board as a
    SyntaxError is sent again, as a CRC-32 mismatch is; three in a row is a corrupted
    transfer, saying so. Found on the emulated STM32F411 (test_f411_maintenance.py)."""
    fake = _fake(monkeypatch, tmp_path, firmware="maintenance", lose_code=1)
    lines = []
    deploy.write_config("/dev/fake", 115200, CFG, log=lines.append)
    assert (tmp_path / "ins.cfg").read_bytes() == CFG
    assert "  ins.cfg: the code sent arrived corrupted (attempt 1)" in lines
    fake = _fake(monkeypatch, tmp_path, firmware="maintenance", lose_code=3)
    with pytest.raises(TransferCorrupted, match="after 3 attempts its code arrived corrupted"):
        deploy.write_config("/dev/fake", 115200, CFG, log=lambda _line: None)
    assert fake.lose_code == 0
