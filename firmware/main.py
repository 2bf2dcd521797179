"""Entry point on the board: build the board, run the 5 ms loop forever.

The board's console (USB REPL) shows the start-up messages: the configuration used, and why
the IMU is not ready if it is not, then "ins: running ..." once the loop starts. Ctrl-C at the
console stops the loop and leaves the REPL usable: the watchdog, which cannot be stopped once
started, is then fed by a timer (App.stop). Ctrl-D (soft reset) starts the firmware again:
with the watchdog running, through a watchdog reset (the start-up outlasts its 50 ms).

Without kernels (no usable lib/navk.mpy on a board whose image, as ours, freezes no Python
kernels) the firmware does not start: one line says why (`ins: cannot start: no kernels: ...`)
and the REPL stays the board's.

A maintenance start (board.maintenance_start: the board tools asked for it before resetting
the board, docs/deploy.md) starts neither the loop nor the watchdog: the console says so in
one line and the REPL is the board's, for writing its filesystem (a flash sector erase stalls
the CPU for longer than the watchdog's 50 ms). Ctrl-D or a reset starts the firmware.
"""

import board
import kern


def main():
    if board.maintenance_start():  # it says so on the console
        return
    try:
        import app
    except kern.Missing as e:  # no lib/navk.mpy, and an image without the Python kernels
        print("ins: cannot start:", e)
        return

    a = app.App(board)
    a.start()
    try:
        a.run()
    except KeyboardInterrupt:  # Ctrl-C at the console, e.g. from tools.flash deploy
        stop(a)


def stop(a):
    """App.stop, which a second Ctrl-C (the tools send two) must not cut short: the watchdog
    would be left without its feeding timer, and reset the board 50 ms later."""
    while True:
        try:
            a.stop()
            return
        except KeyboardInterrupt:
            pass


main()
