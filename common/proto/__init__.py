"""What crosses between a board and a PC, each written once, shared by the emulator and tools/:

frame.py         the 52-byte output frame (docs/requirements.md, output frame): one field table
records.py       the extended frame (0x91) and the raw-input record (0x92)
stream.py        the output stream: the one decoder (incremental), and a strict splitter
crc.py           the CRC-32 of every protected record and file
ticks.py         MicroPython's ticks_us/ticks_diff arithmetic
config.py        the board's configuration file (the firmware's own codec)
stimulus.py      the stimulus file: what the board's peripherals see, tick by tick
session_file.py  a recording of a board's output, with its configuration
serial_port.py   opening a serial port, with errors that say what to do
"""
