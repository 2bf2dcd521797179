"""The UsartGPU screen's pixels: the commands of usartgpu.py drawn into a palette-indexed
framebuffer, written as a PNG.

Text is drawn in fixed cells, an ASCII character `h / 2` pixels wide for a `DSh` command (the
half-width cells of the screen's GBK fonts: 6x12, 8x16, 12x24, 16x32), each cell first filled
with the colour `SBC` set (0 until then), so that a field redrawn over itself replaces its old
text. The glyphs are DejaVu Sans Mono (the copy matplotlib ships: the project's pinned
versions give the same pixels everywhere) at the largest size whose ascent and descent fit
the cell's height and whose advance fits its width, without anti-aliasing: the screen's own
fonts differ in shape, not in where a character sits.

Colours are palette indices; what they look like is not in the stream (the screen's manual
gives index 0 as black and no more, publicly), so the palette is the caller's, with a
16-colour default (`PALETTE`).
"""

import functools
import pathlib

import numpy as np

from host_emulator.display.usartgpu import DisplayError

# index -> (r, g, b): the 16 colours of a VGA text screen, 0 black, 15 white
PALETTE = (
    (0, 0, 0), (0, 0, 170), (0, 170, 0), (0, 170, 170), (170, 0, 0), (170, 0, 170),
    (170, 85, 0), (170, 170, 170), (85, 85, 85), (85, 85, 255), (85, 255, 85),
    (85, 255, 255), (255, 85, 85), (255, 85, 255), (255, 255, 85), (255, 255, 255),
)  # fmt: skip
FONT_HEIGHTS = {"DS12": 12, "DS16": 16, "DS24": 24, "DS32": 32}


@functools.cache
def _font(h):
    """The monospace font whose glyphs fit an (h / 2) x h cell."""
    import matplotlib
    from PIL import ImageFont

    path = pathlib.Path(matplotlib.get_data_path()) / "fonts" / "ttf" / "DejaVuSansMono.ttf"
    size = h
    while size > 4:
        f = ImageFont.truetype(str(path), size)
        ascent, descent = f.getmetrics()
        if ascent + descent <= h and f.getlength("W") <= h // 2:
            return f
        size -= 1
    raise DisplayError(f"no font size fits a {h // 2}x{h} cell")


@functools.cache
def glyph(h, ch):
    """The (h, h // 2) boolean mask of character `ch` in its cell."""
    from PIL import Image, ImageDraw

    f = _font(h)
    img = Image.new("1", (h // 2, h), 0)
    d = ImageDraw.Draw(img)
    d.fontmode = "1"  # no anti-aliasing: a pixel is the glyph's or not
    ascent, descent = f.getmetrics()
    x = (h // 2 - f.getlength(ch)) / 2
    d.text((x, (h - ascent - descent) // 2), ch, font=f, fill=1)
    return np.array(img, dtype=bool)


class Screen:
    """A width x height framebuffer of palette indices and the text background colour."""

    def __init__(self, size):
        self.size = size
        w, h = size
        self.pix = np.zeros((h, w), np.uint8)
        self.text_bg = 0

    def draw(self, cmd):
        """Draw one command (usartgpu.Command, already checked against the screen)."""
        a = cmd.args
        c = cmd.colour
        p = self.pix
        if cmd.name == "CLS":
            p[:, :] = c
        elif cmd.name == "SBC":
            self.text_bg = c
        elif cmd.name in FONT_HEIGHTS:
            self._text(a[0], a[1], a[2], FONT_HEIGHTS[cmd.name], c)
        elif cmd.name == "BOXF":
            p[a[1] : a[3] + 1, a[0] : a[2] + 1] = c
        elif cmd.name == "BOX":
            p[a[1], a[0] : a[2] + 1] = c
            p[a[3], a[0] : a[2] + 1] = c
            p[a[1] : a[3] + 1, a[0]] = c
            p[a[1] : a[3] + 1, a[2]] = c
        elif cmd.name == "PL":
            self._line(*a)
        elif cmd.name == "PS":
            p[a[1], a[0]] = c

    def _text(self, x, y, text, h, c):
        """Cells of h // 2 x h from (x, y) (usartgpu.parse_batch has checked they fit)."""
        w = h // 2
        for i, ch in enumerate(text):
            cell = self.pix[y : y + h, x + i * w : x + (i + 1) * w]
            cell[:, :] = self.text_bg
            cell[glyph(h, ch)] = c

    def _line(self, x0, y0, x1, y1, c):
        """Bresenham's line, both ends included."""
        dx, dy = abs(x1 - x0), -abs(y1 - y0)
        sx, sy = (1 if x0 < x1 else -1), (1 if y0 < y1 else -1)
        err = dx + dy
        while True:
            self.pix[y0, x0] = c
            if x0 == x1 and y0 == y1:
                return
            e2 = 2 * err
            if e2 >= dy:
                err += dy
                x0 += sx
            if e2 <= dx:
                err += dx
                y0 += sy

    def image(self, palette=PALETTE, scale=1):
        """A PIL image of the screen in `palette`'s colours (indices beyond it: magenta, so
        that a colour the firmware uses and the palette lacks shows), `scale` times larger."""
        from PIL import Image

        lut = np.full((256, 3), (255, 0, 255), np.uint8)
        lut[: len(palette)] = palette
        img = Image.fromarray(lut[self.pix], "RGB")
        if scale != 1:
            img = img.resize((img.width * scale, img.height * scale), Image.NEAREST)
        return img
