"""The session file: a recording of what a board sent, with the board's configuration.

Layout (format 2, little-endian), made so that a cut or damaged file loses only what was cut
or damaged:
    b"INSSESS2", header length u32, header (UTF-8 JSON object), CRC-32 of all three u32
    chunks of the captured bytes, exactly as received, each
        b"\\xa5CK2", stream offset u64, length u16, the bytes, CRC-32 of offset..bytes u32
    b"\\xa5EN2", captured length u64, CRC-32 of the length u32
The writer closes a chunk every CHUNK_BYTES or CHUNK_S and hands it to the OS at once, so a
killed recorder, a pulled cable or a full disk loses at most the chunk being filled. A reader
takes every chunk whose CRC holds, finds the next chunk marker after a damaged one, and counts
the bytes it lost from the chunks' offsets (proto/crc.py: the CRC).

Header keys: "format", "source" (file, pipe or serial port), "baud" (serial only),
"started_utc", "config" (the board configuration values, proto/config.py, or null when not
given at record time), "config_file" (where they came from); a repaired file adds "repaired"
(what was lost). Format 1 (b"INSSESS1", the bytes in one piece, one CRC-32 at the end) is still
read: a cut one is salvaged up to the cut, a damaged one is used whole with a warning (it
cannot say where). A plain capture (a file not starting with a magic, e.g. from another
logger) reads as a header {} and its bytes.

Written by `host_emulator session record` and `tools.monitor --record`; read by `session
replay`, `session repair` and `tools.monitor --file`.
"""

import json
import struct
import time
from dataclasses import dataclass, field
from pathlib import Path

from common.errors import EmulatorError
from common.proto.crc import crc32

MAGIC = b"INSSESS2"
MAGIC_V1 = b"INSSESS1"
CHUNK = b"\xa5CK2"
END = b"\xa5EN2"
FORMAT = 2
CHUNK_BYTES = 4096  # a chunk is closed at this many bytes ...
CHUNK_S = 0.5  # ... or this long after its first byte, whichever comes first
_CHUNK_HEAD = struct.Struct("<4sQH")  # marker, stream offset, length
_END = struct.Struct("<4sQI")  # marker, captured length, CRC-32 of the length
_TRAILER_V1 = b"END1"
_TRAILER_V1_LEN = len(_TRAILER_V1) + 8 + 4


class SessionError(EmulatorError):
    """A session that cannot be recorded, read or replayed, with a message that says why."""


class SessionWriter:
    """Writes a session file as the bytes arrive: header first, a chunk at a time, the end
    marker at `close`. A failed write (a full disk, a pulled USB stick) stops the recording
    instead of raising: `failed` then says why, and the file holds every chunk before it.
    `close` never raises."""

    def __init__(self, path, header, chunk_bytes=CHUNK_BYTES, chunk_s=CHUNK_S):
        self.path = Path(path)
        head = json.dumps(header, sort_keys=True).encode()
        start = MAGIC + struct.pack("<I", len(head)) + head
        self.f = open(self.path, "wb")  # noqa: SIM115 (closed in close())
        self.n = 0  # bytes captured and written
        self.failed = None  # why the recording stopped early, or None
        self._buf = bytearray()
        self._t_first = None
        self._chunk_bytes = int(chunk_bytes)
        self._chunk_s = chunk_s
        try:
            self.f.write(start + struct.pack("<I", crc32(start)))
            self.f.flush()
        except OSError:
            self.f.close()
            raise

    def write(self, data):
        """Add captured bytes (kept until the chunk closes); False once the recording has
        stopped (`failed`)."""
        if self.failed is not None:
            return False
        if data:
            if not self._buf:
                self._t_first = time.monotonic()
            self._buf += data
        while len(self._buf) >= self._chunk_bytes:
            self._put_chunk(self._chunk_bytes)
        if self._buf and time.monotonic() - self._t_first >= self._chunk_s:
            self._put_chunk(len(self._buf))
        return self.failed is None

    def _put_chunk(self, k):
        body = struct.pack("<QH", self.n, k) + bytes(self._buf[:k])
        self._out(CHUNK + body + struct.pack("<I", crc32(body)))
        if self.failed is None:
            self.n += k
            del self._buf[:k]
            self._t_first = time.monotonic()

    def _out(self, b):
        if self.failed is not None:
            return
        try:
            self.f.write(b)
            self.f.flush()
        except OSError as e:
            self.failed = (
                f"writing {self.path} failed ({e.strerror or e}): the recording stopped; the "
                f"{self.n} bytes before are kept"
            )
            self._buf.clear()

    def close(self):
        """The last chunk and the end marker; the file closed."""
        if self.f.closed:
            return
        while self._buf and self.failed is None:
            self._put_chunk(min(len(self._buf), self._chunk_bytes))
        self._out(_END.pack(END, self.n, crc32(struct.pack("<Q", self.n))))
        try:
            self.f.close()
        except OSError as e:  # the last flush of a full disk
            if self.failed is None:
                self.failed = f"closing {self.path} failed ({e.strerror or e})"


