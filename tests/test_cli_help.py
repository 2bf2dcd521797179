"""Every option and subcommand of every command line has a help text (`--help` says what each
does)."""

import argparse
import contextlib
import importlib
import io

import pytest

COMMANDS = [
    "host_emulator.__main__", "tools.flash.__main__", "tools.monitor.cli", "tools.image.__main__",
    "host_emulator.session.cli", "host_emulator.eval.gnss_dump", "host_emulator.virtual_board",
    "host_emulator.eval.parity", "host_emulator.bench.navigation", "host_emulator.bench.board",
    "host_emulator.bench.faults", "host_emulator.bench.digests",
    "host_emulator.bench.accuracy_report", "host_emulator.bench.float32",
    "host_emulator.bench.cpi", "host_emulator.bench.profile",
]  # fmt: skip


@pytest.mark.parametrize("module", COMMANDS)
def test_every_option_has_a_help_text(module, monkeypatch):
    missing = []
    add_argument = argparse._ActionsContainer.add_argument
    add_parser = argparse._SubParsersAction.add_parser

    def checked_argument(self, *args, **kw):
        action = add_argument(self, *args, **kw)
        if action.help is None and not isinstance(
            action, (argparse._HelpAction, argparse._SubParsersAction)
        ):
            missing.append(args)
        return action

    def checked_parser(self, name, **kw):
        if not kw.get("help"):
            missing.append(("subcommand", name))
        return add_parser(self, name, **kw)

    monkeypatch.setattr(argparse._ActionsContainer, "add_argument", checked_argument)
    monkeypatch.setattr(argparse._SubParsersAction, "add_parser", checked_parser)
    with contextlib.redirect_stdout(io.StringIO()), pytest.raises(SystemExit):
        importlib.import_module(module).main(["--help"])
    assert not missing, missing


def _texts(module, monkeypatch):
    """Every help text and description `module.main(["--help"])` declares: [(where, text)]."""
    texts = []
    add_argument = argparse._ActionsContainer.add_argument
    add_parser = argparse._SubParsersAction.add_parser
    init = argparse.ArgumentParser.__init__

    def argument(self, *args, **kw):
        texts.append((args, kw.get("help")))
        return add_argument(self, *args, **kw)

    def parser(self, name, **kw):
        texts.append((name, kw.get("help")))
        return add_parser(self, name, **kw)

    def parser_init(self, *args, **kw):
        texts.append((kw.get("prog"), kw.get("description")))
        init(self, *args, **kw)

    monkeypatch.setattr(argparse._ActionsContainer, "add_argument", argument)
    monkeypatch.setattr(argparse._SubParsersAction, "add_parser", parser)
    monkeypatch.setattr(argparse.ArgumentParser, "__init__", parser_init)
    with contextlib.redirect_stdout(io.StringIO()), pytest.raises(SystemExit):
        importlib.import_module(module).main(["--help"])
    return [(w, t) for w, t in texts if t and t != argparse.SUPPRESS]


@pytest.mark.parametrize("module", [*COMMANDS, "common.native.__main__"])
def test_no_help_text_stops_mid_sentence(module, monkeypatch):
    """A description cut from a docstring at a line or paragraph break ends in ',' or ':'."""
    cut = [(w, t[-60:]) for w, t in _texts(module, monkeypatch) if t.rstrip()[-1] in ",:;("]
    assert not cut, cut


def test_the_native_build_helps_without_building(monkeypatch, capsys):
    from common import native
    from common.native.__main__ import main

    monkeypatch.setattr(native, "build_all", lambda: pytest.fail("--help built the kernels"))
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: python -m common.native") and "make native" in out


@pytest.mark.parametrize("module, argv", [
    ("tools.monitor.cli", []), ("host_emulator.session.cli", ["record", "--help"]),
])  # fmt: skip
def test_duration_is_the_option_and_seconds_its_hidden_old_name(module, argv, capsys):
    """--duration, as in run, parity, the virtual board; --seconds still parses, unlisted."""
    with pytest.raises(SystemExit):
        importlib.import_module(module).main([*argv, "--help"] if not argv else argv)
    out = capsys.readouterr().out
    assert "--duration" in out and "--seconds" not in out


def test_the_old_seconds_option_still_stops_a_monitor(tmp_path, capsys):
    from tools.monitor.cli import main

    cap = tmp_path / "cap.bin"
    cap.write_bytes(b"\x00" * 10)
    for name in ("--duration", "--seconds"):
        assert main(["--file", str(cap), name, "0"]) == 1
        assert capsys.readouterr().err == "error: --duration must be more than 0\n"


def test_config_set_help_lists_the_settings_as_replay_does(capsys):
    """`config set help` needs no board or file: the list `replay --set help` prints."""
    from host_emulator.__main__ import main as emulator_main
    from tools.flash.__main__ import main as flash_main

    assert flash_main(["config", "set", "help"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert emulator_main(["replay", "--dataset", "x", "--set", "help"]) == 0
    replay = capsys.readouterr().out.splitlines()
    assert listed[0].startswith("config set NAME=VALUE, the board settings")
    assert listed[1:] == replay[1:] and len(listed) == 41
    assert "  gnss_baud = 9600   (one of 9600, 19200, 38400, 57600, 115200, 230400, " \
        "460800, 921600)" in listed  # fmt: skip
