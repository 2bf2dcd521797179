"""bench/profile.py: the per-function profile of a tick on the emulated Cortex-M4F."""

from host_emulator.bench import profile


def test_a_short_profile_counts_every_tick_and_the_kernels(capsys):
    assert profile.main(["--duration", "2", "--all-ticks"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    rows = {ln.split()[0]: ln.split()[1:] for ln in lines[3:] if ln[:1].isalpha()}
    assert out.splitlines()[1].startswith("400 ticks counted")
    assert rows["App.service"][0] == "1.000" and rows["BMI055.read"][0] == "1.000"
    assert rows["navk.bmi055_decode"][0] == "1.000"  # the native kernels are wrapped too
    tick = int(rows["App.service"][2].replace(",", ""))
    assert tick > int(rows["BMI055.read"][2].replace(",", "")) > 0


def test_bad_input_is_one_line(capsys):
    assert profile.main(["--scenario", "nowhere"]) == 1
    assert "unknown scenario" in capsys.readouterr().err
