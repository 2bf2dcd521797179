"""The run's plots (host_emulator/eval/report.py): error panels scaled to the errors, yaw
drawn unwrapped, no truth where there is none, a zoomed inset per outage."""

import numpy as np

from host_emulator.eval import report, scenario_run


def test_error_panels_are_scaled_to_the_errors_not_the_start_sigma():
    e = np.full((1000, 3), 0.1)
    s = np.full((1000, 3), 0.05)
    s[:50] = 10.0  # the start's heading sigma
    lim = report.error_limit(e, s)
    assert 0.15 < lim < 0.3, lim


def test_yaw_is_unwrapped_and_follows_the_truth():
    t = np.linspace(0.0, 100.0, 1001)
    truth = (np.radians(170.0) + np.radians(1.0) * t + np.pi) % (2 * np.pi) - np.pi
    fw = (truth + np.radians(0.5) + np.pi) % (2 * np.pi) - np.pi  # wraps where truth does
    tu, fu = report.yaw_for_plot(t, truth, t, fw)
    assert np.all(np.abs(np.diff(tu)) < np.radians(2)) and np.all(np.abs(np.diff(fu)) < 0.1)
    assert np.allclose(fu - tu, np.radians(0.5))
    tu, fu = report.yaw_for_plot(t, np.full_like(t, np.nan), t, fw)
    assert tu is None and np.all(np.abs(np.diff(fu)) < 0.1)


def test_the_plots_of_a_run(tmp_path, monkeypatch):
    """A highway_outage run: its outage gets an inset, the attitude panel's scale is the
    errors' (the start's +-10 deg heading sigma runs off), the truth yaw is drawn."""
    drawn = {}
    real = report.plots

    def plots(*a, **kw):
        drawn.update(real(*a, **kw))
        return drawn

    monkeypatch.setattr(report, "plots", plots)
    scenario_run.run("highway_outage", 200.0, 0, "cpython", tmp_path, show_progress=False,
                     log=lambda *a: None)  # fmt: skip
    assert all((tmp_path / p).stat().st_size > 10_000 for p in report.PLOTS)
    assert drawn["insets"] == 1 and drawn["truth_yaw"]
    lo, hi = drawn["attitude_ylim"]
    assert hi < 5.0, (lo, hi)  # degrees: the errors' scale, not the heading sigma's 30
