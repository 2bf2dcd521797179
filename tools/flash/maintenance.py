"""The maintenance start: the board reset into a start with neither the firmware's loop nor its
watchdog, before the board tools write its filesystem or restart it after a read.

Why: the firmware's watchdog (the STM32F4's IWDG, 50 ms: firmware/board.py) cannot be stopped
once started, and a write to the board's filesystem erases a flash sector, which stalls the
CPU, interrupts and the timer that feeds the stopped loop's watchdog included, for 250 ms (a
16 KB sector) to 550 ms (64 KB) or more. A soft reset (Ctrl-D) does not stop it either: the
firmware's start-up outlasts 50 ms. Only a reset does.

How, after Ctrl-C and Ctrl-A (repl.BoardRepl.enter):

    QUERY       the marker register RTC_BKP18R: MAINTENANCE_ON means this start already is a
                maintenance start (nothing to do); no `stm` module: not an stm32 board (the
                virtual board without its stand-in, a scripted board): no watchdog to stop
    ASK         backup-domain write access (RCC_APB1ENR.PWREN, PWR_CR.DBP), MAINTENANCE_ASKED
                into RTC_BKP18R, machine.reset(): a system reset, which stops the watchdog and
                keeps the backup domain; the board does not answer the run
    (reopen)    the port again: a USB board leaves and comes back (its port may take seconds);
                its start's output, then Ctrl-C, Ctrl-A as before
    QUERY       MAINTENANCE_ON: main.py took the marker (board.maintenance_start) and started
                neither the loop nor the watchdog. Anything else: main.py did not (a firmware
                older than this checkout's, whose loop Ctrl-C stopped again, or no main.py):
                the marker is cleared (CLEAR) and the session goes on as without the
                maintenance start, which `maintenance` says (None)

The tools then work as before and end with a soft reset (Ctrl-D): main.py finds
MAINTENANCE_ON, clears it, and starts the firmware normally (loop, watchdog). In maintenance
the board's console says so in one line (board.maintenance_start); Ctrl-D or a reset leaves.

The constants are firmware/board.py's (tests/tools/test_maintenance.py checks they agree): the
tools speak to whatever firmware the board runs, so they carry their own copy.
"""

import time

from tools.flash.errors import FlashError, NotResponding

RTC_BKP18R = 0x40002898
PWR_CR = 0x40007000
DBP = 1 << 8
RCC_APB1ENR = 0x40023840
PWREN = 1 << 28
MAINTENANCE_ASKED = 0x2D4D4E54
MAINTENANCE_ON = 0x2D4D4E4F
NO_STM = -1  # QUERY's answer on a MicroPython without the stm module

RESET_WAIT_S = 15.0  # for the port to come back after the reset (USB enumeration)
SETTLE_S = 0.5  # before the first attempt: the board resets, a USB port goes away
BOOT_QUIET_S = 0.5  # the start's output is over when the port is this long quiet ...
BOOT_OVERALL_S = 5.0  # ... or after this long

QUERY = (
    f"try:\n import stm\n print('MAINT', stm.mem32[{RTC_BKP18R:#x}])\n"
    f"except ImportError:\n print('MAINT', {NO_STM})\n"
)
_ACCESS = (
    f"import stm, machine\nm = stm.mem32\nm[{RCC_APB1ENR:#x}] = m[{RCC_APB1ENR:#x}] | {PWREN:#x}\n"
    f"m[{PWR_CR:#x}] = m[{PWR_CR:#x}] | {DBP:#x}\n"
)
ASK = _ACCESS + f"m[{RTC_BKP18R:#x}] = {MAINTENANCE_ASKED:#x}\nmachine.reset()\n"
CLEAR = _ACCESS + f"m[{RTC_BKP18R:#x}] = 0\nprint('MAINT', m[{RTC_BKP18R:#x}])\n"


