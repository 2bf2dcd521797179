"""Command line of the host side: `python -m host_emulator COMMAND`."""

import argparse
import sys


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m host_emulator", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser(
        "demo", help="self-check of the float32 core and the navigator (the main job for now)"
    )
    sub.add_parser(
        "gnss-dump",
        help="what the firmware's NMEA parser makes of a receiver log (FILE [--json])",
        add_help=False,
    )
    args, rest = parser.parse_known_args(argv)
    if args.command == "gnss-dump":
        from host_emulator import gnss_dump

        return gnss_dump.main(rest)
    if rest:
        parser.error("unrecognized arguments: " + " ".join(rest))
    if args.command == "demo":
        from host_emulator import demo

        return demo.main()
    return 2


if __name__ == "__main__":
    sys.exit(main())
