"""Write a firmware image (.dfu) to an STM32F411 in its ROM DFU bootloader, and verify it.

The USB work is MicroPython's own tools/pydfu.py, imported from the MicroPython tree
(common.toolchain.micropython_dir()), over pyusb and libusb. Around it this module adds what a
user needs before and after:

1. the .dfu is parsed by pydfu (its CRC checked) and its elements must lie in the F411's flash;
2. the DFU devices on the bus: none -> how to enter DFU mode; no backend -> libusb missing;
   the STM32 ROM bootloader is VID:PID 0483:df11, and its DfuSe memory layout (the string of
   alternate setting 0, "@Internal Flash  /0x08000000/04*016Kg,01*064Kg,03*128Kg" on an
   F411) must be the F411's 512 KB internal flash, all checked before anything is erased;
3. the board's filesystem is read (its FAT boot sector at 0x08004000): a volume an earlier
   image formatted over more flash than this image leaves it (the port's own layout: 64 KB,
   into sector 4, where this image's code goes) has its files saved on the host first, since
   what lies in sector 4 is about to be erased (deploy then formats the volume anew);
4. pydfu erases the sectors the image covers (sector 0 and 4-7: the filesystem in sectors 1-3
   survives) and writes them;
5. every element is read back with DfuSe UPLOAD (AN3156: set the address pointer, abort to
   dfuIDLE, UPLOAD block n reads wTransferSize bytes at pointer + (n - 2) * wTransferSize)
   and compared: the first differing address is reported;
6. pydfu leaves DFU mode: the board starts the new image.
"""

import contextlib
import importlib.util
import io
import struct

from common import toolchain
from tools.flash.errors import FlashError

STM32_BOOTLOADER = (0x0483, 0xDF11)
FLASH_BASE = 0x08000000
FS_BASE = 0x08004000  # sector 1: where the port's filesystem starts (its FAT boot sector)
F411_LAYOUT = [(FLASH_BASE, 4, 16 * 1024), (FLASH_BASE + 0x10000, 1, 64 * 1024),
               (FLASH_BASE + 0x20000, 3, 128 * 1024)]  # fmt: skip
F411_FLASH_BYTES = 512 * 1024
DFU_UPLOAD = 2
TIMEOUT_MS = 4000

_pydfu = None


class DfuError(FlashError):
    """A DFU step failed; the message says what to do."""


