"""Entry point on the board: build the board, run the 5 ms loop forever.

The board's console (USB REPL) shows the start-up messages: the configuration used, and why
the IMU is not ready if it is not, then "ins: running ..." once the loop starts. Ctrl-C at the
console stops the loop and leaves the REPL usable: the watchdog, which cannot be stopped once
started, is then fed by a timer (App.stop). Ctrl-D (soft reset) starts the firmware again.
"""

import app
import board


def main():
    a = app.App(board)
    a.start()
    try:
        a.run()
    except KeyboardInterrupt:  # Ctrl-C at the console, e.g. from tools.flash deploy
        a.stop()


main()
