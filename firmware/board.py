"""The one file that knows the hardware: pins, buses, baud rates, the timer.

Written for the stm32 port of MicroPython on an STM32F411, wired like the WMH601
(docs/requirements.md, board and features), with one pin table per board the image is built for
(docs/image.md); the board is told by the name the image gives itself
(`sys.implementation._machine`, "NUCLEO-F411RE with STM32F411xE"). Change a table, nothing
else, for another wiring.

    BMI055 on SPI1 (mode 0, 10 MHz max: 4 MHz asked, 3 MHz given by the port's power-of-two
    prescalers at 96 MHz), accel CS and gyro CS active low
    GNSS NMEA on a UART (USART2 on the Black Pill; USART6 on the NUCLEO, whose USART2 is the
    REPL through the ST-LINK and cannot be re-created), PPS on PB0 (rising edge at the top of
    the second, a hard interrupt: its time is taken in the interrupt, not when the VM gets to it)
    RS485 output on USART1 (TX PA9, RX PA10) with the transceiver's driver enable on PA8: the
    board is the bus's only talker, so DE stays high
    the UsartGPU screen on USART6 when the `display` setting is on (the WMH601's wiring): on
    the Black Pill's STM32F411CE USART6 comes out only on PA11 (TX) and PA12 (RX), the USB
    pins, so a Black Pill with the screen on has no USB console once the loop starts (hold KEY
    at reset for MicroPython's safe mode to get it back: docs/display.md); the NUCLEO has no
    USART left (USART2 is the ST-LINK console), so no screen
    the 5 ms tick from machine.Timer(-1) (a soft timer on SysTick; a hard callback)
    the maintenance start's marker in the RTC's backup register BKP18R (`maintenance_start`)

Only `machine` calls and keywords the stm32 port accepts are used (its ports/stm32/*.c and
extmod/machine_*.c are the spec; tests/firmware/test_machine_api.py checks this file against
them), so the host emulator's stand-in `machine` runs this file unchanged and so does the image
on the emulated STM32F411.
"""

import sys

from micropython import const

import machine

# Pins and peripherals per board (the keys of BOARDS are the images' MICROPY_HW_BOARD_NAME)
_BLACKPILL = {
    "spi_id": 1,  # SPI1: SCK PA5, MISO PA6, MOSI PA7
    "cs_accel": "B6",
    "cs_gyro": "B7",
    "gnss_uart": 2,  # USART2: TX PA2, RX PA3
    "pps": "B0",
    "out_uart": 1,
    "rs485_de": "A8",
    # on when navigating (the original board's loop lights one too: docs/requirements.md,
    # original main loop); active low
    "led": "C13",
    "display_uart": 6,  # USART6: TX PA11, RX PA12 (the USB pins: see above)
}
_NUCLEO = {
    "spi_id": 1,  # SPI1: SCK PA5 (D13; also LED LD2, so no LED), MISO PA6 (D12), MOSI PA7 (D11)
    "cs_accel": "B6",  # D10
    "cs_gyro": "B7",  # morpho CN7 pin 21
    "gnss_uart": 6,  # USART6: TX PC6 (morpho CN10 pin 4), RX PC7 (D9)
    "pps": "B0",  # A3
    "out_uart": 1,  # USART1: TX PA9 (D8), RX PA10 (D2)
    "rs485_de": "A8",  # D7
    "led": None,  # LD2 is PA5, SPI1's clock; PC13 is the user button
    "display_uart": None,  # USART1, 2 and 6 are taken
}
BOARDS = {"WEACT_F411_BLACKPILL": _BLACKPILL, "NUCLEO-F411RE": _NUCLEO}
DEFAULT_BOARD = "WEACT_F411_BLACKPILL"  # an image that names no board of BOARDS


def board_name():
    """The BOARDS key of the board this runs on (DEFAULT_BOARD if the image names another)."""
    machine_name = getattr(sys.implementation, "_machine", "")
    for name in BOARDS:
        if machine_name.startswith(name):
            return name
    return DEFAULT_BOARD


