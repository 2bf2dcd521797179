"""The board time of each decoded frame: `TickClock` numbers the frames by their counter
(gaps included) and anchors that numbering on the tick field of the extended frames."""

TICK_S = 0.005  # the firmware's tick (proto/stimulus.TICK_US)


class TickClock:
    """Board time of each frame. Tick T (app.ticks, 5 ms) sends the frame with counter
    (T // every - 1) mod 256 and, when it is due, the extended frame with counter
    (T // every) mod 256 and tick field T (host_emulator/session/walk.py). The counter is unwrapped
    (gaps included) into a frame number u, whose tick is (u + 1) * every + offset; each extended
    frame sets offset so that its frame's tick matches its tick field (0 until the first one:
    the board's start). `every` is the configuration's output_every_ticks."""

    def __init__(self, every=1):
        self.every = max(1, int(every))
        self.u = None
        self._last = None
        self.offset = 0
        self.anchored = False
        self.last_tick = None  # the last extended frame's tick field
        self.gap = 0  # counter gap before the last frame (0: it followed its predecessor)
        # frames lost in whole counter wraps (256 or a multiple in a row): invisible to the
        # counter, seen when the next extended frame's tick is ahead of the frames counted
        self.wrap_losses = 0

    def frame(self, counter):
        """The unwrapped frame number of the next frame, whose counter is `counter`."""
        if self.u is None:
            self.u = counter
            self.gap = 0
        else:
            self.gap = (counter - self._last - 1) & 0xFF
            self.u += self.gap + 1
        self._last = counter
        return self.u

    def ext(self, rec):
        """Anchor on an extended frame (after the frames before it were given to `frame`);
        True when its tick is below the last one's: the board restarted (its tick count
        starts again from 0), and the frames from here on are timed from that start."""
        restart = self.last_tick is not None and rec["tick"] < self.last_tick
        self.last_tick = rec["tick"]
        if self.u is None:
            return restart
        u_anchor = self.u - ((self._last - rec["counter"] + 1) & 0xFF)
        offset = (rec["tick"] // self.every) * self.every - (u_anchor + 1) * self.every
        if self.anchored and offset > self.offset and not restart:
            self.wrap_losses += (offset - self.offset) // self.every
        self.offset = offset
        self.anchored = True
        return restart

    def tick(self, u):
        return (u + 1) * self.every + self.offset

    def time_s(self, u):
        return self.tick(u) * TICK_S


class CaptureClock:
    """The capture's time (s) from a run's board time: 0 at the first record seen (joining a
    running board counts from there, not from the board's start) and monotonic across board
    restarts: a restarted run's tick 0 is placed at the last time handed out, since the
    board's tick count starts again from 0 and the pause while it rebooted is not in the
    stream."""

    def __init__(self):
        self.zero_s = None  # board time that is capture time 0 (of the current run)
        self.base_s = 0.0  # capture time of the current run's zero_s
        self.last_s = 0.0  # the latest capture time handed out for a frame

    def at(self, board_s):
        """Capture time of board time `board_s` of the current run, without advancing."""
        if self.zero_s is None:
            self.zero_s = board_s
        return self.base_s + board_s - self.zero_s

    def frame(self, board_s):
        """Capture time of a frame at board time `board_s`; never before an earlier frame's
        (a restart the stream showed late must not send the time back)."""
        self.last_s = max(self.last_s, self.at(board_s))
        return self.last_s

    def restart(self):
        """The board restarted: its new run's tick 0 is the last frame's capture time."""
        self.base_s = self.last_s
        self.zero_s = 0.0
