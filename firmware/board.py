"""The one file that knows the hardware: pins, buses, baud rates, the timer.

Written for an STM32F411 "Black Pill" (MicroPython board WEACT_F411_BLACKPILL, v1.25+) wired like
the WMH601 (seed 001 section 4); NUCLEO_F411RE works with the same table (its Arduino-header
pins carry SPI1 and USART1/2/6). Change the PINS table, nothing else, for another wiring.

    BMI055 on SPI1 (mode 0, 10 MHz max: 4 MHz used), accel CS and gyro CS active low
    GNSS NMEA on USART2 (RX PA3, TX PA2), PPS on PB0 (rising edge at the top of the second)
    RS485 output on USART1 (TX PA9, RX PA10) with the transceiver's driver enable on PA8: the
    board is the bus's only talker, so DE stays high
    the 5 ms tick from machine.Timer (a virtual timer on the stm32 port)

Only `machine` APIs of the stm32 port are used, so the host emulator can install a fake
`machine` module and run this file unchanged.
"""

import machine

PINS = {
    "spi_id": 1,  # SPI1: SCK PA5, MISO PA6, MOSI PA7
    "cs_accel": "B6",
    "cs_gyro": "B7",
    "gnss_uart": 2,
    "pps": "B0",
    "out_uart": 1,
    "rs485_de": "A8",
    "led": "C13",  # on when navigating (seed 001 5.2 lights an LED too)
}
SPI_BAUD = 4_000_000
TICK_HZ = 200
WDT_TIMEOUT_MS = 1000
GNSS_RXBUF = 1024  # bytes of the GNSS UART's receive ring: what arrives beyond it is lost
CONFIG_PATH = "/flash/ins.cfg"


class Board:
    """The peripherals, created once. Nothing here runs per tick."""

    def __init__(self, gnss_baud=9600, out_baud=460800):
        p = PINS
        self.cs_accel = machine.Pin(p["cs_accel"], machine.Pin.OUT, value=1)
        self.cs_gyro = machine.Pin(p["cs_gyro"], machine.Pin.OUT, value=1)
        self.spi = machine.SPI(p["spi_id"], baudrate=SPI_BAUD, polarity=0, phase=0)
        # timeout=0: readinto returns at once with what has arrived (the loop must not wait)
        self.gnss_uart = machine.UART(
            p["gnss_uart"], baudrate=gnss_baud, rxbuf=GNSS_RXBUF, timeout=0
        )
        self.out_uart = machine.UART(p["out_uart"], baudrate=out_baud, txbuf=512)
        self.rs485_de = machine.Pin(p["rs485_de"], machine.Pin.OUT, value=1)
        self.pps = machine.Pin(p["pps"], machine.Pin.IN)
        self.led = machine.Pin(p["led"], machine.Pin.OUT, value=1)  # active low on the Black Pill
        self.timer = None
        self.wdt = None

    def start_tick(self, callback):
        """callback(timer) every 5 ms; it must only set a flag."""
        self.timer = machine.Timer(-1, mode=machine.Timer.PERIODIC, freq=TICK_HZ, callback=callback)

    def on_pps(self, handler):
        """handler(pin) on each PPS rising edge; it must only record the time."""
        self.pps.irq(trigger=machine.Pin.IRQ_RISING, handler=handler)

    def start_watchdog(self):
        self.wdt = machine.WDT(timeout=WDT_TIMEOUT_MS)

    def stop(self):
        """Tick timer and PPS interrupt off; a slow timer keeps feeding a started watchdog."""
        if self.timer is not None:
            self.timer.deinit()
            self.timer = None
        self.pps.irq(handler=None)
        if self.wdt is not None:
            self.timer = machine.Timer(
                -1, mode=machine.Timer.PERIODIC, freq=4, callback=self._feed_isr
            )

    def _feed_isr(self, _timer):
        self.wdt.feed()

    def wdt_feed(self):
        if self.wdt is not None:
            self.wdt.feed()

    def navigating_led(self, on):
        self.led.value(0 if on else 1)
