"""A stand-in for an STM32's ROM DFU bootloader on USB, for the flashing tests without a board.

`FakeDfuSe` is what pyusb's usb.core.find returns for a device: the descriptors pydfu reads
(configuration, interface class 0xFE subclass 1, the DFU functional descriptor with
wTransferSize, string descriptors with the DfuSe memory layout) and ctrl_transfer carrying the
DFU class requests as AN3156 describes the STM32 bootloader's DfuSe extension:

    DNLOAD block 0   a command: 0x21 + address (set the address pointer), 0x41 (+ address:
                     erase that sector; alone: mass erase); executed on the next GETSTATUS,
                     which answers dfuDNBUSY, then dfuDNLOAD-IDLE
    DNLOAD block n>1 data written at pointer + (n - 2) * wTransferSize: flash programming can
                     only clear bits (new = old AND data), so unerased sectors show
    DNLOAD, 0 bytes  leave DFU mode (dfuMANIFEST): the "board" then runs from 0x08000000
    UPLOAD block n>1 read wLength bytes at pointer + (n - 2) * wTransferSize (from dfuIDLE or
                     dfuUPLOAD-IDLE)
    GETSTATUS, CLRSTATUS, ABORT, GETSTATE

Faults to inject: `protect` (a range whose erase/write fails with errWRITE: a write-protected
sector), `flip` (an address whose programmed byte comes out inverted: a bad write that only a
read-back finds). It is not a real bootloader: timing, option bytes and the other alternate
settings are not modelled.
"""

import array
import struct

DNLOAD, UPLOAD, GETSTATUS, CLRSTATUS, GETSTATE, ABORT = 1, 2, 3, 4, 5, 6
IDLE, DNLOAD_SYNC, DNBUSY, DNLOAD_IDLE, MANIFEST_SYNC, MANIFEST = 2, 3, 4, 5, 6, 7
UPLOAD_IDLE, ERROR = 9, 10
OK, ERR_TARGET, ERR_WRITE, ERR_ERASE, ERR_ADDRESS = 0x00, 0x01, 0x03, 0x04, 0x08
F411_LAYOUT = "@Internal Flash  /0x08000000/04*016Kg,01*064Kg,03*128Kg"
BASE = 0x08000000


def sectors_of(layout):
    """[(start, size)] of a DfuSe layout string."""
    _name, addr, segs = layout.split("/")[:3]
    addr = int(addr, 0)
    out = []
    for seg in segs.split(","):
        n, rest = seg.split("*")
        size = int(rest[:-2]) * {"K": 1024, "M": 1 << 20}.get(rest[-2], 1)
        for _ in range(int(n)):
            out.append((addr, size))
            addr += size
    return out


class _Ctx:
    """pyusb's device context: claim_interface / dispose_resources go here."""

    def __init__(self):
        self.claimed = set()
        self.disposed = 0

    def managed_claim_interface(self, device, interface):
        self.claimed.add(interface)

    def dispose(self, device, close_handle=True):
        self.disposed += 1


class _Interface:
    bInterfaceClass = 0xFE
    bInterfaceSubClass = 0x01

    def __init__(self, alt, string_index, extra):
        self.bAlternateSetting = alt
        self.bInterfaceNumber = 0
        self.iInterface = string_index
        self.extra_descriptors = extra


class _Configuration:
    def __init__(self, interfaces):
        self._interfaces = interfaces
        self.extra_descriptors = []

    def __iter__(self):
        return iter(self._interfaces)

    def __getitem__(self, key):  # cfg[(interface, alternate setting)]
        number, alt = key
        return next(i for i in self._interfaces if i.bAlternateSetting == alt)

    def interfaces(self):
        return list(self._interfaces)


