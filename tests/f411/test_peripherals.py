"""The emulated STM32F411's peripherals (host_emulator/f411): timing and the errors a board
would hide, on bare-metal programs (programs.c)."""

import pytest
from conftest import run_until_done, word

from host_emulator.f411.bus import TwinError


def test_a_polled_usart_sends_at_its_baud_rate_and_the_wait_costs_that_time(chip_for):
    chip = chip_for("USART")
    sent = []
    chip.usart[1].on_tx.append(lambda b, at: sent.append((at, b)))
    assert run_until_done(chip, 50)
    assert bytes(b for _, b in sent) == b"abcdefghij"
    hz = chip.clock.hz
    char = 10 * (16_000_000 // 9600)  # 10 bits of BRR = 1666 cycles at 16 MHz
    starts = [at for at, _ in sent]
    assert [b - a for a, b in zip(starts, starts[1:], strict=False)] == [char] * 9
    # done after the last character ended (TC): ten characters from the first start
    t_done = chip.clock.now()
    assert starts[0] + 10 * char <= t_done < starts[0] + 10 * char + 200
    # the spinning was not emulated instruction by instruction: the bus fast-forwarded it
    assert chip.bus.polls_skipped >= 9
    assert chip.clock.instructions < 2000
    assert abs(t_done / hz - 10 * 10 / 9600) < 0.0005


def test_flash_erase_stalls_the_core_and_programming_clears_bits(chip_for):
    chip = chip_for("FLASH")
    chip.flash_write_raw(0x08008000, b"\x00" * 8)  # not erased before the program erases it
    assert run_until_done(chip, 400)
    assert word(chip, "data", 1) == 0xFFFFFFFF  # erased
    assert (word(chip, "data", 2), word(chip, "data", 3)) == (0x12345678, 0x9ABCDEF0)
    assert chip.flash_if.erases == 1
    # a 16 KB sector takes 250 ms (typical): the core stood still meanwhile
    assert chip.flash_if.stall_cycles >= 0.250 * 16_000_000
    assert chip.clock.us() > 250_000


def test_a_store_into_flash_without_programming_enabled_stops_the_run(chip_for):
    chip = chip_for("FLASH")
    chip.hook("main", lambda c: c.cpu.uc.mem_write(c.image.address("result"),
                                                  (7).to_bytes(4, "little")))  # fmt: skip
    with pytest.raises(TwinError, match=r"store of 4 byte\(s\) into flash at 0x08008004 without "
                       r"programming enabled \(FLASH_CR.PG\) in main\+"):  # fmt: skip
        run_until_done(chip, 400)
        chip.run_for_ms(1)


def test_the_watchdog_resets_the_chip_when_not_fed(chip_for):
    chip = chip_for("IWDG")
    reasons = []
    chip.on_reset.append(reasons.append)
    assert run_until_done(chip, 50)
    assert reasons == ["IWDG"]
    assert word(chip, "boots") == 2
    # the first boot saw the power-on flags, the second the watchdog's (RCC_CSR.IWDGRSTF)
    assert word(chip, "csr_at_boot", 1) & (1 << 27)  # PORRSTF
    assert not word(chip, "csr_at_boot", 1) & (1 << 29)
    assert word(chip, "csr_at_boot", 2) & (1 << 29)  # IWDGRSTF (RMVF cleared the others)
    assert not word(chip, "csr_at_boot", 2) & (1 << 27)
    # 80 counts of LSI / 4 at 32 kHz: 10 ms after the start
    t_reset = chip.resets[0][0] / chip.clock.hz
    assert 0.010 < t_reset < 0.0115


def test_the_backup_registers_survive_a_system_reset_and_need_dbp(chip_for):
    """RTC_BKP18R, where the firmware keeps its maintenance marker (firmware/board.py): a write
    without PWR_CR.DBP is ignored, as on the chip; with it, the value survives SYSRESETREQ
    (machine.reset()), which clears DBP. The reset, from code with interrupts masked and
    SysTick counting, restarts the core with PRIMASK and BASEPRI clear and leaves no SysTick
    interrupt behind (both left the image's next start without its millisecond tick)."""
    chip = chip_for("BACKUP")
    reasons = []
    chip.on_reset.append(reasons.append)
    assert run_until_done(chip, 50)
    assert reasons == ["SYSRESETREQ (NVIC_SystemReset)"]
    assert word(chip, "boots") == 2
    assert [word(chip, "kept", i) for i in range(5)] == [0, 0x2222, 0x2222, 0, 0x2222]
    assert (word(chip, "kept", 5), word(chip, "kept", 6)) == (0, 0)  # PRIMASK, BASEPRI
    assert word(chip, "kept", 7) == 0  # SysTick interrupts after the reset
