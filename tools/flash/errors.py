"""Errors `python -m tools.flash` reports as one paragraph and exit status 1, never a traceback."""


class FlashError(Exception):
    """A failure the user can act on: the message says what happened and what to do."""


class NotResponding(FlashError):
    """Nothing came back from the port within the timeout."""


class NotMicroPython(FlashError):
    """Bytes came back, but not MicroPython's raw REPL."""


class BoardError(FlashError):
    """Code run on the board raised; the message quotes the board's traceback."""


class FlashFull(FlashError):
    """The firmware does not fit the board's filesystem (or the stated budget)."""


class FrozenMismatch(FlashError):
    """The board's image carries another version of the firmware frozen."""


class TransferCorrupted(FlashError):
    """A file's CRC-32 on the board differed from the host's after every attempt."""


class FirmwareNotRunning(FlashError):
    """After the soft reset the firmware did not report that its loop started."""
