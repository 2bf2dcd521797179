"""IWDG, the independent watchdog (RM0383 section 17), clocked by the LSI (32 kHz typical,
DS10314; the twin takes it as exactly 32,000 Hz).

KR: 0xCCCC starts it (it cannot be stopped but by a reset), 0xAAAA reloads the counter from
RLR (a feed), 0x5555 opens PR and RLR for writing. The 12-bit counter counts down at LSI / (4
x 2^PR); at 0 the chip resets (RCC_CSR.IWDGRSTF). SR.PVU/RVU are set for 5 LSI cycles after a
write of PR/RLR (RM0383: the update crosses into the LSI domain). `feeds` keeps every feed's
cycle so that a run can report the watchdog's margin: the longest gap between feeds against
the timeout.
"""

from host_emulator.f411.bus import Peripheral, TwinError

LSI_HZ = 32_000
KR, PR, RLR, SR = 0x00, 0x04, 0x08, 0x0C


class Iwdg(Peripheral):
    NAME = "IWDG"
    BASE = 0x40003000
    REGISTERS = (
        ("KR", 0x00, 0, 0),
        ("PR", 0x04, 0, 0),
        ("RLR", 0x08, 0x0FFF, 0),
        ("SR", 0x0C, 0, 0),
    )

    def reset(self):
        """A system reset stops the watchdog: its pending expiry goes too."""
        super().reset()
        if getattr(self, "_expiry", None) is not None:
            self._expiry.cancel()
        self.running = False
        self._unlocked = False
        self._busy_until = 0
        self._expiry = None
        self.last_feed = None
        self.longest_gap = 0  # cycles between two feeds (or the start and the first)
        self.feeds = 0

    def timeout_cycles(self):
        div = 4 << (self.v[PR] & 7)
        return (self.v[RLR] + 1) * div * self.clock.hz // LSI_HZ

    def timeout_ms(self):
        return (self.v[RLR] + 1) * (4 << (self.v[PR] & 7)) * 1000 / LSI_HZ

    def _reload(self):
        now = self.clock.now()
        if self.last_feed is not None:
            self.longest_gap = max(self.longest_gap, now - self.last_feed)
        self.last_feed = now
        if self._expiry is not None:
            self._expiry.cancel()
        self._expiry = self.clock.at(now + self.timeout_cycles(), self._bite)

    def _bite(self):
        self._expiry = None
        self.chip.request_reset("IWDG", watchdog=True)

    def write_KR(self, value):
        value &= 0xFFFF
        if value == 0xCCCC:
            self.running = True
            self._reload()
        elif value == 0xAAAA:
            self.feeds += 1
            self._unlocked = False
            if self.running:
                self._reload()
        elif value == 0x5555:
            self._unlocked = True
        else:
            self._unlocked = False

    def _update(self, off, value, mask):
        if not self._unlocked:
            return  # write-protected: ignored as on the chip
        self.v[off] = value & mask
        self._busy_until = self.clock.now() + 5 * self.clock.hz // LSI_HZ

    def write_PR(self, value):
        self._update(PR, value, 7)

    def write_RLR(self, value):
        self._update(RLR, value, 0xFFF)

    def read_SR(self):
        return 3 if self.clock.now() < self._busy_until else 0

    def next_change(self, off):
        if off == SR and self.clock.now() < self._busy_until:
            return self._busy_until
        return None

    def margin(self):
        """(longest gap between feeds, timeout) in ms, or None before it started."""
        if not self.running:
            return None
        if self.longest_gap == 0 and self.last_feed is None:
            raise TwinError("IWDG running without a reload")
        hz = self.clock.hz
        return self.longest_gap * 1000 / hz, self.timeout_ms()
