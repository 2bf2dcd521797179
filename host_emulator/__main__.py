"""Command line of the host side: `python -m host_emulator COMMAND` (`--help` for each).

    scenarios                       the simulated scenarios
    runtimes                        where the firmware can run (runtimes/)
    run --scenario NAME --out DIR   simulate, run the firmware on an emulated board, evaluate
    run --stimulus FILE --out DIR   replay a stimulus file through the firmware
    parity --scenario NAME --duration S   firmware (CPython or M4F) vs the NumPy model, bit for bit
    replay --dataset drive_0708 --out DIR   a real recording through the firmware, evaluated
    replay --kf-gins DIR --out DIR  the same for a dataset in the KF-GINS text layout (your own
                                    recording: docs/formats.md; no outages, scored from t0)
    export --scenario NAME | --dataset drive_0708 --out DIR   KF-GINS files + RTKLIB .pos
    session record|replay|report    record a board's output; replay it bit for bit; report it
    virtual-board --fs DIR          a board on pseudo-terminals (raw REPL, RS485 frames)
    demo                            urban_drive on CPython, with a short summary
    gnss-dump FILE                  what the firmware's NMEA parser makes of a receiver log
  measurements (they write docs/; minutes):
    bench-nav                       navigation accuracy and cost per tick (make bench-nav)
    accuracy-report                 drive_0708 and the scenarios (make accuracy-report)
    float32                         accuracy of the float32 math and kernels (make accuracy)
    bench-board                     the app loop's cost per tick on the emulated Cortex-M4F
    figures [--check]               the board figures the docs quote, from board.json and the
                                    images' budgets (make figures)
    bench-faults                    the fault matrix: detection, trust, recovery (make bench-faults)
    bench-settings                  every board setting swept: what navigates (make bench-settings)
    bench-real                      every real recording in ../shared/data (make bench-real)
    profile                         where a tick goes on the emulated Cortex-M4F, per function
    digests [--update]              the change indicator: frame-stream digests per runtime
    cpi [--no-write]                CPI of MicroPython on an STM32F4 (make cpi; ~1 min)

Bad input (an unknown scenario, an unreadable stimulus, a firmware exception) prints one clear
message and exits non-zero.
"""

import argparse
import dataclasses
import importlib
import sys

from common.errors import EmulatorError
from host_emulator import args as cli_args
from host_emulator import runtimes

# commands with a parser of their own: name -> ("module:function" taking argv, help)
DELEGATED = {
    "parity": ("host_emulator.eval.parity:main",
               "firmware (CPython or the M4F) vs the NumPy float32 model, byte for byte"),
    "session": ("host_emulator.session.cli:main",
                "record a board's output, or replay a recording bit for bit"),
    "virtual-board": ("host_emulator.virtual_board:main",
                      "a board on pseudo-terminals for tools.flash and tools.monitor (--fs DIR)"),
    "gnss-dump": ("host_emulator.eval.gnss_dump:main",
                  "what the firmware's NMEA parser makes of a receiver log (FILE [--json])"),
    "bench-nav": ("host_emulator.bench.navigation:main",
                  "navigation benchmark: accuracy over seeds, cost per tick in the VM"),
    "accuracy-report": ("host_emulator.bench.accuracy_report:main",
                        "drive_0708 and the scenarios: writes docs/accuracy.md"),
    "float32": ("host_emulator.bench.float32:main",
                "accuracy of the float32 math functions and kernels (docs/float32.md)"),
    "bench-board": ("host_emulator.bench.board:main",
                    "instructions per tick of the app loop on the emulated Cortex-M4F"),
    "figures": ("host_emulator.bench.figures:main",
                "the board figures the docs quote, rewritten from board.json and make image"),
    "bench-faults": ("host_emulator.bench.faults:main",
                     "every fault kind injected into a drive: detection, health, recovery"),
    "bench-settings": ("host_emulator.bench.settings:main",
                       "every board setting swept: the ranges that still navigate within spec"),
    "bench-real": ("host_emulator.bench.realdata:main",
                   "every real recording in ../shared/data, next to its own fixes"),
    "profile": ("host_emulator.bench.profile:main",
                "where a tick goes on the emulated Cortex-M4F, per function"),
    "digests": ("host_emulator.bench.digests:main",
                "the change indicator: frame-stream digests per scenario and runtime"),
    "cpi": ("host_emulator.bench.cpi:main",
            "CPI of MicroPython on an STM32F4: published F401 perf_bench cycles over the "
            "emulated Cortex-M4F's instruction counts (docs/benchmarks/cpi.md)"),
}  # fmt: skip


