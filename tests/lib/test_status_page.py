"""firmware/lib/status_page.py: its copies of other modules' indices, its integer decoding and
formatting against the model's (model/display.py, Python's formatting and NumPy's float32),
and its accounting of the screen's OKs."""

import math
import struct
from array import array
from types import SimpleNamespace

import numpy as np
import pytest

from common import firmware_env
from common.proto import records as proto_records
from host_emulator.model import display as model_display

firmware_env.install()
import app  # noqa: E402
import config  # noqa: E402
import frame  # noqa: E402
import kern  # noqa: E402
import nav  # noqa: E402
import records  # noqa: E402
import status_page as sp  # noqa: E402


def test_the_page_turns_where_the_model_says():
    """The app's copies of the turn's slot and phase are generated from here
    (tests/native/test_const_copies.py); the model of the screen has its own."""
    assert app._PAGE_SLOT == sp._PAGE_SLOT == model_display.SLOT
    assert app._PAGE_PHASE == model_display.PHASE and app._PAGE_PHASE % 2  # odd: no ext frame


def test_every_cause_bit_has_its_word():
    bits = [code for code, _ in proto_records.CAUSES]
    assert bits == [1 << k for k in range(sp.NCAUSE)] and bits[-2] == app.CAUSE_DISPLAY
    assert bits[-1] == nav.CAUSE_NOT_NAVIGATING
    words = [sp.CAUSES[12 * k : 12 * k + 12].decode().rstrip() for k in range(sp.NCAUSE)]
    assert len(sp.CAUSES) == 12 * sp.NCAUSE and words == list(model_display.CAUSE_WORDS)
    assert len(sp.LABELS) == 6 * 13 and len(sp.STATES) == 40 and len(sp.HEALTHS) == 27


def _float_bits():
    """float32 bit patterns: specials, the edges of the clamp, and random variances."""
    rng = np.random.default_rng(7)
    vals = [0.0, -0.0, 1e-45, 1e-38, 1e-9, 0.5, 1.0, 2.0, 3.3e4, 5.36e4, 5.37e4, 1e6, 3e38,
            np.inf, -np.inf, np.nan, -1.0]  # fmt: skip
    vals += list(10 ** rng.uniform(-8, 6, 2000))
    out = [np.float32(v).tobytes() for v in vals]
    out += [struct.pack("<I", int(u)) for u in rng.integers(0, 2**32, 2000)]
    return out


def test_a_variance_decodes_from_its_bits_as_the_model_rounds_it():
    for bits in _float_bits():
        fw = sp.var_cm2(bits, 0)
        mo = model_display.variance_cm2(bits)
        assert fw == (-1 if mo is None else mo), bits
    # and what it means: the variance in cm^2 to 14 significant bits
    for v in (0.01, 1.0, 4.2, 1234.5):
        got = sp.var_cm2(np.float32(v).tobytes(), 0)
        assert got <= v * 1e4 < got * (1 + 2**-13) + 1


def test_the_integer_square_root():
    rng = np.random.default_rng(1)
    for v in [0, 1, 2, 3, 4, 15, 16, 2**30 - 1, *rng.integers(0, 2**30, 3000).tolist()]:
        assert sp.isqrt(v) == math.isqrt(v)


def test_the_font_fits_the_screen_as_the_model_says():
    for w in range(200, 500, 7):
        for h in range(150, 340, 5):
            assert sp.font_for(w, h) == model_display.font_for(w, h)
    assert (sp.font_for(220, 176), sp.font_for(320, 240), sp.font_for(480, 320)) == (12, 16, 24)


class _Uart:
    def __init__(self):
        self.rx = bytearray()

    def any(self):
        return len(self.rx)

    def readinto(self, buf, n=-1):
        n = min(len(buf), len(self.rx))
        buf[:n] = self.rx[:n]
        del self.rx[:n]
        return n or None


class _Tx:
    def __init__(self):
        self.out = bytearray()

    def write(self, buf):
        self.out += buf

    def write_n(self, buf, n):
        self.out += bytes(buf[:n])
        return n


def _page(ext_every=20, **settings):
    cfg = config.BoardConfig()
    for k, v in settings.items():
        setattr(cfg, k, v)
    cfg.ext_every_ticks = ext_every
    ext = records.ExtFrame(None)
    a = SimpleNamespace(
        out=bytearray(frame.FRAME_LEN),
        _fields=array("i", bytes(4 * frame.NF)),
        ext=ext,
        nav=SimpleNamespace(ctl=array("i", bytes(4 * 64))),
        gnss=SimpleNamespace(epoch_quality=0, epoch_nsat=-1, epoch_hdop_x100=-1),
    )
    tx, uart = _Tx(), _Uart()
    return sp.StatusPage(tx, uart, cfg, a), a, tx, uart, cfg


