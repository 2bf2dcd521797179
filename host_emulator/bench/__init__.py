"""Measurements, run on purpose (minutes), that write the figures docs/ quotes:

navigation.py       `bench-nav`: accuracy over seeds and GNSS error models, and the cost
                    per tick in the VM (navigator.py drives the navigator alone on CPython,
                    navigator_vm.py inside the MicroPython VM)
accuracy_report.py  `accuracy-report`: drive_0708 and the scenarios -> docs/accuracy.md
float32.py          `float32`: the float32 math functions over their domains, then the
                    rotation and lat/lon kernels (core_figures.py) -> docs/float32.md
digests.py          `digests`: the change indicator (tests/change_indication/)
settings.py         `bench-settings`: every board setting swept, what still navigates within
                    the board spec -> docs/benchmarks/settings.md (firmware/lib/config.py's
                    ranges; the page: settings_report.py)
board.py            `bench-board`: the image's tick time and the board's RAM on the emulated
                    STM32F411 and Cortex-M4F -> docs/benchmarks/board.md (what a tick costs:
                    eval/board_cost.py, eval/board_time.py)
outputs.py          what a benchmark will write, said before it starts (most overwrite a
                    document the repository tracks)
"""
