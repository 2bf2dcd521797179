"""The parity matrix: the firmware on each runtime with each kernel set against the NumPy float32
model, on the same short scenario (quick_start, navigating from ~13 s).

    runtime          native kernels              Python kernels
    cpython          cffi: byte for byte         byte for byte
    m4f              armv7emsp: byte for byte    byte for byte
    mpy_unix (VM)    x64: integer fields exact,  the same
                     floats to one frame step

The VM is a double-precision build: its kernels compute in float32, but the Python glue around
them (alignment, the origin's coefficients, re-anchoring) computes in double, so its frames are
compared with the CPython run (the model's bytes) field by field, not byte for byte.
"""

import struct

import numpy as np
import pytest

from host_emulator.eval import parity
from host_emulator.proto import stream
from host_emulator.runtimes import cpython, mpy_unix
from host_emulator.sim import board_input

DURATION_S = 16.0  # navigating for the last ~3 s: alignment, fixes, the filter's updates


@pytest.fixture(scope="module")
def stim():
    return board_input.simulate("quick_start", DURATION_S, seed=0).stimulus


@pytest.mark.parametrize("runtime", ["cpython", "m4f"])
@pytest.mark.parametrize("kernels", ["native", "python"])
def test_frames_equal_the_model_byte_for_byte(stim, runtime, kernels):
    r = parity.compare(stim, runtime=runtime, kernels=kernels)
    assert r.firmware_stats["kernels"] == kernels
    assert r.identical, r.summary()
    assert r.frame.counts == (len(stim), len(stim)) and r.ext.counts[0] == len(stim) // 20
    d = stream.decode(r.firmware_run.out)
    assert sum(f["nav_state"] == 2 for f in d.frames) > 400  # not vacuous: it navigated


@pytest.fixture(scope="module")
def cpython_frames(stim, tmp_path_factory):
    return stream.decode(cpython.run(stim, tmp_path_factory.mktemp("cpy")).out).frames


@pytest.mark.parametrize("kernels", ["native", "python"])
def test_the_vm_agrees_field_by_field(stim, cpython_frames, kernels, tmp_path):
    vm = mpy_unix.run(stim, tmp_path, kernels=kernels)
    assert vm.stats["kernels"] == kernels
    fv = [f["raw"] for f in stream.decode(vm.out).frames]
    fc = [f["raw"] for f in cpython_frames]
    assert len(fv) == len(fc) == len(stim)
    # bytes 2..28: counter, raw IMU counts, flags, lat/lon/height, state: integer work only
    assert [f[2:29] for f in fv] == [f[2:29] for f in fc]
    assert sum(f[28] == 2 for f in fc) > 400
    fmt = "<3h3hiih"  # attitude, velocity, position: within a step of the frame's scale
    a = np.array([struct.unpack_from(fmt, f, 29) for f in fv])
    b = np.array([struct.unpack_from(fmt, f, 29) for f in fc])
    assert np.abs(a - b).max() <= 2 and np.mean(a == b) > 0.95
