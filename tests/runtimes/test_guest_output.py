"""runtimes/guest_output.py: the report lines a MicroPython guest prints, read back."""

from host_emulator.runtimes.guest_output import GuestOutput


def test_statistics_come_in_one_line_or_one_per_key():
    one = GuestOutput(None)
    one.line('S {"ticks": 4, "overruns": 0}\r\n')
    several = GuestOutput(None)
    for text in ('S {"ticks": 4}\n', "P 4 4\n", 'S {"overruns": 0}\n'):
        several.line(text)
    assert one.stats == several.stats == {"ticks": 4, "overruns": 0}
    assert several.last_tick == 4 and several.other == []


def test_a_broken_statistics_line_is_kept_as_other_output():
    out = GuestOutput(None)
    out.line('S {"ticks": 4}')
    out.line('S {"overruns": ')
    assert out.stats == {"ticks": 4} and out.other == ['S {"overruns": ']
