"""The parity matrix: the firmware on each runtime with each kernel set against the NumPy float32
model, on the same short scenario (quick_start, navigating from ~13 s).

    runtime          native kernels                  Python kernels
    cpython          cffi: byte for byte             byte for byte
    m4f              armv7emsp: byte for byte        byte for byte
    mpy_unix (VM)    x64: frames byte for byte,      integer fields exact,
                     extended frames to float32      floats to one frame step
                     rounding

The VM is a double-precision build. Its kernels compute in float32, and with them every float
of a tick on this scenario is a kernel's (alignment, the origin's coefficients, the start of
navigation: native), so its frames are the model's bytes; the navigator's configuration is
still derived in double at start-up (e.g. the gyro scale, the noise densities), which moves
the floats of the extended frame by an ulp or so. With the Python kernels every float
operation is double, so those frames are compared field by field.
"""

import struct

import numpy as np
import pytest

from common.proto import stream
from host_emulator.eval import parity
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
def cpython_run(stim, tmp_path_factory):
    """The CPython run with the native kernels: the model's bytes (the test above)."""
    return cpython.run(stim, tmp_path_factory.mktemp("cpy"), kernels="native")


def test_the_vm_with_native_kernels_sends_the_models_frames(stim, cpython_run, tmp_path):
    vm = mpy_unix.run(stim, tmp_path, kernels="native")
    assert vm.stats["kernels"] == "native"
    dv, dc = stream.decode(vm.out), stream.decode(cpython_run.out)
    assert len(dv.frames) == len(dc.frames) == len(stim)
    assert [f["raw"] for f in dv.frames] == [f["raw"] for f in dc.frames]  # the model's bytes
    assert sum(f["nav_state"] == 2 for f in dc.frames) > 400
    assert len(dv.ext) == len(dc.ext) == len(stim) // 20
    # the filter's floats from a configuration derived in double (measured on this run:
    # p_diag 2e-6 relative, biases 5e-10 rad/s and 1e-6 m/s^2, position 1.2e-6 m apart)
    atol = {"p_diag": 0.0, "gyro_bias_rad_s": 1e-8, "accel_bias_m_s2": 1e-5, "pos_enu_m": 1e-5}
    for name, tol in atol.items():
        a = np.array([e[name] for e in dv.ext], np.float64)
        b = np.array([e[name] for e in dc.ext], np.float64)
        assert np.allclose(a, b, rtol=1e-5, atol=tol), name
    floats = set(atol)
    for ev, ec in zip(dv.ext, dc.ext, strict=True):  # the rest: integers, exact
        assert {k: v for k, v in ev.items() if k not in floats} == {
            k: v for k, v in ec.items() if k not in floats
        }


def test_the_vm_with_python_kernels_agrees_field_by_field(stim, cpython_run, tmp_path):
    vm = mpy_unix.run(stim, tmp_path, kernels="python")
    assert vm.stats["kernels"] == "python"
    fv = [f["raw"] for f in stream.decode(vm.out).frames]
    fc = [f["raw"] for f in stream.decode(cpython_run.out).frames]
    assert len(fv) == len(fc) == len(stim)
    # bytes 2..28: counter, raw IMU counts, flags, lat/lon/height, state: integer work only
    assert [f[2:29] for f in fv] == [f[2:29] for f in fc]
    assert sum(f[28] == 2 for f in fc) > 400
    fmt = "<3h3hiih"  # attitude, velocity, position: within a step of the frame's scale
    a = np.array([struct.unpack_from(fmt, f, 29) for f in fv])
    b = np.array([struct.unpack_from(fmt, f, 29) for f in fc])
    assert np.abs(a - b).max() <= 2 and np.mean(a == b) > 0.95