def query(repl, code=QUERY, what="reading its maintenance marker"):
    """The marker register's value (NO_STM without the stm module)."""
    out = repl.exec(code, what=what).decode(errors="replace")
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[0] == "MAINT":
            return int(parts[1])
    raise FlashError(
        f"the board answered {out.strip()!r} when asked for its maintenance marker. Reset the "
        "board and run the command again."
    )


def start(repl, reopen, log):
    """The board behind `repl` (in its raw REPL) reset into a maintenance start: (ser, repl) of
    the session after it, whose `maintenance` says how it went: True (a maintenance start),
    False (not an stm32 board: no watchdog to stop, nothing was reset), None (reset, but its
    main.py did not take the marker). `console` keeps what the board said when first stopped
    (e.g. "ins: stopped"), `maintenance_console` what it said after the reset. reopen(): the
    board's port, opened anew."""
    state = query(repl)
    if state == NO_STM:
        repl.maintenance = False
        return repl.ser, repl
    if state == MAINTENANCE_ON:
        log("the board is in maintenance (loop and watchdog off) from an earlier start")
        repl.maintenance = True
        return repl.ser, repl
    log(
        f"resetting the board on {repl.port} into maintenance (the firmware's loop and "
        "watchdog off while its filesystem is written)"
    )
    try:
        repl.exec_no_follow(ASK, what="asking for a maintenance start")
    except (FlashError, OSError):  # serial.SerialException is an OSError
        pass  # the board reset before its acknowledgement came (a USB port goes at once)
    first = repl.console
    repl.ser.close()
    ser, new = _reconnect(reopen, repl)
    try:
        new.console = first
        state = query(new)
        if state == MAINTENANCE_ON:
            new.maintenance = True
            log("the board restarted in maintenance: loop and watchdog off")
            return ser, new
        if state != 0:
            query(new, CLEAR, "clearing its maintenance marker")
        new.maintenance = None
        if b"ins: stopped" in new.maintenance_console:
            log(
                "the board restarted and its firmware, older than this checkout's, started "
                "its loop: it does not know the maintenance start. Stopped (Ctrl-C) as before, "
                "its watchdog runs on: a flash write may be cut short by a watchdog reset "
                "(run the command again then)"
            )
        else:
            log("the board restarted without starting a firmware (no main.py): no watchdog runs")
        return ser, new
    except BaseException:
        ser.close()
        raise


def _reconnect(reopen, old):
    """The board's port opened again after its reset, its start's output read, and its raw
    REPL entered: (ser, BoardRepl)."""
    from tools.flash.repl import BoardRepl

    time.sleep(SETTLE_S)
    deadline = time.monotonic() + RESET_WAIT_S
    while True:
        try:
            ser = reopen()
            break
        except FlashError:
            if time.monotonic() > deadline:
                raise NotResponding(
                    f"the board on {old.port} did not come back within {RESET_WAIT_S:g} s of "
                    "its reset into maintenance. Check that it is powered and connected, "
                    "press its reset button (a reset starts the firmware) and run the "
                    "command again."
                ) from None
            time.sleep(0.2)
    try:
        new = BoardRepl(ser, timeout=old.timeout, port=old.port)
        said = _started(ser)
        new.enter()
        new.maintenance_console = said + new.console
        return ser, new
    except BaseException:
        ser.close()
        raise


def _started(ser):
    """What the board prints as it starts, once it is done: its REPL's prompt (a return is sent
    to have one: a USB port loses what the board printed before it was opened), or a pause
    after output (a firmware that started its loop), or BOOT_OVERALL_S."""
    ser.write(b"\r")
    data = bytearray()
    start = last = time.monotonic()
    while True:
        now = time.monotonic()
        if b">>> " in data and now - last > 0.1:
            break
        if (data and now - last > BOOT_QUIET_S) or now - start > BOOT_OVERALL_S:
            break
        n = ser.in_waiting
        if n:
            data += ser.read(n)
            last = time.monotonic()
        else:
            time.sleep(0.01)
    return bytes(data)
