"""python -m tools.flash image: the built WEACT image written into a fake STM32 DFU bootloader
(tests/tools/fakedfu.py) by MicroPython's own pydfu, read back and verified; and every error a
user meets: no device, no libusb, another DFU device, another STM32, no permission, a
protected or failing flash, a missing or corrupt image."""

import re

import pytest
from fakedfu import BASE, FakeDfuSe, install

from tools.flash import dfu
from tools.flash.__main__ import main

SECTOR0, FS_START, FS_END, SECTOR4, CODE = (BASE, BASE + 0x4000, BASE + 0x10000, BASE + 0x10000,
                                           BASE + 0x20000)  # fmt: skip
SECTORS = [BASE + k * 0x4000 for k in range(4)] + [SECTOR4] + [CODE + k * 0x20000 for k in range(3)]


def _covered(parts):
    """The F411 sectors the image's parts cover: pydfu erases exactly those."""
    ends = SECTORS[1:] + [BASE + 0x80000]
    return [s for s, e in zip(SECTORS, ends, strict=True)
            if any(a < e and s < a + len(d) for a, d in parts)]  # fmt: skip


@pytest.fixture(scope="module")
def image(weact_image):
    """(path of the built .dfu, its parts [(address, bytes)])."""
    _, out, _, _ = weact_image
    path = out / "firmware.dfu"
    return path, dfu.read_image(path)


