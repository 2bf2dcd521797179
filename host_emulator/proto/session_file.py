"""The session file: a recording of what a board sent, with the board's configuration.

Layout (little-endian):
    b"INSSESS1", header length u32, header (UTF-8 JSON object)
    the captured bytes, exactly as received
    b"END1", captured length u64, CRC-32 (proto/crc.py) of everything before it
Header keys: "format" (1), "source" (file, pipe or serial port), "baud" (serial only),
"started_utc", "config" (the board configuration values, proto/config.py, or null when not
given at record time), "config_file" (where they came from). The trailer makes a truncated or
damaged file an error. A plain capture (a file not starting with the magic, e.g. from another
logger) reads as a header {} and its bytes.

Written by `host_emulator session record` and `tools.monitor --record`; read by `session
replay` and `tools.monitor --file`.
"""

import json
import struct
from pathlib import Path

from host_emulator.errors import EmulatorError
from host_emulator.proto.crc import crc32

MAGIC = b"INSSESS1"
TRAILER = b"END1"
_TRAILER_LEN = len(TRAILER) + 8 + 4
FORMAT = 1


class SessionError(EmulatorError):
    """A session that cannot be recorded, read or replayed, with a message that says why."""


class SessionWriter:
    """Writes a session file as the bytes arrive: header first, trailer at `close`."""

    def __init__(self, path, header):
        self.path = Path(path)
        head = json.dumps(header, sort_keys=True).encode()
        self.f = open(self.path, "wb")  # noqa: SIM115 (closed in close())
        self.crc = 0
        self.n = 0
        self._put(MAGIC + struct.pack("<I", len(head)) + head)

    def _put(self, b):
        self.f.write(b)
        self.crc = crc32(b, self.crc)

    def write(self, data):
        if data:
            self._put(data)
            self.n += len(data)

    def close(self):
        self._put(TRAILER + struct.pack("<Q", self.n))
        self.f.write(struct.pack("<I", self.crc))
        self.f.close()


def write_session(path, data, config=None, **info):
    """A session file holding `data` (captured bytes), the configuration values `config` and
    header entries `info` (source, started_utc, ...)."""
    header = {"format": FORMAT, "config": config, **info}
    w = SessionWriter(path, header)
    w.write(bytes(data))
    w.close()


def read_session(path):
    """(header, captured bytes) of a session file; a plain capture gives ({}, its bytes).
    SessionError if the file is unreadable, truncated or damaged."""
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        raise SessionError(f"cannot read session {path}: {e.strerror}") from None
    if not data.startswith(MAGIC):
        return {}, data
    pos = len(MAGIC) + 4
    if len(data) < pos:
        raise SessionError(f"{path}: the session file is truncated (no header)")
    (hlen,) = struct.unpack_from("<I", data, len(MAGIC))
    if len(data) < pos + hlen + _TRAILER_LEN or data[-_TRAILER_LEN:-12] != TRAILER:
        raise SessionError(
            f"{path}: the session file is truncated (no end marker): the recording was "
            "interrupted before it could be closed, or the copy is incomplete"
        )
    (crc,) = struct.unpack_from("<I", data, len(data) - 4)
    if crc32(data[:-4]) != crc:
        raise SessionError(f"{path}: CRC mismatch, the session file is damaged")
    (n,) = struct.unpack_from("<Q", data, len(data) - 12)
    if pos + hlen + n + _TRAILER_LEN != len(data):
        raise SessionError(f"{path}: the session file is damaged (its length does not add up)")
    try:
        header = json.loads(data[pos : pos + hlen].decode())
        if not isinstance(header, dict):
            raise ValueError("not an object")
    except (UnicodeDecodeError, ValueError) as e:
        raise SessionError(f"{path}: the header is not readable JSON ({e})") from None
    return header, data[pos + hlen : pos + hlen + n]
