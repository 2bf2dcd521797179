"""eval/board_cost.py: the cost figures of an m4f run, checked on per-tick records made up
so that every figure is known."""

import json

import numpy as np
import pytest

from host_emulator.eval import board_cost
from host_emulator.runtimes.m4f import PER_TICK


def _ticks():
    """100 aligning ticks of 300,000 (50,000 of them emulation), then 200 navigating ticks of
    600,000 (emulation 100,000), every 10th of which also collected (+400,000)."""
    t = np.zeros(300, PER_TICK)
    t["state"][:100] = 1
    t["instr"][:100] = 300_000
    t["emu_instr"][:100] = 50_000
    t["state"][100:] = 2
    t["instr"][100:] = 600_000
    t["emu_instr"][100:] = 100_000
    t["alloc_bytes"][100:] = 8_000
    gc = np.zeros(300, bool)
    gc[100::10] = True
    t["collected"][gc] = 1
    t["instr"][gc] += 400_000
    t["alloc_bytes"][gc] = -40_000
    return t


def test_the_figures_of_known_ticks(monkeypatch):
    monkeypatch.setattr(board_cost, "cpi_range", lambda: (1.5, 2.0, 2.5, "test"))
    s = board_cost.summary(_ticks(), tick_us=5000, clock_hz=100e6)
    al, nav = s["phases"]["aligning"], s["phases"]["navigating"]
    assert al["ticks"] == 100 and al["firmware_instr"]["mean"] == 250_000
    assert al["gc_collections"] == 0 and al["gc_collect_instr"] is None
    assert al["emulation_instr"]["mean"] == 50_000
    assert nav["ticks"] == 200 and nav["gc_collections"] == 20
    assert nav["ticks_per_collection"] == 10
    mixed = _ticks()
    mixed["instr"][100:150] = 130_000  # 30,000 of firmware: under both lines
    mixed["instr"][150:160] = 170_000  # 70,000: over the p99 line only
    over = board_cost.summary(mixed)["phases"]["navigating"]["ticks_over"]
    assert over == {"50000": 150, "100000": 140}
    assert nav["gc_collect_instr"] == pytest.approx(400_000)
    assert nav["firmware_instr"]["mean"] == pytest.approx(540_000)
    assert nav["firmware_instr_without_gc"]["max"] == 500_000
    assert nav["alloc_bytes_per_tick"]["mean"] == 8_000  # collecting ticks left out
    # 500,000 instructions x CPI 2 at 100 MHz = 10 ms: every tick overruns the 5 ms at any CPI
    assert nav["time_ms"]["2"]["mean"] == pytest.approx(540_000 * 2 / 100e6 * 1e3)
    assert nav["time_ms"]["1.5"]["overrun_share"] == 1.0
    # 250,000 x 1.5 = 3.75 ms fits; x 2.5 = 6.25 ms does not
    assert al["time_ms"]["1.5"]["overrun_share"] == 0.0
    assert al["time_ms"]["2.5"]["overrun_share"] == 1.0
    text = "\n".join(board_cost.lines(s))
    assert "navigating (200 ticks): 540,000 instructions per tick mean" in text
    assert "gc.collect every 10 ticks, ~400,000 instructions each" in text
    assert "CPI 2 (1.5-2.5)" in text


def test_the_board_benchmark_page_states_the_figures_and_the_budget(monkeypatch):
    from host_emulator.bench import board

    monkeypatch.setattr(board_cost, "cpi_range", lambda: (1.5, 2.0, 2.5, "test"))
    t = _ticks()
    result = {
        "label": "default",
        "wall_s": 12.0,
        "cost": board_cost.summary(t),
        "heap": {"free_at_start": 84_880, "live_after_start": 40_000, "system_bytes": 2_600,
                 "emulator_bytes": 6_700, "ballast_bytes": 48, "startup_instructions": 4_600_000,
                 "app_gc_runs": 20},
    }  # fmt: skip
    text = board.markdown([result], "urban_drive", 600.0, ["code region ..."], None, "cmd")
    assert "| default | navigating | 200 | 540,000 | 500,000 |" in text
    # overrunning ticks as counts: aligning (250,000 each) fits at CPI 1.5 and 2, not at 2.5
    assert (
        "| 0 / 0 / 100 (100 %) |" in text and "| 200 (100 %) / 200 (100 %) / 200 (100 %) |" in text
    )
    assert "20 (every 10 ticks) | 400,000 |" in text
    assert "mean 540,000 instructions (18.00x the budget), p99 900,000 (18.00x)" in text
    assert "200 ticks over 100,000, 200 over 50,000)" in text
    assert "200 ticks (100.000 %) overrunning at CPI 2.5" in text
    assert "The budget is not met (5 of 5 figures)." in text
    assert "Live after start-up: 30,652 bytes of the firmware's own" in text
    assert "code region ..." in text
    assert board.main(["--jobs", "0"]) == 2
    assert board.main(["--scenario", "nowhere"]) == 2


