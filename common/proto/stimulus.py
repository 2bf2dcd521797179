"""The stimulus file: everything the board's peripherals see, tick by tick. It is the seam between
what produces input (a simulation, a recording, a recorded board session) and what consumes it
(the firmware on CPython or in the MicroPython VM, the NumPy model), so all of them replay the
same way.

Time. Record k belongs to timer tick k, which fires at t_k = k * tick_us (virtual clock, us
since power-on). The record holds what happened in the interval (t_(k-1), t_k]:
- the BMI055 data registers at t_k: the sample the firmware's burst read of tick k returns
  (gyro 0x02..0x07 and accel 0x02..0x07 as the chip presents them, LSB first; the accel words
  are 12-bit counts left-justified with bit 0 = new_data);
- the temperature register (int8, 0.5 K per LSB, 0 = 23 degC);
- a PPS rising edge, if one came, at t_k - pps_before_us (0 <= pps_before_us < tick_us);
- the bytes that finished arriving on the GNSS UART in the interval, in order.
The emulator replays a record as: set the IMU registers, feed the UART bytes, advance the
clock to the PPS edge and fire it, advance the clock to t_k, fire the timer, run the loop.

File layout (little-endian):
    b"INSSTIM1", header length u32, header (UTF-8 JSON object, see `Stimulus.header`)
    per tick: gyro registers 6 B, accel registers 6 B, temperature i8, flags u8 (bit 0: PPS
              edge in this interval; bit 1: the IMU does not answer in this interval, an
              injected fault), pps_before_us u16, n u16, then the n UART bytes
    b"END1", ticks u32, CRC-32 (u32, proto/crc.py) of everything before it
The trailer makes a truncated or damaged file an error, never a shorter run.

Header keys: "tick_us" (5000), "ticks", "source" ("simulation", ...), "config" (board
configuration values for `firmware/lib/config.py`: gyro_range_dps, accel_range_g, gnss_baud,
lever_b_m, ...), "outages" ([[start_s, length_s], ...] of the GNSS input), and whatever
describes the source ("scenario", "seed", "duration_s", "utc_start", ...).
"""

import json
import struct
from dataclasses import dataclass, field

import numpy as np

from common.errors import EmulatorError
from common.proto.crc import crc32
from common.proto.mpy.feed_protocol import (  # noqa: F401  (this module's names too)
    FLAG_IMU_SILENT,
    FLAG_PPS,
    FLAG_STALL,
    MAGIC,
    REC_LEN,
    TICK_US,
    TRAILER,
)

_REC = struct.Struct("<6s6sbBHH")  # feed_protocol's record
if _REC.size != REC_LEN:
    raise ImportError(f"feed_protocol.REC_LEN {REC_LEN} is not the record's {_REC.size} bytes")


class StimulusError(EmulatorError):
    """A stimulus file that cannot be used, with a message that says why."""


def gyro_registers(counts):
    """(N, 3) int16 gyro counts -> (N, 6) uint8 data registers (LSB first)."""
    c = np.asarray(counts, dtype=np.int64).reshape(-1, 3)
    if c.min(initial=0) < -32768 or c.max(initial=0) > 32767:
        raise ValueError("gyro counts must be int16")
    return (c.astype("<i2").view(np.uint8)).reshape(-1, 6).copy()


def accel_registers(counts, new_data=True):
    """(N, 3) 12-bit accel counts -> (N, 6) uint8 data registers: counts << 4, bit 0 new_data."""
    c = np.asarray(counts, dtype=np.int64).reshape(-1, 3)
    if c.min(initial=0) < -2048 or c.max(initial=0) > 2047:
        raise ValueError("accel counts must be 12-bit (-2048..2047)")
    w = ((c & 0xFFF) << 4) | (1 if new_data else 0)
    return w.astype("<u2").view(np.uint8).reshape(-1, 6).copy()


def gyro_counts(regs):
    """(N, 6) gyro data registers -> (N, 3) int16 counts."""
    return np.ascontiguousarray(regs, dtype=np.uint8).view("<i2").reshape(-1, 3).astype(np.int16)


