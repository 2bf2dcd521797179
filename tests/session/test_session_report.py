"""`session report` (host_emulator/session/report.py): report.md and plots of a board
recording, here the emulator's own output of urban_drive written as a session file (as
tests/session/test_session.py makes its recordings), its figures checked against the frames
the file holds."""

import numpy as np
import pytest

from common.proto import config as board_config
from common.proto import session_file, stream
from host_emulator.runtimes import cpython
from host_emulator.session import cli
from host_emulator.session import report as session_report
from host_emulator.sim import board_input

DURATION_S = 80.0  # urban_drive stands for 60 s, then drives: navigating from ~64 s


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """(path of a session file, its captured bytes, the configuration values)."""
    d = tmp_path_factory.mktemp("recording")
    sim = board_input.simulate("urban_drive", DURATION_S, seed=0).stimulus
    values = board_config.run_values(sim, {})
    out = cpython.run(sim, d, {}).out
    session_file.write_session(d / "drive.ins", out, config=values)
    return d / "drive.ins", out, values


def _row(text, name):
    """The value column of report.md's row `name`."""
    for line in text.splitlines():
        if line.startswith(f"| {name} |"):
            return line.split("|")[2].strip()
    raise AssertionError(f"no row {name!r} in report.md")


def test_the_report_of_a_recording_gives_its_figures_and_plots(recording, tmp_path, capsys):
    path, out, values = recording
    assert cli.main(["report", str(path), "--out", str(tmp_path / "rep")]) == 0
    text = (tmp_path / "rep" / "report.md").read_text()
    d = stream.decode(out)
    every = board_config.from_values(values).output_every_ticks
    nav_s = sum(f["nav_state"] == 2 for f in d.frames) * every * 0.005
    assert 5.0 < nav_s < DURATION_S - 60.0  # it navigated, after the standstill
    assert _row(text, "52-byte frames") == str(len(d.frames)) == str(int(DURATION_S / 0.005))
    assert _row(text, "extended frames") == str(len(d.ext))
    assert _row(text, "time navigating").startswith(f"{nav_s:.1f} s")
    assert _row(text, "duration") == f"{DURATION_S:.1f} s"
    assert _row(text, "dropped frames (counter gaps; a restart adds one)") == "0"
    assert _row(text, "board starts in the recording") == "1"
    health = np.array([e["health"] for e in d.ext])
    assert _row(text, "normal") == f"{100 * np.mean(health == 0):.1f} %"
    aligning = np.mean([e["nav_state"] != 2 for e in d.ext])
    assert _row(text, "not_navigating") == f"{100 * aligning:.1f} %"
    for p in session_report.PLOTS:
        assert (tmp_path / "rep" / p).stat().st_size > 10_000, p
        assert f"({p})" in text
    assert f"{len(d.frames)} frames over {DURATION_S:.1f} s" in capsys.readouterr().out


def test_a_restart_is_found_and_marked(recording):
    """The board restarted halfway: two starts, the clock carries on, a line on each plot."""
    path, out, values = recording
    offsets = [off for kind, off, _ in stream.StreamDecoder().records(out, final=True)
               if kind == stream.FRAME]  # fmt: skip
    half = offsets[len(offsets) // 2]  # the board resets before sending this frame
    restarted = path.with_name("restart.ins")
    session_file.write_session(restarted, out[:half] + out, config=values)
    run = session_report.load(restarted)
    assert len(run.restarts) == 1 and np.all(np.diff(run.tr.t_s) > 0)
    assert run.restarts[0] == pytest.approx(DURATION_S / 2, abs=0.2)
    assert session_report.figures(run)["starts"] == 2
    plt = session_report.report.pyplot()
    fig = session_report.health_figure(plt, "t", run)
    assert "board restart" in [ln.get_label() for ln in fig.axes[0].lines]
    plt.close(fig)


def test_a_bad_file_is_one_line_and_exit_1(tmp_path, capsys):
    bad = tmp_path / "noise.ins"
    bad.write_bytes(bytes(range(256)) * 10)
    assert cli.main(["report", str(bad), "--out", str(tmp_path / "rep")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "no board output in it" in err, err
    assert cli.main(["report", str(tmp_path / "missing.ins")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "cannot read session" in err, err
