"""Parity of the host emulator: the firmware run on CPython (`emulator.run_cpython`) against
the NumPy float32 model (`model_runner.run`), byte for byte over the whole output stream.

    python -m host_emulator parity --scenario highway_outage --duration 45 [--seed 0]

Exit status 0 when both streams are identical, 1 when they differ (the summary names the first
differing frame, its tick and its fields with both values) or the firmware raised, 2 for a
bad command line (unknown scenario, bad duration).

Records are compared per kind in order: the 52-byte frames (fields as integers at the frame's
scale), the extended frames 0x91 and the raw-input records 0x92 (fields as
`host_emulator.frames` decodes them; floats with their float32 bits). Tick k is stimulus
record k, at t = k * tick_us after the first tick.
"""

import argparse
import struct
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from host_emulator.errors import EmulatorError, FirmwareError
from host_emulator.model import app as model_runner
from host_emulator.proto import stream as frames
from host_emulator.runtimes import cpython as emulator

FRAME_LEN = 52
# the 52-byte frame (DESIGN.md 6) as integers at the frame's scale
_FRAME_FMT = struct.Struct("<BBB3h3hBBBiihB3h3hiihB")
_FRAME_NAMES = (
    "header0",
    "header1",
    "counter",
    "gyro_x",
    "gyro_y",
    "gyro_z",
    "accel_x",
    "accel_y",
    "accel_z",
    "pps",
    "gga",
    "gnss_valid",
    "lat_e7",
    "lon_e7",
    "height_dm",
    "nav_state",
    "yaw_cdeg",
    "pitch_cdeg",
    "roll_cdeg",
    "vel_e_cm_s",
    "vel_n_cm_s",
    "vel_u_cm_s",
    "pos_e_cm",
    "pos_n_cm",
    "pos_u_dm",
    "checksum",
)
assert _FRAME_FMT.size == FRAME_LEN and len(_FRAME_NAMES) == 26


@dataclass
class FieldDiff:
    name: str
    firmware: object
    model: object

    def __str__(self):
        return f"{self.name} firmware {self.firmware} model {self.model}"


@dataclass
class KindResult:
    """One kind of record: how many of each side, how many compared, the first difference."""

    kind: str  # "frame", "extended frame", "raw record"
    firmware: int = 0  # records in the firmware's stream
    model: int = 0
    compared: int = 0  # records present on both sides
    first: int | None = None  # index of the first differing (or missing) record
    tick: int | None = None  # its tick
    fields: list = field(default_factory=list)  # FieldDiff of that record

    @property
    def identical(self):
        return self.first is None and self.firmware == self.model


@dataclass
class ParityResult:
    identical: bool  # the two byte streams are equal
    bytes_firmware: int
    bytes_model: int
    first_byte: int | None  # offset of the first differing byte
    frame: KindResult
    ext: KindResult
    raw: KindResult
    tick_us: int = 5000
    wall_firmware_s: float = 0.0
    wall_model_s: float = 0.0
    stream_error: str | None = None  # a stream that does not split into records
    firmware_stats: dict = field(default_factory=dict)  # run_cpython's counters
    out_firmware: bytes = field(default=b"", repr=False)  # the two streams compared
    out_model: bytes = field(default=b"", repr=False)

    def summary(self):
        lines = [
            f"firmware (CPython emulator) {self.wall_firmware_s:.2f} s wall, "
            f"model (NumPy float32) {self.wall_model_s:.2f} s wall"
        ]
        if self.stream_error:
            lines.append("stream: " + self.stream_error)
        for k in (self.frame, self.ext, self.raw):
            if k.firmware == 0 and k.model == 0:
                continue
            line = f"{k.kind}s: {k.compared} compared"
            if k.firmware != k.model:
                line += f" (firmware {k.firmware}, model {k.model})"
            if k.first is None:
                line += ", identical" if k.firmware == k.model else ""
            else:
                where = f"{k.kind} {k.first}"
                if k.tick is not None:
                    where += f" (tick {k.tick}, t = {k.tick * self.tick_us * 1e-6:.3f} s)"
                line += f", first difference at {where}: " + "; ".join(map(str, k.fields))
            lines.append(line)
        if self.identical:
            lines.append(f"PARITY: identical, {self.bytes_firmware} bytes")
        else:
            lines.append(
                f"PARITY: DIFFERENT (firmware {self.bytes_firmware} bytes, model "
                f"{self.bytes_model} bytes, first differing byte {self.first_byte})"
            )
        return "\n".join(lines)


def split(data):
    """(frames, ext, raw, error): the records of an output stream, each kind in order; error
    names the offset where the stream stops splitting (None if it splits to the end)."""
    out = {0x90: [], 0x91: [], 0x92: []}
    i = 0
    n = len(data)
    while i < n:
        if data[i] != 0xEB or i + 3 > n or data[i + 1] not in out:
            return out[0x90], out[0x91], out[0x92], f"no record starts at byte {i}"
        t = data[i + 1]
        end = i + (FRAME_LEN if t == 0x90 else 3 + data[i + 2] + 4)
        if end > n:
            return out[0x90], out[0x91], out[0x92], f"record at byte {i} is cut short"
        out[t].append(bytes(data[i:end]))
        i = end
    return out[0x90], out[0x91], out[0x92], None


def _flat(d):
    """A decoder's field dict with lists expanded to name[i]; floats shown with their bits."""
    items = []
    for name, v in d.items():
        if isinstance(v, (bytes, bytearray)):
            items.append((name, v.hex()))
        elif isinstance(v, list):
            items.extend((f"{name}[{i}]", _show(x)) for i, x in enumerate(v))
        else:
            items.append((name, _show(v)))
    return items


