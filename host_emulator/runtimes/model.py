"""The NumPy float32 model as a runtime: the output stream model/app.py computes for a
stimulus, as the board would send it, in a FirmwareRun (no console, no counters: the model has
no board around it). Bit for bit the cpython runtime's output (tests/eval/test_parity.py)."""

import os
import time

from common.proto import stimulus as stim_mod
from host_emulator.runtimes import FirmwareRun


def run(stim, workdir=None, config_overrides=None, progress=None, board=None):
    """FirmwareRun of the model over `stim`, a Stimulus or a stimulus file (workdir is not
    used: the model has no flash). board: the image's board whose wiring decides whether the
    screen has a UART (parity against the f411 runtime; None: the firmware's default)."""
    from host_emulator.model import app

    if isinstance(stim, (str, os.PathLike)):
        stim = stim_mod.read(stim)
    t = time.perf_counter()
    out, (shown, marks) = app.run_all(stim, config_overrides, progress, board=board)
    return FirmwareRun("model", out, [], len(stim), time.perf_counter() - t, display=shown,
                       display_marks=marks)  # fmt: skip
