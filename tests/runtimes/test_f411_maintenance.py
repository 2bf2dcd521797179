"""The 50 ms watchdog and the maintenance start on the image itself: the NUCLEO-F411RE image
(its REPL is USART2, which the emulated STM32F411 models) with deploy's files on its
filesystem, its console a serial port the board tools open (runtimes/f411/console.py).

- `config set` and `config get` (tools/flash) end to end: Ctrl-C, the marker in RTC_BKP18R,
  machine.reset() (SYSRESETREQ), main.py's maintenance start (its line; neither the loop nor
  the watchdog), the file written (a 16 KB sector erased: the core stalled 250 ms), a soft
  reset, the firmware running again with its watchdog, and no watchdog reset at all;
- the same write the old way, after Ctrl-C with the watchdog running and fed by the stopped
  loop's timer: the erase outlasts the 50 ms and the watchdog resets the board;
- the stopped loop's timer keeps the watchdog fed (every 12 ms), also after a second Ctrl-C;
- a soft reset (Ctrl-D) of a board whose watchdog runs ends in a watchdog reset: the
  firmware's start-up outlasts 50 ms (why the tools restart from a maintenance start);
- the console's read waits in board time: a host too loaded to emulate a second in a second
  still hears the board's answer (the tools' exchanges failed that way under a loaded CI)."""

import pytest

from common.proto import config as board_config
from host_emulator.runtimes.f411.console import TwinBoard
from tools.flash import deploy
from tools.flash import maintenance as maint
from tools.flash.errors import FlashError

BKP18R = 0x98  # RTC's register offset
SYSRESET = "SYSRESETREQ (NVIC_SystemReset)"


def _running(tmp_path, monkeypatch):
    """The image booted and its loop running (a few ticks in), its console the tools' port."""
    board = TwinBoard(workdir=tmp_path)
    assert board.run_until(b"ins: running", 5000), board.console_text()
    board.run_ms(300)
    monkeypatch.setattr(deploy, "open_port", lambda port, baud: board)
    monkeypatch.setattr(maint, "SETTLE_S", 0.0)
    return board


def _reasons(board):
    return [r for _, r in board.chip.resets]


def _ms(board, cycles):
    return cycles * 1000 / board.clock.hz


def test_config_set_and_get_go_through_a_maintenance_start(tmp_path, monkeypatch):
    board = _running(tmp_path, monkeypatch)
    chip = board.chip
    assert chip.iwdg.running and chip.iwdg.timeout_ms() == 50.0
    new = board_config.to_bytes({"output_every_ticks": 2})
    lines = []
    erases = chip.flash_if.erases
    deploy.write_config("twin", 115200, new, log=lines.append)
    text = board.console_text()
    assert "ins: maintenance start (asked by the board tools): loop and watchdog off; " \
           "Ctrl-D or a reset starts the firmware" in text  # fmt: skip
    assert "the board restarted in maintenance: loop and watchdog off" in lines
    # one system reset, no watchdog reset, though the write erased flash (the core stalled)
    assert _reasons(board) == [SYSRESET]
    assert chip.flash_if.erases > erases
    # the soft reset started the firmware normally: its loop, its watchdog, the marker gone
    at = text.index("ins: maintenance start")
    assert board.run_until(b"ins: running", 5000, since=at)
    board.run_ms(500)
    assert "MPY: soft reboot" in board.console_text()[at:]
    assert chip.rtc.v[BKP18R] == 0
    assert chip.iwdg.running and chip.iwdg.margin()[0] < 12.5
    assert _reasons(board) == [SYSRESET]
    # and config get reads it back, through a maintenance start of its own
    assert deploy.read_config("twin", 115200, log=lines.append) == new
    assert _reasons(board) == [SYSRESET, SYSRESET]
    assert board.run_until(b"ins: running", 5000)


def test_a_flash_write_under_the_running_watchdog_resets_the_board(tmp_path, monkeypatch):
    """The old way (no maintenance start): Ctrl-C stops the loop, a timer feeds the watchdog
    every 12 ms, and it does for as long as nothing stalls the core; a file write erases a
    16 KB sector (250 ms of stalled core, the timer's interrupt too): the watchdog resets the
    board in the middle of it, the sector erased and not written back (what the board then
    holds depends on which sector that was, which depends on when the port's cache flushed:
    in trials the port found no filesystem at its next start and formatted it anew, main.py
    and ins.cfg gone, the board at the bare REPL; or it started the firmware again)."""
    board = _running(tmp_path, monkeypatch)
    chip = board.chip
    ser, repl = deploy.connect("twin", 115200, maintenance=False)
    assert b"ins: stopped" in repl.console
    board.run_ms(500)  # stopped: fed by the timer, no reset
    assert _reasons(board) == [] and _ms(board, chip.iwdg.longest_gap) < 25
    erases = chip.flash_if.erases
    with pytest.raises(FlashError, match="stopped responding while writing x.bin"):
        deploy.Board(repl).write("x.bin", bytes(600))
    assert _reasons(board) == ["IWDG"]
    assert chip.flash_if.erases > erases and _ms(board, chip.flash_if.stall_cycles) >= 250


def test_a_soft_reset_with_the_watchdog_running_ends_in_its_reset(tmp_path, monkeypatch):
    """Ctrl-C, then Ctrl-D: the soft reset stops the feeding timer and the firmware's start
    (the port's re-initialisation, main.py, the App) takes longer than 50 ms before it starts
    the watchdog again: the watchdog resets the board, which then starts normally. On a USB
    board its console leaves and comes back."""
    board = _running(tmp_path, monkeypatch)
    board.write(b"\r\x03")
    board.run_ms(100)
    board.write(b"\x03")  # the tools' second Ctrl-C: it must not cut App.stop short
    board.run_ms(200)
    assert _reasons(board) == []
    assert "ins: stopped" in board.console_text()
    board.write(b"\x04")
    assert board.run_until(b"ins: running", 5000)
    assert _reasons(board) == ["IWDG"]


def test_a_read_waits_in_the_boards_time_however_slow_the_host(tmp_path, monkeypatch):
    """A host so loaded that each look at its clock finds a second gone (a test run's parallel
    workers): a read with a 1 s timeout still waits for the board's answer to Ctrl-C, as long
    as the board takes to give it; the board's clock moved on by about that answer's time."""
    from host_emulator.runtimes.f411 import console

    board = _running(tmp_path, monkeypatch)
    host = iter(range(10**6))
    monkeypatch.setattr(console.time, "monotonic", lambda: float(next(host)))
    board._polled = console.time.monotonic()
    board.read(len(board._out))  # what the running firmware said so far
    t0 = board.clock.us()
    board.write(b"\r\x03")
    got = board.read(1)
    assert got != b""
    assert 0 < board.clock.us() - t0 < 1e6  # the answer's time, under the read's timeout
