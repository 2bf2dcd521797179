"""Command line of the host side: `python -m host_emulator COMMAND` (`--help` for each).

    scenarios                       the simulated scenarios
    run --scenario NAME --out DIR   simulate, run the firmware on an emulated board, evaluate
    run --stimulus FILE --out DIR   replay a stimulus file through the firmware
    parity --scenario NAME --duration S   firmware on CPython vs the NumPy model, bit for bit
    demo                            urban_drive on CPython, with a short summary
    gnss-dump FILE                  what the firmware's NMEA parser makes of a receiver log

Bad input (an unknown scenario, an unreadable stimulus, a firmware exception) prints one clear
message and exits non-zero.
"""

import argparse
import sys

from host_emulator.errors import EmulatorError


def _scenarios():
    from host_emulator.sim import trajectory

    for name, fn in trajectory.SCENARIOS.items():
        outages = ", ".join(f"{s:g}+{n:g} s" for s, n in fn.outages) or "none"
        print(f"{name:16} {fn.default_duration_s:5.0f} s  outages: {outages}")
        print(f"{'':16} {fn.description}")
    return 0


def _run(args):
    from host_emulator import scenario_run

    if args.stimulus:
        m = scenario_run.run_stimulus(args.stimulus, args.runtime, args.out, not args.quiet)
    else:
        m = scenario_run.run(
            args.scenario, args.duration, args.seed, args.runtime, args.out, not args.quiet
        )
    from host_emulator import demo

    print(demo.summary(m, args.out))
    return 0


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m host_emulator",
        description="Host emulator of the INS/GNSS board firmware.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("scenarios", help="list the simulated scenarios")
    run = sub.add_parser("run", help="simulate a scenario, run the firmware, evaluate")
    src = run.add_mutually_exclusive_group(required=True)
    src.add_argument("--scenario", help="scenario name (see `scenarios`)")
    src.add_argument("--stimulus", help="replay this stimulus file instead of simulating")
    run.add_argument("--duration", type=float, default=None, help="seconds (default: full)")
    run.add_argument("--seed", type=int, default=0)
    run.add_argument("--runtime", default="cpython", choices=("cpython", "micropython"))
    run.add_argument("--out", required=True, help="output directory")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    sub.add_parser(
        "parity", help="firmware on CPython vs the NumPy float32 model, frame by frame",
        add_help=False,
    )  # fmt: skip
    demo = sub.add_parser("demo", help="urban_drive on CPython with a short summary")
    demo.add_argument("--out", default="out/demo")
    sub.add_parser(
        "gnss-dump",
        help="what the firmware's NMEA parser makes of a receiver log (FILE [--json])",
        add_help=False,
    )
    args, rest = parser.parse_known_args(argv)
    try:
        if args.command == "gnss-dump":
            from host_emulator import gnss_dump

            return gnss_dump.main(rest)
        if args.command == "parity":
            from host_emulator import parity

            return parity.main(rest)
        if rest:
            parser.error("unrecognized arguments: " + " ".join(rest))
        if args.command == "scenarios":
            return _scenarios()
        if args.command == "run":
            return _run(args)
        if args.command == "demo":
            from host_emulator import demo

            return demo.main(args.out)
    except EmulatorError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    return 2


if __name__ == "__main__":
    sys.exit(main())