def test_the_page_sets_each_configuration_s_accuracy_beside_its_cost(tmp_path, monkeypatch):
    from host_emulator.bench import board

    monkeypatch.setattr(board_cost, "cpi_range", lambda: (1.5, 2.0, 2.5, "test"))

    def run(horiz, outs):
        return {"horiz_rms_m": horiz, "vel_rms_m_s": 0.05, "yaw_rms_deg": 0.2,
                "outages": [{"horiz_err_end_m": o} for o in outs]}  # fmt: skip

    runs = {
        "urban_drive/0/white/car": run(0.6, [0.5, 3.0]),
        "urban_drive/1/white/car": run(0.8, [0.7, 4.0]),
        "urban_drive/0/realistic/car": run(9.0, [9.0, 9.0]),  # another GNSS model: left out
        "highway_outage/0/white/car": run(9.0, [9.0]),  # another scenario: left out
    }
    nav_json = tmp_path / "navigation.json"
    nav_json.write_text(json.dumps({"runs": runs}))
    acc = board.accuracy(nav_json, "car")
    assert acc["seeds"] == 2 and acc["horiz_rms_m"] == pytest.approx(0.7)
    assert acc["outage_end_m"] == pytest.approx([0.6, 3.5])
    assert board.accuracy(nav_json, "handheld") is None
    assert board.accuracy(tmp_path / "missing.json", "car") is None
    result = {
        "label": "default (coning off, 1 slice per tick)",
        "cost": board_cost.summary(_ticks()),
    }
    # the walk, last, has no accuracy figures: its row is left out, not the section
    walk = {"label": "default, a hand-held walk (walk_real)", "cost": result["cost"]}
    text = "\n".join(board.accuracy_cost_lines([result, walk], nav_json))
    assert "walk_real" not in text
    assert (
        "| default (coning off, 1 slice per tick) | 0.70 | 0.050 | 0.20 | 0.60 / 3.50 | "
        "540,000 / 900,000 |" in text
    )
    assert "mean of 2 seeds" in text
    assert "`make bench-nav` writes them" in "\n".join(
        board.accuracy_cost_lines([result], tmp_path / "x")
    )


def _twin_ticks(busy_ms, states, late=()):
    from host_emulator.runtimes.f411 import PER_TICK

    t = np.zeros(len(busy_ms), PER_TICK)
    t["busy_cycles"] = (np.asarray(busy_ms) * 96_000).astype(np.int64)
    t["instr"] = 50_000
    t["handler_instr"] = 1_500
    t["late"][list(late)] = 1
    return t, np.asarray(states, np.uint8)


def test_the_images_time_per_tick_is_stated_against_its_targets():
    """eval/board_time.py and the page's section on the emulated STM32F411: busy time per
    phase, late ticks, and the targets (navigating p99 <= 2.0 ms, max <= 3.5 ms, none late or
    missed), met or not."""
    from host_emulator.bench import board
    from host_emulator.eval import board_time

    busy = [1.0] * 100 + [1.2] * 95 + [3.0] * 4 + [3.9]  # navigating: p99 3.0, max 3.9
    t, states = _twin_ticks([4.0] * 10 + busy, [1] * 10 + [2] * 200, late=[3])
    s = board_time.summary(t, states, 96_000_000, 2.4106)
    nav = s["phases"]["navigating"]
    assert nav["ticks"] == 200 and nav["busy_ms"]["max"] == pytest.approx(3.9)
    assert nav["late_ticks"] == 0 and s["phases"]["aligning"]["late_ticks"] == 1
    assert s["phases"]["aligning"]["over_4ms"] == 0  # 4.0 is not over
    run = {"board": "B", "overruns": 0, "late_ticks": 1, "watchdog_longest_gap_ms": 7.5,
           "watchdog_timeout_ms": 1000.0}  # fmt: skip
    text = "\n".join(board.twin_lines([{"label": "img", "time": s, "run": run,
                                        "wall_s": 5.0}], []))  # fmt: skip
    assert "| img | navigating | 200 | " in text and "| img | aligning | 10 | " in text
    assert ">= 5 (late)" in text  # a late tick's busy time is only known to be the period
    assert "navigating busy p99 3.00 ms (target <= 2), max 3.90 ms (<= 3.5)" in text
    assert "0 ticks missed and 1 late in the whole run (target 0)" in text
    assert "Not met (3 of 3)." in text  # p99, max, and the late tick
    ok, states = _twin_ticks([1.0] * 200, [2] * 200)
    s = board_time.summary(ok, states, 96_000_000, 2.4106)
    run = dict(run, late_ticks=0)
    text = "\n".join(board.twin_lines([{"label": "img", "time": s, "run": run,
                                        "wall_s": 5.0}], []))  # fmt: skip
    assert "Met." in text
