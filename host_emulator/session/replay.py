"""Replaying a session: read the file, walk the stream, rebuild the input, run it on a runtime,
compare the outputs (a ReplayResult)."""

import os
from dataclasses import dataclass
from pathlib import Path

from common.proto import config as board_config
from common.proto.session_file import SessionError, load
from host_emulator import runtimes
from host_emulator.replay import carrier
from host_emulator.session.compare import Comparison, compare
from host_emulator.session.rebuild import to_stimulus
from host_emulator.session.walk import TICK_US, Recording, board_cfg, parse


@dataclass(eq=False)
class ReplayResult:
    recording: Recording
    stimulus: object  # proto/stimulus.Stimulus
    run: object  # runtimes.FirmwareRun
    comparison: Comparison
    config_source: str
    file_problems: list  # what a cut or damaged session file lost (session_file.Session)
    runtime_note: str | None = None  # why the runtime was picked (pick_runtime)
    profile_note: str | None = None  # a car profile on a walker's data (carrier.py)

    @property
    def identical(self):
        return self.comparison.identical

    def summary(self):
        rec = self.recording
        n = len(rec)
        lines = ["warning: " + p for p in self.file_problems]
        lines.append(
            f"session: {n} ticks ({n * TICK_US * 1e-6:.3f} s) from byte {rec.start_offset}, "
            f"configuration from {self.config_source}"
        )
        if rec.gap:
            lines.append(f"replayed up to the first gap: {rec.gap}")
        for note in self.stimulus.header.get("notes", []):
            lines.append("note: " + note)
        if self.runtime_note:
            lines.append("note: " + self.runtime_note)
        if self.profile_note:
            lines.append("warning: " + self.profile_note)
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
            try:
                return board_config.load(config), str(config)
            except board_config.ConfigError as e:
                raise SessionError(str(e)) from None
        return dict(config), "the given values"
    if header.get("config"):
        return dict(header["config"]), "the session file"
    raise SessionError(
        f"{path}: the session holds no board configuration: give the board's configuration "
        "file with --config (its ranges, lever arm, output rates, ... shape the output)"
    )


def replay(session_path, workdir, runtime="auto", config=None, until_gap=False, progress=None,
           from_last_start=False, board=None, display=False):  # fmt: skip
    """Replay a session file through the emulator and compare; a ReplayResult.

    config: the board configuration (a path, see proto/config.load, or a dict of values) when
    the session holds none or holds the wrong one. until_gap: replay the ticks before the
    first gap instead of failing. from_last_start: replay from the board's last start in the
    recording (after a restart), not its first. runtime: a name of host_emulator.runtimes;
    one that is not bit-exact (mpy_unix) is compared to its tolerance. FirmwareError if the
    firmware raises. board: the image the f411 runtime runs (None: its default). display: run
    the board's screen (the display setting on; it changes no output record: the emulated
    screen answers every batch) for pictures of it (ReplayResult.run.display)."""
    sf = load(session_path)
    header, data = sf.header, sf.data
    runtime, why = pick_runtime(header, runtime)
    rt = runtimes.get(runtime)
    values, source = _session_config(header, config, session_path)
    rec = parse(data, values, until_gap, from_last_start)
    stim = to_stimulus(rec, values)
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    run = rt.run(stim, workdir, {"display": 1} if display else None, progress, board=board)
    cfg = board_cfg(values)
    c = compare(rec.stream, run.out, cfg.output_every_ticks, cfg.ext_every_ticks, rt.bit_exact)
    return ReplayResult(rec, stim, run, c, source, sf.problems(str(session_path)), why,
                        _profile_note(stim, cfg))  # fmt: skip


def _profile_note(stim, cfg):
    """What to say when the board ran the car profile on a walker's data (the replay keeps
    the board's settings: it must send what the board sent)."""
    if cfg.profile != 0:
        return None
    gait = carrier.of_stimulus(stim)
    if not gait.walking:
        return None
    return (
        f"the board ran profile 0 (car), but its data show {gait.describe()}: "
        "a board carried by a person navigates with profile=1 (config set profile=1)"
    )


def pick_runtime(header, runtime="auto"):
    """(runtime name, why or None): "auto" picks the runtime whose arithmetic is the
    recording's board's: a board that computes in double (the virtual board: a MicroPython VM,
    which the monitor's --board-port records) replays on mpy_unix, the same VM; a board of
    float32 (the STM32F411), or one the session does not describe, on cpython, bit-exact."""
    if runtime != "auto":
        return runtime, None
    board = header.get("board") or {}
    if board.get("floats") == "double":
        return "mpy_unix", (
            f"the recording's board ({board.get('machine', '?')}) computes in double, as a "
            "MicroPython VM does: replayed on mpy_unix, the same VM (--runtime overrides)"
        )
    return "cpython", None