def load_pydfu():
    """MicroPython's tools/pydfu.py, imported from the MicroPython tree (once)."""
    global _pydfu
    if _pydfu is not None:
        return _pydfu
    try:
        src = toolchain.micropython_dir()
    except toolchain.ToolchainError as e:
        raise DfuError(f"{e}; flashing uses its tools/pydfu.py.") from None
    path = src / "tools" / "pydfu.py"
    if not path.is_file():
        raise DfuError(f"{path} is missing: set MICROPY_DIR to a MicroPython v1.28.0 tree.")
    try:
        import usb.core  # noqa: F401  (pydfu needs pyusb)
    except ImportError:
        raise DfuError(
            "pyusb is not installed: run `.venv/bin/pip install -r requirements.txt` (make "
            "does it)."
        ) from None
    spec = importlib.util.spec_from_file_location("pydfu", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    _pydfu = module
    return module


def read_image(path):
    """[(address, bytes)] of a .dfu file; DfuError if it is missing or not a valid DfuSe file."""
    pydfu = load_pydfu()
    said = io.StringIO()
    try:
        with open(path, "rb") as f:
            signature = f.read(5)
        if signature != b"DfuSe":
            raise DfuError(f"{path} is not a DfuSe image (it does not start with 'DfuSe').")
        with contextlib.redirect_stdout(said):
            elements = pydfu.read_dfu_file(str(path))
    except FileNotFoundError:
        raise DfuError(f"no image {path}: build it with `make image` (python -m tools.image "
                       "build --board BOARD) or pass --file with a .dfu.") from None  # fmt: skip
    except (OSError, ValueError, UnicodeDecodeError, struct.error) as e:
        raise DfuError(f"{path} is not a valid DfuSe image ({e}).") from None
    if not elements:
        detail = said.getvalue().strip().splitlines()
        raise DfuError(
            f"{path} is not a valid DfuSe image ({detail[-1] if detail else 'no elements'}): "
            "build it again with `make image`."
        )
    return [(e["addr"], bytes(e["data"])) for e in elements]


def layout_problem(text):
    """Why a DfuSe memory-layout string is not the F411's internal flash (None if it is)."""
    parts = text.split("/")
    if len(parts) < 3 or "internal flash" not in parts[0].lower():
        return f"its first memory is {parts[0].strip('@ ') or text!r}, not Internal Flash"
    try:
        addr = int(parts[1], 0)
        sectors = []
        for seg in parts[2].split(","):
            count, rest = seg.split("*")
            size = int(rest[:-2]) * {"K": 1024, "M": 1024 * 1024}.get(rest[-2], 1)
            sectors.append((addr, int(count), size))
            addr += int(count) * size
    except (ValueError, IndexError):
        return f"its memory layout {text!r} cannot be read"
    total = sum(n * size for _a, n, size in sectors)
    if sectors != F411_LAYOUT:
        return (
            f"its internal flash is {total // 1024} KB at 0x{sectors[0][0]:08x} "
            f"({parts[2].strip()}), not the STM32F411's 512 KB (4x16, 1x64, 3x128 KB sectors)"
        )
    return None


def _no_device_message(board):
    from tools.image.boards import BOARDS, DEFAULT_BOARD

    how = (board or BOARDS[DEFAULT_BOARD]).dfu
    return (
        f"no DFU device found. Put the board into its ROM DFU bootloader: {how}; from "
        "MicroPython's REPL, `import machine; machine.bootloader()` does the same. `lsusb` "
        "should then list 0483:df11 STMicroelectronics STM Device in DFU Mode. On Linux a udev "
        "rule for 0483:df11 (or running as root) may be needed for access."
    )


def find_device(board=None):
    """The one STM32 ROM bootloader on the bus; DfuError when none, several, or another."""
    pydfu = load_pydfu()
    import usb.core

    try:
        devices = pydfu.get_dfu_devices()
    except usb.core.NoBackendError:
        raise DfuError(
            "pyusb found no USB backend: libusb is missing. On Debian/Ubuntu install it with "
            "`sudo apt-get install libusb-1.0-0` (on macOS `brew install libusb`), then run "
            "the command again."
        ) from None
    except usb.core.USBError as e:
        raise DfuError(f"listing the USB devices failed: {e}.") from None
    if not devices:
        raise DfuError(_no_device_message(board))
    ours = [d for d in devices if (d.idVendor, d.idProduct) == STM32_BOOTLOADER]
    if not ours:
        found = ", ".join(f"{d.idVendor:04x}:{d.idProduct:04x}" for d in devices)
        raise DfuError(
            f"wrong device: the DFU device(s) on the bus ({found}) are not the STM32 ROM "
            "bootloader (0483:df11). Nothing was written. Unplug other DFU devices and put the "
            "STM32F411 board into DFU mode."
        )
    if len(ours) > 1:
        raise DfuError(
            f"{len(ours)} STM32 boards are in DFU mode: leave only the one to flash plugged in "
            "(nothing was written)."
        )
    return ours[0]


def memory_layout(device):
    """The DfuSe memory-layout string of the device's alternate setting 0."""
    pydfu = load_pydfu()
    import usb.core

    try:
        intf = device[0][(0, 0)]
        return pydfu.get_string(device, intf.iInterface) or ""
    except (usb.core.USBError, ValueError) as e:
        raise DfuError(_access_message(e)) from None


def _access_message(e):
    text = str(e)
    if getattr(e, "errno", None) == 13 or "ermission" in text or "langid" in text:
        return (
            f"the DFU device is there but cannot be opened ({text}): on Linux add a udev rule, "
            "e.g. a file /etc/udev/rules.d/49-stm32-dfu.rules with the line "
            'SUBSYSTEMS=="usb", ATTRS{idVendor}=="0483", ATTRS{idProduct}=="df11", '
            'MODE="0666", then `sudo udevadm control --reload` and re-plug the board; or run '
            "as root."
        )
    return f"talking to the DFU device failed ({text}): re-plug the board in DFU mode and retry."


def check_image_fits(elements):
    for addr, data in elements:
        if addr < FLASH_BASE or addr + len(data) > FLASH_BASE + F411_FLASH_BYTES:
            raise DfuError(
                f"the image has {len(data)} bytes at 0x{addr:08x}, outside the F411's flash "
                f"(0x{FLASH_BASE:08x}-0x{FLASH_BASE + F411_FLASH_BYTES - 1:08x}): is it an "
                "image for another chip? Nothing was written."
            )


def read_memory(addr, size):
    """size bytes of the device's memory from addr (DfuSe UPLOAD), after pydfu.init()."""
    pydfu = load_pydfu()
    dev = getattr(pydfu, "__dev")
    xfer = getattr(pydfu, "__cfg_descr").wTransferSize
    pydfu.set_address(addr)
    pydfu.abort_request()  # back to dfuIDLE: UPLOAD starts from the address pointer
    out = bytearray()
    block = 2
    while len(out) < size:
        n = min(xfer, size - len(out))
        data = bytes(dev.ctrl_transfer(0xA1, DFU_UPLOAD, block, 0, n, TIMEOUT_MS))
        if len(data) != n:
            raise DfuError(
                f"reading back 0x{addr + len(out):08x} returned {len(data)} bytes instead of "
                f"{n}: is the flash read-protected (RDP)? Re-plug in DFU mode and retry."
            )
        out += data
        block += 1
    pydfu.abort_request()
    return bytes(out)


def first_difference(a, b):
    for i, (x, y) in enumerate(zip(a, b, strict=True)):
        if x != y:
            return i
    return None


def _progress(log):
    shown = {}

    def progress(addr, offset, size):
        step = 4 * offset // size if size else 4
        if shown.get(addr, -1) < step:
            shown[addr] = step
            log(f"  0x{addr:08x}: {offset:,} of {size:,} bytes written ({25 * step} %)")

    return progress


def flash(path, board=None, log=print, verify=True):
    """Write the .dfu at path to the board in DFU mode, read it back, start it. Returns
    {"elements": [(address, size)], "device": "0483:df11", "layout": str}."""
    pydfu = load_pydfu()
    import usb.core

    elements = read_image(path)
    check_image_fits(elements)
    total = sum(len(d) for _a, d in elements)
    log(f"image {path}: {len(elements)} parts, {total:,} bytes: "
        + ", ".join(f"0x{a:08x} ({len(d):,} B)" for a, d in elements))  # fmt: skip
    device = find_device(board)
    layout = memory_layout(device)
    problem = layout_problem(layout)
    if problem:
        raise DfuError(
            f"wrong chip: the STM32 in DFU mode is not an STM32F411: {problem}. Nothing was "
            "erased or written. Build an image for this board (a NUCLEO/Black Pill with an "
            "STM32F411) or flash this one on the right board."
        )
    log(f"DFU device 0483:df11, {layout.strip()}: the STM32F411's 512 KB flash")
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            pydfu.init(idVendor=STM32_BOOTLOADER[0], idProduct=STM32_BOOTLOADER[1])
    except (usb.core.USBError, ValueError) as e:
        raise DfuError(_access_message(e) + " Nothing was written.") from None
    try:
        saved = save_overwritten_files(elements, path, log)
        log("erasing and writing (sector 0 and the code sectors; the filesystem stays)")
        with _stdout_to(log):
            pydfu.write_elements(
                [{"addr": a, "size": len(d), "data": d} for a, d in elements],
                False,
                _progress(log),
            )
        if verify:
            for addr, data in elements:
                back = read_memory(addr, len(data))
                i = first_difference(data, back)
                if i is not None:
                    n = sum(1 for x, y in zip(data, back, strict=True) if x != y)
                    differ = "1 byte differs" if n == 1 else f"{n:,} bytes differ"
                    raise DfuError(
                        f"verify failed: at 0x{addr + i:08x} the board holds 0x{back[i]:02x} "
                        f"where the image has 0x{data[i]:02x} ({differ} in the "
                        f"{len(data):,} written at 0x{addr:08x}). The board is left in DFU "
                        "mode: run the command again; if it repeats, try another USB cable or "
                        "port, and check that the flash is not write-protected."
                    )
            log(f"verified: {total:,} bytes read back equal the image")
        with _stdout_to(log):
            pydfu.exit_dfu()
    except SystemExit as e:  # pydfu's check_status: "DFU: <stage> failed (<state>)"
        raise DfuError(
            f"the bootloader refused: {e}. If the flash is write- or read-protected, clear "
            "the option bytes with STM32CubeProgrammer; otherwise re-enter DFU mode and run "
            "the command again (the board has no complete image until it succeeds)."
        ) from None
    except usb.core.USBError as e:
        raise DfuError(_access_message(e) + " The board has no complete image until a flash "
                       "succeeds.") from None  # fmt: skip
    log("done: the board left DFU mode and runs the new image")
    if saved:
        log(f"its filesystem reached into the flash this image took: run deploy next (make "
            f"deploy PORT=...), which formats it anew and keeps ins.cfg and the files it can "
            f"still read; the copies in {saved['dir']} are of all of them (CONFIG="
            f"{saved['dir']}/ins.cfg gives deploy the configuration)")  # fmt: skip
    return {
        "elements": [(a, len(d)) for a, d in elements],
        "device": "{:04x}:{:04x}".format(*STM32_BOOTLOADER),
        "layout": layout,
        "saved": saved,
    }


def save_overwritten_files(elements, path, log):
    """When the board's FAT volume (its boot sector at FS_BASE, read with DfuSe UPLOAD) reaches
    into flash this image writes (an earlier image's, formatted over 64 KB into sector 4),
    read the whole volume and save its files beside the .dfu in board-files-<time>/, before
    anything is erased. {"dir", "files", "lost", "blocks"} or None (no volume, or none in the
    way)."""
    import pathlib
    import time

    from tools.flash import fatfs

    boot = fatfs.boot_sector(read_memory(FS_BASE, fatfs.BLOCK))
    if boot is None:
        return None
    end = FS_BASE + boot["blocks"] * fatfs.BLOCK
    if not any(a < end and FS_BASE < a + len(d) for a, d in elements):
        return None
    volume = read_memory(FS_BASE, min(end, FLASH_BASE + F411_FLASH_BYTES) - FS_BASE)
    try:
        files, lost = fatfs.read_files(volume)
    except (fatfs.FatError, ValueError, IndexError, struct.error):
        files, lost = {}, ["(the volume could not be read)"]
    out = pathlib.Path(path).resolve().parent / f"board-files-{time.strftime('%Y%m%d-%H%M%S')}"
    for rel, data in files.items():
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_bytes(data)
    (out / "volume.img").parent.mkdir(parents=True, exist_ok=True)
    (out / "volume.img").write_bytes(volume)
    log(
        f"the board's filesystem is a {boot['blocks']}-block ({boot['blocks'] // 2} KB) FAT "
        f"volume up to 0x{end:08x}, formatted by an earlier image: this image's code takes its "
        f"flash from 0x{min(a for a, _d in elements if a + len(_d) > FS_BASE):08x} on. Its "
        f"{len(files)} files ({', '.join(sorted(files)) or 'none'}) are saved in {out}, with "
        "the whole volume (volume.img)" + (f"; unreadable: {', '.join(lost)}" if lost else "")
    )
    return {"dir": str(out), "files": sorted(files), "lost": lost, "blocks": boot["blocks"]}


@contextlib.contextmanager
def _stdout_to(log):
    """pydfu prints (status strings, 'Failed to reset device'): pass its lines to log."""
    buf = io.StringIO()
    try:
        with contextlib.redirect_stdout(buf):
            yield
    finally:
        for line in buf.getvalue().splitlines():
            if line.strip():
                log("  pydfu: " + line.strip())