def _scenarios():
    from host_emulator.sim import trajectory

    for name, fn in trajectory.SCENARIOS.items():
        outages = ", ".join(f"{s:g}+{n:g} s" for s, n in fn.outages) or "none"
        print(f"{name:16} {fn.default_duration_s:5.0f} s  outages: {outages}")
        print(f"{'':16} {fn.description}")
    return 0


def _runtimes():
    for r in runtimes.RUNTIMES.values():
        print(f"{r.name:12} {r.summary}")
    for alias, name in runtimes.ALIASES.items():
        print(f"{alias:12} the old name of {name}")
    return 0


def _add_fault_option(p):
    p.add_argument(
        "--fault", action="append", default=[], metavar="KIND@T0+DURATION[:PARAM]",
        help="inject a fault into the board's input (repeatable; `--fault help` lists them)",
    )  # fmt: skip


def _add_display_option(p):
    p.add_argument(
        "--display", metavar="PATH",
        help="run the board's UsartGPU screen (the display setting on) and draw it: PATH.png "
        "the screen at the end, PATH_strip.png over the run (docs/display.md)",
    )  # fmt: skip


def _faults(args):
    """The parsed --fault options, or None after printing the kinds for `--fault help`;
    FaultError (one line, exit 1) for one written wrong."""
    from host_emulator.sim import faults

    if any(f.strip().lower() == "help" for f in args.fault):
        print("--fault KIND@T0+DURATION[:PARAM] (seconds), the kinds:\n" + faults.describe())
        return None
    return [faults.parse(f) for f in args.fault]


def _run(args):
    from host_emulator.eval import scenario_run

    if not args.stimulus:  # the command line's values: a usage error (2), as parity's
        try:
            cli_args.check_scenario(args.scenario)
            cli_args.check_duration(args.duration)
            cli_args.check_seed(args.seed)
        except EmulatorError as e:
            raise cli_args.UsageError(str(e)) from None
    injected = _faults(args)
    if injected is None:
        return 0
    if args.stimulus:
        m = scenario_run.run_stimulus(
            args.stimulus, args.runtime, args.out, not args.quiet, kernels=_kernels(args),
            faults=injected, board=args.board, display=args.display,
        )  # fmt: skip
    else:
        m = scenario_run.run(
            args.scenario, args.duration, args.seed, args.runtime, args.out, not args.quiet,
            kernels=_kernels(args), faults=injected, board=args.board, display=args.display,
        )  # fmt: skip
    from host_emulator.eval import demo

    print(demo.summary(m, args.out))
    return 0


def _kernels(args):
    """--kernels, or None for a runtime without kernels (the model)."""
    return None if runtimes.get(args.runtime).name == "model" else args.kernels


def _replay_options(args, ds):
    """ReplayOptions of the command line. The defaults depend on the source: drive_0708 keeps
    the protocol of its published figures (to_stimulus.ReplayOptions()), a KF-GINS dataset
    runs as it is (replay_run.kfgins_options())."""
    from host_emulator.replay import replay_run, run_config, to_stimulus

    base = replay_run.kfgins_options(ds) if args.kf_gins else to_stimulus.ReplayOptions()
    noise = args.gnss_noise
    if noise is None:
        # a recorded GNSS file as it is; else the protocol's noise on the reference
        noise = None if ds.gnss is not None else 1.5
    elif noise < 0:
        raise EmulatorError("--gnss-noise must be 0 or more")
    seed = 1 if args.seed is None else args.seed
    if seed < 0:
        raise EmulatorError("--seed must be 0 or more")
    if args.gnss_velocity is not None and not args.gnss_velocity >= 0:
        raise EmulatorError("--gnss-velocity must be 0 or more")
    skip = base.skip_s if args.score_from is None else args.score_from
    if not skip >= 0:
        raise EmulatorError("--score-from must be 0 or more (seconds after t0)")
    settings = tuple(run_config.parse(text) for text in args.set)
    return dataclasses.replace(
        base,
        gnss_rate_hz=args.gnss_rate,
        gnss_noise_m=noise,
        outages=base.outages if args.outages is None else replay_run.parse_outages(args.outages),
        skip_s=skip,
        seed=seed,
        duration_s=args.duration,
        gnss_velocity_sigma=args.gnss_velocity,
        config=settings,
    )


