"""Where the bytes come from: a serial port (pyserial) or a file (a raw capture or a session
file of host_emulator/session.py). Every user mistake becomes a MonitorError with a message
that says what to do."""

import errno
import os
from pathlib import Path

from host_emulator import session


class MonitorError(Exception):
    """A problem the user can fix (bad port, bad file, wrong baud): printed, no traceback."""


def list_ports():
    """The serial ports pyserial sees, as "device (description)" strings."""
    try:
        from serial.tools import list_ports as lp
    except ImportError:
        return []
    out = []
    for p in sorted(lp.comports(), key=lambda p: p.device):
        desc = p.description if p.description and p.description != "n/a" else ""
        out.append(f"{p.device} ({desc})" if desc else p.device)
    return out


def _ports_hint():
    ports = list_ports()
    if not ports:
        return "no serial ports found (is the USB-RS485 adapter plugged in?)"
    return "serial ports found: " + ", ".join(ports)


class PortSource:
    """A serial port, 8N1, read in whatever chunks arrive. read(timeout) -> bytes (b"" when
    nothing came within the timeout)."""

    kind = "serial"

    def __init__(self, port, baud):
        try:
            import serial
        except ImportError:
            raise MonitorError(
                "reading a serial port needs pyserial (pip install pyserial==3.5; it is in "
                "requirements.txt)"
            ) from None
        self._serial = serial
        self.name = port
        self.baud = baud
        looks_like_path = "/" in port or port.startswith(".")
        if looks_like_path and "://" not in port and not os.path.exists(port):
            raise MonitorError(f"no such serial port: {port}; {_ports_hint()}")
        try:
            self.port = serial.serial_for_url(
                port, baudrate=baud, bytesize=8, parity="N", stopbits=1, timeout=0.05,
                exclusive=True,
            )  # fmt: skip
        except ValueError as e:
            raise MonitorError(f"cannot use serial port {port} at {baud} baud: {e}") from None
        except (serial.SerialException, OSError) as e:
            code = getattr(e, "errno", None)
            if code == errno.ENOENT:
                raise MonitorError(f"no such serial port: {port}; {_ports_hint()}") from None
            if code in (errno.EACCES, errno.EPERM):
                raise MonitorError(
                    f"permission denied opening {port}: add yourself to the port's group "
                    "(Linux: sudo usermod -aG dialout $USER, then log in again) or check the "
                    "device's permissions"
                ) from None
            if code in (errno.EAGAIN, errno.EBUSY) or "exclusively lock" in str(e):
                raise MonitorError(
                    f"serial port {port} is busy: another program has it open (a terminal, a "
                    "session recorder, another monitor); close it and try again"
                ) from None
            raise MonitorError(
                f"cannot open serial port {port} at {baud} baud: {e}; {_ports_hint()}"
            ) from None

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
            self.header, self.data = session.read_session(p)
        except session.SessionError as e:
            raise MonitorError(str(e)) from None
        self.is_session = bool(self.header)
        self.baud = self.header.get("baud") if self.header else None
        self._pos = 0

    def config_values(self):
        return (self.header or {}).get("config") or None

    def read(self, _timeout=None, size=1 << 16):
        """The next chunk of the capture; b"" at its end."""
        chunk = self.data[self._pos : self._pos + size]
        self._pos += len(chunk)
        return chunk

    @property
    def at_end(self):
        return self._pos >= len(self.data)

    def close(self):
        pass
