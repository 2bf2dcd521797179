# What the emulated Cortex-M4F carries frozen (MicroPython's manifest format): the firmware
# as the board image freezes it, with its Python reference kernels (nav_kern, yaw_gsf,
# drivers.gnss_kern: a board image leaves them out; kernels="python" runs them here), plus the
# emulated board (machine, time: found before the built-in modules of those names, as frozen
# modules come first on sys.path; bmi055_model, the BMI055 register model machine imports)
# the guest driver that feeds it a stimulus and the profiler's guest side
# (host_emulator/emulated_board/mpy).
include("../../../firmware/manifest.py", reference_kernels=True)
for name in ("machine", "bmi055_model", "time", "feed", "emulate_m4f", "profile_guest"):
    module(name + ".py", base_path="../../emulated_board/mpy")
module("feed_protocol.py", base_path="../../../common/proto/mpy")  # the stimulus record
