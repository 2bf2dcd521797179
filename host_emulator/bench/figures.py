"""The board's figures that README.md and docs/ quote, each read from what the command that
measures it wrote: `python -m host_emulator figures [--check]` (make figures).

A figure in a document is a marker around its text:

    navigating busy p99 <!--fig twin.raw.navigating.busy_p99-->1.85 ms<!--/fig-->

Markdown shows only the text. Its name says where the figure comes from:
- `twin.<config>.<phase>.<figure>` and `twin.<config>.realtime` / `.wall_s`: the image on the
  emulated STM32F411 in `make bench-board` (docs/benchmarks/board.json, "image_on_f411"):
  busy_mean, busy_p50, busy_p99, busy_max (ms at the image's 96 MHz), late (ticks), instr_mean,
  instr_p99 (instructions in the tick's 5 ms); config: off, raw, 10hz, page (bench/board.py's
  TWIN_VARIANTS), phase: aligning, navigating;
- `m4f.<config>.<phase>.instr_<mean|p50|p99|max>`: the emulated Cortex-M4F's firmware
  instructions per tick in the same run ("results"; config: default, coning, 10hz);
- `budget.<board>.<figure>`: the image's budget that `make image` writes (out/image/<BOARD>/
  budget.json; board: blackpill, nucleo): code, code_free, code_free_kb, code_pct, region,
  flash, static_ram, heap, frozen.

`figures` rewrites every marker's text from those files (building the images first, cached:
seconds), `--check` only says which differ (exit 1); bench-board rewrites them after its run.
tests/bench/test_figures.py fails when a marker's text is not its figure, or when a document
quotes a tick time or a code-region figure outside a marker without naming the commit it was
measured at: a stale figure fails `make test`.
"""

import json
import pathlib
import re
import sys

from common.errors import EmulatorError
from common.firmware_env import REPO_DIR

BOARD_JSON = REPO_DIR / "docs" / "benchmarks" / "board.json"
# the documents whose markers `figures` keeps (docs/benchmarks/board.md is bench-board's whole)
DOCS = ("README.md", "docs")
MARK = re.compile(r"<!--fig ([A-Za-z0-9_.]+)-->(.*?)<!--/fig-->")
BOARDS = {"blackpill": "WEACT_F411_BLACKPILL", "nucleo": "NUCLEO_F411RE"}
PHASES = ("aligning", "navigating")


class FigureError(EmulatorError):
    """A marker names no figure, or its source has none."""


def _int(v):
    return f"{round(v):,}"


def _ms(v):
    return f"{v:.2f} ms"


def _twin(data, config, rest):
    runs = {r.get("id"): r for r in data.get("image_on_f411", [])}
    r = runs.get(config)
    if r is None or "error" in r:
        raise FigureError(f"board.json has no image run '{config}'")
    if rest == ["realtime"]:
        return f"{r['run']['realtime_factor']:.2f}x"
    if rest == ["wall_s"]:
        return f"{r['wall_s']:.0f} s"
    if len(rest) != 2:
        raise FigureError(f"twin.{config}.{'.'.join(rest)}: no such figure")
    phase, fig = rest
    ph = r["time"]["phases"].get(phase)
    if ph is None:
        raise FigureError(f"board.json's '{config}' run has no phase '{phase}'")
    if fig == "late":
        return _int(ph["late_ticks"])
    kind, _, stat = fig.partition("_")
    if kind == "busy" and stat in ("mean", "p50", "p99", "max"):
        return _ms(ph["busy_ms"][stat])
    if kind == "instr" and stat in ("mean", "p50", "p99", "max"):
        return _int(ph["instr"][stat])
    raise FigureError(f"twin.{config}.{phase}.{fig}: no such figure")


def _m4f(data, config, rest):
    runs = {r.get("id"): r for r in data.get("results", [])}
    r = runs.get(config)
    if r is None or "error" in r:
        raise FigureError(f"board.json has no emulated Cortex-M4F run '{config}'")
    if len(rest) != 2 or not rest[1].startswith("instr_"):
        raise FigureError(f"m4f.{config}.{'.'.join(rest)}: no such figure")
    phase, fig = rest
    ph = r["cost"]["phases"].get(phase)
    stat = fig[len("instr_") :]
    if ph is None or stat not in ("mean", "p50", "p99", "max"):
        raise FigureError(f"m4f.{config}.{phase}.{fig}: no such figure")
    return _int(ph["firmware_instr"][stat])


