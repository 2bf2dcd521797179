"""SysTick, the Cortex-M4's 24-bit down-counter (ARMv7-M B3.3; registers in nvic.py's Scs).

Counting: enabled, it counts down once per HCLK cycle (CLKSOURCE = 1) or per 8 (CLKSOURCE =
0); from 0 it reloads LOAD on the next count, so it wraps every LOAD + 1 counts. Reaching 0 sets
COUNTFLAG (cleared by reading CTRL or writing VAL) and, with TICKINT, makes the SysTick
exception pending: the port's 1 ms tick (HAL's uwTick, the soft timers, ticks_us, which reads VAL
between ticks). A write to VAL clears it to 0 (no COUNTFLAG, no exception); it reloads on the
next count. VAL is computed from the cycle count when read; an event is scheduled only for the
next zero while TICKINT is set.
"""

CTRL, LOAD = 0x010, 0x014
ENABLE, TICKINT, CLKSOURCE, COUNTFLAG = 1, 2, 4, 1 << 16


class SysTick:
    def __init__(self, scs):
        self.scs = scs
        self.clock = scs.clock
        self._reload_at = None  # the count at which VAL == LOAD (after a reload); None: stopped
        self._val = 0  # VAL while stopped
        self._flags_seen = 0  # zeros counted up to the last clear of COUNTFLAG
        self._flag = False  # COUNTFLAG set while stopped
        self._event = None
        self.interrupts = 0

    def reset(self):
        """A system reset: stopped, and its pending zero dropped (left on the clock, it would
        make a SysTick interrupt of the old count after the reset and reschedule over the new
        one: the port's millisecond tick running fast)."""
        if self._event is not None:
            self._event.cancel()
        self.__init__(self.scs)

    def _ctrl(self):
        return self.scs.v[CTRL]

    def _div(self):
        return 1 if self._ctrl() & CLKSOURCE else 8

    def _load(self):
        return self.scs.v[LOAD]

    def _counts(self):
        return self.clock.now() // self._div()

    def _zeros(self, counts):
        """Zeros reached from the last reload up to count `counts`."""
        if self._reload_at is None:
            return 0
        d = counts - self._reload_at - self._load()
        return 0 if d < 0 else d // (self._load() + 1) + 1

    def read_val(self):
        if self._reload_at is None:
            return self._val
        d = self._counts() - self._reload_at
        if d < 0:
            return 0  # written to 0, reloads on the next count
        return self._load() - d % (self._load() + 1)

    def read_ctrl(self):
        v = self._ctrl() & 7
        if self._reload_at is not None:
            z = self._zeros(self._counts())
            if z > self._flags_seen:
                v |= COUNTFLAG
            self._flags_seen = z
        elif self._flag:
            v |= COUNTFLAG
        self._flag = False
        return v

    def write_ctrl(self, value):
        was = self._ctrl() & ENABLE
        cur = self.read_val() if was else self._val
        self.scs.v[CTRL] = value & 7
        if value & ENABLE:
            # the next count reloads from 0, or counts down from the current value
            now = self._counts()
            self._reload_at = now + 1 if cur == 0 else now - (self._load() - cur)
            self._flags_seen = self._zeros(now)
        else:
            self._val = cur
            self._reload_at = None
        self._schedule()

    def write_val(self):
        self._flag = False
        if self._reload_at is not None:
            now = self._counts()
            self._reload_at = now + 1
            self._flags_seen = 0
        else:
            self._val = 0
        self._schedule()

    def reload_changed(self):
        if self._reload_at is not None:
            # the running count keeps its value; later wraps use the new LOAD
            cur = self.read_val()
            now = self._counts()
            self._reload_at = now + 1 if cur == 0 else now - (self._load() - cur)
            self._flags_seen = self._zeros(now)
            self._schedule()

    def _schedule(self):
        if self._event is not None:
            self._event.cancel()
            self._event = None
        if self._reload_at is None or not self._ctrl() & TICKINT:
            return
        self._event = self.clock.at(self.next_zero_cycle(), self._on_zero)

    def period_cycles(self):
        return (self._load() + 1) * self._div()

    def next_zero_cycle(self):
        """The cycle of the next zero (the next SysTick interrupt), or None when stopped."""
        if self._reload_at is None:
            return None
        z = self._zeros(self._counts())
        return (self._reload_at + self._load() + z * (self._load() + 1)) * self._div()

    def _on_zero(self):
        self._event = None
        self.interrupts += 1
        self.scs.set_pending(15)
        self._schedule()