def accel_counts(regs):
    """(N, 6) accel data registers -> (N, 3) 12-bit counts (the driver's int16 >> 4)."""
    w = np.ascontiguousarray(regs, dtype=np.uint8).view("<i2").reshape(-1, 3)
    return (w >> 4).astype(np.int16)


@dataclass(eq=False)
class Stimulus:
    """One input recording, in memory. Arrays have one row per tick."""

    header: dict
    gyro_regs: np.ndarray  # (N, 6) uint8
    accel_regs: np.ndarray  # (N, 6) uint8
    temp_raw: np.ndarray  # (N,) int8
    pps_before_us: np.ndarray  # (N,) int32, -1: no PPS edge in the interval
    uart_offsets: np.ndarray  # (N + 1,) int64: tick k's bytes are uart_bytes[o[k]:o[k+1]]
    uart_bytes: bytes = b""
    extra: dict = field(default_factory=dict)
    imu_silent: np.ndarray = None  # (N,) bool: the IMU does not answer (None: never)
    stalled: np.ndarray = None  # (N,) bool: the loop does not run (FLAG_STALL; None: never)

    def __post_init__(self):
        n = len(self.gyro_regs)
        if self.imu_silent is None:
            self.imu_silent = np.zeros(n, bool)
        if self.stalled is None:
            self.stalled = np.zeros(n, bool)
        shapes = (
            self.gyro_regs.shape == (n, 6),
            self.accel_regs.shape == (n, 6),
            self.temp_raw.shape == (n,),
            self.pps_before_us.shape == (n,),
            self.uart_offsets.shape == (n + 1,),
            self.imu_silent.shape == (n,),
            self.stalled.shape == (n,),
        )
        if not all(shapes) or int(self.uart_offsets[-1]) != len(self.uart_bytes):
            raise ValueError("Stimulus arrays do not have one row per tick")
        self.header.setdefault("tick_us", TICK_US)
        self.header["ticks"] = n

    def __len__(self):
        return len(self.gyro_regs)

    @property
    def tick_us(self):
        return int(self.header["tick_us"])

    @property
    def duration_s(self):
        return len(self) * self.tick_us * 1e-6

    @property
    def config(self):
        return dict(self.header.get("config", {}))

    def uart_chunk(self, k):
        o = self.uart_offsets
        return self.uart_bytes[o[k] : o[k + 1]]

    def head(self, ticks):
        """The first `ticks` records (a shorter run of the same input)."""
        n = min(int(ticks), len(self))
        o = self.uart_offsets[: n + 1].copy()
        header = dict(self.header)
        header["duration_s"] = n * self.tick_us * 1e-6
        return Stimulus(
            header,
            self.gyro_regs[:n].copy(),
            self.accel_regs[:n].copy(),
            self.temp_raw[:n].copy(),
            self.pps_before_us[:n].copy(),
            o,
            self.uart_bytes[: int(o[-1])],
            dict(self.extra),
            self.imu_silent[:n].copy(),
            self.stalled[:n].copy(),
        )

    # ---- file ----

    def to_bytes(self):
        head = json.dumps(self.header, sort_keys=True).encode()
        parts = [MAGIC, struct.pack("<I", len(head)), head]
        o = self.uart_offsets
        ub = self.uart_bytes
        g = self.gyro_regs.tobytes()
        a = self.accel_regs.tobytes()
        silent = self.imu_silent
        stalled = self.stalled
        for k in range(len(self)):
            pps = int(self.pps_before_us[k])
            n = int(o[k + 1] - o[k])
            parts.append(
                _REC.pack(
                    g[6 * k : 6 * k + 6],
                    a[6 * k : 6 * k + 6],
                    int(self.temp_raw[k]),
                    (FLAG_PPS if pps >= 0 else 0)
                    | (FLAG_IMU_SILENT if silent[k] else 0)
                    | (FLAG_STALL if stalled[k] else 0),
                    pps if pps >= 0 else 0,
                    n,
                )
            )
            if n:
                parts.append(ub[o[k] : o[k + 1]])
        body = b"".join(parts) + TRAILER + struct.pack("<I", len(self))
        return body + struct.pack("<I", crc32(body))

    def write(self, path):
        """The stimulus file, whole or not at all (errors.write_atomic)."""
        from common.errors import write_atomic

        write_atomic(path, self.to_bytes())


