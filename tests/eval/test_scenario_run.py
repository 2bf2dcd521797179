"""host_emulator/eval/scenario_run.py: the figures of what the firmware said of itself."""

from types import SimpleNamespace

import numpy as np

from host_emulator.eval import evaluate, scenario_run

RESET = 0x100  # reset_to_gnss (common/proto/records.py CAUSES)


def test_health_figures_count_navigating_frames_and_each_reset_once():
    nav, aligning = evaluate.NAVIGATING, 1
    tr = SimpleNamespace(
        state=np.array([aligning, aligning, nav, nav, nav, nav, nav, nav, nav, nav]),
        health=np.array([2, 2, 0, 2, 2, 1, 0, 2, 0, 0]),
        # a reset held over two frames counts once; one after a frame without it again
        causes=np.array([RESET, RESET, 0, RESET, RESET | 0x400, 0x20, 0, RESET, 0, 0]),
    )
    got = scenario_run.health_figures(tr)
    assert got == {"health2_share": 3 / 8, "gnss_resets": 2}


def test_health_figures_of_a_run_that_never_navigates():
    tr = SimpleNamespace(state=np.array([1, 1]), health=np.array([2, 2]), causes=np.array([0, 0]))
    assert scenario_run.health_figures(tr) == {"health2_share": None, "gnss_resets": 0}
