"""The twin's bus (host_emulator/f411/bus.py, mmio.c): plain registers served in C, every other
access in the model, the same values either way."""

import pytest

from host_emulator.f411.bus import TwinError
from host_emulator.f411.dma import EN

DMA2 = 0x40026400
S0CR, S0NDTR, S0FCR = 0x10, 0x14, 0x24
SPI1, GPIOA, RCC_AHB1ENR = 0x40013000, 0x40020000, 0x40023830


def load(chip, addr, size=4):
    return int.from_bytes(chip.cpu.uc.mem_read(addr, size), "little")


def store(chip, addr, value, size=4):
    chip.cpu.uc.mem_write(addr, value.to_bytes(size, "little"))


def test_which_registers_c_serves(chip_for):
    chip = chip_for("USART")
    dma = chip.dma2.plain_words()
    assert dma[S0NDTR >> 2] == 3  # no behaviour: loads and stores in C
    assert dma[S0CR >> 2] == 1  # a write_ method (a stream starts): stores in Python
    assert dma[0x00] == 3  # LISR: read in C, and a store changes none of its bits (writable 0)
    assert dma[0x08 >> 2] == 1  # LIFCR clears LISR's flags: written in Python
    spi = chip.spi1.plain_words()
    assert spi[0] == 0  # CR1: SPI's bus_read and bus_write overrides are for it (OVERRIDES)
    assert spi[1] == 1  # CR2 has a write_ method
    gpio = chip.gpio["A"].plain_words()
    assert gpio[0x08 >> 2] == 1  # OSPEEDR: read in C, written in Python (the levels' cache)
    assert not any(p & 2 for p in gpio)
    inert = next(p for p in chip.bus.peripherals if p.NAME == "SPI2")
    assert not any(inert.plain_words())  # both overridden for every register: all in Python


def test_a_plain_register_holds_what_either_side_wrote(chip_for):
    chip = chip_for("USART")
    store(chip, RCC_AHB1ENR, load(chip, RCC_AHB1ENR) | 1 << 22)  # DMA2's clock on (Python)
    store(chip, DMA2 + S0NDTR, 0x12345)  # C: NDTR keeps its 16 bits
    assert chip.dma2.v[S0NDTR] == 0x2345
    chip.dma2.v[S0NDTR] = 0x0102  # the model's side
    assert load(chip, DMA2 + S0NDTR) == 0x0102
    assert load(chip, DMA2 + S0NDTR + 1, 1) == 0x01  # a byte of it, shifted as the bus does
    store(chip, DMA2 + S0NDTR + 1, 0xAB, 1)  # a byte store merges into the word
    assert chip.dma2.v[S0NDTR] == 0xAB02
    store(chip, DMA2 + S0FCR, 0xFFFFFFFF)  # writable bits 0x87 of FCR's reset value 0x21
    assert load(chip, DMA2 + S0FCR) == 0x21 & ~0x87 | 0x87
    store(chip, DMA2 + S0CR, 0x40)  # Python's writer, EN clear: stored, nothing starts
    assert load(chip, DMA2 + S0CR) == 0x40 and not chip.dma2.streams[0].active
    assert not load(chip, DMA2 + S0CR) & EN


def test_a_plain_register_with_its_clock_off_still_stops_the_run(chip_for):
    chip = chip_for("USART")
    assert not chip.rcc.enabled("AHB1ENR", 22)
    store(chip, DMA2 + S0NDTR, 5)  # C sends it to the model, which refuses it
    with pytest.raises(TwinError, match=r"write of DMA2_S0NDTR with the peripheral's clock off"):
        chip.run_for_ms(1)
