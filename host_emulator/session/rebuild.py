"""The emulator's input rebuilt from a recording: tick k's BMI055 registers and GNSS bytes as
the board read them (its raw-input records), PPS edges where the recorded pps_us changes, at
pps_before_us = ticks_diff(t0_us, pps_us) before the tick (MicroPython's ticks_us wraps at
2**30). The BMI055 temperature register is not recorded and not read by the loop: it is 0.
"""

import numpy as np

from common.proto import stimulus as stim_mod
from common.proto.frame import FRAME_TYPE
from common.proto.stream import Decoded
from common.proto.ticks import TICKS_PERIOD, ticks_diff
from host_emulator.session.walk import TICK_US, Recording, from_decoded, parse, rates


def pps_edges(rec):
    """(pps_before_us per tick (-1: none), notes): where the emulator fires each PPS edge.

    An edge shows as a change of the recorded pps_us (the parser's, 0 at start-up) from one
    tick to the next; it came pps_before_us = ticks_diff(t0_us, pps_us) before the tick.
    On a board an edge can also come while a tick runs (pps_before_us < 0): it then goes to
    that tick if the tick's frame already shows its PPS flag, else to the next tick."""
    n = len(rec)
    before = np.full(n, -1, np.int32)
    notes = []
    every, _ = rates(rec.config)
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
    proto/stream.decode result. The header carries the configuration values and the notes."""
    src = decoded_or_bytes
    if isinstance(src, Recording):
        rec = src
    elif isinstance(src, Decoded):
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
