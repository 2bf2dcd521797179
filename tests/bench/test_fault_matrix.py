"""The fault matrix (host_emulator/bench/faults.py) in a short form: a kind of each family,
one seed, on urban_drive up to 30 s after the fault; each must be detected with its cause in
time, say health 2 whenever an error exceeds 10 m, and be back within 2x the no-fault RMS
30 s after it ends. `make bench-faults` runs every kind on three seeds."""

import pytest

from host_emulator.bench import faults as bench

T0 = bench.FAULT_T0_S
SHORT = ("imu-zeros@+1", "imu-stuck@+1", "accel-vibe@+2", "gnss-height@+5:100",
         "gnss-quality@+5:6", "gnss-loss@+10", "stall@+0.2")  # fmt: skip


@pytest.fixture(scope="module")
def nominal():
    return bench._run((None, 0, T0 + 45.0))


@pytest.mark.parametrize("spec", SHORT)
def test_a_fault_is_detected_trusted_and_recovered_from(nominal, spec):
    case = next(c for c in bench.MATRIX if c.spec == spec)
    run_s = T0 + bench._duration(case) + 35.0
    r = bench._run((bench._spec(case, T0), 0, run_s))
    s = bench.score(case, r, nominal, T0)
    assert "error" not in s and s["finite"], s
    assert s["detected"], s  # health >= 1 with an expected cause within the deadline
    assert s["missed_over_10m"] == 0, s
    assert s["recover_s"] is not None and s["recover_s"] <= 30.0, s
    assert s["h_30s_m"] <= 2 * s["rms_h_nominal_m"] and s["v_30s_m"] <= 2 * s["rms_v_nominal_m"]
    assert s["health2_before_fault"] == 0, s


def test_the_matrix_covers_every_kind():
    kinds = {c.spec.split("@")[0] for c in bench.MATRIX}
    from host_emulator.sim import faults

    assert kinds == set(faults.KINDS)


@pytest.mark.parametrize("jobs", ["0", "two"])
def test_a_jobs_count_that_cannot_run_is_one_line(jobs, capsys):
    assert bench.main(["--jobs", jobs]) == 2
    assert "--jobs" in capsys.readouterr().err
