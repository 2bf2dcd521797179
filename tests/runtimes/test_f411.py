"""The f411 runtime: the image `make image` builds, on the emulated STM32F411 (host_emulator/
f411), fed as a board is. Both images are built (cached in build/image: a minute each on a
fresh checkout) and booted; the Black Pill's frames are compared with the model's byte for byte
over 30 s (what a user flashes is what the tests ran)."""

import pytest

from common import firmware_env
from common.proto import stream
from host_emulator import runtimes
from host_emulator.eval import parity
from host_emulator.f411 import boards
from host_emulator.f411.image import Image
from host_emulator.runtimes import f411
from host_emulator.runtimes.f411 import flashfs
from host_emulator.sim import board_input

BOARDS = tuple(boards.BOARDS)


@pytest.fixture(scope="module")
def quick_start_1s():
    return board_input.simulate("quick_start", duration_s=1.0, seed=0).stimulus


@pytest.mark.parametrize("board", BOARDS)
def test_the_image_boots_and_says_what_it_runs(board):
    """The banner of the first boot (the port formats its filesystem, then prints it): the
    MicroPython version pinned by the build, not the describe of whatever git repository holds
    the tree."""
    bd = boards.get(board)
    image = Image(*f411.image_files(board))
    text = flashfs.first_boot_console(bd, image)
    assert text.startswith("MicroPython v1.28.0 on "), text[:80]
    assert f"; {bd.machine} with STM32F411" in text
    assert text.endswith(">>> ")


@pytest.mark.parametrize("board", BOARDS)
def test_both_images_run_the_firmware_to_its_frames(board, quick_start_1s, tmp_path):
    fw = runtimes.get("f411").run(quick_start_1s, tmp_path, board=board)
    assert any(line.startswith("ins: running") for line in fw.console), fw.console
    frames, ext, raw, err = stream.split(fw.out)
    assert err is None
    assert len(frames) == len(quick_start_1s) and len(ext) == len(quick_start_1s) // 20
    assert [f[2] for f in frames] == [k & 0xFF for k in range(len(frames))]  # none missed
    pt = fw.per_tick
    assert fw.stats["overruns"] == 0 and fw.stats["late_ticks"] == 0 and not pt["late"].any()
    # the frames go out by DMA: no tick waits for the UART (uart_tx_data's spin)
    assert pt["poll_wait_cycles"].max() == 0
    # the 50 ms watchdog (firmware/board.py), fed at least four times per timeout
    assert fw.stats["watchdog_timeout_ms"] == 50.0 and fw.stats["watchdog_longest_gap_ms"] < 12.5
    assert fw.stats["resets"] == []
    assert fw.stats["gnss_rx_bytes"] == len(quick_start_1s.uart_bytes)
    assert fw.stats["gnss_rx_lost"] == 0
    assert fw.stats["rs485_muted"] == 0  # the transceiver's DE pin was high for every byte


def test_the_blackpill_images_frames_equal_the_models_over_30_s(tmp_path):
    stim = board_input.simulate("quick_start", duration_s=30.0, seed=0).stimulus
    r = parity.compare(stim, runtime="f411")
    assert r.identical, r.summary()
    assert r.bytes_firmware == len(stim) * 52 + len(stim) // 20 * 136
    assert r.firmware_stats["board"] == "WEACT_F411_BLACKPILL"
    assert r.firmware_stats["overruns"] == 0  # the firmware's own count: no tick missed


def test_with_python_kernels_the_image_runs_them_from_flash_lib(tmp_path):
    """The image freezes no Python kernels (firmware/manifest.py): with kernels="python" the
    twin deploys them to /flash/lib as .mpy instead of lib/navk.mpy, and the firmware loads and
    runs them there. They cannot keep the board's 5 ms tick (measured over 2 s: every tick
    late, 185 of 400 missed), which is why the board runs navk and the image needs no room for
    them."""
    stim = board_input.simulate("quick_start", duration_s=2.0, seed=0).stimulus
    files = f411.deployed_files(stim, None, "python", tmp_path / "files")
    kernels = ["lib/gnss_kern.mpy", "lib/nav_kern.mpy", "lib/yaw_gsf.mpy"]
    assert sorted(files) == ["ins.cfg", *kernels, "main.py"]
    assert all(files[f][:1] == b"M" for f in kernels)
    fw = runtimes.get("f411").run(stim, tmp_path, kernels="python", board="NUCLEO_F411RE")
    assert fw.stats["kernels"] == "python"
    assert "kernels: Python (navk not found)" in fw.console, fw.console
    assert any(line.startswith("ins: running") for line in fw.console)
    # valid frames, fewer than the ticks; the run's end may cut the last record (a late
    # tick's frame begun at the very end: the twin keeps every character started by then)
    d = stream.decode(fw.out)
    assert d.bad_checksum == d.bad_crc == 0 and d.skipped_bytes < stream.FRAME_LEN
    assert len(d.frames) > 50 and d.ext
    assert fw.stats["overruns"] > 0 and fw.stats["resets"] == []


