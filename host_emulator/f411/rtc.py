"""RTC (RM0383 section 17) with its 20 backup registers: the calendar the image reads and sets.

The calendar (TR, DR, SSR) runs from the moment initialisation mode is left (ISR.INIT
cleared), on the twin's clock: seconds since then added to what was written, in BCD, with
PRER's synchronous prescaler for the sub-seconds. ISR.INITF follows INIT at once, RSF (the
shadow registers synchronised) and the write flags (ALRAWF, ALRBWF, WUTWF) read 1, INITS is
set once a year other than 0 has been written. WPR's key sequence (0xCA, 0x53) is checked: a
write to a protected register without it is ignored, as on the chip. Alarms, the wakeup
timer, time-stamp and tamper are stored, not run (enabling one stops the run). The backup
domain (these registers, RCC_BDCR) survives a system reset; RCC's BDRST clears it. The backup
registers BKPxR need no key (WPR does not protect them) but, like every register of the
backup domain, PWR_CR.DBP: written while it is clear (its value after any reset) they keep
what they hold, as on the chip.
"""

import datetime

from host_emulator.f411.bus import Peripheral

TR, DR, CR, ISR, PRER, WPR, SSR = 0x00, 0x04, 0x08, 0x0C, 0x10, 0x24, 0x28
INIT, INITF, RSF, INITS = 1 << 7, 1 << 6, 1 << 5, 1 << 4
_PROTECTED = {TR, DR, CR, PRER, 0x14, 0x18, 0x1C, 0x20, 0x2C, 0x3C, 0x44, 0x48}


def _bcd(n):
    return ((n // 10) << 4) | (n % 10)


def _unbcd(b):
    return (b >> 4) * 10 + (b & 0xF)


def _regs():
    r = [("TR", TR, 0), ("DR", DR, 0x2101), ("CR", CR, 0), ("ISR", ISR, 0x07),
         ("PRER", PRER, 0x007F00FF), ("WUTR", 0x14, 0xFFFF), ("CALIBR", 0x18, 0),
         ("ALRMAR", 0x1C, 0), ("ALRMBR", 0x20, 0), ("WPR", WPR, 0, 0), ("SSR", SSR, 0, 0),
         ("SHIFTR", 0x2C, 0, 0), ("TSTR", 0x30, 0, 0), ("TSDR", 0x34, 0, 0),
         ("TSSSR", 0x38, 0, 0), ("CALR", 0x3C, 0), ("TAFCR", 0x40, 0), ("ALRMASSR", 0x44, 0),
         ("ALRMBSSR", 0x48, 0)]  # fmt: skip
    r += [(f"BKP{i}R", 0x50 + 4 * i, 0) for i in range(20)]
    return tuple(r)


class Rtc(Peripheral):
    NAME = "RTC"
    BASE = 0x40002800
    REGISTERS = _regs()

    def __init__(self, chip):
        super().__init__(chip)
        self.backup_reset()

    def reset(self):
        if not hasattr(self, "_base"):  # power-on only: the backup domain keeps the rest
            super().reset()

    def backup_reset(self):
        super().reset()
        self._unlock = 0
        self._base = datetime.datetime(2000, 1, 1)
        self._since = 0  # cycle the calendar started from _base
        self._running = True
        self._calendar_set = False

    def _now(self):
        if not self._running:
            return self._base, 0
        elapsed = (self.clock.now() - self._since) / self.clock.hz
        s = int(elapsed)
        return self._base + datetime.timedelta(seconds=s), elapsed - s

    def read_TR(self):
        t, _ = self._now()
        return (_bcd(t.hour) << 16) | (_bcd(t.minute) << 8) | _bcd(t.second)

    def read_DR(self):
        t, _ = self._now()
        return ((_bcd(t.year - 2000) << 16) | ((t.isoweekday()) << 13) | (_bcd(t.month) << 8)
                | _bcd(t.day))  # fmt: skip

    def read_SSR(self):
        _, frac = self._now()
        prediv_s = self.v[PRER] & 0x7FFF
        return prediv_s - int(frac * (prediv_s + 1))

    def read_ISR(self):
        v = self.v[ISR] & (INIT | 0x3F00)
        if v & INIT:
            v |= INITF
        v |= RSF | 0x7  # RSF, WUTWF, ALRBWF, ALRAWF
        if self._calendar_set:
            v |= INITS
        return v

    def write_ISR(self, value):
        if not self._writable():
            return
        was = self.v[ISR] & INIT
        self.v[ISR] = value & (INIT | 0x3F00)
        if value & INIT and not was:
            self._base, _ = self._now()
            self._running = False
        elif was and not value & INIT:
            self._running = True
            self._since = self.clock.now()

    def write_WPR(self, value):
        value &= 0xFF
        if value == 0xCA:
            self._unlock = 1
        elif value == 0x53 and self._unlock == 1:
            self._unlock = 2
        else:
            self._unlock = 0

    def _writable(self):
        return self._unlock == 2 and self.chip.pwr.backup_writable()

    def _set_calendar(self, tr=None, dr=None):
        t = self._base
        if tr is not None:
            t = t.replace(hour=_unbcd((tr >> 16) & 0x3F), minute=_unbcd((tr >> 8) & 0x7F),
                          second=_unbcd(tr & 0x7F))  # fmt: skip
        if dr is not None:
            t = t.replace(year=2000 + _unbcd((dr >> 16) & 0xFF), month=_unbcd((dr >> 8) & 0x1F),
                          day=_unbcd(dr & 0x3F))  # fmt: skip
            self._calendar_set = (dr >> 16) & 0xFF != 0
        self._base = t

    def write_TR(self, value):
        if self._writable() and self.v[ISR] & INIT:
            self._set_calendar(tr=value)

    def write_DR(self, value):
        if self._writable() and self.v[ISR] & INIT:
            self._set_calendar(dr=value)

    def write_CR(self, value):
        if not self._writable():
            return
        if value & ((1 << 8) | (1 << 9) | (1 << 10) | (1 << 11)):  # ALRAE/ALRBE/WUTE/TSE
            self.chip.unsupported(f"RTC alarms, wakeup timer or time-stamp (CR = 0x{value:X})")
        self.v[CR] = value

    def _protected_store(self, off, value):
        if self._writable():
            self.v[off] = value

    def write_PRER(self, value):
        if self._writable() and self.v[ISR] & INIT:
            self.v[PRER] = value & 0x007F7FFF

    def write_CALR(self, value):
        self._protected_store(0x3C, value)

    def write_TAFCR(self, value):
        if value & 0x5:  # TAMP1E, TSE
            self.chip.unsupported("RTC tamper detection")
        self.v[0x40] = value


def _backup_writer(off):
    def write(self, value):
        if self.chip.pwr.backup_writable():
            self.v[off] = value

    return write


for _i in range(20):
    setattr(Rtc, f"write_BKP{_i}R", _backup_writer(0x50 + 4 * _i))
