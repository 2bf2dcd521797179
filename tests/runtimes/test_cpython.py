"""The emulator on CPython: the emulated peripherals as the firmware's own drivers see them, a
short run of the unmodified loop, and the command line (outputs, bad input)."""

import json
import time

import numpy as np
import pytest

from common import firmware_env
from common.errors import FirmwareError
from common.proto import stimulus, stream
from host_emulator import __main__ as cli
from host_emulator.emulated_board import install_machine
from host_emulator.runtimes import cpython
from host_emulator.sim import board_input


@pytest.fixture(scope="module")
def highway():
    """45 s of highway_outage: 30 s standing, then accelerating (navigation starts)."""
    return board_input.simulate("highway_outage", 45.0, seed=1)


@pytest.fixture(scope="module")
def highway_run(highway, tmp_path_factory):
    return cpython.run(highway.stimulus, tmp_path_factory.mktemp("board"))


def test_the_firmware_driver_reads_the_stimulus_registers():
    """Registers set from a stimulus record reach the firmware's BMI055 driver unchanged
    (gyro int16, accel 12-bit left-justified with new_data), after its own start-up."""
    board_machine = install_machine()
    board_machine.power_on()
    import machine
    from drivers.bmi055 import BMI055

    assert machine is board_machine  # what the firmware imports
    spi = machine.SPI(1)
    cs_a, cs_g = machine.Pin("B6"), machine.Pin("B7")
    model = machine.Bmi055()
    model.attach(spi, cs_a, cs_g)
    imu = BMI055(spi, cs_a, cs_g, gyro_range_dps=500, accel_range_g=4)
    # written by the driver: range codes for 500 deg/s and 4 g
    assert model.gyro.regs[0x0F] & 0x07 == 2 and model.accel.regs[0x0F] & 0x0F == 0x05
    assert time.now_us() >= 30_000  # it waited for the gyro's start-up after the soft reset
    g = np.array([[123, -32768, 32767]])
    a = np.array([[-2048, 2047, 5]])
    regs = bytes(stimulus.gyro_registers(g)[0]) + bytes(stimulus.accel_registers(a)[0])
    model.set_registers(regs, 0, 6)
    model.set_temperature_raw(-7)
    assert imu.read() is True  # int16 and 12-bit limits: saturated
    assert list(imu.gyro) == [123, -32768, 32767] and list(imu.accel) == [-2048, 2047, 5]
    assert (imu.status >> 6) == 0b111  # new_data bits from the record
    assert imu.read_temperature() == -7


def test_the_uart_receive_ring_drops_what_does_not_fit():
    machine = install_machine()
    machine.power_on()
    port = machine.UART(2, 9600, rxbuf=16)
    port.feed(b"0123456789")
    port.feed(b"abcdefghij")
    assert port.any() == 16 and port.overflow == 4
    buf = bytearray(8)
    assert port.readinto(buf, 8) == 8 and bytes(buf) == b"01234567"
    assert port.readinto(bytearray(20)) == 8 and port.readinto(buf) is None


def test_a_short_run_sends_one_clean_frame_per_tick(highway, highway_run):
    run = highway_run
    d = stream.decode(run.out)
    assert run.ticks == 9000 and len(d.frames) == 9000 and len(d.ext) == 450
    assert d.bad_checksum == d.bad_crc == d.skipped_bytes == 0
    assert [f["counter"] for f in d.frames[:3]] == [0, 1, 2]
    # frame k carries record k's raw sensor counts (at the frame's scale)
    counts = stimulus.accel_counts(highway.stimulus.accel_regs)
    assert d.frames[100]["accel_g"][2] == pytest.approx(counts[100, 2] / 1024, abs=1e-4)
    # one GGA per second, a PPS edge per second while there is a fix
    assert sum(f["gga"] for f in d.frames) == 45
    assert sum(f["pps"] for f in d.frames) == 45
    states = [f["nav_state"] for f in d.frames]
    assert states[0] == 1 and states[-1] == 2  # it navigates once the car is moving
    assert run.stats["overruns"] == 0 and run.stats["gnss_rx_overflow"] == 0
    assert run.stats["wdt_feeds"] == 9000
    e = d.ext[-1]
    assert e["tick"] == 9000 and e["origin_h_m"] == pytest.approx(400.0, abs=30.0)


def test_a_firmware_exception_names_the_tick(highway, tmp_path, monkeypatch):
    firmware_env.install()
    import nav

    real = nav.Navigator.imu_counts  # the app's call

    def failing(self, g, a, s=False):
        if self.tick == 1234:
            raise ZeroDivisionError("float divide by zero")
        return real(self, g, a, s)

    monkeypatch.setattr(nav.Navigator, "imu_counts", failing)
    with pytest.raises(FirmwareError, match=r"at tick 1234 \(t = 6\.170 s\)") as e:
        cpython.run(highway.stimulus.head(2000), tmp_path)
    assert "ZeroDivisionError: float divide by zero" in str(e.value)
    assert "app.py" in str(e.value)  # the firmware's own traceback


