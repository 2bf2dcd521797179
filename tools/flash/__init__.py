"""Deploy the firmware and its configuration to a board over the serial REPL.

Planned (issue 7): build with mpy-cross, copy changed files with CRC-32 verification,
config get/set. Nothing is implemented here yet.
"""
