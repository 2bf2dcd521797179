"""The desktop side of the INS board: the unmodified firmware run, measured and checked on a PC.

sim/, replay/, session/   where input comes from: a simulation, a real recording, a
                          recorded board session; each becomes a stimulus file
proto/                    every format the board and the PC exchange, written once
                          (shared with tools/)
runtimes/                 where the firmware runs: cpython, mpy_unix, model (one registry)
board/                    the emulated board the runtimes run it on (mpy/: one for all)
model/                    the NumPy float32 model of the firmware, module by module
eval/                     scoring, reports, parity, and the `run` and `demo` commands
bench/                    measurements that write docs/, and the change indicator
virtual_board/            a board on pseudo-terminals for tools/flash and tools/monitor
firmware_env/             how CPython imports the firmware as the board does
__main__.py               the one command line: python -m host_emulator COMMAND
"""
