"""Parity: the firmware on a bit-exact runtime (cpython, default; m4f, the emulated
Cortex-M4F with the board's float32 arithmetic) against the NumPy float32 model (the model
runtime), byte for byte over the whole output stream.

    python -m host_emulator parity --scenario highway_outage --duration 45 [--seed 0]
        [--runtime cpython|m4f]

Exit status 0 when both streams are identical, 1 when they differ (the summary names the first
differing frame, its tick and its fields with both values) or the firmware raised, 2 for a
bad command line (unknown scenario, bad duration).

Records are compared per kind in order (eval/compare.py): the 52-byte frames (fields as
integers at the frame's scale), the extended frames 0x91 and the raw-input records 0x92
(fields decoded; floats with their float32 bits). Tick k is stimulus record k, at
t = k * tick_us after the first tick. With the display setting on, what the firmware sent to
the screen's UART is compared too, byte for byte (model/display.py).
"""

import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from common.errors import EmulatorError
from common.proto import config as board_config
from common.proto import records, stream
from host_emulator import args as cli_args
from host_emulator import runtimes
from host_emulator.eval.compare import EXT, FRAME, RAW, KindResult, compare_kind

LABELS = ("firmware", "model")


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
    firmware_stats: dict = field(default_factory=dict)  # the firmware runtime's counters
    runtime: str = "cpython"  # where the firmware ran
    run_time_zeroed: bool = False  # extended frames compared with their run-time counters 0
    clock_zeroed: bool = False  # raw-input records compared with their board times 0
    out_firmware: bytes = field(default=b"", repr=False)  # the two streams compared
    out_model: bytes = field(default=b"", repr=False)
    # the screen's UART (the display setting on): both byte streams, None where they agree
    display_firmware: bytes = field(default=b"", repr=False)
    display_model: bytes = field(default=b"", repr=False)
    display_first_byte: int | None = None

    def summary(self):
        lines = [
            f"firmware ({self.runtime}) {self.wall_firmware_s:.2f} s wall, "
            f"model (NumPy float32) {self.wall_model_s:.2f} s wall"
        ]
        if self.stream_error:
            lines.append("stream: " + self.stream_error)
        for k in (self.frame, self.ext, self.raw):
            if k.counts != (0, 0):
                lines.append(k.line(self.tick_us))
        if self.run_time_zeroed:
            lines.append(
                "(the extended frames' run-time counters, "
                f"{', '.join(records.EXT_TIMING_FIELDS)}, are the board's own: 0 in both "
                f"streams before comparing; the firmware collected garbage "
                f"{self.firmware_stats.get('app_gc_runs', '?')} times)"
            )
        if self.clock_zeroed and self.raw.counts != (0, 0):
            lines.append(
                "(the raw-input records' times, t0_us and pps_us, are the board's clock since its "
                "reset: 0 in both streams before comparing)"
            )
        if self.display_firmware or self.display_model:
            lines.append(self.display_line())
        if self.identical:
            lines.append(f"PARITY: identical, {self.bytes_firmware} bytes")
        else:
            lines.append(
                f"PARITY: DIFFERENT (firmware {self.bytes_firmware} bytes, model "
                f"{self.bytes_model} bytes, first differing byte {self.first_byte})"
            )
        return "\n".join(lines)

    def display_line(self):
        a, b = self.display_firmware, self.display_model
        if self.display_first_byte is None:
            return f"display: identical, {len(a)} bytes to the screen"
        i = self.display_first_byte
        return (
            f"display: DIFFERENT at byte {i} of {len(a)} (model {len(b)}): firmware "
            f"{a[max(i - 20, 0) : i + 40]!r}, model {b[max(i - 20, 0) : i + 40]!r}"
        )


def first_difference(a, b):
    """The first offset where byte strings a and b differ (the shorter's length if one is the
    other's start), None if equal."""
    if a == b:
        return None
    n = min(len(a), len(b))
    d = np.flatnonzero(np.frombuffer(a, np.uint8, n) != np.frombuffer(b, np.uint8, n))
    return int(d[0]) if len(d) else n


def compare_streams(fw_out, model_out, output_every_ticks=1, ext_every_ticks=20, raw=False):
    """A ParityResult for two output streams of the same run (wall times left at 0)."""
    fw_f, fw_e, fw_r, fw_err = stream.split(fw_out)
    mo_f, mo_e, mo_r, mo_err = stream.split(model_out)
    first_byte = first_difference(fw_out, model_out)
    err = "; ".join(f"{s}: {e}" for s, e in zip(LABELS, (fw_err, mo_err), strict=True) if e)
    return ParityResult(
        identical=fw_out == model_out,
        bytes_firmware=len(fw_out),
        bytes_model=len(model_out),
        first_byte=first_byte,
        frame=compare_kind(FRAME, fw_f, mo_f, LABELS, output_every_ticks),
        ext=compare_kind(EXT, fw_e, mo_e, LABELS, ext_every_ticks),
        raw=compare_kind(RAW, fw_r, mo_r, LABELS, 1 if raw else 0),
        stream_error=err or None,
        out_firmware=bytes(fw_out),
        out_model=bytes(model_out),
    )


