"""Entry point on the board: build the board, run the 5 ms loop forever.

The board's console (USB REPL) shows the start-up messages: the configuration used, and why
the IMU is not ready if it is not. Ctrl-C at the console stops the loop (the watchdog then
resets the board within a second unless the REPL disables it: deploy tools stop it first).
"""

import app
import board


def main():
    a = app.App(board)
    a.start()
    a.run()


main()
