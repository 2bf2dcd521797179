"""Where the bytes come from: a serial port (pyserial) or a file (a raw capture or a session
file, common/proto/session_file.py). Every user mistake becomes a MonitorError with a message
that says what to do."""

from pathlib import Path

from common.proto import serial_port, session_file


class MonitorError(Exception):
    """A problem the user can fix (bad port, bad file, wrong baud): printed, no traceback."""


def list_ports():
    """The serial ports pyserial sees, as "device (description)" strings."""
    return serial_port.list_ports()


class PortSource:
    """A serial port, 8N1, read in whatever chunks arrive. read(timeout) -> bytes (b"" when
    nothing came within the timeout)."""

    kind = "serial"

    def __init__(self, port, baud):
        import serial

        self._serial = serial
        self.name = port
        self.baud = baud
        try:
            self.port = serial_port.open_port(port, baud, 0.05)
        except serial_port.PortError as e:
            if e.kind == serial_port.MISSING:
                raise MonitorError(
                    f"no such serial port: {port}; {serial_port.ports_hint()}"
                ) from None
            raise MonitorError(str(e)) from None

    def read(self, timeout):
        try:
            self.port.timeout = timeout
            n = max(1, self.port.in_waiting)
            return self.port.read(n)
        except (self._serial.SerialException, OSError) as e:
            raise MonitorError(
                f"serial port {self.name} failed: {e} (device disconnected?)"
            ) from None

    def close(self):
        try:
            self.port.close()
        except (self._serial.SerialException, OSError):
            pass


class FileSource:
    """A capture file: a session file (header kept in .header) or raw bytes."""

    kind = "file"

    def __init__(self, path):
        p = Path(path)
        self.name = str(path)
        if not p.exists():
            raise MonitorError(f"no such file: {path}")
        if p.is_dir():
            raise MonitorError(f"{path} is a directory, not a capture file")
        try:
            s = session_file.load(p)
        except session_file.SessionError as e:
            raise MonitorError(str(e)) from None
        self.header, self.data = s.header, s.data
        self.problems = s.problems(self.name)  # a cut or damaged file: what was lost
        self.is_session = bool(self.header)
        self.baud = self.header.get("baud") if self.header else None
        self._pos = 0

    @property
    def position(self):
        """Bytes read so far."""
        return self._pos

    @property
    def size(self):
        return len(self.data)

    def config_values(self):
        return (self.header or {}).get("config") or None

    def read(self, _timeout=None, size=1 << 16):
        """The next chunk of the capture; b"" at its end."""
        chunk = self.data[self._pos : self._pos + size]
        self._pos += len(chunk)
        return chunk

    def close(self):
        pass
