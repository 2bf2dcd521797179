"""The twin's time: cycles of the core clock (HCLK), and the events the peripherals schedule.

Time advances three ways, and nothing else moves it:
- executed instructions, at a CPI (cycles per instruction) given as a fraction: MicroPython on
  an STM32F4 at 3 flash wait states runs at 1.6-2.4 (docs/benchmarks/cpi.md), one figure for
  every instruction;
- waiting: WFI until the next event, and a busy loop polling a peripheral flag, which the twin
  recognises and fast-forwards to the event that changes the flag (cpu.py, bus.py);
- exception entry and return, 12 cycles each (the Cortex-M4's latency at zero wait states).

The cycle count is the master clock; microseconds follow from HCLK, which the image sets (16 MHz
HSI at reset, 96 MHz once the PLL runs). Each change of HCLK anchors the conversion anew.

Events are (cycle, callback) in a heap; `Event.cancel()` drops one. The CPU stops exactly at the
next event's cycle (cpu.py) and fires every event that is due before it goes on.
"""

import heapq


class Event:
    __slots__ = ("cycle", "fn", "cancelled", "seq")

    def __init__(self, cycle, fn, seq):
        self.cycle = cycle
        self.fn = fn
        self.cancelled = False
        self.seq = seq

    def cancel(self):
        self.cancelled = True

    def __lt__(self, other):
        return (self.cycle, self.seq) < (other.cycle, other.seq)


class Clock:
    """Cycles = instructions x CPI + waited + exception cycles; events on that scale."""

    def __init__(self, counter, cpi=(241, 100), hz=16_000_000):
        self._counter = counter  # the CPU's instruction counter (cffi struct: .icount)
        self.cpi_num, self.cpi_den = cpi
        self.waited = 0  # cycles in WFI and in fast-forwarded polling loops
        self.exception_cycles = 0  # cycles of exception entry and return
        self._extra = 0  # waited + exception_cycles
        self.hz = hz
        self._anchor_cycle = 0  # HCLK changed at this cycle ...
        self._anchor_ps = 0  # ... at this time (picoseconds since reset)
        self._events = []
        self._seq = 0

    # -- the cycle count ----------------------------------------------------------------

    @property
    def instructions(self):
        return self._counter.icount

    def now(self):
        return self._counter.icount * self.cpi_num // self.cpi_den + self._extra

    def instructions_for(self, cycle):
        """The instruction count at which `now()` first reaches `cycle` (no waits between)."""
        need = cycle - self._extra
        if need <= 0:
            return 0
        return -(-need * self.cpi_den // self.cpi_num)

    def wait_until(self, cycle):
        """The CPU waits (WFI, a polling loop) until `cycle`."""
        d = cycle - self.now()
        if d > 0:
            self.waited += d
            self._extra += d

    def exception(self, cycles):
        self.exception_cycles += cycles
        self._extra += cycles

    # -- time in seconds ----------------------------------------------------------------

    def set_hz(self, hz):
        """HCLK changed (the image switched its system clock) now."""
        if hz == self.hz:
            return
        c = self.now()
        self._anchor_ps = self.ps(c)
        self._anchor_cycle = c
        self.hz = hz

    def ps(self, cycle=None):
        """Picoseconds since reset at `cycle` (default now)."""
        c = self.now() if cycle is None else cycle
        return self._anchor_ps + (c - self._anchor_cycle) * 1_000_000_000_000 // self.hz

    def us(self, cycle=None):
        return self.ps(cycle) / 1e6

    def cycle_at_us(self, t_us):
        """The first cycle at or after t_us microseconds since reset (HCLK as now)."""
        ps = t_us * 1_000_000 - self._anchor_ps
        return self._anchor_cycle + -(-ps * self.hz // 1_000_000_000_000)

    def cycles_for_us(self, us):
        return -(-us * self.hz // 1_000_000)

    # -- events -------------------------------------------------------------------------

    def at(self, cycle, fn):
        """fn() when the clock reaches `cycle`; an Event (cancel() drops it)."""
        self._seq += 1
        e = Event(cycle, fn, self._seq)
        heapq.heappush(self._events, e)
        return e

    def after(self, cycles, fn):
        return self.at(self.now() + cycles, fn)

    def next_event(self):
        """The cycle of the next pending event, or None."""
        ev = self._events
        while ev and ev[0].cancelled:
            heapq.heappop(ev)
        return ev[0].cycle if ev else None

    def fire_due(self):
        """Run every event due by now (in order; an event may schedule more)."""
        ev = self._events
        now = self.now()
        n = 0
        while ev and ev[0].cycle <= now:
            e = heapq.heappop(ev)
            if not e.cancelled:
                e.fn()
                n += 1
        return n