def _view(a, state, ext_on=True):
    ff = a._fields
    e7 = lambda d, f: d * 10**7 + f  # noqa: E731
    ext = bytes(a.ext.data) if ext_on and a.ext.data[0] == 0xEB else None
    return model_display.View(
        state, ff[frame.F_VALID], e7(ff[frame.F_LAT_DEG], ff[frame.F_LAT_FRAC]),
        e7(ff[frame.F_LON_DEG], ff[frame.F_LON_FRAC]), ff[frame.F_HEIGHT_DM],
        a.gnss.epoch_quality, a.gnss.epoch_nsat, a.gnss.epoch_hdop_x100, bytes(a.out), ext,
        a.nav.ctl[nav._C_HEALTH], a.nav.ctl[nav._C_CAUSES],
    )  # fmt: skip


def _ext_frame(health, causes, var_e, var_n):
    """An extended frame as the app packs it: the fields the page reads (health, P's first
    two variances, causes)."""
    d = bytearray(records.EXT_LEN)
    d[0] = 0xEB
    d[4] = health
    struct.pack_into("<ff", d, 16, var_e, var_n)
    struct.pack_into("<I", d, 128, causes)
    return d


EXTREMES = [
    # state, valid, lat_e7, lon_e7, height_dm, quality, nsat, hdop, yaw, pitch, roll, ve, vn,
    # pe, pn, health, causes, var_e, var_n
    (2, 1, 342590005, 1089390081, 4283, 1, 12, 110, 13996, -9, -109, 300, -400, -9736, 11312,
     0, 0, 1.5, 1.7),
    (2, 1, -899999999, -1799999999, -12345, 4, 99, 9999, -18000, -9000, 18000, 32767, -32768,
     2**30 - 1, -(2**30), 2, nav.CAUSE_FAULTS | 0x1, 1e9, np.inf),
    (1, 0, -1, 1, 5, 9, -1, -1, -1, 1, -1, -23170, 23171, -99999999, 100000000, 1,
     app.CAUSE_DISPLAY | app.CAUSE_PPS, 0.0, -0.0),
    (-1, 1, 0, -5, -5, 5, 100, 9994, 17999, 0, 0, 0, 0, 0, 0, 1, 0x7FFFF, 4.0e-6, 3.3e4),
]  # fmt: skip


@pytest.mark.parametrize("case", EXTREMES)
@pytest.mark.parametrize("ext_on", [True, False])
def test_every_field_formats_as_the_model_does(case, ext_on):
    (state, valid, lat, lon, hdm, q, nsat, hdop, yaw, pitch, roll, ve, vn, pe, pn, health,
     causes, var_e, var_n) = case  # fmt: skip
    page, a, tx, _, cfg = _page(ext_every=20 if ext_on else 0)
    ff = a._fields
    ff[frame.F_VALID], ff[frame.F_HEIGHT_DM] = valid, hdm
    for i, v in ((frame.F_LAT_DEG, lat), (frame.F_LON_DEG, lon)):
        d = int(v / 10**7)
        ff[i], ff[i + 1] = d, v - d * 10**7
    a.gnss.epoch_quality, a.gnss.epoch_nsat, a.gnss.epoch_hdop_x100 = q, nsat, hdop
    struct.pack_into("<hhh", a.out, 29, yaw, pitch, roll)
    struct.pack_into("<hh", a.out, 35, ve, vn)
    struct.pack_into("<ii", a.out, 41, pe, pn)
    a.ext.data[:] = _ext_frame(health, causes, var_e, var_n)
    a.ext.fields[records.EF_HEALTH], a.ext.fields[records.EF_CAUSES] = health, causes
    a.nav.ctl[nav._C_HEALTH], a.nav.ctl[nav._C_CAUSES] = health, causes
    model = model_display.Page(cfg)
    view = _view(a, state, ext_on)
    for ticks in range(36000 * 200, 36000 * 200 + 8 * 16, 8):  # 10 h in: the hours' digits
        page.turn(ticks, state)
        model.turn(ticks, view)
    assert bytes(tx.out) == bytes(model.out)
    text = tx.out.decode()
    assert text.count(";") == 13 and text.endswith("\r\n")  # every field once, one batch


def test_the_page_starts_cleared_with_its_labels_and_sends_only_changes():
    page, a, tx, _, cfg = _page(display_bg=1, display_fg=14)
    page.start()
    assert tx.out.startswith(b"SBC(1);CLS(1);DS16(3,3,'UP',14);")
    assert tx.out.endswith(b"DS16(3,219,'CAUSE',14);\r\n") and page.batches == 1
    tx.out.clear()
    for ticks in range(8, 8 * 16, 8):
        page.turn(ticks, 1)
    first = bytes(tx.out)
    assert first.count(b"DS16(59,") == 12 and first.endswith(b"\r\n")  # UP's turn was tick 0
    tx.out.clear()
    for ticks in range(8 * 16, 8 * 32, 8):  # the same values: UP's first text, nothing else
        page.turn(ticks, 1)
    assert bytes(tx.out) == b"DS16(59,3,'   0:00:00',14);\r\n"


