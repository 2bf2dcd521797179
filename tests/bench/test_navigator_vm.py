"""The navigator on the real MicroPython VM: it runs, agrees with the float32 desktop run,
and spreads its work so that no tick is much heavier than the average (docs/requirements.md, time
budget).

GC blocks are counted exactly by the VM (one per boxed float operation, as on the board), so
these are allocation bounds, not timings."""

import numpy as np
import pytest

from host_emulator.bench import navigator as nav_runner
from host_emulator.bench import navigator_vm as nav_vm
from host_emulator.runtimes import mpy_unix
from host_emulator.sim import gnss as sim_gnss
from host_emulator.sim import imu as sim_imu
from host_emulator.sim import trajectory


@pytest.fixture(scope="module")
def vm_run():
    truth = trajectory.SCENARIOS["urban_drive"](duration_s=96, seed=1)
    imu = sim_imu.simulate(truth, seed=1)
    gnss = sim_gnss.simulate(truth, seed=1)
    out = nav_vm.run(imu, gnss, 95)
    desk = nav_runner.run(truth, imu, gnss, duration_s=95, decimate=1)
    return truth, out, desk


def test_navigates_on_micropython_like_on_the_desktop(vm_run):
    truth, out, desk = vm_run
    assert np.sum(out["state"] == 2) > 20 * 200  # over 20 s of navigation
    assert out["updates"] == desk.gnss_updates > 15
    # Same code, double arithmetic in the VM: the two differ by float32 rounding amplified by
    # the filter over 30 s of navigation (measured: 0.2 mm).
    assert np.allclose(out["p_n"], desk.extra["p_n_final"], atol=0.01)


def test_no_tick_is_much_heavier_than_the_average(vm_run):
    _, out, _ = vm_run
    stats = mpy_unix.block_stats(out["blocks"], out["state"])["navigating"]
    # With the native kernels the INS and the filter slices allocate nothing (the Python ones
    # box ~320 floats per tick); the heaviest ticks are the fixes, whose delivery and
    # screening are still Python float work (measured: mean 0.28 blocks, max 494).
    assert stats["mean"] < 5
    assert stats["max"] < 1000
