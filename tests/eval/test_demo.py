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
    text = demo.summary(_metrics(), "out/demo")
    assert "half of their variance correlated over 60 s" in text
    assert "(design: mean <= 300, max <= 2x mean: met)" in text
    text = demo.summary(_metrics(gc_blocks_per_tick_max=900), "out/demo")
    assert "max 900 (design: mean <= 300, max <= 2x mean: NOT met (max))" in text
    text = demo.summary(_metrics(gc_blocks_per_tick_mean=400.0), "out/demo")
    assert "NOT met (mean)" in text
