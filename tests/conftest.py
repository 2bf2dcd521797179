"""Every test sees the firmware as the board does (flat `firmware/lib` modules on the path,
the NumPy float32 backend behind the seam)."""

from common import firmware_env

firmware_env.install()
