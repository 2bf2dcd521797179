"""The figures the README and docs quote from a command are that command's: a change that moves
one (a firmware file more, a new session format, a new accuracy report) fails here until the
text says the new figure. Each test names the command whose output the doc must repeat."""

import re
from pathlib import Path

import pytest

from common.proto import session_file
from tools.flash import build

ROOT = Path(__file__).resolve().parents[1]


def _text(name):
    return (ROOT / name).read_text()


def _flat(text):
    """The text with its line breaks as spaces (a figure may be wrapped)."""
    return re.sub(r"\s+", " ", text)


def _kb(n_bytes):
    return f"{n_bytes / 1024:.1f} KB"


@pytest.fixture(scope="module")
def flash_builds(tmp_path_factory, flash_build_dir):
    """`make build-flash`'s manifest (the session's build, tests/conftest.py), and
    `--strip-lines`'s."""
    strip = tmp_path_factory.mktemp("flash-strip")
    return build.load_manifest(flash_build_dir), build.build(strip, strip_lines=True)


def test_the_flash_figures_are_make_build_flash_s(flash_builds):
    full, strip = flash_builds
    n, size, clusters = len(full["files"]), full["total_bytes"], full["clusters_512"]
    deploy = _flat(_text("docs/deploy.md"))
    for label, m in (("default (line numbers kept)", full), ("`--strip-lines`", strip)):
        row = (
            f"| {len(m['files'])} | {m['total_bytes']:,} ({_kb(m['total_bytes'])}) | "
            f"{m['clusters_512']} ({m['clusters_512'] * 512 / 1024:.1f} KB) |"
        ).replace(",", " ")
        assert re.search(re.escape(label) + r"[^|]*" + re.escape(row), deploy), (label, row)
    need = full["budget"]["needed_clusters"]
    assert f"needs {need} clusters ({need * 512 / 1024:.1f} KB)" in deploy
    saved = full["total_bytes"] - strip["total_bytes"]
    assert f"`--strip-lines` saves {_kb(saved)}" in deploy
    readme = _flat(_text("README.md"))
    assert (
        f"compiles to {_kb(size)} (`make build-flash`: {n} files, {clusters} FAT clusters" in readme
    )
    image = _flat(_text("docs/image.md"))
    assert (
        f"({_kb(size)} of `.mpy` in {n} files, {clusters * 512 / 1024:.1f} KB in FAT clusters"
        in image
    )


def test_the_session_format_named_is_the_one_written():
    magic = session_file.MAGIC.decode()
    monitor = _text("docs/monitor.md")
    assert f"(`{magic}` header" in monitor and f"`{magic}`, a JSON header" in _flat(monitor)


def _accuracy_row(text, starts):
    """The cells of docs/accuracy.md's table row whose first cell starts with `starts`."""
    for line in text.splitlines():
        if line.startswith(f"| {starts}"):
            return [c.strip() for c in line.strip("|").split("|")]
    raise AssertionError(f"docs/accuracy.md has no row {starts!r}")


def test_the_readmes_replay_figures_are_the_accuracy_reports():
    """docs/accuracy.md is written by `make accuracy-report`; its first row is `make replay`."""
    acc = _text("docs/accuracy.md")
    protocol = _accuracy_row(acc, "protocol: 1 Hz")
    with_speed = _accuracy_row(acc, "protocol + RTK velocity")
    readme = _flat(_text("README.md"))
    assert f"measures {protocol[1]} horizontal RMS with GNSS" in readme
    assert f"and {protocol[4]} at the end of three 15 s outages" in readme
    assert f"(with a receiver's velocity as well: {with_speed[1]})" in readme


def test_the_docs_index_lists_every_document():
    """docs/README.md names every document under docs/ (and the README points to it)."""
    index = _text("docs/README.md")
    docs = ROOT / "docs"
    for path in sorted(docs.rglob("*.md")):
        rel = path.relative_to(docs).as_posix()
        if rel != "README.md":
            assert f"]({rel})" in index, f"docs/README.md does not list {rel}"
    assert "(docs/README.md)" in _text("README.md")
