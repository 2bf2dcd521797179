"""The board's raw REPL through mpremote's transport (tools/flash/repl.py) against a scripted
board (tests/tools/fakeboard.py): getting past a running firmware, raw-paste with flow
control, the plain raw-mode fallback, board exceptions, silence and garbage, files."""

import time
import types

import pytest
from fakeboard import FakeSerial
from mpremote import transport_serial

from tools.flash import errors
from tools.flash.repl import BoardRepl


def _repl(ser, timeout=0.5):
    repl = BoardRepl(ser, timeout=timeout, port="/dev/fake")
    repl.enter()
    return repl


def test_enter_stops_the_firmware_and_keeps_what_it_said():
    ser = FakeSerial(on_ctrl_c=b"ins: stopped (Ctrl-D restarts it)")
    repl = _repl(ser)
    assert ser.mode == "raw"
    assert b"ins: stopped" in repl.console


@pytest.mark.parametrize("window", [1, 7, 64, 128])
def test_raw_paste_sends_code_longer_than_the_window(window):
    ser = FakeSerial(window=window)
    repl = _repl(ser)
    code = "x = " + repr("a" * 700) + "\nprint(len(x), 6 * 7)\n"
    out, err = repl.exec_raw(code)
    assert (out, err) == (b"700 42\r\n", b"")
    assert ser.received[-1] == code.encode()
    assert repl.transport.use_raw_paste
    assert repl.exec("print('again')") == b"again\r\n"  # the prompt is tracked between runs


def test_plain_raw_mode_when_the_board_has_no_raw_paste():
    ser = FakeSerial(raw_paste=False)
    repl = _repl(ser)
    code = "print(sum(range(" + "1" * 3 + ")))\n" + "# padding\n" * 60
    assert repl.exec(code) == b"6105\r\n"
    assert not repl.transport.use_raw_paste


def test_board_exception_is_a_board_error_quoting_the_traceback():
    repl = _repl(FakeSerial())
    with pytest.raises(errors.BoardError, match="ZeroDivisionError"):
        repl.exec("1 / 0", what="dividing")
    assert repl.exec("print(3)") == b"3\r\n"  # still usable


def test_silent_port_is_not_responding():
    repl = BoardRepl(FakeSerial(silent=True), timeout=0.2, port="/dev/quiet")
    with pytest.raises(errors.NotResponding, match="does not respond"):
        repl.enter()


def test_garbage_is_not_micropython():
    repl = BoardRepl(FakeSerial(garbage=b"\x00\xfe?"), timeout=0.2, port="/dev/noise")
    with pytest.raises(errors.NotMicroPython, match="not in MicroPython"):
        repl.enter()


def test_syntax_error_mid_paste_is_reported():
    repl = _repl(FakeSerial(window=16))
    with pytest.raises(errors.BoardError, match="SyntaxError"):
        repl.exec("def f(:\n    pass\n")


def test_a_board_that_goes_silent_mid_run_is_not_responding():
    ser = FakeSerial()
    repl = _repl(ser, timeout=0.3)
    ser.silent = True
    with pytest.raises(errors.NotResponding, match="stopped responding while counting"):
        repl.exec("print(1)", what="counting")


def test_files_through_mpremote(tmp_path):
    (tmp_path / "lib").mkdir()
    repl = _repl(FakeSerial(tmp_path))
    data = bytes(range(256)) * 5
    repl.fs("fs_writefile", "/flash/lib/x.bin", data, what="writing x.bin")
    assert (tmp_path / "lib" / "x.bin").read_bytes() == data
    assert repl.fs("fs_readfile", "/flash/lib/x.bin", what="reading x.bin") == data
    assert repl.fs("fs_readfile", "/flash/nope", what="reading nope", missing=True) is None
    with pytest.raises(errors.BoardError, match="reading nope"):
        repl.fs("fs_readfile", "/flash/nope", what="reading nope")


def test_deploy_over_plain_raw_mode(tmp_path, monkeypatch):
    """The virtual board always offers raw-paste: deploy through a board without it (and with
    one corrupted write) on the scripted board."""
    from tools.flash import build, deploy

    out = tmp_path / "build"
    manifest = build.build(out)
    fs = tmp_path / "flash"
    (fs / "lib").mkdir(parents=True)
    (fs / "lib" / "stale.py").write_text("x = 1\n")
    fake = FakeSerial(fs, raw_paste=False, corrupt_writes=1)
    monkeypatch.setattr(deploy, "open_port", lambda port, baud: fake)
    # plain raw mode paces its writes for a board's buffer (256 bytes per 10 ms): the scripted
    # board needs no pacing
    fast = types.SimpleNamespace(sleep=lambda _s: None, monotonic=time.monotonic)
    monkeypatch.setattr(transport_serial, "time", fast)
    lines = []
    result = deploy.deploy(out, "/dev/fake", log=lines.append, watch_s=2)
    assert result["stale"] == ["lib/stale.py"] and not (fs / "lib" / "stale.py").exists()
    assert len(result["written"]) == len(manifest["files"])
    assert any("OK after 2 attempts" in line for line in lines)
    for f in manifest["files"]:
        assert build.crc32((fs / f["path"]).read_bytes()) == int(f["crc32"], 16)


def test_ctrl_c_in_the_middle_of_a_transfer_says_interrupted(tmp_path, monkeypatch, capsys):
    """Ctrl-C while deploy sends a file: "interrupted: run the command again", status 130;
    not a diagnosis of the port or the cable."""
    from tools.flash import build, deploy
    from tools.flash.__main__ import main

    fs = tmp_path / "flash"
    fs.mkdir()
    fake = FakeSerial(fs)
    reads = {"n": 0}
    read = fake.read

    def interrupted_read(n=1):
        reads["n"] += 1
        if reads["n"] == 3000:  # well into the file transfers
            raise KeyboardInterrupt
        return read(n)

    fake.read = interrupted_read
    monkeypatch.setattr(deploy, "open_port", lambda port, baud: fake)
    monkeypatch.setattr(build, "check_budget", lambda manifest: None)
    assert main(["deploy", "--port", "/dev/fake"]) == 130
    err = capsys.readouterr().err
    assert "interrupted: run the command again" in err
    assert "another program" not in err and "cable" not in err
    assert reads["n"] == 3000 and fake.written  # it was writing files
