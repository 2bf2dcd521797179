"""What the PC side of the project stands on, below both the board tools (tools/) and the
emulator (host_emulator/), and importing neither:

    errors.py       the error types and OS-error texts every command reports through
    proto/          the board's byte formats: frames, the extended and raw-input records, the
                    configuration file, stimulus and session files, the serial port
    firmware_env/   the firmware imported on CPython as the board sees it (the float32 seam's
                    NumPy backend, `micropython`, the native kernels through cffi)
    native/         the native kernels' three builds, their bindings and the generated headers
                    (layout.h, tuning.h) they share with the firmware's Python
    toolchain/      the cross compiler, QEMU and the build directory

The layers, bottom up: firmware/ (imports nothing of these), common/, tools/, host_emulator/;
tests/test_layering.py fails on an import that runs the other way.
"""
