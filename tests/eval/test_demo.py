"""`make demo`'s summary (host_emulator/eval/demo.py): it says which GNSS errors the drive has,
and a design target the run misses is flagged, not printed as if it were met."""

from host_emulator.eval import demo


def _metrics(**kw):
    m = {
        "scenario": "urban_drive", "duration_s": 600.0, "seed": 0, "runtime": "mpy_unix",
        "horiz_rms_m": 1.71, "gnss_horiz_rms_m": 2.81, "vert_rms_m": 4.46, "vel_rms_m_s": 0.059,
        "roll_rms_deg": 0.06, "pitch_rms_deg": 0.14, "yaw_rms_deg": 0.17, "align_time_s": 76.4,
        "outages": [], "ticks": 120000, "wall_s": 10.0, "realtime_factor": 60.0, "frames": 1,
        "frame_errors": 0, "gc_blocks_per_tick_mean": 120.0, "gc_blocks_per_tick_max": 200,
    }  # fmt: skip
    m.update(kw)
    return m


def test_the_summary_names_the_gnss_errors_and_flags_a_missed_gc_target():
    """The design's rule is no allocation once navigating (the aligning ticks that screen a
    fix allocate): a run whose navigating ticks allocate nothing meets it however small its
    mean over all ticks; one navigating tick that allocates misses it."""
    by_state = {
        "aligning": {"ticks": 100, "min": 0, "mean": 0.5, "p99": 7.0, "max": 53},
        "navigating": {"ticks": 900, "min": 0, "mean": 0.0, "p99": 0.0, "max": 0},
    }
    text = demo.summary(
        _metrics(gc_blocks_per_tick_mean=0.0117, gc_blocks_per_tick_max=53,
                 gc_blocks_by_state=by_state), "out/demo")  # fmt: skip
    assert "half of their variance correlated over 60 s" in text
    assert "GC blocks per tick     mean 0.0117, max 53" in text
    assert "design: no allocation once navigating: met" in text and "NOT" not in text
    by_state["navigating"].update(mean=0.001, max=4)
    text = demo.summary(_metrics(gc_blocks_by_state=by_state), "out/demo")
    assert "design: no allocation once navigating: NOT met (max 4 blocks)" in text