def test_without_navk_the_image_says_why_it_cannot_start(tmp_path):
    """A board whose /flash lacks lib/navk.mpy (and, as every board, the Python kernels): one
    line on the console, no traceback, no loop, no watchdog; the REPL is the board's."""
    from host_emulator.runtimes.f411.console import TwinBoard

    stim = board_input.simulate("quick_start", duration_s=1.0, seed=0).stimulus
    files = f411.deployed_files(stim, None, "native", tmp_path)
    del files["lib/navk.mpy"]
    board = TwinBoard(files=files, workdir=tmp_path)
    assert board.run_until(b">>> ", 8000), board.console_text()
    text = board.console_text()
    assert ("ins: cannot start: no kernels: navk not found, and this image carries no Python "
            "kernels (no module named 'gnss_kern'): put lib/navk.mpy on /flash (make deploy "
            "PORT=...)\r\n") in text  # fmt: skip
    assert "Traceback" not in text and "ins: running" not in text
    assert not board.chip.iwdg.running


def test_the_blackpills_screen_gets_the_models_bytes_and_answers():
    """The display setting on: the image drives the UsartGPU screen on USART6 (PA11/PA12,
    mpconfigboard.h) by DMA; what it sends equals the model's byte for byte, and the screen's
    OKs come back into USART6 and are counted (the start page and three rounds' batches)."""
    stim = board_input.simulate("quick_start", duration_s=2.0, seed=0).stimulus
    r = parity.compare(stim, {"display": 1}, runtime="f411")
    assert r.identical and r.display_first_byte is None, r.summary()
    assert "display: status page on the screen's UART at 115200" in r.firmware_run.console
    st = r.firmware_stats
    assert st["display_batches"] == 4 and st["display_oks"] == 4, st
    assert st["display_missed"] == st["display_cause_frames"] == st["display_rx_lost"] == 0
    # no tick missed, and none late
    assert st["overruns"] == 0
    pt = r.firmware_run.per_tick
    assert not pt["late"].any(), pt[pt["late"]]
    marks = r.firmware_run.display_marks
    assert marks[0][0] == -1 and marks[-1][1] == len(r.display_firmware) > 1000
    assert all(a[0] < b[0] and a[1] < b[1] for a, b in zip(marks, marks[1:], strict=False))


def test_the_nucleo_has_no_screen_and_says_so():
    """The NUCLEO's three USARTs are taken: display=1 draws nothing, the console says why, and
    the model (told the board) agrees."""
    stim = board_input.simulate("quick_start", duration_s=1.0, seed=0).stimulus
    r = parity.compare(stim, {"display": 1}, runtime="f411", board="NUCLEO_F411RE")
    assert r.identical and r.display_firmware == r.display_model == b"", r.summary()
    assert any("no UART for the screen" in line for line in r.firmware_run.console)


def test_the_twins_wiring_is_the_firmwares_pin_table():
    board_py = firmware_env.import_module("board")
    for name, bd in boards.BOARDS.items():
        pins = board_py.BOARDS[bd.machine]
        assert pins == {
            "spi_id": bd.spi, "cs_accel": bd.cs_accel, "cs_gyro": bd.cs_gyro,
            "gnss_uart": bd.gnss_uart, "pps": bd.pps, "out_uart": bd.out_uart,
            "rs485_de": bd.rs485_de, "led": bd.led, "display_uart": bd.display_uart,
        }, name  # fmt: skip
    assert board_py.DEFAULT_BOARD == f411.DEFAULT_BOARD


def test_a_recorded_session_replays_on_the_image(tmp_path):
    """session replay --runtime f411: a board's recording (raw records on; here the CPython
    runtime's output stands for the board's) rebuilt into its input and run on the image: the
    same stream, the board's own clock in the raw records aside."""
    from common.proto import config as board_config
    from host_emulator.runtimes import cpython
    from host_emulator.session import record, replay

    sim = board_input.simulate("urban_drive", 3.0, seed=0).stimulus
    values = board_config.run_values(sim, {"raw_record": 1})
    (tmp_path / "capture.bin").write_bytes(cpython.run(sim, tmp_path / "b", {"raw_record": 1}).out)
    record.record(tmp_path / "capture.bin", tmp_path / "drive.ins", config=values)
    res = replay.replay(tmp_path / "drive.ins", tmp_path / "r", runtime="f411")
    assert res.identical, res.summary()
    assert res.run.runtime == "f411" and len(res.run.per_tick) == len(sim)


@pytest.mark.parametrize(
    "argv",
    [
        ["parity", "--scenario", "quick_start", "--duration", "1", "--board", "NUCLEO_F411RE"],
        ["run", "--scenario", "quick_start", "--duration", "1", "--runtime", "mpy_unix",
         "--board", "NUCLEO_F411RE", "--out", "unused"],
        ["session", "replay", "x.ins", "--runtime", "cpython", "--board", "NUCLEO_F411RE"],
    ],
)  # fmt: skip
def test_a_board_for_a_runtime_that_runs_no_image_is_a_usage_error(argv, capsys, tmp_path):
    from host_emulator.__main__ import main

    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--board is for --runtime f411" in err and "Traceback" not in err


def test_an_unknown_board_is_refused_naming_the_boards(capsys):
    from host_emulator.eval import parity as parity_cli

    assert parity_cli.main(["--scenario", "quick_start", "--duration", "1", "--runtime", "f411",
                            "--board", "PYBV11"]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "WEACT_F411_BLACKPILL" in err and "NUCLEO_F411RE" in err
