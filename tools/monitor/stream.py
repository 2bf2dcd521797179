"""Incremental decoding of a board's output stream, on top of host_emulator/frames.py.

`StreamDecoder.feed(chunk)` returns the records completed by `chunk`, in stream order; the
record layouts and field decoders are frames.py's (frame_fields, ext_fields, raw_fields), and
the resynchronisation rule is frames.decode's: at each 0xEB try the record its type byte
announces, accept it only if its checksum (52-byte frame) or CRC-32 (extended frame, raw-input
record) is right, otherwise count the failure and skip one byte. A record cut by the end of a
chunk waits in a tail buffer for the next one, so feeding any chunking of a byte string and
then calling `finish()` gives exactly what frames.decode gives on the whole string (the same
records, bad_checksum, bad_crc and skipped_bytes).

Counter gaps: the 52-byte frame's counter (u8) goes up by one per frame sent; every missing
step between two decoded frames counts one dropped frame ((counter - previous - 1) mod 256).

`TickClock` gives each frame its board time: the tick (5 ms) from the unwrapped counter,
anchored on the tick field of the extended frames.
"""

import struct

from host_emulator.proto import stream as frames

FRAME_LEN = 52
TICK_S = 0.005  # the firmware's tick (stimulus.TICK_US)
FRAME, EXT, RAW = "frame", "ext", "raw"


class StreamDecoder:
    """Feed bytes as they arrive; get the decoded records and the error counts."""

    def __init__(self):
        self._buf = bytearray()
        self.bytes_in = 0
        self.n_frames = 0
        self.n_ext = 0
        self.n_raw = 0
        self.bad_checksum = 0  # 52-byte frames whose checksum failed
        self.bad_crc = 0  # extended frames / raw records whose CRC-32 failed
        self.skipped_bytes = 0  # bytes that belonged to nothing decodable
        self.dropped_frames = (
            0  # frames missing by the counter (evaluate.frame_errors counts gap events)
        )
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
        if data:
            self.bytes_in += len(data)
            self._buf += data
        return self._scan(final=False)

    def finish(self):
        """End of the stream: what is left in the tail is decoded as frames.decode would (an
        incomplete record's bytes count as skipped)."""
        return self._scan(final=True)

    def _emit(self, out, kind, fields):
        if kind == FRAME:
            c = fields["counter"]
            if self._last_counter is not None:
                self.dropped_frames += (c - self._last_counter - 1) & 0xFF
            self._last_counter = c
            self.n_frames += 1
        else:
            fields["frame_index"] = self.n_frames - 1  # the 52-byte frame before it
            if kind == EXT:
                self.n_ext += 1
            else:
                self.n_raw += 1
        out.append((kind, fields))

    def _scan(self, final):
        buf = self._buf
        n = len(buf)
        out = []
        i = 0
        while i < n:
            if buf[i] != 0xEB:
                j = buf.find(0xEB, i + 1)
                j = n if j < 0 else j
                self.skipped_bytes += j - i
                i = j
                continue
            if i + 1 >= n:
                if not final:
                    break
            else:
                t = buf[i + 1]
                if t == frames.FRAME_TYPE:
                    if i + FRAME_LEN <= n:
                        f = bytes(buf[i : i + FRAME_LEN])
                        if f[51] == sum(f[2:51]) & 0xFF:
                            self._emit(out, FRAME, frames.frame_fields(f))
                            i += FRAME_LEN
                            continue
                        self.bad_checksum += 1
                    elif not final:
                        break
                elif t in (frames.EXT_TYPE, frames.RAW_TYPE):
                    end = i + 3 + buf[i + 2] + 4 if i + 3 <= n else n + 1
                    if end <= n:
                        r = bytes(buf[i:end])
                        crc = struct.unpack_from("<I", r, len(r) - 4)[0]
                        if crc == frames.crc32(r[:-4]):
                            if t == frames.EXT_TYPE:
                                self._emit(out, EXT, frames.ext_fields(r))
                            else:
                                self._emit(out, RAW, frames.raw_fields(r))
                            i = end
                            continue
                        self.bad_crc += 1
                    elif not final:
                        break
            self.skipped_bytes += 1
            i += 1
        del buf[:i]
        return out


class TickClock:
    """Board time of each frame. Tick T (app.ticks, 5 ms) sends the frame with counter
    (T // every - 1) mod 256 and, when it is due, the extended frame with counter
    (T // every) mod 256 and tick field T (host_emulator/session.py). The counter is unwrapped
    (gaps included) into a frame number u, whose tick is (u + 1) * every + offset; each extended
    frame sets offset so that its frame's tick matches its tick field (0 until the first one:
    the board's start). `every` is the configuration's output_every_ticks."""

    def __init__(self, every=1):
        self.every = max(1, int(every))
        self.u = None
        self._last = None
        self.offset = 0
        self.anchored = False
        # frames lost in whole counter wraps (256 or a multiple in a row): invisible to the
        # counter, seen when the next extended frame's tick is ahead of the frames counted
        self.wrap_losses = 0

    def frame(self, counter):
        """The unwrapped frame number of the next frame, whose counter is `counter`."""
        if self.u is None:
            self.u = counter
        else:
            self.u += ((counter - self._last - 1) & 0xFF) + 1
        self._last = counter
        return self.u

    def ext(self, rec):
        """Anchor on an extended frame (after the frames before it were given to `frame`)."""
        if self.u is None:
            return
        u_anchor = self.u - ((self._last - rec["counter"] + 1) & 0xFF)
        offset = (rec["tick"] // self.every) * self.every - (u_anchor + 1) * self.every
        if self.anchored and offset > self.offset:
            self.wrap_losses += (offset - self.offset) // self.every
        self.offset = offset
        self.anchored = True

    def tick(self, u):
        return (u + 1) * self.every + self.offset

    def time_s(self, u):
        return self.tick(u) * TICK_S
