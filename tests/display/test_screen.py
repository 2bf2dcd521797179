"""display/screen.py: the pixels the UsartGPU commands draw: the primitives, text cells that
redraw over themselves, and a known stream against a committed golden screen."""

import pathlib

import numpy as np

from host_emulator.display import screen
from host_emulator.display.usartgpu import Stream

SIZE = (320, 240)
GOLDEN = pathlib.Path(__file__).with_name("golden_screen.png")
# a status page as the firmware might draw it: every command kind, every font height
PAGE = (
    b"CLS(0);BOX(0,0,319,239,7);SBC(1);DS24(8,4,'INS NAVIGATING',15);SBC(0);"
    b"DS16(8,36,'lat  48.1234567 N',14);DS16(8,56,'lon  11.7654321 E',14);"
    b"DS16(8,76,'h 512.3 m  v 13.9 m/s',15);DS12(8,100,'hdg 271.4 roll -0.3 pitch 1.2',10);"
    b"DS32(8,120,'HEALTH 0',10);BOXF(8,160,111,175,2);PL(120,160,311,230,12);PS(315,5,15);"
    b"DS12(8,224,'GNSS 4 sat 12 hdop 0.9',7);\r\n"
)


def _page():
    s = screen.Screen(SIZE)
    for cmd in Stream(SIZE).feed(PAGE):
        s.draw(cmd)
    return s


def test_the_primitives_draw_the_pixels_they_name():
    s = screen.Screen((20, 10))
    for cmd in Stream((20, 10)).feed(
        b"CLS(3);BOX(1,1,5,4,7);BOXF(10,2,12,3,9);PL(0,9,4,5,1);PS(19,0,2);\r\n"
    ):
        s.draw(cmd)
    p = s.pix
    assert p[0, 0] == 3 and p[2, 2] == 3  # cleared, and a box's inside is not filled
    assert (p[1, 1:6] == 7).all() and (p[4, 1:6] == 7).all() and (p[1:5, 5] == 7).all()
    assert (p[2:4, 10:13] == 9).all() and p[1, 10] == 3 and p[2, 13] == 3
    assert [p[9 - k, k] for k in range(5)] == [1] * 5  # the diagonal, both ends
    assert p[0, 19] == 2


def test_text_fills_its_cells_with_the_background_so_a_field_redraws_over_itself():
    s = screen.Screen(SIZE)
    for cmd in Stream(SIZE).feed(b"CLS(5);SBC(0);DS16(0,0,'88',15);DS16(0,0,'1 ',15);\r\n"):
        s.draw(cmd)
    cells = s.pix[0:16, 0:16]
    assert set(np.unique(cells)) == {0, 15}  # no trace of the clear colour 5 in the cells
    assert not (s.pix[0:16, 8:16] == 15).any()  # the space left nothing of the old 8
    assert (cells[:, :8] == 15).sum() == screen.glyph(16, "1").sum()
    assert s.pix[0, 16] == 5  # outside the cells: untouched


def test_a_known_stream_draws_the_committed_golden_screen(tmp_path):
    """The page above against tests/display/golden_screen.png, pixel for pixel (palette
    indices through the default palette). Regenerate on purpose only (`_page().image().save`
    to GOLDEN), and look at it."""
    got = np.asarray(_page().image())
    from PIL import Image

    want = np.asarray(Image.open(GOLDEN).convert("RGB"))
    assert got.shape == want.shape == (240, 320, 3)
    assert np.array_equal(got, want), int(np.sum(np.any(got != want, axis=2)))
