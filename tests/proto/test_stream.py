"""proto/stream.py: the one decoder of a board's output stream. Fed in any chunking it decodes
a damaged stream (garbage between records, a broken checksum, a broken CRC, a frame left out)
to exactly what one `decode` of the whole gives, with the failures counted as they were made;
a record cut by the end of the stream is skipped; `split` cuts a clean stream at its records."""

import random

import pytest

from common.proto import frame as frame_schema
from common.proto import records, stream
from common.proto.stream import EXT, FRAME, RAW, StreamDecoder
from host_emulator.runtimes import cpython
from host_emulator.sim import board_input


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    """The emulator's output for 4 s of highway_outage (GNSS fixes from the start) with the
    raw-input records on: frames, extended frames and raw records, as a board sends them."""
    stim = board_input.simulate("highway_outage", 4.0, seed=1).stimulus
    return (cpython.run(stim, tmp_path_factory.mktemp("board"), {"raw_record": 1}).out,)


def _records(data):
    """[(offset, length, type)] of the records of a clean stream."""
    out, i = [], 0
    while i < len(data):
        assert data[i] == 0xEB
        n = 52 if data[i + 1] == frame_schema.FRAME_TYPE else 3 + data[i + 2] + 4
        out.append((i, n, data[i + 1]))
        i += n
    return out


def _damaged(data, seed=7):
    """The stream with garbage (no 0xEB) between some records, one 52-byte frame's checksum
    broken, one frame left out, one extended frame's CRC broken; and what that must count."""
    rng = random.Random(seed)
    recs = _records(data)
    frame_ix = [k for k, r in enumerate(recs) if r[2] == frame_schema.FRAME_TYPE]
    ext_ix = [k for k, r in enumerate(recs) if r[2] == records.EXT_TYPE]
    bad_sum, dropped = frame_ix[100], frame_ix[300]
    bad_crc = ext_ix[5]
    out = bytearray()
    garbage = 0
    for k, (i, n, _t) in enumerate(recs):
        if k % 37 == 3:
            g = bytes(
                rng.choice([b for b in range(256) if b != 0xEB]) for _ in range(rng.randint(1, 40))
            )
            out += g
            garbage += len(g)
        rec = bytearray(data[i : i + n])
        if k == dropped:
            continue
        if k == bad_sum:
            rec[51] ^= 0x01
        if k == bad_crc:
            rec[-1] ^= 0x80
        out += rec
    expect = {
        "bad_checksum": 1,
        "bad_crc": 1,
        "skipped_bytes": garbage + 52 + recs[bad_crc][1],
        "dropped_frames": 2,  # the dropped frame and the one whose checksum failed
        "frames": len(frame_ix) - 2,
        "ext": len(ext_ix) - 1,
    }
    return bytes(out), expect


def _feed_chunked(data, rng, max_chunk):
    dec = StreamDecoder()
    got = []
    i = 0
    while i < len(data):
        n = rng.randint(0, max_chunk)
        got += dec.feed(data[i : i + n])
        i += n
    got += dec.finish()
    return dec, got


def test_any_chunking_decodes_like_the_whole_stream(board):
    data, expect = _damaged(board[0])
    ref = stream.decode(data)
    assert len(ref.frames) == expect["frames"] and len(ref.ext) == expect["ext"]
    assert (ref.bad_checksum, ref.bad_crc, ref.skipped_bytes) == (
        expect["bad_checksum"],
        expect["bad_crc"],
        expect["skipped_bytes"],
    )
    rng = random.Random(1)
    for max_chunk in (1, 7, 53, 300, 5000):
        dec, got = _feed_chunked(data, rng, max_chunk)
        assert [r for k, r in got if k == FRAME] == ref.frames
        assert [r for k, r in got if k == EXT] == ref.ext  # frame_index included
        assert [r for k, r in got if k == RAW] == ref.raw
        c = dec.counts()
        assert (c["bad_checksum"], c["bad_crc"], c["skipped_bytes"]) == (
            ref.bad_checksum,
            ref.bad_crc,
            ref.skipped_bytes,
        )
        assert c["dropped_frames"] == expect["dropped_frames"]
        assert c["bytes"] == len(data) and dec.pending == 0


def test_a_record_cut_by_the_end_counts_as_skipped(board):
    data = board[0]
    for cut in (1, 2, 3, 51, 100):  # the stream ends inside a record
        part = data[: len(data) - cut]
        ref = stream.decode(part)
        dec, got = _feed_chunked(part, random.Random(cut), 999)
        assert sum(k == FRAME for k, _ in got) == len(ref.frames)
        assert dec.skipped_bytes == ref.skipped_bytes > 0
    # a stream of junk, a lone header, an unknown type
    for junk in (b"", b"\xeb", b"\xeb\x90", b"\xeb\x91\x05", b"\x00\xeb\x33\xeb\xeb" * 9):
        ref = stream.decode(junk)
        dec, got = _feed_chunked(junk, random.Random(0), 3)
        assert got == [] and dec.skipped_bytes == ref.skipped_bytes == len(junk)


def test_split_cuts_a_clean_stream_at_its_records(board):
    data = board[0]
    f, e, r, err = stream.split(data)
    assert err is None and b"".join(sorted(f + e + r, key=data.index)) == data
    assert len(f) == 800 and len(e) == 40 and len(r) == 800
    assert {len(x) for x in f} == {frame_schema.FRAME_LEN} and {len(x) for x in e} == {
        records.EXT_LEN
    }
    at = _records(data)[2][0]  # the third record's offset
    f2, e2, r2, err = stream.split(data[:at] + b"\x00" + data[at:])
    assert err == f"no record starts at byte {at}" and len(f2 + e2 + r2) == 2
    assert stream.split(data[: at + 10])[3] == f"record at byte {at} is cut short"


def test_without_run_time_zeroes_only_the_extended_frames_run_time_counters(board):
    data = bytearray(board[0])
    recs = _records(bytes(data))
    ext = [(i, n) for i, n, t in recs if t == records.EXT_TYPE]
    assert len(ext) > 5
    for j, (i, n) in enumerate(ext):  # give every run-time counter a value, as a board would
        for name in records.EXT_TIMING_FIELDS:
            at = i + records.EXT_OFFSETS[name]
            data[at : at + 2] = (j + 1000 + at % 7).to_bytes(2, "little")
        data[i : i + n] = records.seal(data[i : i + n - records.CRC_LEN])
    out = stream.without_run_time(bytes(data))
    assert len(out) == len(data)
    for i, n, t in recs:
        rec, orig = out[i : i + n], bytes(data[i : i + n])
        if t != records.EXT_TYPE:
            assert rec == orig  # frames and raw records untouched
            continue
        assert records.crc_ok(rec)
        got, was = records.decode_ext(rec), records.decode_ext(orig)
        for name in records.EXT_TIMING_FIELDS:
            assert got[name] == 0 and was[name] != 0
        same = [k for k in got if k not in records.EXT_TIMING_FIELDS]
        assert {k: got[k] for k in same} == {k: was[k] for k in same}
    assert stream.without_run_time(board[0]) == board[0]  # the emulator's counters are 0
