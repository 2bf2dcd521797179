"""Commands that only read leave a running board alone where they can, against the virtual
board with its firmware running: a bad `deploy --set` is refused before the port is opened, and
the monitor's `--board-port` without `--record` is refused before it stops anything (the
firmware's run count and the board's resets stay put, frames keep coming). `config get` and
`deploy --dry-run` must read a file through the raw REPL, which a running firmware does not
serve (docs/deploy.md): they say so first, then stop it and restart it."""

import pytest

from tools.flash import deploy
from tools.flash.__main__ import main as flash_main
from tools.monitor.cli import main as monitor_main

virtual_board = pytest.importorskip("host_emulator.virtual_board")


def _quiet(_line):
    pass


@pytest.fixture(scope="module")
def board(tmp_path_factory, flash_build_dir):
    """The virtual board, the firmware deployed and running in real time."""
    fs = tmp_path_factory.mktemp("board") / "flash"
    with virtual_board.VirtualBoard(fs, realtime=True, duration_s=600.0) as vb:
        deploy.deploy(flash_build_dir, vb.port, log=_quiet)
        yield vb


def _state(vb):
    return vb.firmware_runs, vb.resets, vb.maintenance_starts


def _still_running(vb, before):
    assert _state(vb) == before
    assert deploy.count_frames(vb.rs485_port, 460800, seconds=2.0) >= 3


def test_a_bad_deploy_set_is_refused_before_the_board_is_touched(board, capsys):
    before = _state(board)
    assert flash_main(["deploy", "--port", board.port, "--set", "gyro_range_dps=7"]) == 1
    err = capsys.readouterr().err
    assert err == (
        "error: invalid setting: gyro_range_dps must be one of (125, 250, 500, 1000, 2000). "
        "Nothing was written.\n"
    )
    _still_running(board, before)


def test_monitor_board_port_without_record_is_refused_before_stopping_it(board, capsys):
    before = _state(board)
    with pytest.raises(SystemExit) as e:
        monitor_main(["--port", board.rs485_port, "--board-port", board.port, "--duration", "1"])
    assert e.value.code == 2
    assert "--board-port is for --record" in capsys.readouterr().err
    _still_running(board, before)


def test_config_get_says_it_stops_the_firmware_before_it_does(board, capsys):
    runs = board.firmware_runs
    assert flash_main(["config", "get", "--port", board.port]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0] == (
        f"note: to read /flash/ins.cfg, the firmware on {board.port} stops (Ctrl-C: the raw "
        "REPL) and is restarted after (it aligns again)"
    )
    assert any("resetting the board" in line for line in err[1:])  # after the note
    assert board.firmware_runs > runs  # restarted, as the note said: frames come again
    assert deploy.count_frames(board.rs485_port, 460800, seconds=3.0) >= 3


def test_deploy_dry_run_says_it_stops_the_firmware_before_it_does(board, capsys):
    runs = board.firmware_runs
    assert flash_main(["deploy", "--port", board.port, "--dry-run"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"note: to compare its files, the firmware on {board.port} stops")
    assert out[-1].startswith("dry run: nothing written; the firmware was stopped")
    assert board.firmware_runs > runs
    assert deploy.count_frames(board.rs485_port, 460800, seconds=3.0) >= 3
