"""The CPI calibration (host_emulator/bench/cpi.py): the published NUCLEO-F401RE figures are stored
as published, one benchmark counts the same instructions twice on the emulated Cortex-M4F and
gives a plausible CPI against them, the committed docs/benchmarks/cpi.json keeps the documented
keys, and the command says what is wrong with its input without running anything."""

import json
import pathlib

import pytest

from common.errors import EmulatorError
from host_emulator.__main__ import main as cli_main
from host_emulator.bench import cpi
from host_emulator.runtimes.m4f import build as m4f_build

COMMITTED = pathlib.Path(__file__).resolve().parents[2] / "docs" / "benchmarks" / "cpi.json"


@pytest.fixture(scope="module")
def pub():
    return cpi.load_published()


def test_the_published_figures_are_stored_with_their_source(pub):
    src = pub["source"]
    assert (src["pull_request"], src["author"], src["date"]) == (18069, "yn386", "2025-09-14")
    assert src["title"] == "stm32: Change flash latency for NUCLEO-F401RE."
    assert src["url"] == "https://github.com/micropython/micropython/pull/18069"
    assert pub["params"] == {"N": 84, "M": 80}
    assert pub["cpu_hz"] == 84_000_000
    assert pub["runs"]["before"]["flash_latency"] == "FLASH_LATENCY_5"
    assert pub["runs"]["before"]["wait_states"] == 5
    assert pub["runs"]["after"]["flash_latency"] == "FLASH_LATENCY_2"
    assert pub["runs"]["after"]["wait_states"] == 2
    assert list(pub["benchmarks"]) == [
        "bm_chaos", "bm_fannkuch", "bm_fft", "bm_float", "bm_nqueens", "bm_pidigits",
        "bm_wordcount", "core_import_mpy_multi",
    ]  # fmt: skip
    b = pub["benchmarks"]
    assert (b["bm_chaos"]["us_before"], b["bm_chaos"]["us_after"]) == (267108.12, 218521.00)
    assert (b["bm_float"]["us_before"], b["bm_float"]["us_after"]) == (47944.88, 37841.00)
    assert b["bm_pidigits"]["us_after"] == 58055.50
    assert b["bm_pidigits"]["error_percent"] == 0.02
    assert b["bm_wordcount"]["diff_us"] == -48608.76
    assert b["core_import_mpy_multi"] == {"us_before": 148190.88, "us_after": 127123.25}


def test_the_transcribed_rows_agree_with_their_own_diff_columns(pub):
    checked = 0
    for name, b in pub["benchmarks"].items():
        if "diff_us" not in b:
            continue
        assert b["us_after"] - b["us_before"] == pytest.approx(b["diff_us"], abs=0.006), name
        pct = 100 * b["diff_us"] / b["us_before"]
        assert pct == pytest.approx(b["diff_percent"], abs=0.0006), name
        checked += 1
    assert checked == 7


def test_a_row_is_cycles_over_instructions_and_interpolates_to_3_wait_states(pub, monkeypatch):
    monkeypatch.setattr(cpi, "expected_result", lambda name, n, m: "ok")
    run = {"instructions": 2_000_000, "norm": 150, "result": "ok", "gc_collect_instructions": None}
    probed = dict(run, gc_collect_instructions=116_000)
    row = cpi._row("bm_float", pub, run, dict(run, instructions=2_000_040), probed)
    assert row["cycles_before"] == pytest.approx(47944.88 * 84)
    assert row["cpi_before"] == round(47944.88 * 84 / 2_000_000, 4)
    assert row["cpi_after"] == round(37841.00 * 84 / 2_000_000, 4)
    third = row["cpi_after"] + (row["cpi_before"] - row["cpi_after"]) / 3
    assert row["cpi_f411"] == pytest.approx(third, abs=1e-4)
    assert row["instructions_runs"] == [2_000_000, 2_000_040]
    assert row["gc_collect_instructions"] == 116_000
    with pytest.raises(EmulatorError, match="two runs disagree"):
        cpi._row("bm_float", pub, run, dict(run, instructions=2_000_080), probed)
    with pytest.raises(EmulatorError, match="not the truth"):
        cpi._row("bm_float", pub, dict(run, result="bad"), dict(run, result="bad"), probed)


def test_every_perf_bench_benchmark_is_measured_or_skipped_with_a_reason(pub):
    skipped = cpi.skipped(pub)
    names = {p.stem for p in cpi.perf_bench_dir().glob("*.py")} - {"benchrun"}
    assert names == set(skipped) | set(pub["benchmarks"])
    assert "M >= 100" in skipped["bm_hexiom"]
    assert "native code" in skipped["viper_call0"]
    assert "retrieved" in skipped["misc_pystone"]


def test_the_f401_heap_build_is_a_build_of_its_own():
    assert m4f_build.build_dir() == m4f_build.BUILD_DIR
    assert m4f_build.build_dir(m4f_build.GC_HEAP_BYTES) == m4f_build.BUILD_DIR
    assert m4f_build.build_dir(cpi.F401_GC_HEAP_BYTES).name == "m4f-heap61900"
    with pytest.raises(EmulatorError, match="GC heap of 1002 bytes"):
        m4f_build.build(progress=None, gc_heap_bytes=1002)


