"""The change indicator (host_emulator/bench/digests.py): short runs of the scenarios on every
runtime give exactly the digests and 1 Hz frame summaries committed in tests/change_indication/.
A failure means the firmware's output, the VM's allocations per tick, or the image's figures
of every tick on the twin changed: if that is
the intent, `python -m host_emulator digests --update` rewrites the files and the review sees
the diff; if not, something changed behaviour that should not have."""

import pytest

from host_emulator.bench import digests


@pytest.fixture(scope="module")
def fresh():
    return digests.compute()


def test_the_committed_digests_are_what_the_runtimes_send(fresh):
    diff = digests.differences(*fresh)
    assert diff == [], "behaviour changed:\n" + "\n".join(diff)


def test_the_model_and_cpython_streams_are_one(fresh):
    d, _ = fresh
    for run in (d[name] for name, *_ in digests.RUNS):
        assert run["model"] == run["cpython"]  # parity, as the change indicator sees it
        assert run["mpy_unix"]["frames"] == run["cpython"]["frames"] > 0


def test_a_changed_output_is_reported(fresh, tmp_path):
    d, csvs = fresh
    digests.write(d, csvs, tmp_path)
    assert digests.differences(d, csvs, tmp_path) == []
    changed = {name: dict(runs) for name, runs in d.items()}
    name = next(iter(changed))
    changed[name]["cpython"] = dict(changed[name]["cpython"], sha256="0" * 64)
    csv_name = next(iter(csvs))
    (tmp_path / csv_name).write_text(csvs[csv_name].replace("2", "3", 1))
    assert digests.differences(changed, csvs, tmp_path) == [
        f"{name} on cpython: sha256 changed",
        f"{csv_name} changed",
    ]


def test_the_twin_digests_its_ticks(fresh):
    d, _ = fresh
    ((name, *_),) = digests.TWIN_RUNS
    entry = d[name][digests.TWIN_RUNTIME]
    assert entry["frames"] > 0 and len(entry["per_tick_sha256"]) == 64
    assert 20_000 < entry["instr_per_tick_mean"] < 100_000  # the image's ticks, not idle ones
