"""The board figures README.md and docs/ quote are what the commands that measure them wrote
(host_emulator/bench/figures.py): each marker's text is its figure, read from the committed
docs/benchmarks/board.json (make bench-board) and the images' budgets as `make image` builds
them now (cached in build/image: seconds); and no document quotes a tick time or a code
region figure of the board outside a marker, unless it names the commit it was measured at
(a figure of the past, which that commit's command reproduces)."""

import json
import re

import pytest

from host_emulator.bench import board as bench_board
from host_emulator.bench import figures

# what a board figure looks like in prose: a time per tick in ms with two decimals, a count
# of instructions, a code region's or heap's bytes
BOARD_FIGURE = re.compile(
    r"\b\d+\.\d\d ms\b|\b\d{1,3}(?:,\d{3})+ instructions\b|\b\d{1,3}(?:,\d{3})+ B (?:free|of)\b"
)
COMMIT = re.compile(r"\b[0-9a-f]{7,40}\b")
# a target, not a measurement: "<= 50,000 instructions", "at most 30,000 instructions"
TARGET = re.compile(r"(?:<=|at most|\*\*at most) \**\d{1,3}(?:,\d{3})+ instructions")


@pytest.fixture(scope="module")
def sources():
    return figures.Sources()


def test_every_marker_reads_its_figure(sources):
    bad = figures.stale(figures.documents(), sources)
    lines = [f"  {p.name}: {n} reads {f!r}, the figure is {w!r}" for p, n, f, w in bad]
    assert not bad, "stale figures (make figures rewrites them):\n" + "\n".join(lines)


def test_a_marker_that_names_no_figure_is_an_error(tmp_path):
    src = figures.Sources(tmp_path / "board.json", budget=lambda b: {"figures": {}})
    (tmp_path / "board.json").write_text(json.dumps({"image_on_f411": [], "results": []}))
    for name, says in (("twin.off.navigating.busy_p99", "no image run 'off'"),
                       ("budget.f401.heap", "the boards are"), ("cpu.load", "names no figure"),
                       ("m4f.default.navigating.mean", "no emulated Cortex-M4F run")):  # fmt: skip
        with pytest.raises(figures.FigureError, match=says):
            src.render(name)


def test_figures_are_rendered_from_their_sources(tmp_path):
    """A twin run's busy time, an M4F run's instructions and a budget's bytes, as the docs
    write them; rewriting replaces only the markers' text."""
    board = {
        "image_on_f411": [{"id": "raw", "run": {"realtime_factor": 2.345}, "wall_s": 255.8,
                           "time": {"phases": {"navigating": {
                               "busy_ms": {"mean": 1.0, "p50": 1.0, "p99": 1.9851, "max": 3.4},
                               "instr": {"mean": 51811.6, "p50": 1, "p99": 2, "max": 3},
                               "late_ticks": 0}}}}],
        "results": [{"id": "default", "cost": {"phases": {"navigating": {
            "firmware_instr": {"mean": 29380.4, "p50": 1, "p99": 61989.6, "max": 82360}}}}}],
    }  # fmt: skip
    (tmp_path / "board.json").write_text(json.dumps(board))
    fig = {"code_bytes": 287196, "code_free_bytes": 171556, "code_region_bytes": 458752}
    src = figures.Sources(tmp_path / "board.json", budget=lambda b: {"figures": fig})
    assert src.render("twin.raw.navigating.busy_p99") == "1.99 ms"
    assert src.render("twin.raw.navigating.late") == "0"
    assert src.render("twin.raw.realtime") == "2.35x"
    assert src.render("m4f.default.navigating.instr_mean") == "29,380"
    assert src.render("budget.blackpill.code_free") == "171,556 B"
    assert src.render("budget.nucleo.code_pct") == "62.6 %"
    text = "p99 <!--fig twin.raw.navigating.busy_p99-->2.27 ms<!--/fig--> (was 2.27 ms, a56d6b9)"
    assert figures.rewrite(text, src) == (
        "p99 <!--fig twin.raw.navigating.busy_p99-->1.99 ms<!--/fig--> (was 2.27 ms, a56d6b9)"
    )


def test_every_configuration_has_a_name_the_docs_can_quote():
    labels = [v[0] for v in bench_board.VARIANTS + bench_board.TWIN_VARIANTS]
    assert sorted(bench_board.IDS) == sorted(labels)
    twin = [bench_board.IDS[v[0]] for v in bench_board.TWIN_VARIANTS]
    assert len(set(twin)) == len(twin)


def _loose(text):
    """The paragraphs of `text` that quote a board figure outside a marker and name no
    commit (a hex word of 7-40 characters with a letter and a digit)."""
    out = []
    for para in text.split("\n\n"):
        t = TARGET.sub("", figures.MARK.sub("", para))
        if BOARD_FIGURE.search(t) and not any(
            re.search(r"[a-f]", c) and re.search(r"\d", c) for c in COMMIT.findall(t)
        ):
            out.append(t.strip()[:120])
    return out


def test_no_board_figure_outside_a_marker_without_its_commit():
    # docs/benchmarks/ is what the benchmarks wrote, each page naming its command and commit
    found = {str(p): _loose(p.read_text()) for p in figures.documents()
             if p.parent.name != "benchmarks"}  # fmt: skip
    found = {p: v for p, v in found.items() if v}
    assert not found, f"board figures with no marker and no commit: {found}"


def test_a_loose_figure_is_found():
    assert _loose("A tick takes 1.52 ms at p99.")
    assert not _loose("A tick took 1.52 ms at p99 at 20103cb.")
    assert not _loose("A tick takes <!--fig twin.off.navigating.busy_p99-->1.52 ms<!--/fig-->.")
    assert not _loose("The budget: p99 <= 50,000 instructions.")
    assert _loose("A tick counts 52,733 instructions at p99.")
