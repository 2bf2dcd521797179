"""display/usartgpu.py: the strict reader of the byte stream the firmware sends the UsartGPU
screen. A batch is drawn at its "\\r\\n", whatever the writes it came in; every way a stream
can fail to draw what was meant is an error naming the offset and the bytes."""

import pytest

from host_emulator.display.usartgpu import Command, DisplayError, Stream, parse_batch

SIZE = (320, 240)


def test_the_boards_first_nine_bytes_clear_the_screen():
    """The board's main() sends exactly these 9 bytes at start."""
    s = Stream(SIZE)
    assert s.feed(b"CLS(0);\r\n") == [Command("CLS", (0,), 0)]
    assert s.batches == 1 and s.pending == b""


def test_a_batch_is_drawn_at_its_end_whatever_the_writes():
    """Every command kind, text holding the separators, fed whole and a byte at a time."""
    stream = (
        b"SBC(0);DS16(0,0,'lat 48.1234567, h 512.3 m; ok',15);BOX(0,20,319,239,7);"
        b"BOXF(10,30,20,40,2);PL(0,0,319,239,1);PS(5,6,3);DS32(8,200,'A',4);\r\n"
        b"DS12(1,2,'x',1);\r\nCLS(0);"
    )
    whole = Stream(SIZE)
    cmds = whole.feed(stream)
    assert [c.name for c in cmds] == ["SBC", "DS16", "BOX", "BOXF", "PL", "PS", "DS32", "DS12"]
    assert cmds[1].args == (0, 0, "lat 48.1234567, h 512.3 m; ok", 15)
    assert cmds[2].args == (0, 20, 319, 239, 7) and cmds[2].colour == 7
    assert cmds[7].offset == stream.index(b"DS12")
    assert whole.pending == b"CLS(0);" and whole.batches == 2
    bytewise = Stream(SIZE)
    got = []
    for b in stream:
        got += bytewise.feed(bytes([b]))
    assert got == cmds and bytewise.pending == b"CLS(0);"


@pytest.mark.parametrize(
    "batch, words",
    [
        (b"CLS(0);FOO(1);", ["byte 7", "unknown command 'FOO'", "CLS, SBC"]),
        (b"CLS(0)", ["byte 6", "';' expected after CLS"]),
        (b"CLS 0;", ["byte 3", "'(' expected after CLS"]),
        (b"PS(1,2);", ["byte 6", "',' expected in PS after argument 2 (3 arguments)"]),
        (b"PS(1,2,3,4);", ["byte 8", "')' expected in PS after argument 3"]),
        (b"PS(1,-2,3);", ["byte 5", "argument 2 must be a number"]),
        (b"DS16(0,0,hello,1);", ["byte 9", "text must be quoted"]),
        (b"DS16(0,0,'hello,1);", ["byte 9", "text is not closed"]),
        ("DS16(0,0,'50°',1);".encode("gbk"), ["0xA1", "ASCII only"]),
        (b"PS(320,0,1);", ["byte 0", "x 320 is off the 320x240 screen"]),
        (b"PL(0,0,10,240,1);", ["y 240 is off the 320x240 screen"]),
        (b"CLS(256);", ["colour 256 is beyond the palette"]),
        (b"BOXF(10,10,5,20,1);", ["second corner is above or left of its first"]),
        (b";", ["byte 0", "a command name expected"]),
        (b"DS16(300,0,'abc',1);", ["3 cells of 8x16 from 300,0", "runs off the 320x240"]),
        (b"DS32(0,220,'a',1);", ["runs off the 320x240 screen"]),
    ],
)
def test_a_stream_the_screen_would_not_draw_is_an_error_naming_the_bytes(batch, words):
    with pytest.raises(DisplayError) as e:
        parse_batch(batch, SIZE)
    text = str(e.value)
    for w in words:
        assert w in text, text
    assert ">>>" in text  # the bytes around the fault


def test_offsets_count_from_the_start_of_the_stream():
    s = Stream(SIZE)
    s.feed(b"CLS(0);\r\n")
    with pytest.raises(DisplayError, match="byte 19: unknown command 'XX'"):
        s.feed(b"PS(1,1,1);XX(1);\r\n")


def test_bytes_that_never_end_a_batch_are_an_error():
    """A firmware that forgets the "\\r\\n" would leave the real screen blank."""
    s = Stream(SIZE)
    s.feed(b"PS(1,1,1);" * 400)
    with pytest.raises(DisplayError, match="bytes without a"):
        s.feed(b"PS(1,1,1);" * 20)