class FakeDfuSe:
    """The STM32F411's ROM bootloader (by default) with 512 KB of flash as a bytearray."""

    def __init__(
        self,
        vid=0x0483,
        pid=0xDF11,
        layout=F411_LAYOUT,
        transfer_size=2048,
        fill=0x5A,
        protect=None,
        flip=None,
    ):
        self.idVendor, self.idProduct = vid, pid
        self.bus, self.address = 1, 7
        self.layout = layout
        self.sectors = sectors_of(layout)
        self.size = sum(size for _a, size in self.sectors)
        self.memory = bytearray([fill]) * self.size  # what the previous firmware left
        self.transfer_size = transfer_size
        self.protect = protect
        self.flip = flip
        self.state, self.status = IDLE, OK
        self.pointer = BASE
        self.pending = None
        self.erased = []  # sector addresses, in order
        self.writes = 0  # data blocks programmed
        self.uploads = 0
        self.commands = []  # (kind, address) of every DfuSe command executed
        self.running = False  # left DFU mode: runs the flashed image
        self.configured = False
        self._ctx = _Ctx()
        functional = list(struct.pack("<BBBHHH", 9, 0x21, 0x0B, 255, transfer_size, 0x011A))
        strings = ["STMicroelectronics", "STM32  BOOTLOADER", "FAKE0001", layout,
                   "@Option Bytes  /0x1FFFC000/01*016 e"]  # fmt: skip
        self.strings = {i + 1: s for i, s in enumerate(strings)}
        self.langids = (0x0409,)
        self._cfg = _Configuration([_Interface(0, 4, functional), _Interface(1, 5, functional)])

    # -- what pyusb's Device offers pydfu -------------------------------------------------

    def __iter__(self):
        return iter([self._cfg])

    def __getitem__(self, index):
        return self._cfg

    def configurations(self):
        return [self._cfg]

    def set_configuration(self, configuration=None):
        self.configured = True

    def ctrl_transfer(self, bmRequestType, bRequest, wValue=0, wIndex=0, data_or_wLength=None,
                      timeout=None):  # fmt: skip
        if bmRequestType == 0x80 and bRequest == 6:  # GET_DESCRIPTOR (strings only)
            return self._string(wValue & 0xFF)
        if self.running:
            import usb.core

            raise usb.core.USBError("No such device (it left DFU mode)", errno=19)
        if bmRequestType == 0x21 and bRequest == DNLOAD:
            data = data_or_wLength
            if isinstance(data, str):
                data = data.encode("latin-1")
            return self._dnload(wValue, bytes(data or b""))
        if bmRequestType == 0xA1 and bRequest == UPLOAD:
            return self._upload(wValue, int(data_or_wLength))
        if bmRequestType == 0xA1 and bRequest == GETSTATUS:
            return self._getstatus()
        if bmRequestType == 0xA1 and bRequest == GETSTATE:
            return array.array("B", [self.state])
        if bmRequestType == 0x21 and bRequest == CLRSTATUS:
            self.state, self.status = IDLE, OK
            return 0
        if bmRequestType == 0x21 and bRequest == ABORT:
            if self.state != ERROR:
                self.state, self.pending = IDLE, None
            return 0
        raise AssertionError(f"unexpected request {bmRequestType:#x} {bRequest}")

    # -- the bootloader -----------------------------------------------------------------------

    def _string(self, index):
        if index == 0:
            body = b"".join(struct.pack("<H", x) for x in self.langids)
        else:
            body = self.strings[index].encode("utf-16-le")
        return array.array("B", bytes((len(body) + 2, 3)) + body)

    def _fail(self, status):
        self.state, self.status, self.pending = ERROR, status, None

    def _dnload(self, block, data):
        if self.state not in (IDLE, DNLOAD_IDLE):
            self._fail(ERR_TARGET)
            return 0
        if not data:
            self.pending = ("leave", None)
            self.state = MANIFEST_SYNC
            return 0
        self.pending = ("cmd", data) if block == 0 else ("data", (block, data))
        self.state = DNLOAD_SYNC
        return len(data)

    def _getstatus(self):
        if self.state == DNLOAD_SYNC:
            self._execute()
            if self.state != ERROR:
                self.state = DNBUSY
        elif self.state == DNBUSY:
            self.state = DNLOAD_IDLE
        elif self.state == MANIFEST_SYNC:
            self.state = MANIFEST
            self.running = True  # the bootloader jumps to the application
            return array.array("B", [OK, 0, 0, 0, MANIFEST, 0])
        return array.array("B", [self.status, 10, 0, 0, self.state, 0])

    def _offset(self, addr, n=1):
        off = addr - BASE
        if off < 0 or off + n > self.size:
            return None
        return off

    def _protected(self, addr, n):
        if self.protect is None:
            return False
        lo, hi = self.protect
        return addr < hi and addr + n > lo

    def _execute(self):
        kind, arg = self.pending
        self.pending = None
        if kind == "cmd":
            op, rest = arg[0], arg[1:]
            if op == 0x21 and len(rest) == 4:
                (addr,) = struct.unpack("<I", rest)
                if self._offset(addr) is None:
                    return self._fail(ERR_ADDRESS)
                self.pointer = addr
                self.commands.append(("set_address", addr))
            elif op == 0x41 and len(rest) == 4:
                (addr,) = struct.unpack("<I", rest)
                sector = next(((a, s) for a, s in self.sectors if a == addr), None)
                if sector is None:
                    return self._fail(ERR_ADDRESS)
                if self._protected(*sector):
                    return self._fail(ERR_ERASE)
                off = sector[0] - BASE
                self.memory[off : off + sector[1]] = b"\xff" * sector[1]
                self.erased.append(addr)
                self.commands.append(("erase", addr))
            elif op == 0x41 and not rest:
                self.memory[:] = b"\xff" * self.size
                self.commands.append(("mass_erase", None))
            else:
                return self._fail(ERR_TARGET)
        else:
            block, data = arg
            addr = self.pointer + (block - 2) * self.transfer_size
            off = self._offset(addr, len(data))
            if off is None or len(data) > self.transfer_size:
                return self._fail(ERR_ADDRESS)
            if self._protected(addr, len(data)):
                return self._fail(ERR_WRITE)
            old = self.memory[off : off + len(data)]
            new = bytearray(a & b for a, b in zip(old, data, strict=True))
            if self.flip is not None and addr <= self.flip < addr + len(data):
                new[self.flip - addr] ^= 0xFF
            self.memory[off : off + len(data)] = new
            self.writes += 1

    def _upload(self, block, length):
        if self.state not in (IDLE, UPLOAD_IDLE) or block < 2:
            self._fail(ERR_TARGET)
            return array.array("B")
        addr = self.pointer + (block - 2) * self.transfer_size
        off = self._offset(addr, length)
        if off is None or length > self.transfer_size:
            self._fail(ERR_ADDRESS)
            return array.array("B")
        self.state = UPLOAD_IDLE
        self.uploads += 1
        return array.array("B", self.memory[off : off + length])

    # -- for the tests ------------------------------------------------------------------------

    def read(self, addr, n):
        off = addr - BASE
        return bytes(self.memory[off : off + n])


def install(monkeypatch, *devices, no_backend=False):
    """Make usb.core.find see `devices` (or raise NoBackendError, as without libusb)."""
    import usb.core

    def find(find_all=False, custom_match=None, **kwargs):
        if no_backend:
            raise usb.core.NoBackendError("No backend available")
        found = [
            d
            for d in devices
            if all(getattr(d, k) == v for k, v in kwargs.items())
            and (custom_match is None or custom_match(d))
        ]
        return iter(found) if find_all else (found[0] if found else None)

    monkeypatch.setattr(usb.core, "find", find)
