"""Board sessions: record a board's output stream, rebuild its input from the raw-input records
and replay it through the emulator; the replayed output must equal the recorded one.

    python -m host_emulator session record /dev/ttyUSB0 --out drive.ins --config ins.cfg
    python -m host_emulator session replay drive.ins [--runtime micropython] [--until-gap]

With the configuration setting `raw_record` = 1 the firmware sends, after the frames of each
5 ms tick, a raw-input record (type 0x92, firmware/lib/records.py): the tick's start time
(time.ticks_us), the parser's PPS edge time, the BMI055 gyro and accel data registers as read,
the saturation flag and the GNSS bytes fed to the parser. Those, plus the board's
configuration file (and the same firmware), are what the firmware's output depends on, so the
emulator fed with them sends the same bytes; docs/sessions.md says where a real board's
timing (which the emulator does not model) can still make a fix land one tick apart.

Session file (little-endian; `write_session`, `read_session`):
    b"INSSESS1", header length u32, header (UTF-8 JSON object)
    the captured bytes, exactly as received
    b"END1", captured length u64, CRC-32 (binascii.crc32) of everything before it
Header keys: "format" (1), "source" (file, pipe or serial port), "baud" (serial only),
"started_utc", "config" (the board configuration values of firmware/lib/config.py's
BoardConfig, or null when not given at record time), "config_file" (where they came from).
The trailer makes a truncated or damaged file an error. A plain capture (a file not starting
with the magic, e.g. from another logger) is accepted too; its configuration comes from
`--config`.

The stream (what `parse` checks). From the firmware's start, tick k (app.ticks = T = k + 1)
sends, in this order: the 52-byte frame if T % output_every_ticks == 0 (counter
(T // output_every_ticks - 1) & 0xFF), the extended frame if T % ext_every_ticks == 0
(counter (T // output_every_ticks) & 0xFF, tick field T), the raw-input record (same counter).
The replay starts at the board's first tick, found as the first group that chains like tick 0
and whose first extended frame carries tick T (bytes before it, e.g. the end of an earlier
run, are skipped). A record that is missing, damaged (its checksum or CRC fails) or out of
sequence is a gap: the firmware's state after it cannot be known, so `parse` raises
SessionError naming the byte offset and tick, or with `until_gap` keeps the ticks before it.
Stray bytes between records that still chain (line noise) are counted, not an error. The
last tick, if cut short by the end of the capture, is left out.

Rebuilding the input (`to_stimulus`): tick k's registers and GNSS bytes as recorded; a PPS
edge where the recorded pps_us changes, at pps_before_us = ticks_diff(t0_us, pps_us) before
the tick (MicroPython's ticks_us wraps at 2**30 us; ticks_diff is taken modulo that). The
BMI055 temperature register is not recorded and not read by the loop: it is set to 0.

Comparison (`compare`): the 52-byte frames byte for byte; the extended frames byte for byte
except their timing fields (worst and mean tick us, overruns, GC runs: run time, which the
emulator does not model) and the CRC that covers them; the raw records except their two
absolute times (the emulator's clock is not the board's) and CRC. With the MicroPython VM
(double-precision floats) the frames' integer fields must be equal and their attitude,
velocity and position within 2 steps, and only the extended frames' integer fields are
compared.
"""

import argparse
import binascii
import datetime
import json
import os
import re
import select
import stat
import struct
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from host_emulator.errors import EmulatorError, FirmwareError
from host_emulator.eval import parity
from host_emulator.proto import stimulus as stim_mod
from host_emulator.proto import stream as frames
from host_emulator.runtimes import cpython as emulator

MAGIC = b"INSSESS1"
TRAILER = b"END1"
_TRAILER_LEN = len(TRAILER) + 8 + 4
FORMAT = 1
TICK_US = stim_mod.TICK_US
TICKS_PERIOD = 1 << 30  # MicroPython's ticks_us wraps here (the stm32 and unix ports)
TICK_MASK = 0x3FFFFFFF  # the extended frame's tick field wraps here
DEFAULT_BAUD = 460800  # config.py's default output_baud
FRAME_TYPE = frames.FRAME_TYPE
EXT_TYPE = frames.EXT_TYPE
RAW_TYPE = frames.RAW_TYPE
FRAME_LEN = 52
EXT_LEN = 132
RAW_MIN_LEN = 30  # no GNSS bytes
RAW_MAX_LEN = 30 + 255
_KIND_NAME = {FRAME_TYPE: "frame", EXT_TYPE: "extended frame", RAW_TYPE: "raw-input record"}
# fields the comparison leaves out (names as parity._record_fields gives them)
EXT_TIMING_FIELDS = ("worst_tick_us", "mean_tick_us", "overruns", "gc_runs")
RAW_TIME_FIELDS = ("t0_us", "pps_us")
VM_FLOAT_STEPS = 2  # MicroPython VM: frame attitude/velocity/position within this many steps
_FRAME_FLOAT_FIELDS = parity._FRAME_NAMES[16:25]  # yaw_cdeg .. pos_u_dm


