"""The twin's instruction counter (host_emulator/f411/counter.c): where it may call back into
the CPU at an event instead of stopping. Unicorn cannot stop inside an IT block, so there the
counter must keep to the plain stop: an instruction it misses there would be taken as outside
and the tick's figures would change."""

from host_emulator.f411 import counter

IT_EQ_1 = 0xBF08  # it eq: one instruction
ITTTT_EQ = 0xBF01  # itttt eq: four
MOVS = 0x2001  # movs r0, #1 (16 bits)
MOV_W = (0xF04F, 0x0001)  # mov.w r0, #1 (32 bits)


def _in_it(code, h):
    ffi, lib = counter.load()
    return lib.twin_maybe_in_it(ffi.new("uint16_t[]", code), h)


def test_the_instructions_of_an_it_block_are_inside_it_and_no_other():
    code = [IT_EQ_1, MOVS, MOVS]
    assert [_in_it(code, h) for h in range(3)] == [0, 1, 0]  # the IT itself is outside


def test_a_four_instruction_block_is_decoded_through_its_32_bit_instructions():
    code = [ITTTT_EQ, *MOV_W, MOVS, MOVS, MOVS, MOVS]
    # halfwords 1 (mov.w), 3, 4, 5 start the block's four instructions; 2 is mov.w's second
    # half (no instruction starts there); 6 comes after the block
    assert [_in_it(code, h) for h in range(7)] == [0, 1, 0, 1, 1, 1, 0]


def test_hints_are_not_it_and_a_look_alike_is_only_a_maybe():
    assert _in_it([0xBF00, MOVS], 1) == 0  # nop: mask 0
    assert _in_it([0xBF30, MOVS], 1) == 0  # wfi
    # a 32-bit instruction whose second half reads as IT: "maybe" (the plain stop, exact)
    assert _in_it([0xF04F, IT_EQ_1, MOVS], 2) == 1