def bit_exact_runtimes():
    """The runtimes whose firmware output can equal the model's byte for byte."""
    return tuple(n for n, r in runtimes.RUNTIMES.items() if r.bit_exact and n != "model")


def compare(stim, config_overrides=None, progress=None, runtime="cpython", kernels=None,
            board=None, model_progress=None):  # fmt: skip
    """Run the firmware (on `runtime` with `kernels`, "native" or "python", None: the default,
    native; in a temporary flash directory) and the model over `stim` with the same board
    configuration; a ParityResult. progress(k, n) is passed to each side in turn (firmware
    first), model_progress, when given, to the model instead. FirmwareError if the firmware
    raises."""
    if runtime not in bit_exact_runtimes():
        raise EmulatorError(
            f"parity needs a bit-exact runtime ({', '.join(bit_exact_runtimes())}), not "
            f"{runtime!r}: the unix VM computes in double"
        )
    with tempfile.TemporaryDirectory(prefix="parity-") as d:
        fw = runtimes.get(runtime).run(stim, Path(d), config_overrides, progress, kernels,
                                       board)  # fmt: skip
        # the model told the image's board: whether it wires a screen (the runtimes' own check
        # refuses --board for the model on the command line)
        from host_emulator.runtimes import model as model_runtime

        model = model_runtime.run(stim, Path(d), config_overrides, model_progress or progress,
                                  board=board)  # fmt: skip
    cfg = board_config.from_values(board_config.run_values(stim, config_overrides))
    zeroed = runtimes.get(runtime).own_run_time
    fw_out, model_out = fw.out, model.out
    if zeroed:
        fw_out, model_out = stream.without_run_time(fw_out), stream.without_run_time(model_out)
    clock = runtimes.get(runtime).own_clock
    if clock:
        fw_out = stream.without_board_clock(fw_out)
        model_out = stream.without_board_clock(model_out)
    r = compare_streams(
        fw_out, model_out, cfg.output_every_ticks, cfg.ext_every_ticks, bool(cfg.raw_record)
    )
    r.run_time_zeroed = zeroed
    r.clock_zeroed = clock
    r.tick_us = stim.tick_us
    r.wall_firmware_s = fw.wall_s
    r.wall_model_s = model.wall_s
    r.firmware_stats = dict(fw.stats)
    r.runtime = runtime
    r.firmware_run = fw
    r.display_firmware, r.display_model = fw.display, model.display
    r.display_first_byte = first_difference(fw.display, model.display)
    r.identical = r.identical and r.display_first_byte is None
    return r


def main(argv=None):
    """`parity --scenario NAME --duration S [--seed N]`: 0 identical, 1 different, 2 usage."""
    from host_emulator.eval.scenario_run import firmware_bar
    from host_emulator.sim import board_input

    p = cli_args.Parser(
        prog="python -m host_emulator parity",
        description="firmware on the emulated board vs the NumPy float32 model, byte for byte",
    )
    p.add_argument("--scenario", required=True, help="simulated scenario (sim/trajectory.py)")
    p.add_argument("--duration", required=True, help="seconds of the scenario to run")
    p.add_argument("--seed", type=int, default=0, help="simulation seed (default 0)")
    p.add_argument(
        "--runtime",
        default="cpython",
        choices=bit_exact_runtimes(),
        help="where the firmware runs (default cpython; m4f: the emulated Cortex-M4F, f411: the "
        "image on the emulated STM32F411; both about real time)",
    )
    cli_args.add_kernels_option(p)
    cli_args.add_board_option(p)
    try:
        args = p.parse_args(argv)
        cli_args.check_board(args.runtime, args.board)
        duration = cli_args.number(args.duration, "--duration")
        cli_args.check_scenario(args.scenario)  # the same input checks as `run`
        cli_args.check_duration(duration)
        cli_args.check_seed(args.seed)
    except (cli_args.UsageError, EmulatorError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2

    def command():
        stim = board_input.simulate(args.scenario, duration_s=duration, seed=args.seed).stimulus
        print(
            f"parity: {args.scenario}, {stim.duration_s:g} s ({len(stim)} ticks), seed "
            f"{args.seed}, {args.runtime}, {args.kernels} kernels"
        )
        r = compare(stim, runtime=args.runtime, kernels=args.kernels, board=args.board,
                    progress=firmware_bar(args.runtime, stim.duration_s),
                    model_progress=firmware_bar("model", stim.duration_s))  # fmt: skip
        print(r.summary())
        return 0 if r.identical else 1

    return cli_args.run_reporting(command)
