"""A benchmark says which files it will write before its minutes of work, and that a document
of the repository among them is overwritten (host_emulator/bench/outputs.py)."""

import io
from pathlib import Path

import pytest

from host_emulator.bench import board, faults, navigation, outputs, settings

REPO = Path(__file__).resolve().parents[2]


class Started(Exception):
    """Raised where the benchmark's work would begin."""


def _stop(*_args, **_kw):
    raise Started


def test_a_repository_document_is_said_to_be_overwritten(tmp_path):
    said = io.StringIO()
    doc = REPO / "docs" / "benchmarks" / "x.md"  # not a file: what the line says of one
    outputs.announce("bench-x", [doc, tmp_path / "x.json"], stream=said)
    line = said.getvalue()
    assert line.startswith(f"bench-x will write {doc.relative_to(REPO)}, {tmp_path / 'x.json'}")
    assert "overwriting the repository's copies" in line and "--out elsewhere" in line
    said = io.StringIO()
    outputs.announce("bench-x", [tmp_path / "x.md"], stream=said)
    assert said.getvalue() == f"bench-x will write {tmp_path / 'x.md'}\n"


@pytest.mark.parametrize(
    "module, name, heavy",
    [
        (board, "bench-board", "m4f_build.build"),
        (faults, "bench-faults", "ProcessPoolExecutor"),
        (settings, "bench-settings", "execute"),
        (navigation, "bench-nav", "_run_tasks"),
    ],
)
def test_each_benchmark_names_its_files_before_it_starts(module, name, heavy, monkeypatch, capsys):
    target = module
    *path, attr = heavy.split(".")
    for part in path:
        target = getattr(target, part)
    monkeypatch.setattr(target, attr, _stop)
    with pytest.raises(Started):
        module.main([])
    said = capsys.readouterr()
    line = next(s for s in (said.out + said.err).splitlines() if s.startswith(name))
    assert f"{name} will write docs/benchmarks/" in line and "overwriting" in line
