"""Modules the MicroPython side imports too: plain Python (no CPython-only module, no
dataclass), found by the VMs on their path (host_emulator/runtimes/mpy_unix/vm.py) and frozen
into the emulated Cortex-M4F (host_emulator/runtimes/m4f/manifest.py).

    feed_protocol.py   the stimulus record and the feeding harness's exit code
"""
