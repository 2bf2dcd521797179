"""python -m tools.monitor --port PORT | --file FILE [options] (see tools/monitor/cli.py)."""

import sys

from tools.monitor.cli import main

if __name__ == "__main__":
    sys.exit(main())
