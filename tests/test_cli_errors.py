"""Every command line meets a full disk, a read-only directory and a closed pipe with one line
(or, for the pipe, silence) and a non-zero exit status, never a traceback.

A full disk and a read-only directory are injected (the tests may run as root, who writes
anywhere): every write under a chosen directory fails with ENOSPC or EROFS, as the kernel
would fail it. The closed pipe is real: the command's stdout is a pipe whose reading end is
closed before it starts."""

import builtins
import errno
import io
import os
import pathlib
import subprocess
import sys

import pytest

from host_emulator.sim import board_input

ROOT = pathlib.Path(__file__).resolve().parents[1]
NMEA = ROOT.parent / "shared" / "data" / "nmea"


@pytest.fixture(params=[errno.ENOSPC, errno.EROFS], ids=["full_disk", "read_only"])
def broken_dir(request, tmp_path, monkeypatch):
    """A directory every write into fails with the param's errno."""
    bad = tmp_path / "bad"
    bad.mkdir()
    real_open = io.open

    def open_(file, mode="r", *a, **kw):
        if (
            isinstance(file, (str, os.PathLike))
            and ("w" in mode or "a" in mode or "x" in mode)
            and bad in pathlib.Path(file).absolute().parents
        ):
            raise OSError(request.param, os.strerror(request.param), str(file))
        return real_open(file, mode, *a, **kw)

    monkeypatch.setattr(builtins, "open", open_)
    monkeypatch.setattr(io, "open", open_)
    return bad, request.param


def _check(capsys, rc, code):
    err = capsys.readouterr().err
    assert rc != 0 and "Traceback" not in err, err
    assert err.count("\n") == 1 and err.startswith("error: ") and os.strerror(code) in err, err
    return err


def _config_file(d):
    from tools.flash.__main__ import main

    assert main(["config", "set", "--file", str(d / "ins.cfg"), "gnss_hdop_max=2.5"]) == 0
    return d / "ins.cfg"


def test_run_out_into_a_broken_directory(broken_dir, capsys):
    from host_emulator.__main__ import main

    bad, code = broken_dir
    rc = main(["run", "--scenario", "quick_start", "--duration", "2", "--out", str(bad / "r"),
               "--quiet"])  # fmt: skip
    _check(capsys, rc, code)
    assert not [p for p in (bad / "r").glob("*.bin")]  # no part of frames.bin left


def test_config_get_out_into_a_broken_directory(broken_dir, tmp_path, capsys):
    from tools.flash.__main__ import main

    bad, code = broken_dir
    cfg = _config_file(tmp_path)
    capsys.readouterr()
    rc = main(["config", "get", "--file", str(cfg), "--out", str(bad / "copy.cfg")])
    _check(capsys, rc, code)
    rc = main(["config", "set", "--file", str(bad / "new.cfg"), "gnss_hdop_max=2.5"])
    _check(capsys, rc, code)


@pytest.mark.parametrize("command", ["monitor", "session_record"])
def test_a_capture_written_into_a_broken_directory(command, broken_dir, tmp_path, capsys):
    """The monitor's --csv and session record's --out."""
    from host_emulator.session.cli import main as session_main
    from tools.monitor.cli import main as monitor_main

    bad, code = broken_dir
    cap = tmp_path / "cap.bin"
    cap.write_bytes(b"\x00" * 10)
    if command == "monitor":
        rc = monitor_main(["--file", str(cap), "--csv", str(bad / "x.csv")])
    else:
        rc = session_main(["record", str(cap), "--out", str(bad / "s.ins")])
    _check(capsys, rc, code)


def _closed_pipe(argv):
    """Run `python argv` with stdout a pipe nobody reads (its reading end closed first)."""
    r, w = os.pipe()
    os.close(r)
    try:
        p = subprocess.run(
            [sys.executable, *argv], stdout=w, stderr=subprocess.PIPE, cwd=ROOT, timeout=120,
            env={**os.environ, "PYTHONPATH": str(ROOT)},
        )  # fmt: skip
    finally:
        os.close(w)
    return p.returncode, p.stderr.decode()


@pytest.mark.parametrize(
    "argv",
    [
        ["-m", "host_emulator", "scenarios"],
        ["-m", "host_emulator", "gnss-dump", str(NMEA / "mtk-3301.log")],
        ["-m", "tools.flash", "config", "get", "--file", "CFG"],
        ["-m", "tools.monitor", "--file", "CAP"],
    ],
    ids=["scenarios", "gnss_dump", "config_get", "monitor"],
)
def test_a_closed_pipe_ends_a_command_quietly(argv, tmp_path):
    cfg = _config_file(tmp_path)
    stim = board_input.simulate("quick_start", 1.0, seed=0).stimulus
    cap = tmp_path / "cap.bin"
    from host_emulator.runtimes import cpython

    cap.write_bytes(cpython.run(stim, tmp_path / "w").out)
    argv = [str(cfg) if a == "CFG" else str(cap) if a == "CAP" else a for a in argv]
    rc, err = _closed_pipe(argv)
    assert "Traceback" not in err and "Exception ignored" not in err, err
    assert rc == 141, (rc, err)


