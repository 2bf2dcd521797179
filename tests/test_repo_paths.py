"""Every repository path a document, docstring or comment names exists: a path that starts
with one of the repository's top-level directories (firmware/, common/, tools/,
host_emulator/, tests/, docs/) names a file or directory of this repository, or, for the
MicroPython tree's own tools/ and tests/ (tools/mpy_ld.py, tests/perf_bench), one of the
vendored tree the builds use. `module.attribute` after a file's path (firmware/lib/config.load)
counts as the file."""

import re
import subprocess

from common import toolchain
from common.firmware_env import REPO_DIR

TOPS = ("firmware", "common", "tools", "host_emulator", "tests", "docs")
PATH = re.compile(r"(?<![\w./-])((?:" + "|".join(TOPS) + r")/[A-Za-z0-9_./*-]*[A-Za-z0-9_*])")
TEXT = (".py", ".md", ".c", ".h", ".sh", ".toml", ".txt")


def named_paths(text):
    return [m.group(1) for m in PATH.finditer(text)]


def exists(path, micropython_dir):
    """True if path names something here (or, tools/ and tests/ only, in the MicroPython
    tree); a glob must match something; module.attribute after a .py path counts."""
    bases = [REPO_DIR]
    if path.startswith(("tools/", "tests/")) and micropython_dir is not None:
        bases.append(micropython_dir)
    for base in bases:
        if "*" in path:
            if any(base.glob(path)):
                return True
            continue
        p = base / path
        if p.exists() or (p.suffix and p.with_suffix(".py").exists()):
            return True
    return False


def repository_files():
    out = subprocess.run(["git", "ls-files"], cwd=REPO_DIR, capture_output=True, text=True)
    return [
        REPO_DIR / f for f in out.stdout.split()
        if f.endswith(TEXT) or f.endswith("Makefile")
    ]  # fmt: skip


def missing(texts, micropython_dir):
    """'file: path' for every named path that does not exist; texts: (file name, text)."""
    return [
        f"{name}: {path}"
        for name, text in texts
        for path in named_paths(text)
        if not exists(path.rstrip("."), micropython_dir)
    ]


def test_every_named_path_exists():
    texts = [
        (str(f.relative_to(REPO_DIR)), f.read_text(errors="replace"))
        for f in repository_files()
        if f.exists()  # deleted in the work tree, not yet in the index
    ]
    assert missing(texts, toolchain.micropython_dir()) == []


def test_a_stale_path_is_found():
    stale, tree = (
        "host_emulator" + "/periph/spi.py",
        ("tools" + "/pydfu.py", "tests" + "/perf_bench"),
    )
    text = f"see {stale}, firmware/lib/config.load, docs/*.md, {tree[0]} and {tree[1]}"
    want = [f"doc.md: {p}" for p in (stale, *tree)]
    assert missing([("doc.md", text)], None) == want
    assert missing([("doc.md", text)], toolchain.micropython_dir()) == want[:1]
