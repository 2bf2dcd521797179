"""Command line of the host side: `python -m host_emulator COMMAND`."""

import argparse
import sys


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m host_emulator", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser(
        "demo", help="self-check of the float32 core (the main job until the emulator exists)"
    )
    args = parser.parse_args(argv)
    if args.command == "demo":
        from host_emulator import demo

        return demo.main()
    return 2


if __name__ == "__main__":
    sys.exit(main())