def test_cli_lists_the_scenarios(capsys):
    assert cli.main(["scenarios"]) == 0
    out = capsys.readouterr().out
    assert "urban_drive" in out and "highway_outage" in out and "static" in out


def test_cli_run_writes_every_output(tmp_path, capsys):
    out = tmp_path / "run"
    assert cli.main(["run", "--scenario", "highway_outage", "--duration", "45", "--seed", "1",
                     "--out", str(out), "--quiet"]) == 0  # fmt: skip
    for name in ("frames.bin", "metrics.json", "report.md", "stimulus.bin", "trajectory.png",
                 "errors.png", "attitude.png", "biases.png"):  # fmt: skip
        assert (out / name).stat().st_size > 0, name
    m = json.loads((out / "metrics.json").read_text())
    keys = ("scenario duration_s seed runtime ticks wall_s realtime_factor horiz_rms_m "
            "vert_rms_m vel_rms_m_s roll_rms_deg pitch_rms_deg yaw_rms_deg gnss_horiz_rms_m "
            "outages gc_blocks_per_tick_mean gc_blocks_per_tick_max align_time_s frames "
            "frame_errors").split()  # fmt: skip
    assert all(k in m for k in keys)
    assert m["scenario"] == "highway_outage" and m["ticks"] == 9000 and m["frames"] == 9000
    assert m["frame_errors"] == 0 and m["runtime"] == "cpython"
    assert m["gc_blocks_per_tick_mean"] is None  # counted on the MicroPython runtime only
    assert 30.0 < m["align_time_s"] < 45.0
    # 10 s of navigating: the errors are real and small, not placeholders
    assert 0.0 < m["horiz_rms_m"] < 5.0 and 0.0 < m["vel_rms_m_s"] < 1.0
    assert 0.0 < m["yaw_rms_deg"] < 5.0
    assert m["outages"] == []  # the 60 s outage at 180 s is beyond these 45 s
    assert "highway_outage" in (out / "report.md").read_text()
    assert (out / "frames.bin").read_bytes()[:2] == b"\xeb\x90"
    summary = capsys.readouterr().out  # the newcomer's table
    # the firmware's error with GNSS beside GNSS alone over the same periods; the whole run apart
    gnss_row = next(r for r in summary.splitlines() if r.startswith("horizontal error with GNSS"))
    assert (
        f"{m['horiz_rms_gnss_m']:.2f} m" in gnss_row
        and f"{m['gnss_horiz_rms_m']:.2f} m" in gnss_row
    )
    whole_row = next(r for r in summary.splitlines() if r.startswith("horizontal error, whole"))
    assert f"{m['horiz_rms_m']:.2f} m" in whole_row
    assert "GNSS outage" not in summary and "report:" in summary


def test_cli_replays_its_own_stimulus_to_the_same_frames(tmp_path):
    a = tmp_path / "a"
    b = tmp_path / "b"
    assert cli.main(["run", "--scenario", "static", "--duration", "5", "--out", str(a),
                     "--quiet"]) == 0  # fmt: skip
    assert cli.main(["run", "--stimulus", str(a / "stimulus.bin"), "--out", str(b),
                     "--quiet"]) == 0  # fmt: skip
    assert (a / "frames.bin").read_bytes() == (b / "frames.bin").read_bytes()
    assert json.loads((b / "metrics.json").read_text())["scenario"] == "static"


@pytest.mark.parametrize(
    "argv, message, status",
    [  # a value of the command line is a usage error (2, as parity's); a bad file's is 1
        (["run", "--scenario", "moon_landing", "--out", "X"], "unknown scenario 'moon_landing'", 2),
        (["run", "--scenario", "static", "--duration", "-3", "--out", "X"], "--duration", 2),
        (["run", "--scenario", "static", "--duration", "0.001", "--out", "X"], "--duration", 2),
        (["run", "--scenario", "static", "--seed", "-1", "--out", "X"], "--seed", 2),
        (["run", "--stimulus", "MISSING", "--out", "X"], "cannot read stimulus file", 1),
        (["run", "--stimulus", "GARBAGE", "--out", "X"], "not a stimulus file", 1),
    ],
)
def test_cli_bad_input_is_one_clear_message(tmp_path, capsys, argv, message, status):
    (tmp_path / "GARBAGE").write_bytes(b"hello")
    argv = [str(tmp_path / a) if a in ("X", "MISSING", "GARBAGE") else a for a in argv]
    assert cli.main(argv) == status
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "X" / "metrics.json").exists()


def test_a_failed_run_leaves_no_report(tmp_path, capsys, monkeypatch):
    out = tmp_path / "run"
    out.mkdir()
    (out / "metrics.json").write_text("{}")  # from an earlier run
    firmware_env.install()
    import nav

    def broken(self, *a):
        raise ValueError("math domain error")

    monkeypatch.setattr(nav.Navigator, "imu_counts", broken)
    assert cli.main(["run", "--scenario", "static", "--duration", "2", "--out", str(out),
                     "--quiet"]) == 1  # fmt: skip
    err = capsys.readouterr().err
    assert "the firmware raised at tick 0" in err and "ValueError: math domain error" in err
    assert not (out / "metrics.json").exists() and not (out / "report.md").exists()
