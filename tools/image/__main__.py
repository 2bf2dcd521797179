"""`python -m tools.image build|sizes|boards`: see docs/image.md.

Usage errors exit with status 2, failures with status 1 and one paragraph saying what to do.
"""

import argparse
import sys

from tools.image.boards import BOARDS, DEFAULT_BOARD


def _build(args):
    from tools.image import build

    build.build(args.board, args.out)
    return 0


def _sizes(args):
    from tools.image import sizes

    sizes.main(args.board, args.top, args.save, args.against)
    return 0


def _boards(_args):
    for name, board in BOARDS.items():
        where = "this repository" if board.board_dir else "the MicroPython tree"
        print(f"{name}: {board.description} (board definition from {where})")
    return 0


def _parser():
    p = argparse.ArgumentParser(
        prog="python -m tools.image",
        description="Build MicroPython for the STM32F411 with the firmware frozen in.",
    )
    sub = p.add_subparsers(dest="command", required=True)
    b = sub.add_parser("build", help="build the image and report its budget")
    b.add_argument(
        "--board", default=DEFAULT_BOARD, choices=sorted(BOARDS), help=f"({DEFAULT_BOARD})"
    )
    b.add_argument("--out", help="output folder (out/image/BOARD)")
    b.set_defaults(func=_build)
    z = sub.add_parser("sizes", help="where the last build's bytes go: by object file, by "
                       "frozen module, the built-in modules")  # fmt: skip
    z.add_argument(
        "--board", default=DEFAULT_BOARD, choices=sorted(BOARDS), help=f"({DEFAULT_BOARD})"
    )
    z.add_argument("--top", type=int, default=40, help="object files shown (40; 0: all)")
    z.add_argument("--save", metavar="FILE", help="keep the figures (JSON) for a later --against")
    z.add_argument("--against", metavar="FILE", help="print the change from a --save file")
    z.set_defaults(func=_sizes)
    sub.add_parser("boards", help="the boards an image can be built for").set_defaults(func=_boards)
    return p


def main(argv=None):
    args = _parser().parse_args(argv)
    from common.errors import os_error_text, quiet_broken_pipe
    from common.toolchain import ToolchainError
    from tools.image.budget import BudgetError
    from tools.image.build import ImageError
    from tools.image.fwid import FirmwareIdError

    try:
        return args.func(args)
    except (ImageError, BudgetError, FirmwareIdError, ToolchainError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted: run the command again (make resumes where it stopped)",
              file=sys.stderr)  # fmt: skip
        return 130
    except BrokenPipeError:
        return quiet_broken_pipe()
    except OSError as e:  # a full disk, a read-only output directory
        print(f"error: {os_error_text(e)}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