def write_session(path, data, config=None, **info):
    """A session file holding `data` (captured bytes), the configuration values `config` and
    header entries `info` (source, started_utc, ...). SessionError if it cannot be written."""
    _write(path, {"format": FORMAT, "config": config, **info}, data)


def _write(path, header, data):
    try:
        w = SessionWriter(path, header)
    except OSError as e:
        raise SessionError(f"cannot write session {path}: {e.strerror or e}") from None
    w.write(bytes(data))
    w.close()
    if w.failed:
        raise SessionError(w.failed)


@dataclass(eq=False)
class Session:
    """A session file as read: its header, the captured bytes that survived, and what did not.
    lost: (stream offset, length) of each run of captured bytes lost to damage; cut: the end
    marker is missing (the bytes of the chunk being filled at the cut are lost too, their
    number unknown); damaged_bytes: file bytes that were not a whole, intact chunk."""

    header: dict
    data: bytes
    format: int
    lost: list = field(default_factory=list)
    cut: bool = False
    damaged_bytes: int = 0
    header_damaged: bool = False

    @property
    def intact(self):
        return not (self.lost or self.cut or self.damaged_bytes or self.header_damaged)

    def problems(self, name):
        """One line per problem, for a warning or an error; [] when the file is intact."""
        out = []
        if self.header_damaged:
            out.append(
                f"{name}: the header is damaged: the recording's configuration and source are "
                "unknown (give --config)"
            )
        if self.format == 1 and self.damaged_bytes:
            out.append(
                f"{name}: CRC mismatch: the session file is damaged somewhere (a format 1 "
                "file cannot say where): its bytes are used as they are"
            )
        elif self.lost:
            n = sum(k for _, k in self.lost)
            where = ", ".join(f"byte {o}" for o, _ in self.lost[:3])
            more = ", ..." if len(self.lost) > 3 else ""
            out.append(
                f"{name}: {len(self.lost)} damaged part(s) skipped: {n} of "
                f"{len(self.data) + n} captured bytes lost (at {where}{more})"
            )
        elif self.damaged_bytes:
            out.append(f"{name}: {self.damaged_bytes} damaged bytes skipped; no captured byte lost")
        if self.cut:
            out.append(
                f"{name}: the recording was cut (no end marker: a killed recorder, a pulled "
                f"cable or a full disk?): the {len(self.data)} bytes before the cut are used"
            )
        return out


def load(path):
    """A Session of the file at `path`: what survived of a cut or damaged session file (say
    what was lost: Session.problems), a plain capture as header {} and its bytes. SessionError
    if the file cannot be read at all."""
    try:
        buf = Path(path).read_bytes()
    except OSError as e:
        raise SessionError(f"cannot read session {path}: {e.strerror or e}") from None
    if buf.startswith(MAGIC):
        return _load_v2(buf, path)
    if buf.startswith(MAGIC_V1):
        return _load_v1(buf, path)
    return Session({}, buf, 0)


