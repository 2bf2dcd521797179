"""python -m common.native: build the kernels' three modules (make native), printing each
build's time and output; a failure says what to install and exits 1."""

import sys

from common import native


def main():
    try:
        native.build_all()
    except (native.NativeError, ValueError) as e:  # ValueError: bindings.HeaderError
        print(f"native: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