NAME = board_name()
PINS = BOARDS[NAME]
SPI_BAUD = 4_000_000
TICK_HZ = 200
# The independent watchdog (IWDG): the loop feeds it every tick (5 ms); started, it cannot be
# stopped but by a reset. A flash write (a sector erase stalls the CPU 250-550 ms) outlasts it:
# the board tools write the filesystem only after a maintenance start (below, docs/health.md).
WDT_TIMEOUT_MS = 50
_FEED_HZ = const(80)  # the stopped loop's feeding timer: 4 feeds per WDT_TIMEOUT_MS
GNSS_RXBUF = 1024  # bytes of the GNSS UART's receive ring: what arrives beyond it is lost
CONFIG_PATH = "/flash/ins.cfg"


class _Direct:
    """The UART's own write, for a port without the DMA transmitter (poll does nothing):
    write(buf) is the UART's method itself; write_n(buf, n), buf's first n bytes, slices a
    memoryview, a heap object (the raw record's, when on)."""

    def __init__(self, uart):
        self.write = uart.write
        self.dropped = 0

    def write_n(self, buf, n):
        return self.write(memoryview(buf)[0:n])

    def poll(self):
        pass


class _Chars:
    """The screen's transmitter without DMA: write_n(buf, n) byte by byte (writechar), so a
    command of any length goes out without a slice (a heap object). The host emulator's
    stand-in takes no time for it; an stm32 board has the DMA transmitter instead."""

    def __init__(self, uart):
        self._put = uart.writechar
        self.write = uart.write
        self.dropped = 0

    def write_n(self, buf, n):
        put = self._put
        for i in range(n):
            put(buf[i])
        return n

    def poll(self):
        pass


# The maintenance start (docs/deploy.md): the board tools write _MAINT_ASKED into the RTC
# backup register BKP18R and reset the board (machine.reset()). The backup domain survives a
# system reset (RM0383: the battery backup domain), which stops the watchdog; writing it needs
# PWR_CR.DBP (the PWR clock on). main.py, first thing, calls maintenance_start(): the marker
# found, it answers _MAINT_ON and the start is a maintenance start (neither the loop nor the
# watchdog); any other value is cleared, so that the next start, a reset or a soft reset
# (Ctrl-D), is a normal one. BKP19R is the port's (MICROPY_HW_CLK_LAST_FREQ,
# ports/stm32/powerctrl.c); nothing in the port touches BKP18R. Constants, not globals: the
# board module's dictionary stays as it was (tools/flash/maintenance.py has the same values).
_RTC_BKP18R = const(0x40002898)  # RTC 0x40002800 + BKP0R's 0x50 + 4 x 18
_PWR_CR = const(0x40007000)
_DBP = const(0x100)
_RCC_APB1ENR = const(0x40023840)
_PWREN = const(0x10000000)
_MAINT_ASKED = const(0x2D4D4E54)  # the tools' request
_MAINT_ON = const(0x2D4D4E4F)  # the answer: this start is a maintenance start


def maintenance_start(mem32=None):
    """Whether this start is a maintenance start: the marker _MAINT_ASKED in BKP18R (replaced
    by _MAINT_ON, which the tools read back; the console told, in one line); otherwise the
    register is cleared (a normal start). mem32: stm.mem32, or a stand-in with its registers
    (the virtual board's); without the `stm` module (not the stm32 port) no start is one."""
    if mem32 is None:
        try:
            import stm
        except ImportError:
            return False
        mem32 = stm.mem32
    v = mem32[_RTC_BKP18R]
    if v == 0:
        return False  # a normal start, nothing to clear
    mem32[_RCC_APB1ENR] = mem32[_RCC_APB1ENR] | _PWREN
    mem32[_PWR_CR] = mem32[_PWR_CR] | _DBP  # backup-domain write access
    if v != _MAINT_ASKED:
        mem32[_RTC_BKP18R] = 0
        return False
    mem32[_RTC_BKP18R] = _MAINT_ON
    print(
        "ins: maintenance start (asked by the board tools): loop and watchdog off; "
        "Ctrl-D or a reset starts the firmware"
    )
    return True


def _transmitter(uart_id, uart, direct=_Direct):
    from drivers import uart_dma

    if not uart_dma.supported(uart_id):  # not the stm32 port (no `stm`), or not this UART
        return direct(uart)
    return uart_dma.DmaTx(uart_id)