def _show(v):
    if isinstance(v, float):
        return f"{v!r} (0x{struct.unpack('<I', struct.pack('<f', v))[0]:08x})"
    return v


def _record_fields(kind, rec):
    if kind == "frame":
        return list(zip(_FRAME_NAMES, _FRAME_FMT.unpack(rec), strict=True))
    try:
        d = frames.ext_fields(rec) if kind == "extended frame" else frames.raw_fields(rec)
    except struct.error:  # a length the decoder does not know
        return [("bytes", rec.hex())]
    return _flat(d) + [("crc32", rec[-4:].hex())]


def _compare_kind(kind, fw, mo, every):
    r = KindResult(kind, len(fw), len(mo), min(len(fw), len(mo)))
    for i in range(r.compared):
        if fw[i] != mo[i]:
            r.first = i
            a = _record_fields(kind, fw[i])
            b = _record_fields(kind, mo[i])
            if [n for n, _ in a] != [n for n, _ in b]:
                r.fields = [FieldDiff("length", len(fw[i]), len(mo[i]))]
            else:
                r.fields = [
                    FieldDiff(n, x, y) for (n, x), (_, y) in zip(a, b, strict=True) if x != y
                ]
                r.fields = r.fields or [FieldDiff("bytes", fw[i].hex(), mo[i].hex())]
            break
    else:
        if len(fw) != len(mo):
            r.first = r.compared
            r.fields = [
                FieldDiff("present", r.compared < len(fw), r.compared < len(mo)),
            ]
    if r.first is not None and every:
        r.tick = (r.first + 1) * every - 1
    return r


def compare_streams(fw_out, model_out, output_every_ticks=1, ext_every_ticks=20, raw=False):
    """A ParityResult for two output streams of the same run (wall times left at 0)."""
    fw_f, fw_e, fw_r, fw_err = split(fw_out)
    mo_f, mo_e, mo_r, mo_err = split(model_out)
    first_byte = None
    if fw_out != model_out:
        n = min(len(fw_out), len(model_out))
        a = np.frombuffer(fw_out, np.uint8, n)
        b = np.frombuffer(model_out, np.uint8, n)
        d = np.flatnonzero(a != b)
        first_byte = int(d[0]) if len(d) else n
    err = "; ".join(f"{s}: {e}" for s, e in (("firmware", fw_err), ("model", mo_err)) if e)
    return ParityResult(
        identical=fw_out == model_out,
        bytes_firmware=len(fw_out),
        bytes_model=len(model_out),
        first_byte=first_byte,
        frame=_compare_kind("frame", fw_f, mo_f, output_every_ticks),
        ext=_compare_kind("extended frame", fw_e, mo_e, ext_every_ticks),
        raw=_compare_kind("raw record", fw_r, mo_r, 1 if raw else 0),
        stream_error=err or None,
        out_firmware=bytes(fw_out),
        out_model=bytes(model_out),
    )


def compare(stim, config_overrides=None, progress=None):
    """Run the firmware (run_cpython, in a temporary flash directory) and the model over
    `stim` with the same board configuration; a ParityResult. progress(k, n) is passed to
    each side in turn (firmware first). FirmwareError if the firmware raises."""
    with tempfile.TemporaryDirectory(prefix="parity-") as d:
        fw = emulator.run_cpython(stim, Path(d), config_overrides, progress)
    t = time.perf_counter()
    out = model_runner.run(stim, config_overrides, progress)
    wall_model = time.perf_counter() - t
    cfg = emulator.board_config(emulator.board_values(stim, config_overrides))
    r = compare_streams(
        fw.out, out, cfg.output_every_ticks, cfg.ext_every_ticks, bool(cfg.raw_record)
    )
    r.tick_us = stim.tick_us
    r.wall_firmware_s = fw.wall_s
    r.wall_model_s = wall_model
    r.firmware_stats = dict(fw.stats)
    return r


class _UsageError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage dump, status 2 (main)
        raise _UsageError(message)


def _duration(text):
    try:
        return float(text)
    except ValueError:
        raise _UsageError(f"--duration must be a number of seconds, got {text!r}") from None


def main(argv=None):
    """`parity --scenario NAME --duration S [--seed N]`: 0 identical, 1 different, 2 usage."""
    from host_emulator.eval import scenario_run
    from host_emulator.sim import board_input

    p = _Parser(
        prog="python -m host_emulator parity",
        description="firmware on the emulated board vs the NumPy float32 model, byte for byte",
    )
    p.add_argument("--scenario", required=True, help="simulated scenario (sim/trajectory.py)")
    p.add_argument("--duration", required=True, help="seconds of the scenario to run")
    p.add_argument("--seed", type=int, default=0, help="simulation seed (default 0)")
    try:
        args = p.parse_args(argv)
        duration = _duration(args.duration)
        scenario_run.check_scenario(args.scenario)  # the same input checks as `run`
        scenario_run.check_duration(duration)
        scenario_run.check_seed(args.seed)
    except (_UsageError, EmulatorError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    try:
        stim = board_input.simulate(args.scenario, duration_s=duration, seed=args.seed).stimulus
        print(
            f"parity: {args.scenario}, {stim.duration_s:g} s ({len(stim)} ticks), seed {args.seed}"
        )
        r = compare(stim)
    except FirmwareError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except EmulatorError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(r.summary())
    return 0 if r.identical else 1


if __name__ == "__main__":
    sys.exit(main())
