"""Pictures of the board's screen over a run (`--display PATH` of run, replay, session
replay): PATH, the screen at the end of the run, twice its size; and PATH's strip
(`NAME_strip.png` beside it), the screen at STRIP moments spread over the run, each under its
time. Drawn from what the firmware sent to the screen's UART (FirmwareRun.display), through the
strict reader and the renderer (usartgpu.py, screen.py, device.play).
"""

import io
from pathlib import Path

from common.errors import EmulatorError, write_atomic
from host_emulator.display import device
from host_emulator.display.screen import PALETTE, Screen

STRIP = 8  # screens in the strip
STRIP_COLUMNS = 4
SCALE = 2  # the end screen's pixels per screen pixel


def check_path(path):
    """The --display argument as a Path; EmulatorError unless it names a .png file."""
    p = Path(path)
    if p.suffix.lower() != ".png" or p.is_dir():
        raise EmulatorError(f"--display takes the path of a .png file to write, not {path!r}")
    return p


def strip_path(path):
    p = Path(path)
    return p.with_name(p.stem + "_strip" + p.suffix)


def _png(img):
    buf = io.BytesIO()
    img.save(buf, "PNG")
    return buf.getvalue()


def _caption(img, text):
    """img with `text` in a band under it."""
    from PIL import Image, ImageDraw

    band = 18
    out = Image.new("RGB", (img.width, img.height + band), (255, 255, 255))
    out.paste(img, (0, 0))
    ImageDraw.Draw(out).text((4, img.height + 3), text, fill=(0, 0, 0))
    return out


def screens(fw, size, tick_s, duration_s, moments=STRIP):
    """[(t_s, Screen)] at `moments` times spread over the run, the last at its end."""
    if not fw.display:
        raise EmulatorError(
            "the firmware sent nothing to the screen's UART: the display setting is off, or "
            "this board has no UART for the screen (docs/display.md)"
        )
    at = [duration_s * (i + 1) / moments for i in range(moments)]
    out = []
    for t, pix in device.play(fw.display, fw.display_marks, size, tick_s, at):
        s = Screen(size)
        s.pix = pix
        out.append((t, s))
    return out


def write(fw, size, tick_s, duration_s, path, palette=PALETTE):
    """Write the end screen to `path` and the strip beside it; the two paths."""
    from PIL import Image

    path = check_path(path)
    shots = screens(fw, size, tick_s, duration_s)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise EmulatorError(f"cannot create {path.parent}: {e.strerror}") from None
    write_atomic(path, _png(shots[-1][1].image(palette, SCALE)))
    tiles = [_caption(s.image(palette), f"t = {t:.1f} s") for t, s in shots]
    w, h = tiles[0].size
    rows = -(-len(tiles) // STRIP_COLUMNS)
    gap = 4
    sheet_size = (STRIP_COLUMNS * (w + gap) - gap, rows * (h + gap) - gap)
    sheet = Image.new("RGB", sheet_size, (255, 255, 255))
    for i, tile in enumerate(tiles):
        sheet.paste(tile, ((i % STRIP_COLUMNS) * (w + gap), (i // STRIP_COLUMNS) * (h + gap)))
    strip = strip_path(path)
    write_atomic(strip, _png(sheet))
    return [path, strip]