def test_a_write_the_disk_cuts_short_leaves_no_part_of_the_file(tmp_path, monkeypatch):
    """errors.write_atomic: ENOSPC halfway through leaves the previous file as it was, and no
    partial file beside it."""
    from common.errors import write_atomic

    (tmp_path / "frames.bin").write_bytes(b"old")
    real = pathlib.Path.write_bytes

    def half(self, data):
        real(self, data[: len(data) // 2])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))

    monkeypatch.setattr(pathlib.Path, "write_bytes", half)
    with pytest.raises(OSError, match="No space left"):
        write_atomic(tmp_path / "frames.bin", b"new bytes" * 1000)
    assert (tmp_path / "frames.bin").read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["frames.bin"]


def test_export_into_a_broken_directory(broken_dir, capsys):
    from host_emulator.__main__ import main

    bad, code = broken_dir
    rc = main(["export", "--scenario", "quick_start", "--out", str(bad / "x")])
    _check(capsys, rc, code)


def test_session_replay_and_repair_into_a_broken_directory(broken_dir, tmp_path, capsys):
    from common.proto import session_file
    from host_emulator.session.cli import main

    bad, code = broken_dir
    session_file.write_session(tmp_path / "s.ins", b"\x00" * 100)
    rc = main(["repair", str(tmp_path / "s.ins"), "--out", str(bad / "fixed.ins")])
    _check(capsys, rc, code)


def _flash(*argv, timeout=30):
    """`python -m tools.flash argv` in a process of its own: (status, stdout, stderr)."""
    p = subprocess.run(
        [sys.executable, "-m", "tools.flash", *argv], capture_output=True, text=True, cwd=ROOT,
        timeout=timeout, env={**os.environ, "PYTHONPATH": str(ROOT)},
    )  # fmt: skip
    return p.returncode, p.stdout, p.stderr


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="no /dev/zero")
def test_a_config_file_without_end_is_refused_after_a_bounded_read():
    """/dev/zero as a configuration: refused by size, at once, not read into memory."""
    from common.proto import config as board_config

    rc, out, err = _flash("config", "get", "--file", "/dev/zero", timeout=15)
    assert rc == 1 and err.count("\n") == 1, (rc, err)
    assert err.startswith("error: /dev/zero is not a configuration file: it holds more than 64 KB")
    assert out == ""
    with pytest.raises(board_config.ConfigError, match="/dev/zero is not a configuration"):
        board_config.load("/dev/zero")  # the monitor's and replay's --config


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
def test_a_config_written_to_a_full_device_fails_at_once_naming_it(tmp_path):
    rc, out, err = _flash("config", "set", "--file", "/dev/full", "gnss_hdop_max=2.5", timeout=15)
    assert rc == 1, (rc, out, err)
    assert err == "error: /dev/full: No space left on device (the disk is full)\n"
    assert "wrote" not in out
    cfg = _config_file(tmp_path)
    rc, out, err = _flash("config", "get", "--file", str(cfg), "--out", "/dev/full")
    assert rc == 1 and err == "error: /dev/full: No space left on device (the disk is full)\n"


@pytest.mark.parametrize(
    "argv, command",
    [
        (["session"], "session"), (["session", "record"], "session record"),
        (["session", "replay"], "session replay"), (["session", "repair", "x"], "session repair"),
        (["parity"], "parity"), (["bench-faults", "--nope"], "bench-faults"),
        (["cpi", "--nope"], "cpi"), (["bench-settings", "--nope"], "bench-settings"),
    ],
)  # fmt: skip
def test_a_command_line_error_names_its_command(argv, command, capsys):
    """Not a bare "error: the following arguments are required: ...": which command wants it."""
    from host_emulator.__main__ import main

    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: python -m host_emulator {command}: ") and err.count("\n") == 1


def test_config_set_without_a_setting_is_a_command_line_error(tmp_path, capsys):
    from tools.flash.__main__ import main

    with pytest.raises(SystemExit) as e:
        main(["config", "set", "--file", str(tmp_path / "x.cfg")])
    assert e.value.code == 2 and not (tmp_path / "x.cfg").exists()
    assert "config set: error: give at least one NAME=VALUE" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(["config", "get"])
    assert e.value.code == 2
    assert "one of the arguments --port --file is required" in capsys.readouterr().err


def test_a_failure_exits_1_in_every_command(tmp_path, capsys):
    """A file that is not there: status 1 in session as in tools.flash and tools.monitor (2 is
    for a command line argparse refuses)."""
    from host_emulator.__main__ import main as emulator_main
    from tools.flash.__main__ import main as flash_main
    from tools.monitor.cli import main as monitor_main

    missing = str(tmp_path / "missing")
    for run in (
        lambda: emulator_main(["session", "replay", missing]),
        lambda: emulator_main(["session", "repair", missing, "--out", str(tmp_path / "o")]),
        lambda: flash_main(["config", "get", "--file", missing]),
        lambda: monitor_main(["--file", missing]),
    ):
        assert run() == 1
        err = capsys.readouterr().err
        assert err.startswith("error: ") and missing in err and err.count("\n") == 1, err
