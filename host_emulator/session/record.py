"""Recording a board's output into a session file (proto/session_file.py): from a serial
port, a named pipe, standard input or a file holding a capture. The file is closed properly on
Ctrl-C, on a port failure and on a full disk, so what was captured is kept."""

import datetime
import os
import re
import select
import stat
import sys
import time

from common.proto import config as board_config
from common.proto.session_file import FORMAT, SessionError, SessionWriter


def _is_serial_name(source):
    return bool(re.fullmatch(r"(?i)com\d+", source)) or "://" in source


def _open_source(source, baud):
    """(kind, reader, closer): kind "file", "stream" or "serial"; reader(timeout_s) returns
    bytes, b"" at the end (file, pipe) or None when nothing came within timeout_s."""
    if source == "-":
        fd = sys.stdin.buffer.fileno()
        return "stream", _stream_reader(fd), lambda: None
    try:
        st = os.stat(source)
    except OSError:
        st = None
    if st is not None and stat.S_ISREG(st.st_mode):
        f = open(source, "rb")  # noqa: SIM115 (closed by the closer)
        return "file", lambda _t: f.read(1 << 20), f.close
    if st is not None and stat.S_ISFIFO(st.st_mode):
        fd = os.open(source, os.O_RDONLY)
        return "stream", _stream_reader(fd), lambda: os.close(fd)
    serial_like = (st is not None and stat.S_ISCHR(st.st_mode)) or _is_serial_name(source)
    if st is None and not serial_like and not source.startswith("/dev/"):
        raise SessionError(f"no such file or serial port: {source}")
    import serial

    from common.proto import serial_port

    try:
        port = serial_port.open_port(source, baud, 0.2)
    except serial_port.PortError as e:
        raise SessionError(str(e)) from None

    def read_serial(_timeout):
        try:
            return port.read(max(1, port.in_waiting)) or None
        except (serial.SerialException, OSError) as e:
            raise SessionError(f"serial port {source} failed: {e}") from None

    return "serial", read_serial, port.close


def _stream_reader(fd):
    def read(timeout):
        if os.name == "posix":
            ready, _, _ = select.select([fd], [], [], timeout)
            if not ready:
                return None
        return os.read(fd, 1 << 16)

    return read


def record(source, out_path, seconds=None, progress=None, config=None, baud=None):
    """Capture a board's output into the session file `out_path`.

    source: a serial port ("/dev/ttyUSB0", "COM3", a pyserial URL), a named pipe, "-" (stdin)
        or a file holding a capture (copied whole). Start recording before the board starts:
        a replay begins at the firmware's first tick.
    seconds: stop after this long (serial ports and pipes; default: until the end of the pipe
        or Ctrl-C). config: the board's configuration (path or dict of values) to keep in the
        session. baud: serial baud rate (default: the configuration's output_baud, else 460800).
    progress(nbytes, elapsed_s): called about once a second.
    Returns {"path", "bytes", "seconds", "stopped"}; the file is closed properly on Ctrl-C and
    on a port failure (SessionError then says so)."""
    values = None
    if config is not None:
        if isinstance(config, (str, os.PathLike)):
            values = board_config.load(config)
        else:
            values = dict(config)
            board_config.from_values(values)
    if baud is None:
        baud = int((values or {}).get("output_baud", board_config.default_output_baud()))
    kind, read, close = _open_source(str(source), baud)
    header = {
        "format": FORMAT,
        "source": str(source),
        "baud": baud if kind == "serial" else None,
        "started_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "config": values,
        "config_file": str(config) if isinstance(config, (str, os.PathLike)) else None,
    }
    try:
        w = SessionWriter(out_path, header)
    except OSError as e:
        close()
        raise SessionError(f"cannot write session {out_path}: {e.strerror}") from None
    t_start = time.monotonic()
    t_report = t_start
    stopped = "end of input"
    failure = None
    try:
        while True:
            now = time.monotonic()
            if seconds is not None and kind != "file" and now - t_start >= seconds:
                stopped = "time"
                break
            chunk = read(0.2)
            if chunk == b"":
                break
            if chunk and not w.write(chunk):  # a full disk: what was written is kept
                stopped = "write failed"
                break
            if progress and now - t_report >= 1.0:
                t_report = now
                progress(w.n, now - t_start)
    except KeyboardInterrupt:
        stopped = "interrupted"
    except SessionError as e:
        failure = e
    finally:
        close()
        w.close()
    elapsed = time.monotonic() - t_start
    if progress:
        progress(w.n, elapsed)
    if failure is not None:
        raise SessionError(f"{failure}; the {w.n} bytes captured before are saved in {out_path}")
    if w.failed:
        raise SessionError(w.failed)
    return {"path": str(out_path), "bytes": w.n, "seconds": elapsed, "stopped": stopped}
