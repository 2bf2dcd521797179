"""The one file that knows the hardware: pins, buses, baud rates, the timer.

Written for the stm32 port of MicroPython on an STM32F411, wired like the WMH601 (seed 001
section 4), with one pin table per board the image is built for (docs/image.md); the board is
told by the name the image gives itself (`sys.implementation._machine`, "NUCLEO-F411RE with
STM32F411xE"). Change a table, nothing else, for another wiring.

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

Only `machine` calls and keywords the stm32 port accepts are used (its ports/stm32/*.c and
extmod/machine_*.c are the spec; tests/firmware/test_machine_api.py checks this file against
them), so the host emulator's stand-in `machine` runs this file unchanged and so does the image
on the emulated STM32F411.
"""

import sys

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
    "led": "C13",  # on when navigating (seed 001 5.2 lights an LED too); active low
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
WDT_TIMEOUT_MS = 1000
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


def _transmitter(uart_id, uart, direct=_Direct):
    try:
        from drivers import uart_dma
    except ImportError:  # no `stm` module: not the stm32 port
        return direct(uart)
    if not uart_dma.supported(uart_id):
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
        """Tick timer and PPS interrupt off; a slow timer keeps feeding a started watchdog."""
        if self.timer is not None:
            self.timer.deinit()
            self.timer = None
        self.pps.irq(handler=None)
        if self.wdt is not None:
            self.timer = machine.Timer(
                -1, mode=machine.Timer.PERIODIC, freq=4, callback=self._feed_isr, hard=True
            )

    def _feed_isr(self, _timer):
        self.wdt.feed()

    def wdt_feed(self):
        if self.wdt is not None:
            self.wdt.feed()

    def navigating_led(self, on):
        if self.led is not None:
            self.led.value(0 if on else 1)
