"""The run's plots (host_emulator/eval/report.py): error panels scaled to the errors, yaw
drawn unwrapped, no truth where there is none, a zoomed inset per outage."""

from types import SimpleNamespace

import numpy as np

from host_emulator.eval import evaluate, report, scenario_run


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


# Synthetic runs shaped like the real drive's (drive_0708): a start-up whose sigma is 100x
# the settled one, no attitude reference, a bias transient. The assertions read the figures
# the real plotting functions draw.

N = 1000  # 100 s at 10 Hz; the first 10 % is the start-up


def _synthetic(attitude_truth=True):
    """(tr, err, truth) of a 100 s run: errors ~0.05, sigma 100x larger in the start-up."""
    rng = np.random.default_rng(0)
    t = np.arange(N) * 0.1
    sigma = np.full((N, 15), 0.02)
    sigma[:100] *= 100.0  # the start-up: sigma 100x the settled one
    err_scale = np.where(np.arange(N) < 100, 1.0, 0.05)[:, None]  # start-up errors too
    da = rng.normal(size=(N, 3)) * np.radians(0.05)
    if not attitude_truth:
        da[:] = np.nan  # a real drive: the reference has no attitude
    err = evaluate.TrackErrors(
        t_s=t,
        dp=rng.normal(size=(N, 3)) * err_scale,
        dv=rng.normal(size=(N, 3)) * err_scale,
        da=da,
        sigma=sigma,
        in_outage=np.zeros(N, bool),
    )
    bg = np.full((N, 3), np.radians(100.0 / 3600.0))  # 100 deg/h, settled
    bg[:100] += np.radians(5000.0 / 3600.0) * rng.normal(size=(100, 3))  # the transient
    tr = evaluate.Track(
        t_s=t, state=np.full(N, 2), p_n=np.zeros((N, 3)), v_n=np.zeros((N, 3)),
        ypr=np.zeros((N, 3)), sigma=sigma.copy(), bg=bg, ba=np.full((N, 3), 0.05),
        health=np.zeros(N, int), causes=np.zeros(N, int), gnss_valid=np.ones(N, bool),
        align_time_s=0.0,
    )  # fmt: skip
    truth = SimpleNamespace(t_s=t, p_n=np.zeros((N, 3)), ypr=np.full((N, 3), np.nan))
    return tr, err, truth


def _legend(ax):
    return [x.get_text() for x in ax.get_legend().get_texts()]


def _drawn(ax):
    """The labels of the lines and bands drawn on ax (matplotlib's own are '_child...')."""
    arts = [*ax.lines, *ax.collections, *ax.patches]
    return {a.get_label() for a in arts if not a.get_label().startswith("_")}


def test_attitude_without_a_reference_draws_and_names_only_the_sigma():
    tr, err, truth = _synthetic(attitude_truth=False)
    plt = report.pyplot()
    fig = report.attitude_figure(plt, "t", tr, err, truth, tr.state == 2, (), 100.0)
    ax = fig.axes[0]
    assert not any("error" in label for label in _drawn(ax))
    assert set(_legend(ax)) <= _drawn(ax) and _legend(ax)  # the legend names drawn lines
    assert any("3-sigma" in label for label in _legend(ax))
    assert any("no attitude reference" in x.get_text() for x in ax.texts)
    plt.close(fig)


def test_attitude_with_a_reference_draws_its_errors():
    tr, err, truth = _synthetic(attitude_truth=True)
    plt = report.pyplot()
    fig = report.attitude_figure(plt, "t", tr, err, truth, tr.state == 2, (), 100.0)
    ax = fig.axes[0]
    assert {"yaw error", "pitch error", "roll error"} <= set(_legend(ax)) <= _drawn(ax)
    assert not any("no attitude reference" in x.get_text() for x in ax.texts)
    plt.close(fig)


def test_velocity_panel_is_scaled_to_the_settled_errors_and_clips_the_bands():
    """Sigma 100x the errors in the start-up: the panel is the settled errors' (~0.05 m/s,
    3-sigma 0.06), and no band runs off it."""
    tr, err, _ = _synthetic()
    plt = report.pyplot()
    fig = report.errors_figure(plt, "t", err, (), 100.0)
    ax = fig.axes[1]
    lo, hi = ax.get_ylim()
    assert 0.1 < hi < 0.4 and lo == -hi, (lo, hi)
    for band in ax.collections:  # the 3-sigma bands, clipped to the panel
        assert np.abs(band.get_paths()[0].vertices[:, 1]).max() <= hi, band.get_label()
    assert any("3-sigma" in b.get_label() for b in ax.collections)
    assert set(_legend(ax)) <= _drawn(ax)
    plt.close(fig)


def test_bias_panel_is_scaled_to_the_settled_part_and_marks_the_transient():
    """A gyro bias transient of +-5000 deg/h in the start-up, 100 deg/h after: the panel
    shows the settled 100 deg/h and its 3-sigma, and the transient is marked."""
    tr, _, _ = _synthetic()
    plt = report.pyplot()
    fig = report.biases_figure(plt, "t", tr, tr.state == 2, None, (), 100.0)
    ax = fig.axes[0]
    lo, hi = ax.get_ylim()
    settled_3s = 3 * 0.02 * 180 / np.pi * 3600  # the settled 3-sigma, deg/h
    assert lo > 100 - 2 * settled_3s and hi < 100 + 2 * settled_3s, (lo, hi)
    assert hi > 100 + settled_3s and lo < 100 - settled_3s  # the band is on the panel
    assert any("start-up" in label for label in _legend(ax))
    assert set(_legend(ax)) <= _drawn(ax)
    plt.close(fig)


def test_the_board_spec_is_explained_where_it_is_first_used():
    m = {
        "scenario": "s", "duration_s": 1.0, "seed": 0, "runtime": "cpython",
        "align_time_s": 1.0, "horiz_rms_m": 1.0, "gnss_horiz_rms_m": 2.0, "vert_rms_m": 1.0,
        "vel_rms_m_s": 0.1, "roll_rms_deg": 0.1, "pitch_rms_deg": 0.1, "yaw_rms_deg": 0.1,
        "outages": [{"start_s": 1.0, "length_s": 1.0, "horiz_err_end_m": 1.0}],
        "realtime_factor": 1.0, "ticks": 1, "wall_s": 1.0, "frames": 1, "frame_errors": 0,
    }  # fmt: skip
    text = report.markdown(m)
    first = text.index("board spec")
    assert "WMH601" in text[first : first + 200] and "docs/requirements.md" in text
    assert "WMH601 spec" not in text
