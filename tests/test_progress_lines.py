"""Progress lines on a terminal (common/progress.py): the real commands, run on an 80-column
pseudo-terminal, draw no line wider than it, redraw their bars in place with \\r, and name each
wait after the run (the evaluation, the plots) instead of going silent."""

import io
import os
import re
import sys

import tty_timing

from common import progress
from common.firmware_env import REPO_DIR

PY = sys.executable


def _env():
    return {**os.environ, "PYTHONPATH": str(REPO_DIR)}


def _bar_rows(r, label):
    """The rows (between newlines) that hold `label`'s bar, each split at its \\r redraws."""
    text = tty_timing.ANSI.sub(b"", r.data).decode()
    return [row.split("\r") for row in re.split(r"\r?\n", text) if f"  {label} [" in row]


def test_run_draws_within_80_columns_and_redraws_its_bar_on_one_row(tmp_path):
    # in tmp_path, out/ beside: the summary's paths are short, as a user's are
    r = tty_timing.run([PY, "-m", "host_emulator", "run", "--scenario", "quick_start",
                        "--duration", "20", "--out", "out"], cols=80, timeout=120,
                       env=_env(), cwd=tmp_path)  # fmt: skip
    assert r.status == 0, r.data.decode(errors="replace")[-2000:]
    assert r.widest() <= 80, max(r.segments(), key=len)
    rows = _bar_rows(r, "cpython")
    assert len(rows) == 1, rows  # every redraw on the row of the first: no wrap left behind
    draws = [d for d in rows[0] if d]
    assert len(draws) >= 2 and "100%" in draws[-1]
    text = r.data.decode()
    assert text.index("evaluating the output") < text.index("4/4 written") < text.index("report:")


def test_parity_shows_the_firmware_and_the_model_running(tmp_path):
    r = tty_timing.run([PY, "-m", "host_emulator", "parity", "--scenario", "quick_start",
                        "--duration", "10"], cols=80, timeout=120, cwd=REPO_DIR)  # fmt: skip
    assert r.status == 0, r.data.decode(errors="replace")[-2000:]
    assert r.widest() <= 80, max(r.segments(), key=len)
    assert len(_bar_rows(r, "cpython")) == 1
    assert len(_bar_rows(r, "model")) == 1
    assert "PARITY: identical" in r.data.decode()


def _bar_on_pty(cols, label, detail):
    """What a Bar of 100 steps draws in a child process whose stderr is a pty `cols` wide."""
    code = (
        "import sys, time\nfrom common import progress\n"
        f"b = progress.Bar({label!r}, lambda k, n, w: {detail!r})\n"
        "for k in range(0, 101, 5):\n    b(k, 100)\n    time.sleep(0.05)\n"
    )
    return tty_timing.run([PY, "-c", code], cols=cols, timeout=30, cwd=REPO_DIR)


def test_a_bar_fits_narrow_terminals_and_cuts_a_long_detail():
    for cols in (40, 60, 80, 132):
        r = _bar_on_pty(cols, "firmware", "300/600 s  140.2x real time, and a long tail " * 3)
        assert r.status == 0
        assert r.widest() <= cols - 1, (cols, r.segments())
        rows = [row for row in re.split(r"\r?\n", r.data.decode()) if row.strip()]
        assert len(rows) == 1 and rows[0].count("\r") >= 5  # redrawn in place
        assert "…" in r.data.decode()


def test_bar_line_keeps_label_and_percentage_and_shrinks_the_bar():
    line = progress.bar_line("cpython", 0.5, "300/600 s  140.2x real time", 80)
    assert line == "  cpython [###############---------------]  50%  300/600 s  140.2x real time"
    narrow = progress.bar_line("cpython", 0.5, "300/600 s  140.2x real time", 60)
    assert len(narrow) == 59 and narrow.startswith("  cpython [####") and "50%  300/600" in narrow
    assert progress.bar_line("cpython", 0.5, "x" * 70, 40) == "  cpython  50%  " + "x" * 22 + "…"


def test_without_a_terminal_a_bar_writes_a_line_per_tenth():
    out = io.StringIO()
    b = progress.Bar("model", lambda k, n, _w: f"{k}/{n}", stream=out)
    for k in range(0, 1001):
        b(k, 1000)
    lines = out.getvalue().splitlines()
    assert lines[0] == "  model:   0%  0/1000" and lines[-1] == "  model: 100%  1000/1000"
    assert len(lines) == 11


