"""deploy (tools/flash) against the image itself, the NUCLEO-F411RE's on the emulated STM32F411
(its REPL is USART2: runtimes/f411/console.py), for the filesystem of our flash layout: 48 KB
in sectors 1-3 (tools/image/boards/stm32f411_fs48.ld), the code from sector 4.

- a board that had an earlier image (the port's own layout: a 128-block volume over 64 KB,
  into sector 4) and gets this one: the volume still mounts, but what lay in sector 4 is gone
  (main.py and lib/navk.mpy after two deploys: the board starts with a SyntaxError, reading
  them gives EIO); `config set` refuses to write; deploy formats the volume anew, keeps
  ins.cfg and boot.py (read first, written back, copies on the host), writes main.py and
  lib/navk.mpy, and the firmware runs with the configuration it had;
- a freshly formatted board (the port's f_mkfs: a 512-entry root directory, 31 KB of files,
  less than lib/navk.mpy and main.py need): deploy gives it the compact root directory (46 KB
  of files) and the firmware runs.

Each deploy sends the 30 KB native module through the 115200-baud REPL: 15-30 s of wall time.
No character may be lost on the way: `uart.rx_lost` stays 0 (each write's run ends with
os.sync(), tools/flash/deploy.py Board.write: without it the storage interrupt's erase,
250 ms of stalled core, lost 159-373 characters of the next run, and the deploy failed)."""

import pytest

from common.proto import config as board_config
from host_emulator.runtimes import f411
from host_emulator.runtimes.f411 import flashfs
from host_emulator.runtimes.f411.console import TwinBoard
from host_emulator.sim import board_input
from tools.flash import deploy, fatfs
from tools.flash import maintenance as maint
from tools.flash.errors import FlashError

FS = 48 * 1024


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """What deploy writes next to the frozen image (main.py, ins.cfg, lib/navk.mpy)."""
    stim = board_input.simulate("quick_start", duration_s=1.0, seed=0).stimulus
    return f411.deployed_files(stim, {"output_every_ticks": 2}, "native",
                               tmp_path_factory.mktemp("files"))  # fmt: skip


def _earlier_images_volume(files):
    """The 64 KB volume an image of the port's layout formats (128 blocks, 512 root entries),
    with its factory files and two deploys, the second with a changed lib/navk.mpy: FatFs
    allocates the new clusters after the old ones, beyond the first 48 KB."""
    empty = fatfs.empty_volume(128, fatfs.PORT_ROOT_ENTRIES)
    vol = empty + b"\xff" * (128 * fatfs.BLOCK - len(empty))
    vol = flashfs.with_files(vol, {"boot.py": b"# boot.py -- run on boot\r\n",
                                   "main.py": b"# main.py -- put your code here!\r\n"},
                             fresh=False)  # fmt: skip
    vol = flashfs.with_files(vol, files, fresh=False)
    changed = {**files, "lib/navk.mpy": files["lib/navk.mpy"][:-16] + bytes(16)}
    vol = flashfs.with_files(vol, changed, fresh=False)
    return flashfs.with_files(vol, files, fresh=False)


def _twin(monkeypatch, tmp_path, partition=None, files=None):
    board = TwinBoard(files=files or {}, workdir=tmp_path)
    if partition is not None:
        board.chip.flash_write_raw(flashfs.PART_BASE, partition)
    monkeypatch.setattr(deploy, "open_port", lambda port, baud: board)
    # the twin's board time runs with the test's polls, slower than a board's on a busy machine
    # (make test's workers): the tools' 5 s of silence become 30 s here
    connect = deploy.connect
    monkeypatch.setattr(deploy, "connect", lambda *a, **k: connect(*a, **{**k, "timeout": 30.0}))
    monkeypatch.setattr(deploy, "SAVE_ROOT", tmp_path / "saved")
    monkeypatch.setattr(maint, "SETTLE_S", 0.0)
    return board


def _volume(board):
    return board.chip.flash_bytes(flashfs.PART_BASE, FS)


