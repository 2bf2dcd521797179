"""serial_port.open_port: a port held for an instant is waited for, one held on stays busy."""

import os
import subprocess
import sys
import time

import pytest

from common.proto import serial_port

HOLD = (
    "import fcntl, os, sys, time\n"
    "fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)\n"
    "fcntl.flock(fd, fcntl.LOCK_EX)\n"
    "print('held', flush=True)\n"
    "time.sleep(float(sys.argv[2]))\n"
)


@pytest.fixture
def pty_name():
    master, slave = os.openpty()
    yield os.ttyname(slave)
    os.close(slave)
    os.close(master)


def _holder(name, seconds):
    proc = subprocess.Popen(
        [sys.executable, "-c", HOLD, name, str(seconds)], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout.readline().strip() == "held"
    return proc


def test_a_lock_held_for_an_instant_is_waited_for(pty_name):
    """As when a process forked in the instant before the port was closed holds the lock's
    copy until it runs its program: the open succeeds once it lets go."""
    proc = _holder(pty_name, 0.3)
    t0 = time.monotonic()
    try:
        ser = serial_port.open_port(pty_name, 115200, 0.05)
    finally:
        proc.wait()
    ser.close()
    assert time.monotonic() - t0 < serial_port.BUSY_RETRY_S + 0.5


def test_a_port_held_on_is_busy_after_the_wait(pty_name):
    proc = _holder(pty_name, 5.0)
    t0 = time.monotonic()
    try:
        with pytest.raises(serial_port.PortError) as e:
            serial_port.open_port(pty_name, 115200, 0.05)
    finally:
        proc.kill()
        proc.wait()
    assert e.value.kind == serial_port.BUSY and "is busy" in str(e.value)
    assert time.monotonic() - t0 >= serial_port.BUSY_RETRY_S
