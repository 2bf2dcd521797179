"""Opening a serial port for the host's tools (session record, tools.flash, tools.monitor):
one place that tells pyserial's failures apart (no such port, busy, permission denied) and
lists the ports that exist, so every tool can say what to do."""

import errno
import os

from common.errors import EmulatorError

MISSING, BUSY, DENIED, OTHER = "missing", "busy", "denied", "other"


class PortError(EmulatorError):
    """A port that cannot be opened; `kind` is MISSING, BUSY, DENIED or OTHER."""

    def __init__(self, kind, port, baud, detail):
        self.kind = kind
        self.port = port
        super().__init__(_message(kind, port, baud, detail))


def _message(kind, port, baud, detail):
    if kind == MISSING:
        return f"cannot open serial port {port}: it does not exist ({ports_hint()})"
    if kind == BUSY:
        return (
            f"cannot open serial port {port}: it is busy, another program has it open (a "
            "terminal, a monitor, mpremote, a session recorder); close it and try again"
        )
    if kind == DENIED:
        return (
            f"cannot open serial port {port}: permission denied (Linux: sudo usermod -aG "
            "dialout $USER, then log in again; or check the device's permissions)"
        )
    return f"cannot open serial port {port} at {baud} baud: {detail}"


def list_ports():
    """The serial ports pyserial sees, as "device (description)" strings."""
    from serial.tools import list_ports as lp

    out = []
    for p in sorted(lp.comports(), key=lambda p: p.device):
        desc = p.description if p.description and p.description != "n/a" else ""
        out.append(f"{p.device} ({desc})" if desc else p.device)
    return out


def ports_hint():
    ports = list_ports()
    return "serial ports found: " + ", ".join(ports) if ports else "no serial ports found"


BUSY_RETRY_S = 1.0  # how long a busy port is tried again before it counts as held


def open_port(port, baud, timeout, **kwargs):
    """pyserial's port (a device path, COM name or pyserial URL) opened exclusively, 8N1;
    PortError otherwise.

    A port found busy is tried again for BUSY_RETRY_S: the exclusive lock (flock) belongs to the
    open file, and a process forked by this one in the instant before it closed the port (the
    virtual board starting a MicroPython VM on a soft reset) holds a copy of it until that child
    runs its program, so a tool that closes the port and opens it again at once can find its
    own lock. A port another program holds stays busy, and is reported so after the wait."""
    import time

    deadline = time.monotonic() + BUSY_RETRY_S
    while True:
        try:
            return _open(port, baud, timeout, **kwargs)
        except PortError as e:
            if e.kind != BUSY or time.monotonic() > deadline:
                raise
        time.sleep(0.05)


def _open(port, baud, timeout, **kwargs):
    import serial

    if ("/" in port or port.startswith(".")) and "://" not in port and not os.path.exists(port):
        raise PortError(MISSING, port, baud, "")
    try:
        return serial.serial_for_url(port, baudrate=baud, timeout=timeout, exclusive=True, **kwargs)
    except ValueError as e:
        raise PortError(OTHER, port, baud, str(e)) from None
    except (serial.SerialException, OSError) as e:
        code = getattr(e, "errno", None)
        text = str(e)
        if code == errno.ENOENT or "FileNotFoundError" in text or "cannot find" in text:
            kind = MISSING
        elif code in (errno.EBUSY, errno.EAGAIN) or "busy" in text or "lock" in text.lower():
            kind = BUSY
        elif code in (errno.EACCES, errno.EPERM) or "ermission" in text:
            kind = DENIED
        else:
            kind = OTHER
        raise PortError(kind, port, baud, text) from None