def _add_replay_options(p):
    p.add_argument(
        "--gnss-rate", type=float, default=1.0, metavar="HZ",
        help="GNSS epochs per second at most: 1, 2, 4, 5 or 10 (default 1); epochs on that "
        "rate's grid if the data has them, else at their own times (docs/formats.md)",
    )  # fmt: skip
    p.add_argument(
        "--gnss-noise", type=float, default=None, metavar="M",
        help="white noise sigma per horizontal axis, m (vertical twice); default 1.5 when the "
        "GNSS input is made from the reference, none for a recorded GNSS file",
    )  # fmt: skip
    p.add_argument(
        "--outages", default=None, metavar="START+LENGTH,...",
        help="GNSS outages in s after the first epoch t0, or none (default: drive_0708 "
        "60+15,200+15,400+15, its protocol; --kf-gins none)",
    )  # fmt: skip
    p.add_argument(
        "--score-from", type=float, default=None, metavar="S",
        help="score from S seconds after t0 (default: drive_0708 30, its protocol; --kf-gins 0)",
    )  # fmt: skip
    p.add_argument(
        "--set", action="append", default=[], metavar="NAME=VALUE",
        help="a board setting (ins.cfg) for this run, as `python -m tools.flash config set` "
        "takes it; repeatable; applied after the dataset's own (`--set help` lists them)",
    )  # fmt: skip
    p.add_argument(
        "--gnss-velocity", type=float, default=None, metavar="SIGMA",
        help="also send the GNSS source's velocity (the GNSS file's, or the reference's) "
        "with this noise (m/s) as RMC speed/course (default: positions only)",
    )  # fmt: skip
    p.add_argument("--duration", type=float, default=None, help="replay the first seconds")
    p.add_argument(
        "--seed", type=int, default=None,
        help="GNSS noise seed of a replay (default 1: the protocol); a scenario's seed (0)",
    )  # fmt: skip
    p.add_argument("--gnss-pos", help="an RTKLIB .pos to use as the GNSS input")
    p.add_argument("--truth-pos", help="an RTKLIB .pos to use as the reference (antenna)")
    p.add_argument("--data", help="drive_0708's directory (default ../shared/data/drive_0708)")


def _settings_help():
    """`--set help`: every ins.cfg setting with its default (and range, for the floats)."""
    from common.proto import config as board_config

    board_config.print_catalogue("--set")


def _load(args):
    from host_emulator.replay import replay_run

    return replay_run.load_dataset(
        getattr(args, "dataset", None), getattr(args, "kf_gins", None), args.data,
        gnss_pos=args.gnss_pos, truth_pos=args.truth_pos,
    )  # fmt: skip


def _replay(args):
    from host_emulator.eval import demo
    from host_emulator.replay import replay_run

    injected = _faults(args)
    if injected is None:
        return 0
    if any(t.strip().lower() == "help" for t in args.set):
        _settings_help()
        return 0
    ds = _load(args)
    m = replay_run.replay(
        ds, _replay_options(args, ds), args.runtime, args.out,
        show_progress=not args.quiet, kernels=_kernels(args), faults=injected, board=args.board,
        display=args.display,
    )  # fmt: skip
    print(demo.summary(m, args.out))
    return 0


