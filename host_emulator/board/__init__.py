"""(docstring follows in phase B)"""

import pathlib

MPY_DIR = pathlib.Path(__file__).resolve().parent / "mpy"  # MicroPython code, not a host package
EMULATE = MPY_DIR / "emulate.py"