class SessionError(EmulatorError):
    """A session that cannot be recorded or replayed, with a message that says why."""


def ticks_diff(a, b):
    """MicroPython's time.ticks_diff for ticks_us values: a - b, signed, modulo 2**30."""
    d = (int(a) - int(b)) % TICKS_PERIOD
    return d - TICKS_PERIOD if d >= TICKS_PERIOD // 2 else d


# ---- board configuration ------------------------------------------------------------------


def _plain(v):
    """A configuration value as JSON: float32 scalars and buffers become Python floats (the
    exact value of the float32, so re-encoding it gives the same bits)."""
    if v is None or isinstance(v, (bool, int, str)):
        return v
    if isinstance(v, (float, np.floating)):
        return float(v)
    return [_plain(x) for x in v]


def config_values(cfg):
    """A firmware BoardConfig -> dict of its settings (JSON-able)."""
    return {name: _plain(value) for name, value in vars(cfg).items()}


def load_config(path):
    """The board configuration values in `path`: the board's own configuration file
    (firmware/lib/config.py's binary format, as on the board's flash) or a JSON object of
    settings (names of BoardConfig; missing ones keep their defaults)."""
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        raise SessionError(f"cannot read configuration {path}: {e.strerror}") from None
    if data[:4] == b"INSC":
        try:
            return config_values(emulator.decode_config(data))
        except EmulatorError as e:
            raise SessionError(f"configuration {path} is {e}") from None
    try:
        values = json.loads(data.decode())
        if not isinstance(values, dict):
            raise ValueError("not a JSON object")
    except (UnicodeDecodeError, ValueError) as e:
        raise SessionError(
            f"configuration {path} is neither a board configuration file nor a JSON object of "
            f"settings ({e})"
        ) from None
    try:
        cfg = emulator.board_config(values)
    except EmulatorError as e:
        raise SessionError(f"configuration {path}: {e}") from None
    return config_values(cfg)


def _board_cfg(values):
    try:
        return emulator.board_config(values)
    except EmulatorError as e:
        raise SessionError(f"the session's configuration: {e}") from None


# ---- the session file ------------------------------------------------------------------------


def _header_bytes(header):
    return json.dumps(header, sort_keys=True).encode()


class SessionWriter:
    """Writes a session file as the bytes arrive: header first, trailer at `close`."""

    def __init__(self, path, header):
        self.path = Path(path)
        head = _header_bytes(header)
        self.f = open(self.path, "wb")  # noqa: SIM115 (closed in close())
        self.crc = 0
        self.n = 0
        self._put(MAGIC + struct.pack("<I", len(head)) + head)

    def _put(self, b):
        self.f.write(b)
        self.crc = binascii.crc32(b, self.crc)

    def write(self, data):
        if data:
            self._put(data)
            self.n += len(data)

    def close(self):
        self._put(TRAILER + struct.pack("<Q", self.n))
        self.f.write(struct.pack("<I", self.crc & 0xFFFFFFFF))
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
    if binascii.crc32(data[:-4]) & 0xFFFFFFFF != crc:
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


# ---- recording ----------------------------------------------------------------------------


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

    from host_emulator.proto import serial_port

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
        values = load_config(config) if isinstance(config, (str, os.PathLike)) else dict(config)
        _board_cfg(values)
    if baud is None:
        baud = int(values.get("output_baud", DEFAULT_BAUD)) if values else DEFAULT_BAUD
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
            if chunk:
                w.write(chunk)
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
    return {"path": str(out_path), "bytes": w.n, "seconds": elapsed, "stopped": stopped}


# ---- the stream: records, ticks, gaps ----------------------------------------------------


def _record_len(data, i, n):
    """Length of the valid record starting at data[i] (checksum or CRC right), else 0."""
    if i + 3 > n or data[i] != 0xEB:
        return 0
    t = data[i + 1]
    if t == FRAME_TYPE:
        if i + FRAME_LEN <= n and sum(data[i + 2 : i + 51]) & 0xFF == data[i + 51]:
            return FRAME_LEN
        return 0
    if t not in (EXT_TYPE, RAW_TYPE):
        return 0
    end = i + 3 + data[i + 2] + 4
    if end > n:
        return 0
    if t == EXT_TYPE and end - i != EXT_LEN:
        return 0
    if t == RAW_TYPE and (end - i < RAW_MIN_LEN or data[i + 2] != 23 + data[i + 25]):
        return 0
    (crc,) = struct.unpack_from("<I", data, end - 4)
    return end - i if binascii.crc32(data[i : end - 4]) & 0xFFFFFFFF == crc else 0


