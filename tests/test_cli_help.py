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
