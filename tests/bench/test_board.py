"""host_emulator/bench/board.py: which runs bench-board makes (the reports' figures are
tests/bench/test_figures.py's)."""

from host_emulator.bench import board as bench_board


def test_the_walk_runs_over_its_own_scenario_and_the_rest_over_the_benchs():
    own = {"urban_drive": 600.0, "walk_real": 300.0}
    runs = bench_board.tasks("urban_drive", None, own.get)
    assert len(runs) == len(bench_board.VARIANTS) + len(bench_board.TWIN_VARIANTS)
    by_label = {(r[0], r[1]): r[4:] for r in runs}
    assert by_label[("m4f", "default (coning off, 1 slice per tick)")] == ("urban_drive", 600.0)
    assert by_label[("m4f", "default, a hand-held walk (walk_real)")] == ("walk_real", 300.0)
    assert by_label[("f411", "image, a hand-held walk (walk_real)")] == ("walk_real", 300.0)
    assert [r[0] for r in runs[: len(bench_board.TWIN_VARIANTS)]] == ["f411"] * 5
    # --duration applies to every run
    assert {r[5] for r in bench_board.tasks("urban_drive", 20.0, own.get)} == {20.0}


def test_the_report_names_the_other_scenario_and_its_duration():
    runs = [{"scenario": "urban_drive", "duration_s": 600.0},
            {"scenario": "walk_real", "duration_s": 300.0}]  # fmt: skip
    assert bench_board._other_scenarios(runs, "urban_drive") == (
        "; the rows that name walk_real over it (300 s, seed 0)"
    )
    assert bench_board._other_scenarios(runs[:1], "urban_drive") == ""