def _items(data):
    """The stream split into ("rec", offset, bytes) and ("junk", offset, length), in order."""
    out = []
    n = len(data)
    i = 0
    junk_at = None
    while i < n:
        m = _record_len(data, i, n)
        if m:
            if junk_at is not None:
                out.append(("junk", junk_at, i - junk_at))
                junk_at = None
            out.append(("rec", i, bytes(data[i : i + m])))
            i += m
            continue
        if junk_at is None:
            junk_at = i
        j = data.find(b"\xeb", i + 1)
        i = n if j < 0 else j
    if junk_at is not None:
        out.append(("junk", junk_at, n - junk_at))
    return out


def _expected(k, every, ext_every):
    """[(type, counter)] tick k sends (app.ticks = k + 1), in order."""
    t = k + 1
    c = (t // every) & 0xFF
    exp = []
    if t % every == 0:
        exp.append((FRAME_TYPE, (c - 1) & 0xFF))
    if ext_every and t % ext_every == 0:
        exp.append((EXT_TYPE, c))
    exp.append((RAW_TYPE, c))
    return exp


def _describe(item):
    if item is None:
        return "the end of the capture"
    if item[0] == "junk":
        return f"{item[2]} undecodable bytes"
    rec = item[2]
    what = f"a {_KIND_NAME[rec[1]]} with counter {rec[2] if rec[1] == FRAME_TYPE else rec[3]}"
    if rec[1] == EXT_TYPE:
        what += f" and tick {struct.unpack_from('<I', rec, 120)[0]}"
    return what


@dataclass
class _Walk:
    groups: list  # per tick: [record bytes, ...] in stream order
    end_offset: int  # byte after the last complete tick
    stray: int  # bytes between records of the chain that belong to nothing
    stop: str | None  # why the walk stopped before the end of the stream (a gap), or None
    stop_offset: int | None = None


def _walk(items, start, every, ext_every, max_ticks=None, explain=True):
    """Follow the tick chain from items[start] as tick 0 (explain: say in the gap's message
    whether the board restarted there)."""
    groups = []
    idx = start
    stray = 0
    end_offset = items[start][1]
    k = 0
    while max_ticks is None or k < max_ticks:
        group = []
        skipped = []
        for typ, counter in _expected(k, every, ext_every):
            while idx < len(items) and items[idx][0] == "junk":
                skipped.append(items[idx])
                idx += 1
            if idx == len(items):
                return _Walk(groups, end_offset, stray, None)  # the capture ends here
            rec = items[idx][2]
            got_counter = rec[2] if rec[1] == FRAME_TYPE else rec[3]
            ok = rec[1] == typ and got_counter == counter
            if ok and typ == EXT_TYPE:
                ok = struct.unpack_from("<I", rec, 120)[0] == (k + 1) & TICK_MASK
            if not ok:
                at = skipped[0][1] if skipped else items[idx][1]
                want = f"the {_KIND_NAME[typ]} with counter {counter}"
                if typ == EXT_TYPE:
                    want += f" and tick {(k + 1) & TICK_MASK}"
                found = ", then ".join(_describe(x) for x in skipped + [items[idx]])
                if explain and _starts_run(items, idx, every, ext_every):
                    found += " (the board restarted)"
                msg = f"gap at byte {at}, tick {k} (t = {k * TICK_US * 1e-6:.3f} s): expected "
                msg += f"{want}, found {found}"
                return _Walk(groups, end_offset, stray, msg, at)
            stray += sum(x[2] for x in skipped)
            skipped = []
            group.append(rec)
            idx += 1
        groups.append(group)
        end_offset = items[idx - 1][1] + len(items[idx - 1][2])
        k += 1
    return _Walk(groups, end_offset, stray, None)


def _starts_run(items, idx, every, ext_every):
    """Whether tick 0 of a run starts at items[idx]: its first ticks chain, up to and including
    the first extended frame, whose tick field must say so."""
    need = ext_every if ext_every else 1
    w = _walk(items, idx, every, ext_every, max_ticks=need, explain=False)
    return w.stop is None and len(w.groups) == need


@dataclass(eq=False)
class Recording:
    """The replayable part of a recorded stream: one row per tick from the board's first."""

    config: dict  # the board configuration values
    start_offset: int  # byte offset of tick 0's first record in the capture
    end_offset: int  # byte after the last tick used
    t0_us: np.ndarray  # (N,) int64: the tick's start, time.ticks_us (wraps at 2**30)
    pps_us: np.ndarray  # (N,) int64: the parser's pps_us after the tick
    gyro_regs: np.ndarray  # (N, 6) uint8
    accel_regs: np.ndarray  # (N, 6) uint8
    saturated: np.ndarray  # (N,) uint8
    gnss_offsets: np.ndarray  # (N + 1,) int64 into gnss_bytes
    gnss_bytes: bytes
    records: list  # the recorded records of these ticks (bytes), in stream order
    gap: str | None = None  # the gap the ticks stop at (parse(until_gap=True))
    notes: list = field(default_factory=list)  # what was skipped or tolerated

    def __len__(self):
        return len(self.t0_us)

    def kind(self, rtype):
        """The records of one type (FRAME_TYPE, EXT_TYPE, RAW_TYPE), in order."""
        return [r for r in self.records if r[1] == rtype]

    @property
    def stream(self):
        """The recorded records of these ticks, as the board sent them."""
        return b"".join(self.records)


def _recording(values, groups, start_offset, end_offset):
    n = len(groups)
    raws = [g[-1] for g in groups]
    t0 = np.fromiter((struct.unpack_from("<I", r, 4)[0] for r in raws), np.int64, n)
    pps = np.fromiter((struct.unpack_from("<I", r, 8)[0] for r in raws), np.int64, n)
    regs = np.frombuffer(b"".join(r[12:24] for r in raws), np.uint8).reshape(n, 12)
    sat = np.fromiter((r[24] & 1 for r in raws), np.uint8, n)
    lens = np.fromiter((r[25] for r in raws), np.int64, n)
    offs = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
    rec = Recording(
        config=dict(values),
        start_offset=start_offset,
        end_offset=end_offset,
        t0_us=t0,
        pps_us=pps,
        gyro_regs=regs[:, :6].copy(),
        accel_regs=regs[:, 6:].copy(),
        saturated=sat,
        gnss_offsets=offs,
        gnss_bytes=b"".join(r[26 : 26 + r[25]] for r in raws),
        records=[r for g in groups for r in g],
    )
    _check_saturation(rec)
    return rec


def _check_saturation(rec):
    """The recorded saturation flag must be what the firmware's driver derives from the
    recorded registers (else the records come from another firmware, or are damaged)."""
    if not len(rec):
        return
    g = stim_mod.gyro_counts(rec.gyro_regs).astype(np.int64)
    a = stim_mod.accel_counts(rec.accel_regs).astype(np.int64)
    derived = ((g >= 32766) | (g <= -32767)).any(axis=1) | ((a >= 2046) | (a <= -2047)).any(axis=1)
    bad = np.flatnonzero(derived.astype(np.uint8) != rec.saturated)
    if len(bad):
        k = int(bad[0])
        raise SessionError(
            f"raw-input record of tick {k}: saturation flag {int(rec.saturated[k])} but its "
            f"registers say {int(derived[k])} (recorded with another firmware version?)"
        )


def _rates(values):
    cfg = _board_cfg(values)
    if not cfg.raw_record:
        raise SessionError(
            "the configuration has raw_record = 0: a board configured so sends no raw-input "
            "records, and a session cannot be replayed without them (record the board with "
            "raw_record = 1, and give that configuration)"
        )
    return cfg.output_every_ticks, cfg.ext_every_ticks


def parse(data, config_values, until_gap=False):
    """The Recording in a captured stream: from the board's first tick to the end, or to the
    first gap. SessionError (naming the byte offset and tick) if the stream holds no start,
    or has a gap and until_gap is False."""
    every, ext_every = _rates(config_values)
    items = _items(data)
    recs = [i for i, it in enumerate(items) if it[0] == "rec"]
    if not any(items[i][2][1] == RAW_TYPE for i in recs):
        raise SessionError(
            "nothing in the recording decodes as the board's output (wrong baud rate or "
            "wiring, or not this board's output port)"
            if not recs
            else "no raw-input records (type 0x92) in the recording, only frames: the board "
            "ran with raw_record = 0; set it to 1 in the board's configuration and record again"
        )
    first_type = _expected(0, every, ext_every)[0]
    start = None
    for i in recs:
        rec = items[i][2]
        counter = rec[2] if rec[1] == FRAME_TYPE else rec[3]
        if (rec[1], counter) == first_type and _starts_run(items, i, every, ext_every):
            start = i
            break
    if start is None:
        raise SessionError(
            "the recording does not hold the board's first tick: start recording before "
            "powering up or resetting the board (a replay must begin where the firmware "
            "starts); or the configuration's output_every_ticks / ext_every_ticks are not "
            "the board's"
        )
    w = _walk(items, start, every, ext_every)
    if w.stop and not until_gap:
        raise SessionError(
            f"{w.stop}. The firmware's state after a gap is unknown, so the session cannot be "
            f"replayed past it; --until-gap replays the {len(w.groups)} ticks before it"
        )
    rec = _recording(config_values, w.groups, items[start][1], w.end_offset)
    rec.gap = w.stop
    if items[start][1]:
        rec.notes.append(f"{items[start][1]} bytes before the board's first tick skipped")
    if w.stray:
        rec.notes.append(f"{w.stray} stray bytes between records ignored (the records chain)")
    tail = len(data) - w.end_offset
    if not w.stop and tail:
        rec.notes.append(f"{tail} bytes after the last complete tick left out")
    return rec


def from_decoded(dec, config_values):
    """A Recording from a `frames.decode` result (its raw records' counters must chain from
    the board's first tick; bytes given to `parse` are checked more closely)."""
    every, ext_every = _rates(config_values)
    if not dec.raw:
        raise SessionError("no raw-input records (type 0x92) in the decoded stream")
    for k, r in enumerate(dec.raw):
        want = ((k + 1) // every) & 0xFF
        if r["counter"] != want:
            raise SessionError(
                f"gap at raw-input record {k}: counter {r['counter']}, expected {want}"
                + (" (the stream does not start at the board's first tick)" if k == 0 else "")
            )
    raws = []
    for r in dec.raw:
        g = r["gnss_bytes"]
        body = struct.pack("<BBBBII", 0xEB, RAW_TYPE, 23 + len(g), r["counter"], r["t0_us"], 0)
        body = bytearray(body)
        struct.pack_into("<I", body, 8, r["pps_us"])
        body += r["gyro_regs"] + r["accel_regs"] + bytes((r["saturated"], len(g))) + g
        raws.append(bytes(body) + struct.pack("<I", binascii.crc32(body) & 0xFFFFFFFF))
    groups = []
    for k, r in enumerate(dec.raw):
        fi = r.get("frame_index", -1)
        has_frame = (k + 1) % every == 0 and 0 <= fi < len(dec.frames)
        groups.append(([dec.frames[fi]["raw"]] if has_frame else []) + [raws[k]])
    rec = _recording(config_values, groups, 0, 0)
    if ext_every:
        rec.notes.append("built from decoded records: the extended frames are not kept")
    return rec


# ---- the emulator's input -------------------------------------------------------------------


def pps_edges(rec):
    """(pps_before_us per tick (-1: none), notes): where the emulator fires each PPS edge.

    An edge shows as a change of the recorded pps_us (the parser's, 0 at start-up) from one
    tick to the next; it came pps_before_us = ticks_diff(t0_us, pps_us) before the tick.
    On a board an edge can also come while a tick runs (pps_before_us < 0): it then goes to
    that tick if the tick's frame already shows its PPS flag, else to the next tick."""
    n = len(rec)
    before = np.full(n, -1, np.int32)
    notes = []
    every, _ = _rates(rec.config)
    prev = np.concatenate([[0], rec.pps_us[:-1]])
    late = far = 0
    frames_ = None
    for k in np.flatnonzero(rec.pps_us != prev).tolist():
        d = ticks_diff(rec.t0_us[k], rec.pps_us[k])
        if d < 0:  # the edge came while tick k ran
            late += 1
            fi = (k + 1) // every - 1
            frames_ = rec.kind(FRAME_TYPE) if frames_ is None else frames_
            seen = (k + 1) % every == 0 and fi < len(frames_) and frames_[fi][15]
            if seen:
                before[k] = 0
            elif k + 1 < n:
                before[k + 1] = max(0, ticks_diff(rec.t0_us[k + 1], rec.pps_us[k]))
            continue
        if d >= TICK_US:
            far += 1
        before[k] = min(d, 0xFFFF)
    if late:
        notes.append(
            f"{late} PPS edges came while a tick ran (placed at a tick boundary: a fix's "
            "measurement time may then differ by a tick)"
        )
    if far:
        notes.append(f"{far} PPS edges came more than a tick interval before their tick")
    return before, notes


def timing_notes(rec):
    """What of the board's timing the emulator (ticks exactly tick_us apart) cannot follow."""
    if len(rec) < 2:
        return []
    step = (rec.t0_us[1:] - rec.t0_us[:-1]) % TICKS_PERIOD
    step = np.where(step >= TICKS_PERIOD // 2, step - TICKS_PERIOD, step)
    off = np.flatnonzero(step != TICK_US)
    if not len(off):
        return []
    over = int(np.sum(step >= TICK_US * 3 // 2))
    return [
        f"{len(off)} tick starts not {TICK_US} us after the previous one (steps "
        f"{int(step.min())}..{int(step.max())} us; {over} look like overruns): the emulator "
        "runs ticks exactly 5 ms apart, so a fix's PPS age, and with it the fix's measurement "
        "tick, can differ by one where it is within that jitter of a 5 ms boundary"
    ]


def to_stimulus(decoded_or_bytes, config_values, until_gap=False):
    """The emulator's input (a stimulus.Stimulus) that reproduces a recorded session: tick k's
    BMI055 registers and GNSS bytes as the board read them, its PPS edges (`pps_edges`), the
    temperature register 0 (not recorded; the loop does not read it).

    decoded_or_bytes: the captured bytes (checked by `parse`), a Recording, or a
    `frames.decode` result. The header carries the configuration values and the notes."""
    src = decoded_or_bytes
    if isinstance(src, Recording):
        rec = src
    elif isinstance(src, frames.Decoded):
        rec = from_decoded(src, config_values)
    else:
        rec = parse(bytes(src), config_values, until_gap)
    before, notes = pps_edges(rec)
    n = len(rec)
    header = {
        "source": "board session",
        "tick_us": TICK_US,
        "config": dict(config_values),
        "duration_s": n * TICK_US * 1e-6,
        "session_start_byte": rec.start_offset,
        "session_gap": rec.gap,
        "notes": rec.notes + notes + timing_notes(rec),
    }
    return stim_mod.Stimulus(
        header,
        rec.gyro_regs.copy(),
        rec.accel_regs.copy(),
        np.zeros(n, np.int8),
        before,
        rec.gnss_offsets.copy(),
        rec.gnss_bytes,
    )


# ---- comparison -------------------------------------------------------------------------


@dataclass
class FieldDiff:
    name: str
    recorded: object
    replayed: object

    def __str__(self):
        return f"{self.name} recorded {self.recorded} replayed {self.replayed}"


@dataclass
class KindComparison:
    kind: str  # "frame", "extended frame", "raw record"
    recorded: int = 0
    replayed: int = 0
    compared: int = 0
    first: int | None = None  # index of the first differing (or missing) record
    tick: int | None = None
    fields: list = field(default_factory=list)  # FieldDiff of that record
    excluded: str = ""  # what is not compared, in words

    @property
    def identical(self):
        return self.first is None and self.recorded == self.replayed


@dataclass
class Comparison:
    frame: KindComparison
    ext: KindComparison
    raw: KindComparison
    tick_us: int = TICK_US
    timing_differs: int = 0  # extended frames whose (excluded) timing fields differ
    exact: bool = True  # False: MicroPython VM tolerance mode
    stream_error: str | None = None

    @property
    def identical(self):
        return (
            self.stream_error is None
            and self.frame.identical
            and self.ext.identical
            and self.raw.identical
        )

    def summary(self):
        lines = []
        if self.stream_error:
            lines.append("stream: " + self.stream_error)
        for k in (self.frame, self.ext, self.raw):
            if k.recorded == 0 and k.replayed == 0:
                continue
            line = f"{k.kind}s: {k.compared} compared"
            if k.recorded != k.replayed:
                line += f" (recorded {k.recorded}, replayed {k.replayed})"
            if k.first is None:
                same = "identical" if self.exact else "equal"
                line += f", {same}" if k.recorded == k.replayed else ""
            else:
                where = f"{k.kind} {k.first}"
                if k.tick is not None:
                    where += f" (tick {k.tick}, t = {k.tick * self.tick_us * 1e-6:.3f} s)"
                line += f", first difference at {where}: " + "; ".join(map(str, k.fields))
                if k.kind == "frame" and k.first == 0:
                    names = {f.name for f in k.fields}
                    if names & set(parity._FRAME_NAMES[3:9]):
                        line += " (the configuration's sensor ranges are not the board's?)"
            if k.excluded:
                line += f" [not compared: {k.excluded}]"
            lines.append(line)
        if self.timing_differs:
            lines.append(
                f"extended frames: timing fields differ in {self.timing_differs} (expected "
                "for a board: the emulator does not model run time)"
            )
        return "\n".join(lines)


def _ext_key(rec, exact):
    if exact:
        return rec[:8] + rec[16:-4]
    return rec[:8] + rec[112:124]  # integer fields: health .. flags, origin lat/lon, tick


def _raw_key(rec):
    return rec[:4] + rec[12:-4]


def _frame_ok(a, b, exact):
    if a == b:
        return True
    if exact or a[:29] != b[:29]:
        return False
    va = parity._FRAME_FMT.unpack(a)[16:25]
    vb = parity._FRAME_FMT.unpack(b)[16:25]
    return all(abs(x - y) <= VM_FLOAT_STEPS for x, y in zip(va, vb, strict=True))


def _field_diffs(kind, a, b, skip):
    fa = parity._record_fields(kind, a)
    fb = parity._record_fields(kind, b)
    if [n for n, _ in fa] != [n for n, _ in fb]:
        return [FieldDiff("length", len(a), len(b))]
    out = [
        FieldDiff(n, x, y)
        for (n, x), (_, y) in zip(fa, fb, strict=True)
        if x != y and n not in skip and n.split("[")[0] not in skip
    ]
    return out or [FieldDiff("bytes", a.hex(), b.hex())]


def _compare_kind(kind, rec, rep, same, every, skip, excluded):
    r = KindComparison(kind, len(rec), len(rep), min(len(rec), len(rep)), excluded=excluded)
    for i in range(r.compared):
        if not same(rec[i], rep[i]):
            r.first = i
            r.fields = _field_diffs(kind, rec[i], rep[i], skip)
            break
    else:
        if len(rec) != len(rep):
            r.first = r.compared
            r.fields = [FieldDiff("present", r.compared < len(rec), r.compared < len(rep))]
    if r.first is not None and every:
        r.tick = (r.first + 1) * every - 1
    return r


_EXT_FLOATS = ("p_diag", "gyro_bias_rad_s", "accel_bias_m_s2", "pos_enu_m", "origin_h_m")


def compare(recorded, replayed, output_every_ticks=1, ext_every_ticks=20, exact=True):
    """Compare two output streams (bytes of records: the recorded one as `Recording.stream`
    gives it, the replayed one as the emulator wrote it): a Comparison naming the first
    differing record of each kind, its tick and fields. exact=False: the MicroPython VM's
    tolerance (module docstring)."""
    rec_f, rec_e, rec_r, rec_err = parity.split(recorded)
    rep_f, rep_e, rep_r, rep_err = parity.split(replayed)
    err = "; ".join(f"{s}: {e}" for s, e in (("recorded", rec_err), ("replayed", rep_err)) if e)
    ext_skip = set(EXT_TIMING_FIELDS) | {"crc32"} | (set() if exact else set(_EXT_FLOATS))
    f_skip = set() if exact else set(_FRAME_FLOAT_FIELDS) | {"checksum"}
    c = Comparison(
        frame=_compare_kind(
            "frame",
            rec_f,
            rep_f,
            lambda a, b: _frame_ok(a, b, exact),
            output_every_ticks,
            f_skip,
            ""
            if exact
            else f"checksum; attitude, velocity, position within {VM_FLOAT_STEPS} steps",
        ),
        ext=_compare_kind(
            "extended frame",
            rec_e,
            rep_e,
            lambda a, b: _ext_key(a, exact) == _ext_key(b, exact),
            ext_every_ticks,
            ext_skip,
            "timing fields (tick us, overruns, GC runs)" + ("" if exact else ", float fields"),
        ),
        raw=_compare_kind(
            "raw record",
            rec_r,
            rep_r,
            lambda a, b: _raw_key(a) == _raw_key(b),
            1,
            set(RAW_TIME_FIELDS) | {"crc32"},
            "tick start and PPS times",
        ),
        stream_error=err or None,
        exact=exact,
    )
    c.timing_differs = sum(
        a[8:16] != b[8:16] for a, b in zip(rec_e, rep_e, strict=False) if len(a) == len(b)
    )
    return c


# ---- replay -----------------------------------------------------------------------------


@dataclass(eq=False)
class ReplayResult:
    recording: Recording
    stimulus: object  # stimulus.Stimulus
    run: object  # emulator.FirmwareRun
    comparison: Comparison
    config_source: str

    @property
    def identical(self):
        return self.comparison.identical

    def summary(self):
        rec = self.recording
        n = len(rec)
        lines = [
            f"session: {n} ticks ({n * TICK_US * 1e-6:.3f} s) from byte {rec.start_offset}, "
            f"configuration from {self.config_source}",
        ]
        if rec.gap:
            lines.append(f"replayed up to the first gap: {rec.gap}")
        for note in self.stimulus.header.get("notes", []):
            lines.append("note: " + note)
        lines.append(f"replayed on {self.run.runtime} in {self.run.wall_s:.1f} s")
        lines.append(self.comparison.summary())
        if self.identical:
            what = "identical" if self.comparison.exact else "equal within the VM's tolerance"
            lines.append(f"REPLAY: {what}, {n} ticks")
        else:
            lines.append("REPLAY: DIFFERENT")
        return "\n".join(lines)


def _session_config(header, config, path):
    if config is not None:
        if isinstance(config, (str, os.PathLike)):
            return load_config(config), str(config)
        return dict(config), "the given values"
    if header.get("config"):
        return dict(header["config"]), "the session file"
    raise SessionError(
        f"{path}: the session holds no board configuration: give the board's configuration "
        "file with --config (its ranges, lever arm, output rates, ... shape the output)"
    )


def replay(session_path, workdir, runtime="cpython", config=None, until_gap=False, progress=None):
    """Replay a session file through the emulator and compare; a ReplayResult.

    config: the board configuration (a path, see load_config, or a dict of values) when the
    session holds none or holds the wrong one. until_gap: replay the ticks before the first
    gap instead of failing. runtime: "cpython" (bit-exact) or "micropython" (the VM, compared
    to its tolerance). FirmwareError if the firmware raises."""
    if runtime not in ("cpython", "micropython"):
        raise SessionError(f"runtime must be cpython or micropython, got {runtime!r}")
    header, data = read_session(session_path)
    values, source = _session_config(header, config, session_path)
    rec = parse(data, values, until_gap)
    stim = to_stimulus(rec, values)
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    if runtime == "cpython":
        run = emulator.run_cpython(stim, workdir, progress=progress)
    else:
        from host_emulator.runtimes import mpy_unix as vm_runner

        run = vm_runner.run_micropython(stim, workdir, progress=progress)
    cfg = _board_cfg(values)
    c = compare(
        rec.stream, run.out, cfg.output_every_ticks, cfg.ext_every_ticks, runtime == "cpython"
    )
    return ReplayResult(rec, stim, run, c, source)


# ---- command line -----------------------------------------------------------------------


class _UsageError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage dump, status 2
        raise _UsageError(message)


def _positive(text, name):
    try:
        v = float(text)
    except ValueError:
        raise _UsageError(f"{name} must be a number, got {text!r}") from None
    if not v > 0:
        raise _UsageError(f"{name} must be positive, got {text!r}")
    return v


def _progress_printer():
    if not sys.stderr.isatty():
        return None
    return lambda a, b: print(f"\r{a} / {b}", end="", file=sys.stderr, flush=True)


def main(argv=None):
    """`session record SOURCE --out FILE ...` / `session replay FILE ...`: exit status 0 (done,
    identical), 1 (replay differs, or the firmware raised), 2 (bad input)."""
    p = _Parser(
        prog="python -m host_emulator session",
        description="record a board's output; replay it through the emulator, byte for byte",
    )
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    r = sub.add_parser("record", help="capture a board's output into a session file")
    r.add_argument("source", help="serial port (/dev/ttyUSB0, COM3), named pipe, '-' or file")
    r.add_argument("--out", required=True, help="session file to write")
    r.add_argument("--seconds", help="stop after this long (default: Ctrl-C or end of input)")
    r.add_argument("--baud", help="serial baud rate (default: the configuration's, else 460800)")
    r.add_argument("--config", help="the board's configuration file (or JSON), kept in the file")
    s = sub.add_parser("replay", help="replay a session through the emulator and compare")
    s.add_argument("session", help="session file (or a plain capture, with --config)")
    s.add_argument("--config", help="the board's configuration (overrides the session's)")
    s.add_argument("--runtime", default="cpython", choices=("cpython", "micropython"))
    s.add_argument("--until-gap", action="store_true", help="replay up to the first gap")
    s.add_argument("--out", help="directory for stimulus.bin and replayed.bin (kept)")
    try:
        args = p.parse_args(argv)
        if args.command == "record":
            seconds = None if args.seconds is None else _positive(args.seconds, "--seconds")
            baud = None if args.baud is None else int(_positive(args.baud, "--baud"))
    except _UsageError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    try:
        if args.command == "record":
            return _main_record(args, seconds, baud)
        return _main_replay(args)
    except FirmwareError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except EmulatorError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


def _main_record(args, seconds, baud):
    tty = sys.stderr.isatty()

    def progress(nbytes, elapsed):
        if tty:
            print(f"\r{nbytes} bytes, {elapsed:.0f} s", end="", file=sys.stderr, flush=True)

    if tty and seconds is None:
        print("recording; Ctrl-C stops", file=sys.stderr)
    res = record(args.source, args.out, seconds, progress, args.config, baud)
    if tty:
        print(file=sys.stderr)
    print(
        f"recorded {res['bytes']} bytes in {res['seconds']:.1f} s ({res['stopped']}) into "
        f"{res['path']}"
    )
    if res["bytes"] == 0:
        print("warning: nothing was received (baud rate? wiring? is the board on?)")
    return 0


def _main_replay(args):
    progress = _progress_printer()
    if args.out:
        work = Path(args.out)
        res = replay(args.session, work, args.runtime, args.config, args.until_gap, progress)
        res.stimulus.write(work / "stimulus.bin")
        (work / "replayed.bin").write_bytes(res.run.out)
    else:
        with tempfile.TemporaryDirectory(prefix="session-") as d:
            res = replay(args.session, d, args.runtime, args.config, args.until_gap, progress)
    if progress:
        print(file=sys.stderr)
    print(res.summary())
    return 0 if res.identical else 1


if __name__ == "__main__":
    sys.exit(main())
