"""Errors the host side reports to a user as a message and a non-zero exit, never a traceback."""


class EmulatorError(Exception):
    """Bad input or a failed run: the message says what and, where it can, what to do."""


class FirmwareError(EmulatorError):
    """The firmware raised: the message holds the tick, the time and the firmware's traceback."""
