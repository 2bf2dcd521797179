"""A virtual INS board on pseudo-terminals, for trying the board tools without hardware
(docs/virtual_board.md):

    pty_board.py     VirtualBoard (the REPL's port, the RS485 port, the firmware's VM) and
                     `python -m host_emulator virtual-board`
    repl_server.py   the MicroPython VM behind the REPL: /flash, the board's `stm` stand-in
"""

from host_emulator.virtual_board.pty_board import VirtualBoard, main  # noqa: F401