def test_bm_float_counts_the_same_twice_and_gives_a_plausible_cpi(pub):
    """bm_float collects no garbage inside run(), so the default build (113 KB heap) counts
    what the F401-sized one does; two fresh boards count the same instructions."""
    n, m = pub["params"]["N"], pub["params"]["M"]
    first = cpi.count("bm_float", n, m, gc_heap_bytes=None)
    second = cpi.count("bm_float", n, m, gc_heap_bytes=None)
    assert abs(first["instructions"] - second["instructions"]) <= cpi.RESOLUTION
    assert first["instructions"] % cpi.RESOLUTION == 0
    assert first["norm"] == 150  # bm_params (50, 25): 1 x 150 points
    assert first["result"] == cpi.expected_result("bm_float", n, m)
    b = pub["benchmarks"]["bm_float"]
    cpi_after = b["us_after"] * 84 / first["instructions"]
    cpi_before = b["us_before"] * 84 / first["instructions"]
    assert 1.0 < cpi_after < cpi_before < 4.0


def test_a_benchmark_that_collects_garbage_counts_the_same_twice(pub):
    """bm_chaos collects garbage inside run(): with QEMU's SysTick left running (cpi.SHIM stops
    it) two runs differed by up to a few thousand instructions."""
    n, m = pub["params"]["N"], pub["params"]["M"]
    counts = [cpi.count("bm_chaos", n, m, gc_heap_bytes=None)["instructions"] for _ in range(2)]
    assert abs(counts[0] - counts[1]) <= cpi.RESOLUTION, counts


def test_the_committed_calibration_keeps_its_documented_keys(pub):
    result = json.loads(COMMITTED.read_text())
    assert tuple(result) == cpi.KEYS
    assert tuple(result["summary"]) == cpi.SUMMARY_KEYS
    assert [r["name"] for r in result["rows"]] == list(pub["benchmarks"])
    for r in result["rows"]:
        assert tuple(r) == cpi.ROW_KEYS
        assert r["us_after"] == pub["benchmarks"][r["name"]]["us_after"]
        assert r["cpi_after"] == pytest.approx(r["cycles_after"] / r["instructions"], abs=1e-4)
        assert abs(r["instructions_runs"][0] - r["instructions_runs"][1]) <= cpi.RESOLUTION
        assert r["result"] == r["expected_result"]
    s = result["summary"]
    assert s["cpi_low"] <= s["after"]["median"] < s["cpi_central"] < s["before"]["median"]
    assert s["cpi_central"] == s["f411"]["median"] <= s["cpi_high"]
    assert result["gc_heap_bytes"] == cpi.F401_GC_HEAP_BYTES
    text = cpi.report(result)
    assert "pull request #18069" in text and "| bm_chaos |" in text


def _no_board(*args, **kwargs):
    raise AssertionError("the command ran the emulated board for bad input")


@pytest.mark.parametrize(
    "args, says",
    [
        (["--bogus"], "unrecognized arguments: --bogus"),
        (["--published", "{missing}"], "cannot read the published figures"),
        (["--published", "{not_json}"], "is not JSON"),
        (["--published", "{zero_time}"], "bm_chaos: us_after must be positive"),
        (["--published", "{no_params}"], "missing 'params'"),
        # a failure, not a command line: status 1
        (["--published", "{unknown}", "--no-write"], "bm_nosuch.py is not in"),
        (["--out", "{a_file}"], "is a file, not a directory"),
    ],
)  # fmt: skip
def test_the_command_reports_bad_input_in_one_line(args, says, tmp_path, monkeypatch, capsys, pub):
    monkeypatch.setattr(cpi.guest, "run", _no_board)
    monkeypatch.setattr(cpi.m4f_build, "build", _no_board)
    files = {
        "missing": tmp_path / "missing.json",
        "not_json": tmp_path / "not.json",
        "zero_time": tmp_path / "zero.json",
        "no_params": tmp_path / "no_params.json",
        "unknown": tmp_path / "unknown.json",
        "a_file": tmp_path / "a_file",
    }
    files["not_json"].write_text("{ not json")
    zero = json.loads(json.dumps(pub))
    zero["benchmarks"]["bm_chaos"]["us_after"] = 0
    files["zero_time"].write_text(json.dumps(zero))
    files["no_params"].write_text(json.dumps({k: v for k, v in pub.items() if k != "params"}))
    unknown = json.loads(json.dumps(pub))
    unknown["benchmarks"] = {"bm_nosuch": {"us_before": 2.0, "us_after": 1.0}}
    files["unknown"].write_text(json.dumps(unknown))
    files["a_file"].write_text("")
    argv = ["cpi"] + [a.format(**files) for a in args]
    assert cli_main(argv) == (1 if "{unknown}" in args else 2)
    err = capsys.readouterr().err
    assert err.startswith("error: ") and says in err
    assert "Traceback" not in err
