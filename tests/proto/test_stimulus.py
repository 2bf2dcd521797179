"""The stimulus file: round trip, register encoding, and clear errors for unusable files."""

import numpy as np
import pytest

from common.errors import EmulatorError
from common.proto import stimulus


def small():
    n = 5
    g = np.array([[1, -2, 3], [32767, -32768, 0], [0, 0, 0], [5, 6, 7], [-1, -1, -1]])
    a = np.array([[10, -5, 1024], [2047, -2048, 0], [0, 0, 1], [1, 2, 3], [-1, 0, 1]])
    chunks = [b"$GPGGA", b"", b",1,2*00\r\n", b"", b"x"]
    pps = [-1, 0, -1, 4999, -1]
    return stimulus.from_arrays({"source": "test", "config": {"gnss_baud": 9600}}, g, a,
                                np.arange(n) - 2, pps, chunks)  # fmt: skip


def test_registers_are_what_the_chip_presents():
    regs = stimulus.accel_registers([[1, -1, 2047]])
    # 1 << 4 | new_data = 0x0011; -1 -> 0xFFF0 | 1; 2047 -> 0x7FF0 | 1, LSB first
    assert bytes(regs[0]) == bytes([0x11, 0x00, 0xF1, 0xFF, 0xF1, 0x7F])
    assert bytes(stimulus.gyro_registers([[1, -2, 256]])[0]) == bytes([1, 0, 0xFE, 0xFF, 0, 1])
    s = small()
    assert stimulus.gyro_counts(s.gyro_regs).tolist()[1] == [32767, -32768, 0]
    assert stimulus.accel_counts(s.accel_regs).tolist()[1] == [2047, -2048, 0]
    with pytest.raises(ValueError):
        stimulus.accel_registers([[2048, 0, 0]])


def test_a_file_round_trips_exactly(tmp_path):
    s = small()
    path = tmp_path / "s.bin"
    s.write(path)
    r = stimulus.read(path)
    assert len(r) == 5 and r.header["ticks"] == 5 and r.header["source"] == "test"
    assert r.config == {"gnss_baud": 9600} and r.tick_us == 5000
    for name in ("gyro_regs", "accel_regs", "temp_raw", "pps_before_us", "uart_offsets"):
        assert np.array_equal(getattr(r, name), getattr(s, name)), name
    assert [r.uart_chunk(k) for k in range(5)] == [b"$GPGGA", b"", b",1,2*00\r\n", b"", b"x"]
    assert r.pps_before_us.tolist() == [-1, 0, -1, 4999, -1]
    h = r.head(3)
    assert len(h) == 3 and h.uart_bytes == b"$GPGGA,1,2*00\r\n" and h.to_bytes() != s.to_bytes()
    r3 = stimulus.from_bytes(h.to_bytes())  # a head is a file of its own
    assert r3.header["ticks"] == 3 and r3.header["duration_s"] == pytest.approx(0.015)
    assert r3.uart_bytes == h.uart_bytes and r3.pps_before_us.tolist() == [-1, 0, -1]


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda b: b"NOTSTIM!" + b[8:], "not a stimulus file"),
        (lambda b: b[:-20], "truncated"),
        (lambda b: b[:40] + bytes([b[40] ^ 1]) + b[41:], "CRC mismatch"),
        (lambda b: b"", "not a stimulus file"),
    ],
)
def test_unusable_files_say_what_is_wrong(tmp_path, damage, message):
    path = tmp_path / "bad.bin"
    path.write_bytes(damage(small().to_bytes()))
    with pytest.raises(stimulus.StimulusError, match=message) as e:
        stimulus.read(path)
    assert isinstance(e.value, EmulatorError) and str(path) in str(e.value)


def test_a_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(stimulus.StimulusError, match="cannot read stimulus file"):
        stimulus.read(tmp_path / "nope.bin")
