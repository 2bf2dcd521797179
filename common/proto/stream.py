"""The board's output stream: 52-byte frames (proto/frame.py), extended frames and raw-input
records (proto/records.py) back to back, with whatever garbage a line adds between them.

One decoder, incremental: `StreamDecoder.feed(chunk)` returns the records that chunk completes,
`finish()` what is left at the end of the stream; `decode(data)` is the same over a whole byte
string. The rule: at each 0xEB try the record its type byte announces and take it only if its
checksum (frame) or CRC-32 and length (records) are right; otherwise count the failure and skip
one byte; bytes that start nothing are skipped. A record cut by the end of a chunk waits for the
next one, so any chunking of a stream decodes to exactly what `decode` gives for all of it.

`split(data)` is the other reading, for comparing two streams record by record: it cuts a
stream at the lengths the headers announce without checking anything, and stops where no
record starts.
"""

from dataclasses import dataclass, field

from common.proto import frame, records
from common.proto.frame import FRAME_LEN, FRAME_TYPE, HEADER
from common.proto.records import EXT_TYPE, RAW_TYPE

FRAME, EXT, RAW = "frame", "ext", "raw"
KIND = {FRAME_TYPE: FRAME, EXT_TYPE: EXT, RAW_TYPE: RAW}


@dataclass
class Decoded:
    frames: list = field(default_factory=list)  # frame.decode dicts
    ext: list = field(default_factory=list)  # records.decode_ext dicts (+ "frame_index")
    raw: list = field(default_factory=list)  # records.decode_raw dicts (+ "frame_index")
    bad_checksum: int = 0  # frames whose checksum failed
    bad_crc: int = 0  # records whose CRC-32 (or length) failed
    skipped_bytes: int = 0  # bytes that belonged to nothing decodable


class StreamDecoder:
    """Feed bytes as they arrive; get the decoded records and the error counts.

    Dropped frames: the frame counter (u8) goes up by one per frame sent, so every missing step
    between two decoded frames counts one ((counter - previous - 1) mod 256)."""

    def __init__(self):
        self._buf = bytearray()
        self._offset = 0  # stream offset of _buf[0]
        self.bytes_in = 0
        self.n_frames = 0
        self.n_ext = 0
        self.n_raw = 0
        self.bad_checksum = 0
        self.bad_crc = 0
        self.skipped_bytes = 0
        self.dropped_frames = 0
        self._last_counter = None

    @property
    def pending(self):
        """Bytes held back (the start of a record not complete yet)."""
        return len(self._buf)

    def counts(self):
        return {
            "bytes": self.bytes_in,
            "frames": self.n_frames,
            "ext": self.n_ext,
            "raw": self.n_raw,
            "bad_checksum": self.bad_checksum,
            "bad_crc": self.bad_crc,
            "skipped_bytes": self.skipped_bytes,
            "dropped_frames": self.dropped_frames,
        }

    def feed(self, data):
        """[(kind, fields)] of the records completed by `data` (kind FRAME, EXT or RAW)."""
        return [self._fields(kind, r) for kind, _, r in self.records(data)]

    def finish(self):
        """End of the stream: the tail decodes as `decode` would (an incomplete record's bytes
        count as skipped)."""
        return [self._fields(kind, r) for kind, _, r in self.records(b"", final=True)]

    def records(self, data, final=False):
        """[(kind, stream offset, record bytes)] of the valid records `data` completes (the
        counters as `feed`; no field decoding)."""
        if data:
            self.bytes_in += len(data)
            self._buf += data
        buf = self._buf
        n = len(buf)
        out = []
        i = 0
        while i < n:
            if buf[i] != HEADER:
                j = buf.find(HEADER, i + 1)
                j = n if j < 0 else j
                self.skipped_bytes += j - i
                i = j
                continue
            if i + 1 >= n:
                if not final:
                    break
            else:
                t = buf[i + 1]
                if t == FRAME_TYPE:
                    end = i + FRAME_LEN
                else:  # header, length byte, counter + payload, CRC (unknown: length unread)
                    end = i + 3 + buf[i + 2] + records.CRC_LEN if i + 3 <= n else n + 1
                if t in KIND:
                    if end > n:
                        if not final:
                            break
                    else:
                        r = bytes(buf[i:end])
                        if t == FRAME_TYPE:
                            ok = r[-1] == frame.checksum(r)
                        else:
                            ok = records.length_ok(r) and records.crc_ok(r)
                        if ok:
                            out.append((KIND[t], self._offset + i, r))
                            i = end
                            continue
                        if t == FRAME_TYPE:
                            self.bad_checksum += 1
                        else:
                            self.bad_crc += 1
            self.skipped_bytes += 1
            i += 1
        del buf[:i]
        self._offset += i
        return out

    def _fields(self, kind, r):
        if kind == FRAME:
            fields = frame.decode(r)
            c = fields["counter"]
            if self._last_counter is not None:
                self.dropped_frames += (c - self._last_counter - 1) & 0xFF
            self._last_counter = c
            self.n_frames += 1
            return kind, fields
        if kind == EXT:
            fields = records.decode_ext(r)
            self.n_ext += 1
        else:
            fields = records.decode_raw(r)
            self.n_raw += 1
        fields["frame_index"] = self.n_frames - 1  # the 52-byte frame before it
        return kind, fields


