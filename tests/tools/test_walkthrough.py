"""The README's board walk-through, end to end on the virtual board: deploy with raw_record on
(`make deploy SET=raw_record=1`), the console (`make console`), the monitor recording with the
board's REPL port given (`make monitor RECORD=run.ins BOARD_PORT=...`: the configuration and
which board it is go into the session, and the firmware restarts so that the recording holds
its start), then `session replay run.ins`, which picks the runtime of the board's arithmetic
and says "equal"."""

import io

import pytest

from common.proto import session_file
from host_emulator.session import cli as session_cli
from tools.flash.__main__ import main as flash_main
from tools.monitor import cli as monitor_cli

virtual_board = pytest.importorskip("host_emulator.virtual_board")


def test_deploy_record_and_replay_gives_equal(tmp_path, capsys):
    from console_pty import Console

    with virtual_board.VirtualBoard(tmp_path / "flash", realtime=True, duration_s=60.0) as vb:
        assert flash_main(["deploy", "--port", vb.port, "--set", "raw_record=1"]) == 0
        capsys.readouterr()
        with Console(vb.port) as c:  # `make console`: a look, and the firmware runs on
            assert c.ready(), bytes(c.seen)
            assert c.leave() == 0, bytes(c.seen)
        out, err = io.StringIO(), io.StringIO()
        argv = ["--port", vb.rs485_port, "--board-port", vb.port, "--record",
                str(tmp_path / "run.ins"), "--duration", "6", "--quiet"]  # fmt: skip
        assert monitor_cli.main(argv, out=out, err=err) == 0, err.getvalue()
        assert "its firmware restarts now" in err.getvalue()
    header = session_file.load(tmp_path / "run.ins").header
    assert header["config"]["raw_record"] == 1
    assert header["board"]["floats"] == "double"  # the virtual board's VM
    rc = session_cli.main(["replay", str(tmp_path / "run.ins")])
    cap = capsys.readouterr()
    text = cap.out
    assert rc == 0, text + cap.err
    assert "replayed on mpy_unix, the same VM" in text
    assert "REPLAY: identical" in text or "REPLAY: equal within the VM's tolerance" in text
    n = int(text.split("session: ")[1].split(" ticks")[0])
    assert n > 4 * 200, text  # seconds of the firmware from its start