def from_bytes(data, name="stimulus"):
    """Parse a stimulus file's bytes; StimulusError saying what is wrong."""
    if len(data) < len(MAGIC) + 4 or data[: len(MAGIC)] != MAGIC:
        raise StimulusError(f"{name}: not a stimulus file (it does not start with {MAGIC!r})")
    (hlen,) = struct.unpack_from("<I", data, len(MAGIC))
    pos = len(MAGIC) + 4
    try:
        header = json.loads(data[pos : pos + hlen].decode())
        if not isinstance(header, dict):
            raise ValueError("not an object")
    except (UnicodeDecodeError, ValueError) as e:
        raise StimulusError(f"{name}: the header is not readable JSON ({e})") from None
    pos += hlen
    if len(data) < pos + 12 or data[-12:-8] != TRAILER:
        raise StimulusError(f"{name}: the file is truncated (no end marker): incomplete copy?")
    (crc,) = struct.unpack_from("<I", data, len(data) - 4)
    if crc32(data[:-4]) != crc:
        raise StimulusError(f"{name}: CRC mismatch, the file is damaged")
    (ticks,) = struct.unpack_from("<I", data, len(data) - 8)
    end = len(data) - 12
    gyro = bytearray(6 * ticks)
    accel = bytearray(6 * ticks)
    temp = np.zeros(ticks, np.int8)
    pps = np.full(ticks, -1, np.int32)
    silent = np.zeros(ticks, bool)
    stalled = np.zeros(ticks, bool)
    offs = np.zeros(ticks + 1, np.int64)
    chunks = []
    total = 0
    unpack = _REC.unpack_from
    for k in range(ticks):
        if pos + REC_LEN > end:
            raise StimulusError(f"{name}: record {k} of {ticks} is cut short")
        g, a, t, flags, before, n = unpack(data, pos)
        pos += REC_LEN
        gyro[6 * k : 6 * k + 6] = g
        accel[6 * k : 6 * k + 6] = a
        temp[k] = t
        if flags & FLAG_PPS:
            pps[k] = before
        if flags & FLAG_IMU_SILENT:
            silent[k] = True
        if flags & FLAG_STALL:
            stalled[k] = True
        if n:
            if pos + n > end:
                raise StimulusError(f"{name}: record {k} of {ticks} is cut short")
            chunks.append(data[pos : pos + n])
            pos += n
            total += n
        offs[k + 1] = total
    if pos != end:
        raise StimulusError(f"{name}: {end - pos} bytes after the last record")
    tick_us = header.get("tick_us", TICK_US)
    if not isinstance(tick_us, int) or not 100 <= tick_us <= 1_000_000:
        raise StimulusError(f"{name}: tick_us must be an integer 100..1000000, got {tick_us!r}")
    return Stimulus(
        header,
        np.frombuffer(bytes(gyro), np.uint8).reshape(-1, 6).copy(),
        np.frombuffer(bytes(accel), np.uint8).reshape(-1, 6).copy(),
        temp,
        pps,
        offs,
        b"".join(chunks),
        {},
        silent,
        stalled,
    )


def read_bytes(path):
    """A stimulus file's bytes; StimulusError (with the path) if it cannot be read."""
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError as e:
        raise StimulusError(f"cannot read stimulus file {path}: {e.strerror}") from None


def read(path):
    """Load a stimulus file; StimulusError (with the path) if it is missing or unusable."""
    return from_bytes(read_bytes(path), str(path))


def from_arrays(header, gyro_counts_, accel_counts_, temp_raw, pps_before_us, chunks):
    """A Stimulus from per-tick counts, temperatures, PPS offsets (-1 none) and a list of
    per-tick byte strings (or (offsets, bytes))."""
    if isinstance(chunks, tuple):
        offs, data = chunks
    else:
        lens = np.fromiter((len(c) for c in chunks), np.int64, len(chunks))
        offs = np.concatenate([[0], np.cumsum(lens)])
        data = b"".join(chunks)
    return Stimulus(
        dict(header),
        gyro_registers(gyro_counts_),
        accel_registers(accel_counts_),
        np.asarray(temp_raw, np.int8),
        np.asarray(pps_before_us, np.int32),
        np.asarray(offs, np.int64),
        bytes(data),
    )