def test_deploy_formats_an_earlier_images_volume_keeping_its_configuration(
    files, flash_build_dir, monkeypatch, tmp_path
):
    old = _earlier_images_volume(files)
    assert fatfs.read_files(old) == ({"boot.py": b"# boot.py -- run on boot\r\n", **files}, [])
    kept, lost = fatfs.read_files(old[:FS])
    assert sorted(kept) == ["boot.py", "ins.cfg"] and sorted(lost) == ["lib/navk.mpy", "main.py"]
    board = _twin(monkeypatch, tmp_path, old[:FS])
    # what the board does with it: the volume mounts, main.py cannot be read
    assert board.run_until(b">>> ", 8000), board.console_text()
    text = board.console_text()
    assert 'File "main.py", line 1\r\nSyntaxError: invalid syntax' in text
    assert "ins: running" not in text
    # config set refuses to write into it, saying what to do
    with pytest.raises(FlashError) as e:
        deploy.write_config("twin", 115200, board_config.to_bytes({}), log=lambda _: None)
    assert "needs formatting anew before writing ins.cfg" in str(e.value)
    assert "larger than this image's 96-block (48 KB) filesystem" in str(e.value)
    assert "Run `make deploy PORT=...`" in str(e.value) and "Nothing was written" in str(e.value)
    assert _volume(board) == old[:FS]
    # deploy formats it anew, keeps what it can read, writes the firmware's files again
    lines = []
    r = deploy.deploy(flash_build_dir, "twin", log=lines.append)
    assert board.uart.rx_lost == 0
    said = "\n".join(lines)
    assert "the board's filesystem needs formatting anew: its FAT volume is 128 blocks (64 KB)" \
        in said  # fmt: skip
    assert "formatted /flash anew: 47104 bytes, 47104 free (512-byte clusters); keeping " \
        "boot.py, ins.cfg (read now, written back)" in said  # fmt: skip
    assert r["formatted"]["kept"] == ["boot.py", "ins.cfg"] and r["formatted"]["lost"] == []
    saved = tmp_path / "saved"
    assert (next(saved.iterdir()) / "ins.cfg").read_bytes() == files["ins.cfg"]
    assert sorted(r["written"]) == ["lib/navk.mpy", "main.py"]
    assert "configuration /flash/ins.cfg loaded" in r["console"]  # the one it had
    assert "ins: running" in r["console"]
    vol = _volume(board)
    assert fatfs.boot_sector(vol)["blocks"] == 96 and fatfs.boot_sector(vol)["root_entries"] == 32
    got, lost = fatfs.read_files(vol)
    assert lost == [] and got == {"boot.py": b"# boot.py -- run on boot\r\n", **files}
    # and a reset starts the firmware from it (the port mounts it as its own)
    at = len(board.console)
    board.chip.request_reset("test: power cycle")
    assert board.run_until(b"ins: running", 8000, since=at), board.console_text()[at:]
    # a second deploy finds nothing to format or write
    lines.clear()
    again = deploy.deploy(flash_build_dir, "twin", log=lines.append)
    assert again["formatted"] is None and again["written"] == []


def test_deploy_gives_a_freshly_formatted_volume_room_for_the_native_kernels(
    files, flash_build_dir, monkeypatch, tmp_path
):
    board = _twin(monkeypatch, tmp_path)  # the port's first boot: f_mkfs, its factory files
    part = _volume(board)
    assert fatfs.boot_sector(part)["root_entries"] == 512 and fatfs.boot_sector(part)["clusters"] \
        == 62  # fmt: skip
    need = sum(-(-len(files[f]) // 512) for f in ("main.py", "lib/navk.mpy")) + 1  # with lib/
    assert need > 62 - 2  # main.py and lib/navk.mpy alone do not fit beside boot.py, main.py
    assert board.run_until(b">>> ", 8000), board.console_text()
    lines = []
    dry = deploy.deploy(flash_build_dir, "twin", dry_run=True, log=lines.append)
    assert dry["dry_run"] and dry["written"] == [] and _volume(board) == part
    assert "would format it anew (96 blocks, a 32-entry root directory), keeping boot.py " \
        "(read now, written back)" in "\n".join(lines)  # fmt: skip
    assert sorted(f["path"] for f in dry["planned"]) == ["lib/navk.mpy", "main.py"]
    lines = []
    r = deploy.deploy(flash_build_dir, "twin", log=lines.append)
    said = "\n".join(lines)
    assert "it has the port's layout, whose 512-entry root directory leaves 62 clusters " \
        "(31 KB) for files; with a 32-entry one its 96 blocks hold 92 (46 KB)" in said  # fmt: skip
    assert r["formatted"]["kept"] == ["boot.py"]
    assert "ins: running" in r["console"] and board.uart.rx_lost == 0
    got, lost = fatfs.read_files(_volume(board))
    assert lost == [] and sorted(got) == ["boot.py", "lib/navk.mpy", "main.py"]


def test_the_twins_volume_is_the_same_whatever_the_hosts_clock(files, monkeypatch):
    """The unix VM's FAT driver stamps what it writes with the host's local time; the twin's
    volume carries the time a board's RTC gives after a cold start instead (1 January 2015),
    so a volume written at another hour (here: in two time zones a day apart) is the same
    bytes, and the image does the same thing on it."""
    vols = []
    for tz in ("Etc/GMT-12", "Etc/GMT+12"):
        monkeypatch.setenv("TZ", tz)
        empty = fatfs.empty_volume(96)
        vols.append(flashfs.with_files(empty + b"\xff" * (96 * 512 - len(empty)), files,
                                       fresh=False))  # fmt: skip
    assert vols[0] == vols[1]
    assert fatfs.read_files(vols[0]) == (files, [])
    entries = list(fatfs.Volume(vols[0]).entries([]))
    assert {p for p, _, _ in entries} >= {"main.py", "ins.cfg", "lib", "lib/.", "lib/navk.mpy"}
    assert {e[22:26] for _, _, e in entries} == {bytes.fromhex("00002146")}  # 00:00, 2015-01-01