def _budget(budgets, board, rest):
    if board not in BOARDS:
        raise FigureError(f"budget.{board}: the boards are {', '.join(BOARDS)}")
    f = budgets(BOARDS[board])["figures"]
    fig = ".".join(rest)
    if fig == "code_free_kb":
        return f"{f['code_free_bytes'] / 1024:.1f} KB"
    if fig == "code_pct":
        return f"{100 * f['code_bytes'] / f['code_region_bytes']:.1f} %"
    key = {"code": "code_bytes", "code_free": "code_free_bytes", "region": "code_region_bytes",
           "flash": "flash_programmed_bytes", "static_ram": "static_ram_bytes",
           "heap": "heap_bytes", "frozen": "frozen_bytes"}.get(fig)  # fmt: skip
    if key is None:
        raise FigureError(f"budget.{board}.{fig}: no such figure")
    return f"{f[key]:,} B"


class Sources:
    """What the figures are read from: board.json (loaded once) and the images' budgets
    (built, or brought up to date, on first use: tools.image, cached)."""

    def __init__(self, board_json=BOARD_JSON, budget=None):
        self._path = pathlib.Path(board_json)
        self._board = None
        self._budget_fn = budget
        self._budgets = {}

    def board(self):
        if self._board is None:
            try:
                self._board = json.loads(self._path.read_text())
            except (OSError, ValueError) as e:
                raise FigureError(f"cannot read {self._path}: {e}") from None
        return self._board

    def budget(self, board):
        if board not in self._budgets:
            if self._budget_fn is not None:
                self._budgets[board] = self._budget_fn(board)
            else:
                from tools.image import build as image_build

                self._budgets[board] = image_build.build(board, log=lambda msg: None)
        return self._budgets[board]

    def render(self, name):
        source, *rest = name.split(".")
        if source == "twin" and rest:
            return _twin(self.board(), rest[0], rest[1:])
        if source == "m4f" and rest:
            return _m4f(self.board(), rest[0], rest[1:])
        if source == "budget" and len(rest) >= 2:
            return _budget(self.budget, rest[0], rest[1:])
        raise FigureError(f"'{name}' names no figure (twin.*, m4f.*, budget.*)")


def documents(root=REPO_DIR):
    """README.md and every docs/**/*.md but what bench-board writes whole."""
    out = []
    for entry in DOCS:
        p = root / entry
        out += [p] if p.is_file() else sorted(p.rglob("*.md"))
    return [p for p in out if p.name != "board.md"]


def rewrite(text, sources):
    """text with every marker's text its figure's."""
    return MARK.sub(lambda m: f"<!--fig {m[1]}-->{sources.render(m[1])}<!--/fig-->", text)


def stale(paths, sources):
    """(path, name, the text found, the figure) of every marker whose text is not its figure."""
    out = []
    for p in paths:
        for m in MARK.finditer(p.read_text()):
            want = sources.render(m[1])
            if m[2] != want:
                out.append((p, m[1], m[2], want))
    return out


def main(argv=None):
    from host_emulator import args as cli_args

    p = cli_args.Parser(prog="python -m host_emulator figures",
                        description=__doc__.split("\n\n")[0])  # fmt: skip
    p.add_argument(
        "--check",
        action="store_true",
        help="say which markers differ from their figures (exit 1); write nothing",
    )
    try:
        args = p.parse_args(argv)
    except cli_args.UsageError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2

    def command():
        sources = Sources()
        paths = documents()
        if args.check:
            bad = stale(paths, sources)
            for path, name, found, want in bad:
                print(f"{path.relative_to(REPO_DIR)}: {name} reads '{found}', the figure is "
                      f"'{want}'")  # fmt: skip
            print(f"figures: {len(bad)} stale" if bad else "figures: all current")
            return 1 if bad else 0
        changed = write_all(paths, sources)
        print(f"figures: rewrote {', '.join(changed)}" if changed else "figures: all current")
        return 0

    return cli_args.run_reporting(command)


def write_all(paths, sources):
    """Rewrite the markers of every document; the names of those that changed."""
    changed = []
    for path in paths:
        text = path.read_text()
        new = rewrite(text, sources)
        if new != text:
            path.write_text(new)
            changed.append(str(path.relative_to(REPO_DIR)))
    return changed
