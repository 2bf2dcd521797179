"""The change indicator, in the spirit of PX4-ECL's test/change_indication: short runs of the
simulated scenarios on every runtime, each summed up in files committed under
tests/change_indication/, so that any change of behaviour shows in review as a diff of them.

    digests.json     per run and runtime: the SHA-256 of the whole output stream, its length and
                     frame count (and, on mpy_unix, of the GC blocks of every tick; on f411, the
                     image on the emulated STM32F411, of its per-tick records: the instructions,
                     cycles and interrupts of every tick, which a change of the twin must keep)
    RUN.RUNTIME.csv  the run's frames at 1 Hz in physical units (cpython and mpy_unix; the
                     model's stream is the cpython one, which its digest shows)

`make test` recomputes them (tests/bench/test_digests.py) and fails on any difference;
`python -m host_emulator digests --update` rewrites them, on purpose, with the change that
explains it. A refactoring that leaves them unchanged changed no output bit.
"""

import argparse
import hashlib
import json
import pathlib
import sys
import tempfile

from common.firmware_env import REPO_DIR
from common.proto import stream
from host_emulator import runtimes

DIR = REPO_DIR / "tests" / "change_indication"
# (name, scenario, seconds, seed, board configuration overrides): the first two include
# levelling, heading from the GNSS course and navigation with GNSS updates, ZUPT and NHC; the
# third sends raw-input records and frames every other tick
RUNS = (
    ("urban_drive_75s", "urban_drive", 75.0, 0, {}),
    ("highway_outage_45s", "highway_outage", 45.0, 0, {}),
    ("highway_outage_45s_raw", "highway_outage", 45.0, 1,
     {"raw_record": 1, "ext_every_ticks": 10, "output_every_ticks": 2}),
)  # fmt: skip
# Not m4f: it runs at about real time (these runs would add ~3 minutes to make test); its
# parity test (tests/runtimes/test_m4f.py) shows its stream equals the model's, digested here.
RUNTIMES = ("cpython", "model", "mpy_unix")
# the image on the twin (f411), shorter: it runs at about 1.5x real time
TWIN_RUNS = (("urban_drive_12s", "urban_drive", 12.0, 0, {}),)
TWIN_RUNTIME = "f411"
CSV_RUNTIMES = ("cpython", "mpy_unix")
_COLUMNS = (
    "t_s,counter,nav_state,gnss_valid,lat_e7,lon_e7,height_m,yaw_deg,pitch_deg,roll_deg,"
    "vel_e_m_s,vel_n_m_s,vel_u_m_s,pos_e_m,pos_n_m,pos_u_m"
)


def _csv(out, every_frames, tick_s):
    """The frames of a stream at 1 Hz (one row per second of board time)."""
    rows = [_COLUMNS]
    step = max(1, round(1.0 / (every_frames * tick_s)))
    frames = stream.decode(out).frames
    for i in range(step - 1, len(frames), step):
        f = frames[i]
        t = (i + 1) * every_frames * tick_s
        v, p = f["vel_enu_m_s"], f["pos_enu_m"]
        rows.append(
            f"{t:.3f},{f['counter']},{f['nav_state']},{f['gnss_valid']},{f['lat_e7']},"
            f"{f['lon_e7']},{f['height_m']:.1f},{f['yaw_deg']:.2f},{f['pitch_deg']:.2f},"
            f"{f['roll_deg']:.2f},{v[0]:.2f},{v[1]:.2f},{v[2]:.2f},{p[0]:.2f},{p[1]:.2f},"
            f"{p[2]:.1f}"
        )
    return "\n".join(rows) + "\n"


def compute(log=None):
    """({run: {runtime: digest entry}}, {file name: CSV text}) of fresh runs."""
    from host_emulator.sim import board_input

    digests, csvs = {}, {}
    plan = [(run, rt) for run in RUNS for rt in RUNTIMES]
    plan += [(run, TWIN_RUNTIME) for run in TWIN_RUNS]
    stims = {}
    for (name, scenario, seconds, seed, overrides), rt in plan:
        if name not in stims:
            stims[name] = board_input.simulate(scenario, seconds, seed).stimulus
        stim = stims[name]
        every = overrides.get("output_every_ticks", 1)
        if log:
            log(f"{name} on {rt}")
        with tempfile.TemporaryDirectory(prefix="digest-") as d:
            fw = runtimes.get(rt).run(stim, pathlib.Path(d), overrides)
        entry = {
            "sha256": hashlib.sha256(fw.out).hexdigest(),
            "bytes": len(fw.out),
            "frames": len(stream.decode(fw.out).frames),
        }
        if fw.blocks_per_tick is not None:
            blocks = fw.blocks_per_tick.astype("<i4").tobytes()
            entry["gc_blocks_sha256"] = hashlib.sha256(blocks).hexdigest()
            entry["gc_blocks_per_tick_mean"] = round(float(fw.blocks_per_tick.mean()), 3)
        per_tick = getattr(fw, "per_tick", None)
        if per_tick is not None:
            entry["per_tick_sha256"] = hashlib.sha256(per_tick.tobytes()).hexdigest()
            entry["instr_per_tick_mean"] = round(float(per_tick["instr"].mean()), 1)
        digests.setdefault(name, {})[rt] = entry
        if rt in CSV_RUNTIMES:
            csvs[f"{name}.{rt}.csv"] = _csv(fw.out, every, stim.tick_us * 1e-6)
    return digests, csvs


def digests_text(digests):
    return json.dumps(digests, indent=1, sort_keys=True) + "\n"


def differences(digests, csvs, directory=DIR):
    """What differs from the committed files, in words ([] when nothing does)."""
    out = []
    path = directory / "digests.json"
    committed = json.loads(path.read_text()) if path.exists() else {}
    for name in sorted(set(digests) | set(committed)):
        mine, theirs = digests.get(name, {}), committed.get(name, {})
        for rt in sorted(set(mine) | set(theirs)):
            a, b = theirs.get(rt), mine.get(rt)
            if a != b:
                keys = sorted(
                    k for k in set(a or {}) | set(b or {}) if (a or {}).get(k) != (b or {}).get(k)
                )
                out.append(f"{name} on {rt}: {', '.join(keys)} changed")
    for fname, text in sorted(csvs.items()):
        p = directory / fname
        if not p.exists() or p.read_text() != text:
            out.append(f"{fname} changed")
    return out


def write(digests, csvs, directory=DIR):
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "digests.json").write_text(digests_text(digests))
    for fname, text in csvs.items():
        (directory / fname).write_text(text)


def main(argv=None):
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator digests",
        description="the change indicator: recompute the frame-stream digests of short runs on "
        "every runtime and compare them with tests/change_indication/ (--update rewrites them)",
    )
    ap.add_argument("--update", action="store_true", help="write the new files (on purpose)")
    args = ap.parse_args(argv)
    digests, csvs = compute(log=lambda m: print(m, file=sys.stderr, flush=True))
    diff = differences(digests, csvs)
    if args.update:
        write(digests, csvs)
        print(f"wrote {DIR} ({len(diff)} changes)" + "".join(f"\n  {d}" for d in diff))
        return 0
    if diff:
        print("behaviour changed:\n  " + "\n  ".join(diff))
        print("if that is intended, run `python -m host_emulator digests --update` and commit it")
        return 1
    print(f"unchanged: {len(RUNS)} runs on {len(RUNTIMES)} runtimes, {len(TWIN_RUNS)} on the twin")
    return 0