def test_a_built_image_is_flashed_verified_and_started(image, monkeypatch):
    path, parts = image
    board = FakeDfuSe()
    install(monkeypatch, board)
    lines = []
    result = dfu.flash(path, log=lines.append)
    for addr, data in parts:
        assert board.read(addr, len(data)) == data
    # sector 0 and the code's sectors from 4 on (4-6 for 286,736 B) erased, nothing else: the
    # filesystem (sectors 1-3) stays
    assert [a for a, _d in parts] == [SECTOR0, SECTOR4]
    assert board.erased == _covered(parts)
    assert board.erased[:3] == [SECTOR0, SECTOR4, CODE]
    assert not set(SECTORS[1:4]) & set(board.erased)
    assert board.read(FS_START, FS_END - FS_START) == b"\x5a" * (FS_END - FS_START)
    # every byte read back, and the filesystem's boot sector before (none there: nothing saved)
    assert board.uploads == sum(-(-len(d) // 2048) for _a, d in parts) + 1
    assert result["saved"] is None
    assert board.running and board.commands[-1] == ("set_address", BASE)
    assert result["elements"] == [(a, len(d)) for a, d in parts]
    text = "\n".join(lines)
    assert "the STM32F411's 512 KB flash" in text
    assert f"verified: {sum(len(d) for _a, d in parts):,} bytes" in text
    assert re.search(r"0x08010000: (2\d\d,\d{3}) of \1 bytes written \(100 %\)", text)


def _volume(blocks, root_entries, files):
    """A FAT volume of `blocks` blocks holding `files`, written by MicroPython's own FAT driver
    (the unix VM's VfsFat, as the twin writes a board's)."""
    from host_emulator.runtimes.f411 import flashfs
    from tools.flash import fatfs

    empty = fatfs.empty_volume(blocks, root_entries)
    empty += b"\xff" * (blocks * fatfs.BLOCK - len(empty))
    return flashfs.with_files(empty, files, fresh=False)


OLD_FILES = {
    "boot.py": b"# boot.py\r\n",
    "ins.cfg": bytes(range(256)) + b"cfg",
    "main.py": b"import board\n" * 300,
    "lib/navk.mpy": bytes(range(256)) * 120,
}


def test_an_earlier_images_filesystem_has_its_files_saved_before_the_flash(image, monkeypatch,
                                                                          tmp_path):  # fmt: skip
    """The port's own layout (an image before this one): a 64 KB volume, 128 blocks with a
    512-entry root directory, reaching into sector 4, which this image's code takes. Before
    anything is erased flash-image reads the volume (DfuSe UPLOAD) and saves its files beside
    the .dfu; then it flashes as ever (sectors 1-3 stay) and says to run deploy."""
    from tools.flash import fatfs

    dfu_path = tmp_path / "firmware.dfu"
    dfu_path.write_bytes(image[0].read_bytes())
    old = _volume(128, 512, OLD_FILES)
    assert fatfs.read_files(old) == (OLD_FILES, [])
    assert fatfs.read_files(old[: 96 * 512])[1]  # lib/navk.mpy reaches beyond sector 3
    board = FakeDfuSe()
    board.memory[FS_START - BASE : FS_START - BASE + len(old)] = old
    install(monkeypatch, board)
    lines = []
    result = dfu.flash(dfu_path, log=lines.append)
    saved = result["saved"]
    assert saved["blocks"] == 128 and saved["files"] == sorted(OLD_FILES) and saved["lost"] == []
    where = tmp_path / saved["dir"]
    assert where.parent == tmp_path and where.name.startswith("board-files-")
    assert {p.relative_to(where).as_posix(): p.read_bytes() for p in where.rglob("*")
            if p.is_file() and p.name != "volume.img"} == OLD_FILES  # fmt: skip
    assert (where / "volume.img").read_bytes() == old
    text = "\n".join(lines)
    assert "the board's filesystem is a 128-block (64 KB) FAT volume up to 0x08014000" in text
    assert "this image's code takes its flash from 0x08010000 on" in text
    assert "run deploy next (make deploy PORT=...), which formats it anew" in text
    assert board.erased == _covered(image[1])
    assert board.read(FS_START, 0xC000) == old[:0xC000]  # sectors 1-3 as they were


def test_a_filesystem_within_sectors_1_to_3_is_left_alone(image, monkeypatch, tmp_path):
    dfu_path = tmp_path / "firmware.dfu"
    dfu_path.write_bytes(image[0].read_bytes())
    vol = _volume(96, 32, {"ins.cfg": b"cfg"})
    board = FakeDfuSe()
    board.memory[FS_START - BASE : FS_START - BASE + len(vol)] = vol
    install(monkeypatch, board)
    assert dfu.flash(dfu_path, log=lambda _: None)["saved"] is None
    assert not list(tmp_path.glob("board-files-*"))
    assert board.read(FS_START, len(vol)) == vol


def test_the_cli_flashes_a_file(image, monkeypatch, capsys):
    install(monkeypatch, FakeDfuSe())
    assert main(["image", "--file", str(image[0])]) == 0
    out = capsys.readouterr().out
    assert "flash-image OK" in out and "make deploy PORT=" in out


def test_the_cli_flashes_the_boards_built_image(image, monkeypatch, tmp_path, capsys):
    from tools.image import build

    (tmp_path / "WEACT_F411_BLACKPILL").mkdir()
    (tmp_path / "WEACT_F411_BLACKPILL" / "firmware.dfu").write_bytes(image[0].read_bytes())
    monkeypatch.setattr(build, "OUT_ROOT", tmp_path)
    board = FakeDfuSe()
    install(monkeypatch, board)
    assert main(["image", "--board", "WEACT_F411_BLACKPILL"]) == 0
    assert board.read(SECTOR4, 16) == image[1][1][1][:16]


def _fails(argv, capsys):
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


def test_no_dfu_device_says_how_to_enter_dfu_mode(image, monkeypatch, capsys):
    install(monkeypatch)
    err = _fails(["image", "--file", str(image[0])], capsys)
    assert "no DFU device found" in err and "hold BOOT0, press and release NRST" in err
    assert "machine.bootloader()" in err and "udev rule" in err and "root" in err


def test_no_dfu_device_for_a_nucleo_says_to_use_its_st_link(image, monkeypatch, tmp_path, capsys):
    from tools.image import build

    (tmp_path / "NUCLEO_F411RE").mkdir()
    (tmp_path / "NUCLEO_F411RE" / "firmware.dfu").write_bytes(image[0].read_bytes())
    monkeypatch.setattr(build, "OUT_ROOT", tmp_path)
    install(monkeypatch)
    err = _fails(["image", "--board", "NUCLEO_F411RE"], capsys)
    assert "no DFU device found" in err and "no USB connector on the F411" in err
    assert "copy firmware.bin to the NOD_F411RE drive" in err


def test_no_libusb_backend_names_the_package(image, monkeypatch, capsys):
    install(monkeypatch, FakeDfuSe(), no_backend=True)
    err = _fails(["image", "--file", str(image[0])], capsys)
    assert "libusb is missing" in err and "apt-get install libusb-1.0-0" in err


def test_another_dfu_device_is_refused_before_erasing(image, monkeypatch, capsys):
    other = FakeDfuSe(vid=0x1209, pid=0x2002)
    install(monkeypatch, other)
    err = _fails(["image", "--file", str(image[0])], capsys)
    assert "(1209:2002) are not the STM32 ROM bootloader (0483:df11)" in err
    assert other.erased == [] and other.writes == 0


@pytest.mark.parametrize(
    "layout, kb",
    [
        ("@Internal Flash  /0x08000000/04*016Kg,01*064Kg,07*128Kg", 1024),  # F405/F407
        ("@Internal Flash  /0x08000000/04*016Kg,01*064Kg,01*128Kg", 256),  # F401xC
    ],
)
def test_another_stm32_is_refused_before_erasing(image, monkeypatch, capsys, layout, kb):
    chip = FakeDfuSe(layout=layout)
    install(monkeypatch, chip)
    err = _fails(["image", "--file", str(image[0])], capsys)
    assert "wrong chip" in err and f"its internal flash is {kb} KB at 0x08000000" in err
    assert "Nothing was erased or written" in err
    assert chip.erased == [] and chip.writes == 0 and set(chip.memory) == {0x5A}


def test_two_boards_in_dfu_mode_are_refused(image, monkeypatch, capsys):
    a, b = FakeDfuSe(), FakeDfuSe()
    install(monkeypatch, a, b)
    err = _fails(["image", "--file", str(image[0])], capsys)
    assert "2 STM32 boards are in DFU mode" in err and a.writes == b.writes == 0


def test_no_permission_suggests_a_udev_rule(image, monkeypatch, capsys):
    import usb.core

    board = FakeDfuSe()

    def denied(*_a, **_k):
        raise usb.core.USBError("Access denied (insufficient permissions)", errno=13)

    monkeypatch.setattr(board, "ctrl_transfer", denied)
    install(monkeypatch, board)
    err = _fails(["image", "--file", str(image[0])], capsys)
    assert "cannot be opened" in err and 'ATTRS{idProduct}=="df11"' in err and "as root" in err


def test_a_byte_that_reads_back_wrong_is_reported_at_its_address(image, monkeypatch, capsys):
    board = FakeDfuSe(flip=SECTOR4 + 0x1234)
    install(monkeypatch, board)
    err = _fails(["image", "--file", str(image[0])], capsys)
    want = image[1][1][1][0x1234]
    assert f"verify failed: at 0x08011234 the board holds 0x{want ^ 0xFF:02x} where the image " \
           f"has 0x{want:02x} (1 byte differs" in err  # fmt: skip
    assert not board.running  # left in DFU mode for another try


def test_a_protected_sector_stops_the_write(image, monkeypatch, capsys):
    board = FakeDfuSe(protect=(CODE + 0x20000, CODE + 0x40000))  # sector 6 write-protected
    install(monkeypatch, board)
    err = _fails(["image", "--file", str(image[0])], capsys)
    assert "the bootloader refused: DFU: erase failed (STATE_DFU_ERROR)" in err
    assert "option bytes" in err and "no complete image" in err


def test_a_missing_image_says_how_to_build_it(monkeypatch, tmp_path, capsys):
    from tools.image import build

    monkeypatch.setattr(build, "OUT_ROOT", tmp_path)
    err = _fails(["image", "--board", "NUCLEO_F411RE"], capsys)
    assert "no image for NUCLEO_F411RE" in err and "make image BOARD=NUCLEO_F411RE" in err
    err = _fails(["image", "--file", str(tmp_path / "none.dfu")], capsys)
    assert "no image" in err and "make image" in err


def test_a_corrupt_image_is_refused_before_any_usb(image, monkeypatch, tmp_path, capsys):
    board = FakeDfuSe()
    install(monkeypatch, board)
    bad = tmp_path / "bad.dfu"
    data = bytearray(image[0].read_bytes())
    data[1000] ^= 0x01
    bad.write_bytes(bytes(data))
    err = _fails(["image", "--file", str(bad)], capsys)
    assert "not a valid DfuSe image (CRC ERROR" in err and board.writes == 0
    (tmp_path / "text.dfu").write_text("not a dfu")
    err = _fails(["image", "--file", str(tmp_path / "text.dfu")], capsys)
    assert "is not a DfuSe image (it does not start with 'DfuSe')" in err
    (tmp_path / "short.dfu").write_bytes(b"DfuSe\x01")
    err = _fails(["image", "--file", str(tmp_path / "short.dfu")], capsys)
    assert "is not a valid DfuSe image (unpack requires" in err


def test_board_and_file_together_are_a_usage_error(capsys):
    with pytest.raises(SystemExit) as e:
        main(["image", "--board", "NUCLEO_F411RE", "--file", "x.dfu"])
    assert e.value.code == 2