class Board:
    """The peripherals, created once. Nothing here runs per tick but `idle`."""

    def __init__(self, gnss_baud=9600, out_baud=460800):
        p = PINS
        self.cs_accel = machine.Pin(p["cs_accel"], machine.Pin.OUT, value=1)
        self.cs_gyro = machine.Pin(p["cs_gyro"], machine.Pin.OUT, value=1)
        self.spi = machine.SPI(p["spi_id"], baudrate=SPI_BAUD, polarity=0, phase=0)
        # timeout=0: readinto returns at once with what has arrived (the loop must not wait)
        self.gnss_uart = machine.UART(
            p["gnss_uart"], baudrate=gnss_baud, rxbuf=GNSS_RXBUF, timeout=0
        )
        self.out_uart = machine.UART(p["out_uart"], baudrate=out_baud)
        # what the loop writes to: the UART's DMA on the stm32 port (a tick then never waits
        # for the line), else the UART itself (the host emulator's stand-in)
        self.out = _transmitter(p["out_uart"], self.out_uart)
        self.rs485_de = machine.Pin(p["rs485_de"], machine.Pin.OUT, value=1)
        self.pps = machine.Pin(p["pps"], machine.Pin.IN)
        self.led = None
        if p["led"] is not None:
            self.led = machine.Pin(p["led"], machine.Pin.OUT, value=1)  # off (active low)
        self.timer = None
        self.wdt = None
        self.display_uart = None
        self.display = None

    def start_display(self, baud):
        """The screen's UART and transmitter (display_uart, display), if this board has a
        UART for it (True); else False. Its receive ring holds the screen's OKs (timeout=0:
        read when they are there)."""
        uart_id = PINS["display_uart"]
        if uart_id is None:
            return False
        self.display_uart = machine.UART(uart_id, baudrate=baud, rxbuf=64, timeout=0)
        self.display = _transmitter(uart_id, self.display_uart, _Chars)
        return True

    def start_tick(self, callback):
        """callback(timer) every 5 ms, in the interrupt (hard): it must only count."""
        self.timer = machine.Timer(
            -1, mode=machine.Timer.PERIODIC, freq=TICK_HZ, callback=callback, hard=True
        )

    def on_pps(self, handler):
        """handler(pin) on each PPS rising edge, in the interrupt: it must only record the time."""
        self.pps.irq(trigger=machine.Pin.IRQ_RISING, handler=handler, hard=True)

    def start_watchdog(self):
        self.wdt = machine.WDT(timeout=WDT_TIMEOUT_MS)

    def idle(self, app):
        """Sleep until the next interrupt unless a tick is due (app.due). The check and the
        sleep run with interrupts masked, and a pending interrupt still ends the sleep (WFI),
        so a tick that comes between them is not slept through. Queued output is started
        first (the DMA transmitter has no interrupt of its own)."""
        self.out.poll()
        if self.display is not None:
            self.display.poll()
        s = machine.disable_irq()
        if not app.due:
            machine.idle()
        machine.enable_irq(s)

    def stop(self):
        """Tick timer and PPS interrupt off; a timer keeps feeding a started watchdog, 4 times
        per timeout (every 12 ms, the port's 1000 // 80: a hard callback on SysTick, which a
        flash erase stalls).
        Interrupts unmasked first: a Ctrl-C pending when `idle` masked them raises in its
        masked section (the VM checks at the `if` after disable_irq), and with them masked
        SysTick stops, the feeding timer too: the emulated STM32F411's watchdog reset the
        board 40 ms after such a Ctrl-C. (The port's enable_irq takes a bool, True: enabled,
        ports/stm32/irq.c; disable_irq returns whether they were.)"""
        machine.enable_irq(True)
        if self.timer is not None:
            self.timer.deinit()
            self.timer = None
        self.pps.irq(handler=None)
        if self.wdt is not None:
            self.timer = machine.Timer(
                -1, mode=machine.Timer.PERIODIC, freq=_FEED_HZ, callback=self._feed_isr, hard=True
            )

    def _feed_isr(self, _timer):
        self.wdt.feed()

    def wdt_feed(self):
        if self.wdt is not None:
            self.wdt.feed()

    def navigating_led(self, on):
        if self.led is not None:
            self.led.value(0 if on else 1)