def test_columns_falls_back_to_80_when_nothing_is_a_terminal(monkeypatch):
    monkeypatch.delenv("COLUMNS", raising=False)
    monkeypatch.setattr(progress.shutil, "get_terminal_size", os.terminal_size)
    assert progress.columns(io.StringIO()) == 80
    monkeypatch.setenv("COLUMNS", "100")
    assert progress.columns(io.StringIO()) == 100


def _capture(path, seconds, times):
    """A capture of `seconds` of quick_start, the board restarting `times` times."""
    from host_emulator.runtimes import cpython
    from host_emulator.sim import board_input

    stim = board_input.simulate("quick_start", seconds, seed=0).stimulus
    out = cpython.run(stim, path.parent / "board").out
    path.write_bytes(out * times)


def test_monitor_shows_how_much_of_a_file_it_read_between_its_warnings(tmp_path):
    _capture(tmp_path / "cap.bin", 20, 12)  # 2.8 MB: a second or two to read
    r = tty_timing.run([PY, "-m", "tools.monitor", "--file", "cap.bin"], cols=80, timeout=120,
                       env=_env(), cwd=tmp_path)  # fmt: skip
    assert r.status == 0, r.data.decode(errors="replace")[-2000:]
    text = tty_timing.ANSI.sub(b"", r.data).decode()
    rows = [row for row in re.split(r"\r?\n", text) if "  reading [" in row]
    draws = [d for row in rows for d in row.split("\r") if d]
    assert draws and all(len(d) <= 79 for d in draws), draws
    mb = (tmp_path / "cap.bin").stat().st_size / 1e6
    assert len(draws) >= 2 and f"100%  {mb:.1f}/{mb:.1f} MB" in draws[-1]
    warnings = [w for w in re.split(r"\r?\n", text) if "the board restarted" in w]
    assert len(warnings) == 11  # each on a row of its own, the bar's row blanked first
    assert all(w.split("\r")[-1].startswith("warning: the board restarted") for w in warnings)


class _Tty(io.StringIO):
    def isatty(self):
        return True


def test_make_hands_each_line_to_the_build_and_keeps_the_log(tmp_path):
    from common import toolchain

    (tmp_path / "Makefile").write_text("all:\n\t@echo CC a.c\n\t@echo CC b.c\n\t@echo LINK x.elf\n")
    seen = []
    toolchain.make(["-C", str(tmp_path)], "a test", tmp_path / "make.log", seen.append)
    assert [s.strip() for s in seen if not s.startswith("make")] == ["CC a.c", "CC b.c",
                                                                     "LINK x.elf"]  # fmt: skip
    assert "CC b.c" in (tmp_path / "make.log").read_text()


def test_the_m4f_build_counts_what_make_compiled_and_promises_no_time(monkeypatch):
    from host_emulator.runtimes.m4f import build

    err = _Tty()
    monkeypatch.setattr(sys, "stderr", err)
    monkeypatch.setattr(progress, "REDRAW_S", 0.0)
    on_line, counter = build._compile_counter(True)
    for line in ("mkdir -p x/py/", "GEN x/genhdr/qstr.i.last", "CC ../../py/a.c", "MPY app.py",
                 "CC ../../py/b.c", "LINK x/firmware.elf", "text data bss"):  # fmt: skip
        on_line(line + "\n")
    counter.end()
    draws = [d for d in re.sub(r"\x1b\[K", "", err.getvalue()).split("\r") if d]
    assert [d.split(", ")[0] for d in draws[:2]] == ["  m4f build: generating qstr.i.last",
                                                      "  m4f build: 1 C files"]  # fmt: skip
    assert draws[3].startswith("  m4f build: 2 C files, 1 frozen modules compiled, 0 s")
    assert draws[4].startswith("  m4f build: linking firmware.elf") and draws[-1].endswith("\n")
    assert "~30 s" not in build.ANNOUNCE and len(build.ANNOUNCE.format(jobs=64)) < 80


def test_the_first_make_says_it_installs_and_lets_pip_show_its_progress(tmp_path):
    import os
    import subprocess

    venv = tmp_path / "venv"
    # as a user types it: not as a sub-make of `make test` (its "Entering directory" lines)
    env = {k: v for k, v in os.environ.items() if k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL")}
    proc = subprocess.run(["make", "-n", f"VENV={venv}", "demo"], cwd=REPO_DIR, env=env,
                          capture_output=True, text=True, check=True)  # fmt: skip
    lines = proc.stdout.splitlines()
    install = next(x for x in lines if "pip install" in x)
    assert lines[0].startswith("echo ") and "installing the pinned dependencies" in lines[0]
    assert "--quiet" not in install and " -q" not in install
