"""python -m common.native: build the kernels' three modules (make native), printing each
build's time and output; a failure says what to install and exits 1."""

import argparse
import sys

from common import native


def main(argv=None):
    argparse.ArgumentParser(
        prog="python -m common.native",
        description="Build the native float32 kernels three ways (make native): the armv7emsp "
        "MicroPython module for the board, the x64 one for the unix VM, the cffi module for "
        "CPython (docs/native.md). A failure says what to install and exits 1.",
    ).parse_args(argv)
    try:
        native.build_all()
    except (native.NativeError, ValueError) as e:  # ValueError: bindings.HeaderError
        print(f"native: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
