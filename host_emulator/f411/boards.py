"""The boards the image is built for, as the twin wires them: the crystal, the button, and
where the project's hardware (firmware/board.py's pin tables) is connected. A test checks that
these wirings and firmware/board.py's BOARDS agree.

    hse_hz          the HSE clock: the Black Pill's 25 MHz crystal; the NUCLEO's 8 MHz from
                    the ST-LINK's MCO (bypass)
    button          (port, pin): the user button, released: pulled high (the Black Pill's
                    KEY on PA0 by the internal pull-up the port enables; the NUCLEO's B1 on
                    PC13 by its external pull-up). Held low at reset, the port enters its
                    boot-mode selection, which no test wants.
    repl_uart       the USART of the image's REPL, or None (the Black Pill's is on USB)
    spi, cs_accel, cs_gyro, gnss_uart, pps, out_uart, rs485_de, led, display_uart: as
                    firmware/board.py (display_uart: the UsartGPU screen's USART, or None)
"""

from dataclasses import dataclass


@dataclass(frozen=True)
class Board:
    name: str  # the image's BOARD (tools/image/boards)
    machine: str  # what the image calls itself (MICROPY_HW_BOARD_NAME)
    hse_hz: int
    button: tuple
    repl_uart: int | None
    spi: int
    cs_accel: str
    cs_gyro: str
    gnss_uart: int
    pps: str
    out_uart: int
    rs485_de: str
    led: str | None
    display_uart: int | None


BOARDS = {
    "WEACT_F411_BLACKPILL": Board("WEACT_F411_BLACKPILL", "WEACT_F411_BLACKPILL", 25_000_000,
                                  ("A", 0), None, 1, "B6", "B7", 2, "B0", 1, "A8", "C13", 6),
    "NUCLEO_F411RE": Board("NUCLEO_F411RE", "NUCLEO-F411RE", 8_000_000, ("C", 13), 2, 1, "B6",
                           "B7", 6, "B0", 1, "A8", None, None),
}  # fmt: skip


def get(name):
    from common.errors import EmulatorError

    b = BOARDS.get(name)
    if b is None:
        raise EmulatorError(f"no board {name!r} in the twin: choose {', '.join(BOARDS)}")
    return b
