"""USB OTG FS (RM0383 section 22), enough for the image's start-up with no host attached.

The registers TinyUSB's DWC2 driver and the port's start-up use, with their reset values
(RM0383; the identification registers RM0383 leaves out as TinyUSB's dwc2_info.md lists them for
the F4 FS core: GSNPSID 0x4F54281A, core 2.81a, GHWCFG1-4): core and FIFO resets
(GRSTCTL.CSRST, TXFFLSH, RXFFLSH) complete at once and AHBIDL reads 1; the core stays in device
mode (GINTSTS.CMOD 0); interrupt flags clear by writing 1. No cable: no VBUS session, no bus
reset, no enumeration, so the OTG_FS interrupt (IRQ 67) never fires and the REPL over USB is not
reachable in the twin (the image's console is captured at its stdout, chip.py). Host mode, the
FIFOs' data windows and endpoint traffic are not modelled: an access stops the run.
"""

from host_emulator.f411.bus import Peripheral

GRSTCTL, GINTSTS = 0x010, 0x014


def _regs():
    r = [("GOTGCTL", 0x000, 0x00010000), ("GOTGINT", 0x004, 0), ("GAHBCFG", 0x008, 0),
         ("GUSBCFG", 0x00C, 0x00000A00), ("GRSTCTL", GRSTCTL, 0x80000000),
         ("GINTSTS", GINTSTS, 0x04000020), ("GINTMSK", 0x018, 0), ("GRXSTSR", 0x01C, 0, 0),
         ("GRXSTSP", 0x020, 0, 0), ("GRXFSIZ", 0x024, 0x200), ("DIEPTXF0", 0x028, 0x200),
         ("HNPTXSTS", 0x02C, 0x00080200, 0), ("GCCFG", 0x038, 0), ("CID", 0x03C, 0x00001200),
         ("GSNPSID", 0x040, 0x4F54281A, 0), ("GHWCFG1", 0x044, 0, 0),
         ("GHWCFG2", 0x048, 0x229DCD20, 0), ("GHWCFG3", 0x04C, 0x020001E8, 0),
         ("GHWCFG4", 0x050, 0x0FF08030, 0), ("HPTXFSIZ", 0x100, 0x02000600)]  # fmt: skip
    # DIEPTXF1-3 exist; ST's HAL (USB_DevInit) clears DIEPTXF1-15, 4-15 reserved on the F411
    r += [(f"DIEPTXF{i}", 0x100 + 4 * i, 0x02000400 if i < 4 else 0) for i in range(1, 16)]
    r += [("DCFG", 0x800, 0x02200000), ("DCTL", 0x804, 0), ("DSTS", 0x808, 0x10, 0),
          ("DIEPMSK", 0x810, 0), ("DOEPMSK", 0x814, 0), ("DAINT", 0x818, 0, 0),
          ("DAINTMSK", 0x81C, 0), ("DVBUSDIS", 0x828, 0x17D7), ("DVBUSPULSE", 0x82C, 0x5B8),
          ("DIEPEMPMSK", 0x834, 0)]  # fmt: skip
    for n in range(4):
        i, o = 0x900 + 0x20 * n, 0xB00 + 0x20 * n
        r += [(f"DIEPCTL{n}", i, 0x8000 if n == 0 else 0), (f"DIEPINT{n}", i + 8, 0x80, 0),
              (f"DIEPTSIZ{n}", i + 0x10, 0), (f"DTXFSTS{n}", i + 0x18, 0x200, 0),
              (f"DOEPCTL{n}", o, 0x8000 if n == 0 else 0), (f"DOEPINT{n}", o + 8, 0x80, 0),
              (f"DOEPTSIZ{n}", o + 0x10, 0)]  # fmt: skip
    r.append(("PCGCCTL", 0xE00, 0))
    return tuple(r)


class UsbOtgFs(Peripheral):
    NAME = "OTG_FS"
    BASE = 0x50000000
    SIZE = 0x1000
    CLOCK = ("AHB2ENR", 7)
    REGISTERS = _regs()

    def write_GRSTCTL(self, value):
        # CSRST, RXFFLSH, TXFFLSH complete at once; TXFNUM kept; AHBIDL reads 1
        self.v[GRSTCTL] = 0x80000000 | (value & 0x7C0)
        if value & 1:
            for off, r in self.regs.items():
                if off not in (GRSTCTL, 0x024, 0x028) and off < 0x800 and r.writable:
                    self.v[off] = r.reset

    def write_GINTSTS(self, value):
        self.v[GINTSTS] &= ~(value & 0xF077FC0A)  # the rc_w1 flags

    def write_DIEPINT0(self, value):
        self.v[0x908] &= ~value
