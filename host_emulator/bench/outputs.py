"""What a benchmark will write, said before its minutes of work: most write documents the
repository tracks (docs/benchmarks/*.md, docs/accuracy.md), which a run overwrites."""

import pathlib
import sys

REPO = pathlib.Path(__file__).resolve().parents[2]


def _tracked(path):
    """path as the repository names it, when it lies in the repository's docs/ (None else)."""
    try:
        rel = pathlib.Path(path).resolve().relative_to(REPO)
    except ValueError:
        return None
    return rel.as_posix() if rel.parts[:1] == ("docs",) else None


def announce(command, paths, out_option="--out", stream=None):
    """One line: the files `command` will write; a document of the repository is said to be
    overwritten, with how to keep it (`out_option`, None when the command has none)."""
    stream = stream or sys.stdout
    names = [_tracked(p) or str(p) for p in paths]
    line = f"{command} will write {', '.join(names)}"
    if any(_tracked(p) for p in paths):
        keep = f"; {out_option} elsewhere keeps them" if out_option else ""
        line += f" (overwriting the repository's copies: git diff shows what changed{keep})"
    print(line, file=stream, flush=True)
