"""The emulated Cortex-M4F: counting, exceptions, priorities, sleep (host_emulator/f411/cpu.py,
nvic.py, systick.py), on bare-metal programs (programs.c)."""

from conftest import run_until_done, word

HSI_HZ = 16_000_000


def test_systick_interrupts_every_reload_and_the_core_sleeps_between(chip_for):
    chip = chip_for("SYSTICK")
    chip.run(chip.clock.cycles_for_us(20_500))  # 20.5 ms of board time at 16 MHz
    # SysTick counts from the write of VAL: its n-th interrupt comes at n ms (+ start-up)
    assert word(chip, "counter") == 20
    assert chip.scs.systick.interrupts == 20
    # asleep most of the time: a few hundred instructions a tick, the rest WFI
    assert chip.clock.instructions < 20 * 400
    assert chip.cpu.sleeping_cycles > 0.95 * chip.clock.now()
    # each wake-up read VAL right after its interrupt: counted down by the handler's cycles
    vals = [word(chip, "data", i) for i in range(1, 20)]
    assert all(15000 < v < 16000 for v in vals), vals


def test_an_interrupt_preserves_the_registers_it_interrupts(chip_for):
    """The handler clobbers R0-R3, R12, S0-S15 and FPSCR every 400 cycles; the main loop's
    results equal those computed with SysTick off (the frame is stacked and unstacked as the
    core does, FP context included)."""
    chip = chip_for("PRESERVE")
    assert run_until_done(chip, 200)
    assert word(chip, "data", 0) > 1000  # interrupted many times
    assert word(chip, "result") == 1


def test_a_higher_priority_interrupt_preempts_basepri_and_primask_hold_them_back(chip_for):
    chip = chip_for("NESTING")
    assert run_until_done(chip, 10)
    n = word(chip, "result")
    assert [word(chip, "data", i) for i in range(n)] == [
        0x10, 0x30, 0x11, 0x12, 0x20,  # IRQ2 preempts IRQ0 at once; IRQ1 waits for IRQ0's end
        0x01, 0x02,  # BASEPRI at IRQ2's priority holds it back ...
        0x30, 0x03,  # ... until BASEPRI is raised above it: taken right after the MSR
        0x05, 0x20, 0x06,  # with PRIMASK set the pending IRQ1 ends WFI, and runs after CPSIE
    ]  # fmt: skip


def test_an_access_nobody_models_stops_the_run_naming_it_and_the_function(chip_for):
    import pytest

    from host_emulator.f411.bus import TwinError

    chip = chip_for("UNMODELLED")
    with pytest.raises(TwinError, match=r"TIM2 \(not modelled by the twin\), in read_timer\+"):
        run_until_done(chip, 10)
    chip = chip_for("UNMODELLED")
    chip.cpu.uc.mem_write(chip.image.address("data"), (1).to_bytes(4, "little"))
    chip.flash_write_raw(0x08000000, chip.image.data)  # (data is .bss: set after start-up)
    addr = chip.image.address("data")

    def set_flag(c):
        c.cpu.uc.mem_write(addr, (1).to_bytes(4, "little"))

    chip.hook("main", set_flag)
    with pytest.raises(TwinError, match=r"read of RCC\+0x0A0 \(0x400238A0\), a register the "
                       r"twin does not model, in read_rcc_reserved\+"):  # fmt: skip
        run_until_done(chip, 10)