def _export(args):
    from host_emulator.replay import replay_run

    if args.scenario:
        from host_emulator import args as cli_args

        cli_args.check_scenario(args.scenario)
        cli_args.check_duration(args.duration)
        seed = 0 if args.seed is None else args.seed
        cli_args.check_seed(seed)
        written = replay_run.export_scenario(args.scenario, args.duration, seed, args.out)
    else:
        if any(t.strip().lower() == "help" for t in args.set):
            _settings_help()
            return 0
        ds = _load(args)
        written = replay_run.export_replay(ds, _replay_options(args, ds), args.out)
    for path in written:
        print(path)
    return 0


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m host_emulator",
        description="Host emulator of the INS/GNSS board firmware.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    runtime_names = runtimes.names()
    runtime_help = "where the firmware runs (default cpython; `runtimes` lists them)"
    sub.add_parser("scenarios", help="list the simulated scenarios")
    sub.add_parser("runtimes", help="list the runtimes")
    run = sub.add_parser("run", help="simulate a scenario, run the firmware, evaluate")
    src = run.add_mutually_exclusive_group(required=True)
    src.add_argument("--scenario", help="scenario name (see `scenarios`)")
    src.add_argument("--stimulus", help="replay this stimulus file instead of simulating")
    run.add_argument("--duration", type=float, default=None, help="seconds (default: full)")
    run.add_argument("--seed", type=int, default=0, help="the simulation's random seed (0)")
    run.add_argument("--runtime", default="cpython", choices=runtime_names, help=runtime_help)
    cli_args.add_kernels_option(run)
    cli_args.add_board_option(run)
    run.add_argument("--out", default="out/run", help="output directory (out/run)")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_display_option(run)
    _add_fault_option(run)
    rp = sub.add_parser("replay", help="a recorded drive through the firmware, evaluated")
    src = rp.add_mutually_exclusive_group(required=True)
    src.add_argument("--dataset", help="a built-in recording: drive_0708")
    src.add_argument(
        "--kf-gins", metavar="DIR",
        help="a directory in the KF-GINS layout, e.g. your own recording (docs/formats.md): "
        "replayed as it is (no outages, scored from t0)",
    )  # fmt: skip
    _add_replay_options(rp)
    rp.add_argument("--runtime", default="cpython", choices=runtime_names, help=runtime_help)
    cli_args.add_kernels_option(rp)
    cli_args.add_board_option(rp)
    rp.add_argument("--out", default="out/replay", help="output directory (out/replay)")
    rp.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_display_option(rp)
    _add_fault_option(rp)
    ex = sub.add_parser(
        "export", help="a scenario or a replay's input as KF-GINS text files and RTKLIB .pos"
    )
    src = ex.add_mutually_exclusive_group(required=True)
    src.add_argument("--scenario", help="a simulated scenario (its truth, IMU and GNSS)")
    src.add_argument("--dataset", help="a recording's replay input: drive_0708")
    src.add_argument("--kf-gins", help="a KF-GINS directory (re-export with the options)")
    _add_replay_options(ex)
    ex.add_argument("--out", required=True, help="output directory")
    demo = sub.add_parser("demo", help="urban_drive on CPython with a short summary")
    demo.add_argument("--out", default="out/demo", help="output directory (out/demo)")
    for name, (_, text) in DELEGATED.items():
        sub.add_parser(name, help=text, add_help=False)
    args, rest = parser.parse_known_args(argv)
    return cli_args.run_reporting(lambda: _command(parser, args, rest))


def _command(parser, args, rest):
    if args.command in DELEGATED:
        module, func = DELEGATED[args.command][0].split(":")
        return getattr(importlib.import_module(module), func)(rest)
    if rest:
        parser.error("unrecognized arguments: " + " ".join(rest))
    if args.command == "scenarios":
        return _scenarios()
    if args.command == "runtimes":
        return _runtimes()
    if args.command in ("run", "replay"):
        try:
            cli_args.check_board(args.runtime, args.board)
        except cli_args.UsageError as e:
            print(f"error: {e}", file=sys.stderr)
            return 2
    if args.command == "run":
        return _run(args)
    if args.command == "replay":
        return _replay(args)
    if args.command == "export":
        return _export(args)
    if args.command == "demo":
        from host_emulator.eval import demo

        return demo.main(args.out)
    return 2


if __name__ == "__main__":
    sys.exit(main())
