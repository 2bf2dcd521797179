"""The boards an image is built for (python -m tools.image build --board B).

Every board is a definition kept in this folder (BOARD_DIR=): WEACT_F411_BLACKPILL wraps the
MicroPython tree's own board folder with one change (no REPL on USART1, the firmware's RS485
output; its pins.csv is the tree's, `pins_from`), NUCLEO_F411RE is written here (the vendored
tree does not carry it). Each entry also says how the board is flashed, for the messages of
tools.flash image.
"""

import dataclasses
import pathlib

HERE = pathlib.Path(__file__).resolve().parent


@dataclasses.dataclass(frozen=True)
class Board:
    name: str
    description: str
    board_dir: pathlib.Path | None  # None: ports/stm32/boards/<name> of the MicroPython tree
    dfu: str  # how to put it into its ROM DFU bootloader (or why not)
    pins_from: str | None = None  # take pins.csv from ports/stm32/boards/<this> of the tree


BOARDS = {
    b.name: b
    for b in (
        Board(
            "WEACT_F411_BLACKPILL",
            "WeAct STM32F411CEU6 'Black Pill' v3.1, 25 MHz crystal, no SPI flash "
            "(filesystem in internal flash); REPL on USB only (USART1 is the RS485 output)",
            HERE / "WEACT_F411_BLACKPILL",
            "on a WeAct Black Pill, hold BOOT0, press and release NRST, then release BOOT0 (the "
            "USB-C cable plugged into the PC)",
            pins_from="WEACT_F411_BLACKPILL",
        ),
        Board(
            "NUCLEO_F411RE",
            "ST NUCLEO-F411RE: 8 MHz clock from the ST-LINK, REPL on the ST-LINK's virtual COM "
            "port (USART2)",
            HERE / "NUCLEO_F411RE",
            "on a NUCLEO-F411RE there is no USB connector on the F411 (the board's USB port is "
            "the ST-LINK's), so flash it through the ST-LINK instead: copy firmware.bin to the "
            "NOD_F411RE drive the ST-LINK shows, or program firmware.hex with "
            "STM32CubeProgrammer or st-flash; DFU needs a USB cable wired to PA11/PA12 and "
            "BOOT0 tied high at reset",
        ),
    )
}
DEFAULT_BOARD = "WEACT_F411_BLACKPILL"