def read_session(path):
    """(header, captured bytes) of an intact session file; a plain capture gives ({}, its
    bytes). SessionError if the file is unreadable, cut or damaged: it says what was lost and
    how to keep the rest (`session repair`)."""
    s = load(path)
    if not s.intact:
        raise SessionError(
            "; ".join(s.problems(path))
            + f" (python -m host_emulator session repair {path} --out FILE keeps what survived)"
        )
    return s.header, s.data


def _header(buf, start, path):
    """(header dict, position after it, damaged?) of the JSON header at `start`."""
    if len(buf) < start + 4:
        raise SessionError(f"{path}: the session file is truncated (no header)")
    (hlen,) = struct.unpack_from("<I", buf, start)
    end = start + 4 + hlen
    if len(buf) < end:
        raise SessionError(f"{path}: the session file is truncated (its header is cut)")
    try:
        header = json.loads(buf[start + 4 : end].decode())
        if not isinstance(header, dict):
            raise ValueError("not an object")
    except (UnicodeDecodeError, ValueError):
        return None, end, True
    return header, end, False


def _load_v2(buf, path):
    header, pos, bad = _header(buf, len(MAGIC), path)
    if not bad:
        (crc,) = struct.unpack_from("<I", buf, pos) if len(buf) >= pos + 4 else (None,)
        bad = crc != crc32(buf[:pos])
    s = Session(header if not bad else {}, b"", 2, header_damaged=bad)
    pos += 4
    data = bytearray()
    expected = 0
    n = len(buf)
    complete = False
    while pos < n:
        if buf.startswith(CHUNK, pos) and pos + _CHUNK_HEAD.size <= n:
            _, off, k = _CHUNK_HEAD.unpack_from(buf, pos)
            end = pos + _CHUNK_HEAD.size + k
            if end + 4 <= n and crc32(buf[pos + 4 : end]) == struct.unpack_from("<I", buf, end)[0]:
                if off >= expected:
                    if off > expected:
                        s.lost.append((expected, off - expected))
                    data += buf[pos + _CHUNK_HEAD.size : end]
                    expected = off + k
                pos = end + 4
                continue
        if buf.startswith(END, pos) and pos + _END.size <= n:
            _, total, crc = _END.unpack_from(buf, pos)
            if crc == crc32(struct.pack("<Q", total)):
                if total > expected:
                    s.lost.append((expected, total - expected))
                s.damaged_bytes += n - pos - _END.size  # anything after the end
                complete = True
                break
        nxt = [i for i in (buf.find(CHUNK, pos + 1), buf.find(END, pos + 1)) if i >= 0]
        if not nxt:  # the rest is a chunk cut short, or damage up to a cut
            if buf.startswith(CHUNK, pos) or buf.startswith(END, pos):
                break  # a chunk or end marker the cut left incomplete: nothing else lost
            s.damaged_bytes += n - pos
            break
        s.damaged_bytes += min(nxt) - pos
        pos = min(nxt)
    s.cut = not complete
    s.data = bytes(data)
    return s


def _load_v1(buf, path):
    header, pos, bad = _header(buf, len(MAGIC_V1), path)
    s = Session(header if not bad else {}, b"", 1, header_damaged=bad)
    n = len(buf)
    if n < pos + _TRAILER_V1_LEN or buf[n - _TRAILER_V1_LEN : n - 12] != _TRAILER_V1:
        s.cut = True
        s.data = buf[pos:]
        return s
    (length,) = struct.unpack_from("<Q", buf, n - 12)
    (crc,) = struct.unpack_from("<I", buf, n - 4)
    s.data = buf[pos : n - _TRAILER_V1_LEN]
    if crc32(buf[:-4]) != crc or length != len(s.data):
        s.damaged_bytes = len(s.data)
    return s


def repair(path, out_path):
    """Write what survived of the session file `path` as an intact session file `out_path`;
    the Session read. The header keeps the original's entries and adds "repaired"."""
    s = load(path)
    header = dict(s.header)
    header["format"] = FORMAT
    header["repaired"] = {
        "from": str(path),
        "problems": s.problems(Path(path).name),
        "lost": [list(x) for x in s.lost],
        "cut": s.cut,
    }
    _write(out_path, header, s.data)
    return s
