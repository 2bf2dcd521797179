"""The emulated UsartGPU's timing (display/device.py) and the pictures of a run's screen
(display/pictures.py, `run --display`)."""

import json

import numpy as np
import pytest

from common.errors import EmulatorError
from host_emulator import runtimes
from host_emulator.__main__ import main
from host_emulator.display import device, pictures
from host_emulator.display.screen import Screen
from host_emulator.display.usartgpu import DisplayError, Stream
from host_emulator.runtimes import FirmwareRun
from host_emulator.sim import board_input


def test_the_screen_answers_each_batch_after_drawing_it():
    gpu = device.UsartGpu((320, 240), baud=115200)
    gpu.receive(b"CLS(0);DS16(3,3,'UP',15);", 1_000)
    assert gpu.replies(10_000_000) == b""  # no \r\n: nothing drawn, no answer
    gpu.receive(b"\r\nCLS(1);\r\n", 2_000)  # two batches end at 2 ms
    back = 4 * 10e6 / 115200
    first = 2_000 + device.DRAW_BASE_US + device.DRAW_PER_COMMAND_US * 1.5 + back
    assert gpu.replies(first - 1) == b""
    assert gpu.replies(first) == b"OK\r\nOK\r\n"
    assert gpu.replies(first + 1e6) == b""  # each once
    assert gpu.commands == 3 and (gpu.screen.pix == 1).all() and gpu.demo_at_us is None


def test_a_screen_left_without_commands_for_10_s_starts_its_demo():
    gpu = device.UsartGpu((320, 240))
    gpu.demo_check(9_000_000)
    assert gpu.demo_at_us is None
    gpu.receive(b"CLS(0);\r\n", 10_500_000)
    assert gpu.demo_at_us == device.DEMO_AFTER_US


def test_a_broken_stream_stops_the_screen_with_the_bytes():
    gpu = device.UsartGpu((320, 240))
    with pytest.raises(DisplayError, match="byte 7"):
        gpu.receive(b"CLS(0);CIR(1,2,3,4);\r\n", 1000)


def _run_of(chunks):
    data, marks = b"", []
    for tick, chunk in chunks:
        data += chunk
        marks.append((tick, len(data)))
    return FirmwareRun("test", b"", [], 0, 0.0, display=data, display_marks=marks)


def test_the_strip_shows_the_screen_as_drawn_by_each_moment(tmp_path):
    run = _run_of([(-1, b"CLS(0);\r\n"), (100, b"CLS(1);\r\n"), (300, b"CLS(2);"),
                   (301, b"\r\n")])  # fmt: skip
    shots = pictures.screens(run, (220, 176), 0.005, 2.0, moments=4)
    assert [t for t, _ in shots] == [0.5, 1.0, 1.5, 2.0]
    # at 0.5 s (tick 100) CLS(1) has come; CLS(2)'s batch ends at tick 301 (1.505 s)
    assert [int(s.pix[0, 0]) for _, s in shots] == [1, 1, 1, 2]
    paths = pictures.write(run, (220, 176), 0.005, 2.0, tmp_path / "s.png")
    assert paths == [tmp_path / "s.png", tmp_path / "s_strip.png"]
    from PIL import Image

    assert Image.open(paths[0]).size == (440, 352)
    assert Image.open(paths[1]).size[0] == 4 * 220 + 3 * 4
    with pytest.raises(EmulatorError, match="sent nothing to the screen"):
        pictures.screens(_run_of([]), (220, 176), 0.005, 2.0)
    with pytest.raises(EmulatorError, match="a .png file"):
        pictures.check_path(tmp_path / "s.jpg")


def test_run_with_display_draws_a_readable_status_page(tmp_path, capsys):
    """The command of docs/display.md: the screen at the end equals a fresh drawing of what
    the firmware sent, shows the run navigating, and is in the report."""
    png = tmp_path / "screen.png"
    argv = ["run", "--scenario", "quick_start", "--duration", "30", "--out", str(tmp_path / "r"),
            "--quiet", "--display", str(png)]  # fmt: skip
    assert main(argv) == 0
    assert f"screen: {png}" in capsys.readouterr().out
    frames = (tmp_path / "r" / "frames.bin").read_bytes()
    assert frames  # the output stream is the run's as ever
    m = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert m["display_bytes"] > 3000 and 100 < m["display_bytes_per_s"] < 1000
    assert (
        "![the status page at the end of the run](screen.png)"
        in (tmp_path / "r" / "report.md").read_text()
    )
    from PIL import Image

    # the model's bytes for the same run, drawn afresh: the same picture, pixel for pixel
    stim = board_input.simulate("quick_start", duration_s=30, seed=0).stimulus
    model = runtimes.get("model").run(stim, None, {"display": 1})
    shots = pictures.screens(model, (320, 240), 0.005, 30.0)
    end = np.asarray(Image.open(png))
    ref = np.asarray(shots[-1][1].image(scale=2))
    assert (end == ref).all()
    assert 0.02 < (end[::2, ::2] != 0).any(axis=2).mean() < 0.2  # text on the black page
    assert "'navigating'" in model.display.decode()
    assert (tmp_path / "screen_strip.png").exists() and (tmp_path / "r" / "screen.png").exists()
    assert main(["run", "--scenario", "quick_start", "--duration", "2", "--quiet", "--out",
                 str(tmp_path / "r2"), "--display", str(tmp_path)]) == 1  # fmt: skip
    assert "--display takes the path of a .png file" in capsys.readouterr().err


def test_the_stream_reader_sees_the_page_as_the_screen_draws_it():
    """A page drawn byte by byte and whole gives the same pixels (the screen's batches)."""
    data = b"SBC(0);CLS(0);DS16(3,3,'UP',15);\r\nDS16(59,3,'   0:00:01',15);\r\n"
    whole, single = Screen((320, 240)), Screen((320, 240))
    s1, s2 = Stream((320, 240)), Stream((320, 240))
    for c in s1.feed(data):
        whole.draw(c)
    for i in range(len(data)):
        for c in s2.feed(data[i : i + 1]):
            single.draw(c)
    assert (whole.pix == single.pix).all() and (whole.pix == 15).sum() > 50
