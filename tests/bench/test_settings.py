"""The settings benchmark (host_emulator/bench/settings.py) in its quick form: the ends and the
default of two settings on the first 150 s of urban_drive and 100 s of walk, one seed. The
defaults must pass and the absurd ends a user met must fail with their figures; the machinery
around it (the values swept, the range table's rows, a right mounting, the frames every run
sends) is checked on its own. `make bench-settings` sweeps every setting over the whole
scenarios (docs/benchmarks/settings.md)."""

import json

import pytest

from host_emulator.bench import settings as bench
from host_emulator.bench import settings_report

SW = {s.name: s for s in bench.SWEEPS}


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("settings") / "settings.md"
    argv = ["--quick", "--only", "gate_sigma", "--only", "gnss_uere_m", "--jobs", "1"]
    assert bench.main([*argv, "--out", str(out)]) == 0
    data = json.loads(out.with_suffix(".json").read_text())
    return out.read_text(), data


def _verdict(data, name, value):
    return next(v for v in data["verdicts"][name] if v["value"] == value)


def _run(data, scenario, name, value):
    return next(r for r in data["runs"] if (r["scenario"], r["setting"], r["value"])
                == (scenario, name, value))  # fmt: skip


def test_the_defaults_pass(quick):
    _text, data = quick
    for name, default in (("gate_sigma", 5.0), ("gnss_uere_m", 2.0)):
        assert _verdict(data, name, default)["pass"], _verdict(data, name, default)
    base = _run(data, "urban_drive", None, None)
    assert base["horiz_rms_m"] < 3.0 and base["finite"] and base["align_time_s"] < 70.0, base


def test_a_gate_of_one_sigma_fails_with_its_figure(quick):
    """A user measured 28 m horizontal RMS with gate_sigma=1; the quick walk: 8.6 m (35.8 m
    before the yaw estimator reset the heading such a gate lets go wrong), the fixes' 3 m."""
    _text, data = quick
    v = _verdict(data, "gate_sigma", 1.0)
    assert not v["pass"] and any(w.startswith("horiz") for w in v["why"]["walk"]), v
    assert _run(data, "walk", "gate_sigma", 1.0)["horiz_rms_m"] > 5.0


def test_a_uere_at_its_lower_end_fails_with_its_figure(quick):
    """A user measured 98 m with gnss_uere_m=0.001; the quick runs: 5.2 m (urban_drive) and
    10.9 m (walk): the filter believes fixes far better than they are."""
    _text, data = quick
    v = _verdict(data, "gnss_uere_m", 0.001)
    assert not v["pass"], v
    for scenario in ("urban_drive", "walk"):
        assert _run(data, scenario, "gnss_uere_m", 0.001)["horiz_rms_m"] > 3.0
        assert any(w.startswith("horiz") for w in v["why"][scenario]), v


def test_the_report_says_the_criterion_the_range_and_the_refusals(quick):
    text, data = quick
    assert "| horizontal position RMS, m | 3 |" in text and "Benchmark wall time:" in text
    row = next(line for line in text.splitlines() if line.startswith("| gate_sigma |"))
    assert "| 1: " in row and "walk horiz" in row, row  # the first value below, and why
    lo, hi, den = data["ranges"]["gate_sigma"]["table_row"]
    assert lo / den == 5.0 and hi / den == 100.0  # the quick sweep: only the ends and 5
    # a value the firmware's table refuses now is still run (the table widened) and marked
    refused = settings_report._refused({"gate_sigma": 1.0})
    assert ("| 1 *refused* |" in text) == refused


def test_the_values_span_the_swept_range_and_the_defaults():
    g = bench.grid(SW["gate_sigma"], [5.0])
    assert g[0] == 1.0 and g[-1] == 100.0 and 5.0 in g and 3.0 in g
    assert bench.grid(SW["gate_sigma"], [5.0], quick=True) == [1.0, 5.0, 100.0]
    g = bench.grid(SW["gnss_uere_m"], [2.0])  # open at 0: from sw.first on
    assert g[0] == 0.001 and g[-1] == 100.0 and 0.3 in g
    g = bench.grid(SW["gyro_bias0"], [0.0])  # offsets both ways, exact decimals
    assert g == sorted(-x for x in g) and 0.003 in g and -0.35 in g
    assert bench.grid(SW["gyro_matrix"], [1.0])[:3] == [-2.0, 0.0, 0.7]


def test_a_value_between_a_pass_and_a_fail_and_the_passing_run():
    assert bench.between(SW["gate_sigma"], 5.0, 3.0, 1.0) == 2.0
    assert bench.between(SW["gyro_bias0"], 0.0, 0.003, 0.01) == 0.005
    assert bench.between(SW["gyro_bias0"], 0.0, 0.0, -0.003) == -0.001
    assert bench.interval([1, 2, 3, 4, 5], [False, True, True, False, True], 2) == (1, 2)
    assert bench.interval([1, 2, 3], [True, False, True], 1) is None


def test_the_range_table_rows():
    assert bench.table_row(SW["gate_sigma"], (4.0, 100.0)) == (4, 100, 1)
    # an end at a default's float32 is rounded outwards to two digits
    assert bench.table_row(SW["gyro_arw"], (0.0003, 0.00048869219)) == (30, 49, 100000)
    assert bench.table_row(SW["still_accel"], (0.004861, 1.0)) == (48, 10000, 10000)
    # a matrix: the largest scale that passes and the sensor's own scale error (1 %)
    assert bench.table_row(SW["gyro_matrix"], (0.97, 1.03)) == (-104, 104, 100)
    # a bias: the BMI055's offset widened by half the passing run
    assert bench.table_row(SW["gyro_bias0"], (-0.001, 0.005)) == (-205, 205, 10000)


def test_a_right_mounting_navigates_as_the_default_does():
    """mount_ypr_deg=30,30,30 with the simulated sensor turned so (the counts rotated through
    the firmware's own rot.euler_to_dcm): the figures of the sensor that is not turned."""
    a = bench.run(("urban_drive", 150.0, 0, "mount_ypr_deg", 0.0))
    b = bench.run(("urban_drive", 150.0, 0, "mount_ypr_deg", 30.0))
    assert "error" not in b, b
    for k in bench.SPEC:
        assert b[k] == pytest.approx(a[k], rel=0.02), (k, a[k], b[k])


def test_a_frame_with_each_extended_frame_alone_leaves_the_figures_as_they_are():
    """bench.FRAMES (output_every_ticks=20) changes what the board sends, not its navigation:
    the figures are those of a run that sends a frame every tick."""
    import pathlib
    import tempfile

    from host_emulator.eval import scenario_run

    sim = bench.simulation("walk", 100.0, 0)
    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(tmp) / "stimulus.bin"
        sim.stimulus.write(path)
        fw = scenario_run.run_firmware("cpython", path)
        every_tick, _tr, _err = scenario_run.evaluate_run(sim, fw, sim.stimulus, tmp, "cpython")
    r = bench.run(("walk", 100.0, 0, None, None))
    for k in (*bench.SPEC, "vert_rms_m"):
        assert r[k] == every_tick[k], k
    assert abs(r["align_time_s"] - every_tick["align_time_s"]) <= 0.1


@pytest.mark.parametrize(
    "argv, says",
    [(["--only", "no_such"], "not a swept setting"), (["--seeds", "0"], "at least 1"),
     (["--jobs", "0"], "--jobs")],
)  # fmt: skip
def test_a_command_line_that_cannot_run_is_one_line(argv, says, capsys):
    assert bench.main(argv) == 2
    err = capsys.readouterr().err
    assert says in err and err.count("\n") == 1, err
