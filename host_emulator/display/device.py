"""The emulated UsartGPU on the board's display UART: what it is sent, when it answers, what
it shows at any moment of a run.

    gpu = UsartGpu((320, 240), baud=115200)
    gpu.receive(data, t_us)      # bytes whose last one has arrived at t_us (strict: usartgpu)
    gpu.replies(t_us)            # the OKs that have arrived at the board by t_us
    gpu.screen                   # display/screen.py's framebuffer

Timing. The manual says only that the screen answers `OK` once a batch is drawn, in up to
~200 ms. Nothing here is measured on a screen: a batch is taken to be drawn DRAW_BASE_US plus
DRAW_PER_COMMAND_US per command after its `\\r\\n` arrived, at most DRAW_MAX_US, and its OK to
take 4 characters at the UART's baud to come back. The firmware waits for none of it and allows
a round (0.64 s) before it counts an OK as missing (firmware/lib/status_page.py).

The demo loop: a screen that has received nothing DEMO_AFTER_US after power-up starts its demo
(`demo_at_us` says when; the picture is then not the board's). `play` replays a run's display
stream for pictures at chosen moments.
"""

from host_emulator.display.screen import Screen
from host_emulator.display.usartgpu import REPLY, Stream

DRAW_BASE_US = 5_000
DRAW_PER_COMMAND_US = 2_000
DRAW_MAX_US = 200_000
DEMO_AFTER_US = 10_000_000


class UsartGpu:
    def __init__(self, size, baud=115200):
        self.stream = Stream(size)
        self.screen = Screen(size)
        self.baud = baud
        self._due = []  # arrival times of the OKs not yet read
        self.first_byte_us = None
        self.demo_at_us = None
        self.commands = 0

    def receive(self, data, t_us):
        """`data` has arrived, its last byte at t_us (us since power-up): the batches it
        completes are drawn (DisplayError if the stream breaks the screen's rules) and their
        OKs scheduled."""
        if not data:
            return
        if self.first_byte_us is None:
            self.first_byte_us = t_us - len(data) * 10e6 / self.baud
            if self.first_byte_us > DEMO_AFTER_US:
                self.demo_at_us = DEMO_AFTER_US
        before = self.stream.batches
        cmds = self.stream.feed(data)
        for c in cmds:
            self.screen.draw(c)
        self.commands += len(cmds)
        batches = self.stream.batches - before
        if batches:
            per = len(cmds) / batches
            draw = min(DRAW_BASE_US + DRAW_PER_COMMAND_US * per, DRAW_MAX_US)
            back = len(REPLY) * 10e6 / self.baud
            self._due += [t_us + draw + back] * batches

    def replies(self, t_us):
        """The OK bytes that have reached the board by t_us (each once)."""
        n = sum(1 for t in self._due if t <= t_us)
        if not n:
            return b""
        self._due = [t for t in self._due if t > t_us]
        return REPLY * n

    def demo_check(self, t_us):
        """Note the demo loop if nothing has come by DEMO_AFTER_US and t_us is past it."""
        if self.first_byte_us is None and t_us > DEMO_AFTER_US and self.demo_at_us is None:
            self.demo_at_us = DEMO_AFTER_US


def play(data, marks, size, tick_s, at_s):
    """Pictures of the screen over a run: `data` the display stream, `marks` its (tick, end
    offset) after each tick that wrote (FirmwareRun.display_marks; tick -1: start-up), at_s
    the moments wanted (s from the first tick, ascending). [(t_s, Screen pixels copy)] at
    each moment, the screen as drawn by the batches complete by then."""
    stream = Stream(size)
    screen = Screen(size)
    out = []
    want = list(at_s)
    start = 0
    for tick, end in marks:
        t = max(tick, 0) * tick_s
        while want and want[0] < t:
            out.append((want.pop(0), screen.pix.copy()))
        for c in stream.feed(data[start:end]):
            screen.draw(c)
        start = end
    for t in want:
        out.append((t, screen.pix.copy()))
    return out