def decode(data):
    """All decodable records in `data`, each kind in order of appearance (a Decoded)."""
    d = StreamDecoder()
    out = Decoded()
    lists = {FRAME: out.frames, EXT: out.ext, RAW: out.raw}
    for kind, fields in d.feed(data) + d.finish():
        lists[kind].append(fields)
    out.bad_checksum, out.bad_crc, out.skipped_bytes = d.bad_checksum, d.bad_crc, d.skipped_bytes
    return out


def _cuts(data):
    """(record type, start, end) of each record of a stream cut at the lengths their headers
    announce, then (None, offset, error message) if it does not split to its end."""
    types = (FRAME_TYPE, EXT_TYPE, RAW_TYPE)
    i = 0
    n = len(data)
    while i < n:
        if data[i] != HEADER or i + 3 > n or data[i + 1] not in types:
            yield None, i, f"no record starts at byte {i}"
            return
        t = data[i + 1]
        end = i + (FRAME_LEN if t == FRAME_TYPE else 3 + data[i + 2] + 4)
        if end > n:
            yield None, i, f"record at byte {i} is cut short"
            return
        yield t, i, end
        i = end


def split(data):
    """(frames, ext, raw, error): the records of a stream cut at the lengths their headers
    announce (nothing checked), each kind in order; error names the offset where no record
    starts or one is cut short (None if the stream splits to its end)."""
    out = {FRAME_TYPE: [], EXT_TYPE: [], RAW_TYPE: []}
    err = None
    for t, i, end in _cuts(data):
        if t is None:
            err = end
            break
        out[t].append(bytes(data[i:end]))
    return out[FRAME_TYPE], out[EXT_TYPE], out[RAW_TYPE], err


RAW_CLOCK_FIELDS = ("t0_us", "pps_us")  # the board's time.ticks_us in a raw-input record


def without_board_clock(data):
    """A copy of the stream with the raw-input records' times (RAW_CLOCK_FIELDS: the board's
    ticks_us at the tick's start and at the PPS edge) set to 0 and their CRC renewed: a board,
    or the image on the emulated STM32F411, reads a clock that started at its reset and runs
    on through its start-up, which the emulators' virtual clock and the model do not share.
    What the record says about the tick (the registers read, the GNSS bytes) stays."""
    out = bytearray(data)
    for t, i, end in _cuts(data):
        if t is None:
            break
        if t == RAW_TYPE:
            for name in RAW_CLOCK_FIELDS:
                at = i + records.RAW_OFFSETS[name]
                out[at : at + 4] = bytes(4)
            out[i:end] = records.seal(out[i : end - records.CRC_LEN])
    return bytes(out)


def without_run_time(data):
    """A copy of the stream with the board's run-time counters of every extended frame
    (records.EXT_TIMING_FIELDS: tick times, overruns, gc_runs; the overrun cause, and the
    health 1 it alone raised) set to 0 and its CRC renewed:
    what is left is the firmware's arithmetic and logic, comparable between a board (or the
    emulated Cortex-M4F, which collects garbage as the board does) and the model."""
    out = bytearray(data)
    for t, i, end in _cuts(data):
        if t is None:
            break
        if t == EXT_TYPE and end - i == records.EXT_LEN:
            for name in records.EXT_TIMING_FIELDS:
                at = i + records.EXT_OFFSETS[name]
                out[at : at + 2] = bytes(2)  # the timing fields are u16
            at = i + records.EXT_OFFSETS["causes"]
            causes = int.from_bytes(out[at : at + 4], "little") & ~records.CAUSE_OVERRUN
            out[at : at + 4] = causes.to_bytes(4, "little")
            if not causes and out[i + records.EXT_OFFSETS["health"]] == 1:
                out[i + records.EXT_OFFSETS["health"]] = 0  # health is 0 exactly when no cause is
            out[i:end] = records.seal(out[i : end - records.CRC_LEN])
    return bytes(out)
