"""Errors the host side reports to a user as a message and a non-zero exit, never a traceback."""


class EmulatorError(Exception):
    """Bad input or a failed run: the message says what and, where it can, what to do."""


class FirmwareError(EmulatorError):
    """The firmware raised: the message holds the tick, the time and the firmware's traceback."""


def os_error_text(e):
    """One line for an OSError a user can act on: what, which file, why (a full disk, a
    read-only directory, a missing one)."""
    why = e.strerror or str(e)
    hint = {28: " (the disk is full)", 30: " (a read-only filesystem)", 13: " (no permission)"}
    name = f"{e.filename}: " if e.filename else ""
    return f"{name}{why}{hint.get(e.errno, '')}"


def quiet_broken_pipe():
    """The reader of our output went away (`... | head`): stop without a word, and without
    Python complaining about stdout at exit; the exit status of a process killed by SIGPIPE."""
    import os
    import sys

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # no real stdout (a test's StringIO)
        pass
    return 141


def _write_through(path, data):
    """Write to a device or a pipe; its OSError names the file (the one close raises, as on
    /dev/full, carries no name)."""
    try:
        with open(path, "w" if isinstance(data, str) else "wb") as f:
            f.write(data)
    except OSError as e:
        if e.filename is None:
            e.filename = str(path)
        raise


def write_atomic(path, data):
    """Write bytes or text to `path` whole or not at all: a full disk or a Ctrl-C leaves the
    previous file (or none), never a part of the new one."""
    import os
    from pathlib import Path

    path = Path(path)
    if path.exists() and not path.is_file():  # a device or a pipe: written as it is
        _write_through(path, data)
        return
    part = path.with_name(f".{path.name}.part")
    try:
        if isinstance(data, str):
            part.write_text(data)
        else:
            part.write_bytes(data)
        os.replace(part, path)
    except BaseException:
        part.unlink(missing_ok=True)
        raise
