"""Every test sees the firmware as the board does (flat `firmware/lib` modules on the path,
the NumPy float32 backend behind the seam)."""

import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

from host_emulator import firmware_env  # noqa: E402

firmware_env.install()