def test_a_screen_that_stops_answering_is_a_fault_one_that_never_answered_is_none():
    page, a, tx, uart, _ = _page()
    page.start()
    rounds = [8 * 16 * r for r in range(1, 7)]

    def round_(r):
        a.out[29] = r // 128  # the heading changes every round: a batch each time
        for ticks in range(r, r + 8 * 16, 8):
            page.turn(ticks, 2)

    round_(rounds[0])
    assert page.batches == 2 and page.missed == 0 and page.bad_until == 0  # never answered
    uart.rx += b"OK\r\nOK\r\n"
    round_(rounds[1])
    assert page.oks == 2 and page.missed == 0
    uart.rx += b"OK\r\n"
    round_(rounds[2])
    assert page.missed == 0 and page.bad_until == 0
    round_(rounds[3])  # no answer to the last batch
    end = rounds[3] + 8 * 13
    assert page.missed == 1 and page.bad_until == end + 200
    uart.rx += b"OK\r\nOK\r\nOK\r\n"  # late and extra OKs count no more than the batches sent
    round_(rounds[4])
    assert page.missed == 1 and page.oks == page.batches - 1


def test_the_display_settings_are_checked():
    for name, value, text in (
        ("display", 2, "display must be 0 (off) or 1 (on)"),
        ("display_baud", 19200, "display_baud must be one of (38400,"),
        ("display_w", 219, "display_w x display_h must be within 220..480 x 176..320"),
        ("display_h", 321, "display_w x display_h must be within"),
        ("display_fault", 256, "display_fault must be a palette index, 0..255"),
    ):
        cfg = config.BoardConfig()
        setattr(cfg, name, value)
        assert cfg.validate().startswith(text), name
    cfg = config.BoardConfig()
    assert cfg.display == 0 and cfg.validate() is None  # off by default


def test_a_field_whose_inputs_did_not_change_is_not_made_again():
    """The fields that change seldom keep their inputs: the same inputs, no text made (and
    no command); any input changed, the text is made and compared again."""
    page, a, tx, _, _ = _page()
    made = []
    real = page._angle
    page._angle = lambda f: made.append(f) or real(f)

    def round_(r):
        for ticks in range(r, r + 8 * 16, 8):
            page.turn(ticks, 2)

    round_(0)
    assert made == [sp._P_LAT, sp._P_LON]
    round_(128)
    assert made == [sp._P_LAT, sp._P_LON]  # nothing changed: neither made again
    a._fields[frame.F_LON_FRAC] = 1
    tx.out.clear()
    round_(256)
    assert made[2:] == [sp._P_LON] and b"'  +0.0000001 deg'" in bytes(tx.out)
    a.gnss.epoch_hdop_x100 = 120  # the third input of the fix's field
    tx.out.clear()
    round_(384)
    assert b"HDOP 1.2" in bytes(tx.out)


def test_the_text_kernels_are_their_python_references():
    """navk's text_num and text_diff (firmware/native/text.c) against the page's Python
    references, on the forms the page uses and random ones within their preconditions."""
    assert kern.navk is not None
    rng = np.random.default_rng(3)
    for _ in range(3000):
        w = int(rng.integers(1, 26))
        dec = int(rng.integers(0, 4)) if w > 4 else 0
        flags = int(rng.choice([0, sp.TN_SIGNED, sp.TN_ZEROS]))
        room = w - (dec + 1 if dec else 0) - (1 if flags & sp.TN_SIGNED else 0)
        if room < 1:  # no room for a digit (and the sign): not a form the page uses
            continue
        v = int(rng.integers(0, 10 ** min(room, 9)))
        if flags & sp.TN_SIGNED and rng.random() < 0.5:
            v = -v
        p = int(rng.integers(0, 5))
        form = w | dec << 8 | flags
        a, b = bytearray(b"#" * 32), bytearray(b"#" * 32)
        assert sp._text_num_py(a, p, v, form) == kern.navk.text_num(b, p, v, form) == p + w
        assert a == b, (v, w, dec, flags)
    for _ in range(500):
        n = int(rng.integers(1, 26))
        s1 = bytearray(rng.integers(65, 68, 40).astype(np.uint8).tobytes())
        s2 = bytearray(s1)
        t = bytes(rng.integers(65, 68, n).astype(np.uint8))
        o = int(rng.integers(0, 40 - n))
        assert sp._text_diff_py(s1, o, t, n) == kern.navk.text_diff(s2, o, t, n)
        assert s1 == s2 and s1[o : o + n] == t
    t = bytearray(16)
    sp._text_num_py(t, 0, -1234, 9 | 2 << 8 | sp.TN_SIGNED)
    assert bytes(t[:9]) == b"   -12.34"
    sp._text_num_py(t, 0, 42, 7 | sp.TN_ZEROS)
    assert bytes(t[:7]) == b"0000042"
