"""The simulated receiver's byte stream: sentences the firmware's parser reads back to the exact
fix, byte timing at the baud rate, damaged sentences, PPS per tick, the stimulus it makes."""

import dataclasses

import numpy as np
import pytest

from common import firmware_env
from host_emulator.sim import board_input, gnss, nmea, trajectory

firmware_env.install()
from drivers.gnss import Nmea  # noqa: E402


@pytest.fixture(scope="module")
def drive():
    truth = trajectory.SCENARIOS["urban_drive"](120.0, 3)
    return truth, gnss.simulate(truth, seed=3)


def parse_epochs(data):
    p = Nmea()
    out = []
    for i in range(0, len(data), 7):  # small chunks, as the loop reads them
        chunk = data[i : i + 7]
        p.feed(chunk, len(chunk))
        if p.epoch_take():
            out.append(
                (p.epoch_utc_ms, p.epoch_quality, p.epoch_lat_e7, p.epoch_lon_e7(),
                 p.epoch_alt_mm + p.epoch_sep_mm, p.epoch_hdop_x100, p.epoch_speed_mm_s,
                 p.epoch_course_cdeg, p.epoch_nsat)
            )  # fmt: skip
    return p, out


def test_the_parser_reads_back_every_fix_exactly(drive):
    truth, g = drive
    g = dataclasses.replace(g, model=dataclasses.replace(g.model, corrupt_per_sentence=0.0))
    epochs, damaged = nmea.stream(g)
    assert damaged == 0 and len(epochs) == len(g)
    p, got = parse_epochs(b"".join(d for _, d in epochs))
    assert p.rejected() == 0 and len(got) == len(g)
    assert {q for _, q, *_ in got} == {1, 2}  # DGPS segments appear in 120 s at this seed
    for fx, e in zip(g, got, strict=True):
        assert e[0] == (2 * 3600 + round(fx.t_fix_s)) * 1000  # utc_start 02:00:00
        assert e[1] == fx.quality
        if fx.quality == 0:
            continue
        assert (e[2], e[3]) == (fx.lat_e7, fx.lon_e7)  # six minute decimals: exact
        assert abs(e[4] - 1000 * fx.h_m) <= 1  # ellipsoidal = MSL + separation, 1 mm steps
        assert abs(e[5] - 100 * fx.hdop) <= 0.5 and e[8] == fx.nsat
        assert abs(e[6] - 1000 * fx.speed_m_s) <= 1  # knots with 3 decimals: 0.5 mm/s
        if np.isnan(fx.course_deg):
            assert e[7] == -1
        else:
            assert abs(e[7] - 100 * fx.course_deg) <= 0.5 + 1e-6


def test_an_outage_prints_empty_sentences():
    truth = trajectory.SCENARIOS["highway_outage"](200.0, 0)
    g = gnss.simulate(truth, seed=0)
    epochs, _ = nmea.stream(g)
    t, data = next((t, d) for t, d in epochs if t > 185.0)
    assert b",,,,,0," in data and b"RMC,020305.00,V," in data
    p, got = parse_epochs(b"".join(d for _, d in epochs))
    assert sum(1 for e in got if e[1] == 0) == int(np.sum(g.quality == 0))


def test_damaged_sentences_are_rejected_by_the_parser(drive):
    _, g = drive
    g = dataclasses.replace(g, model=dataclasses.replace(g.model, corrupt_per_sentence=0.2))
    epochs, damaged = nmea.stream(g, seed=1)
    assert 40 < damaged < 110  # 363 sentences at 20 %
    p, _ = parse_epochs(b"".join(d for _, d in epochs))
    assert p.rejected() == damaged  # every damaged sentence, and nothing else


@pytest.mark.parametrize("baud", [9600, 115200])
def test_bytes_arrive_at_the_baud_rate(drive, baud):
    _, g = drive
    g = dataclasses.replace(g, model=dataclasses.replace(g.model, baud=baud))
    epochs, _ = nmea.stream(g)
    ticks = 24000
    offs, data = nmea.per_tick(epochs, baud, ticks, 0.005)
    per_tick = np.diff(offs)
    assert data == b"".join(d for _, d in epochs)[: len(data)]
    # at most one tick's worth of bits (plus one byte for the phase), never more
    assert per_tick.max() <= int(np.ceil(baud / 10 * 0.005)) + 1
    # the first byte of each epoch arrives one byte time after its start
    starts = np.cumsum([0] + [len(d) for _, d in epochs])[:-1]
    for (t0, _), s in zip(epochs[:5], starts[:5], strict=True):
        k = int(np.searchsorted(offs, s, side="right")) - 1
        assert k == int(np.ceil((t0 + 10 / baud) / 0.005 - 1e-9))
    # an epoch of ~230 bytes takes ~240 ms at 9600 baud, ~20 ms at 115200
    t0, d = epochs[10]
    s = starts[10]
    k0 = np.searchsorted(offs, s, side="right") - 1
    k1 = np.searchsorted(offs, s + len(d) - 1, side="right") - 1
    assert abs((k1 - k0) * 0.005 - len(d) * 10 / baud) <= 0.0051


def test_epochs_that_do_not_fit_the_baud_rate_are_refused(drive):
    truth, _ = drive
    model = gnss.GnssModel(rate_hz=10.0, baud=9600)
    with pytest.raises(ValueError, match="do not fit 9600 baud"):
        nmea.stream(gnss.simulate(truth, model, seed=0))


def test_pps_edges_land_in_the_tick_at_or_after_them():
    pps = board_input.pps_per_tick([0.0, 1.0, 1.0012, 2.9999999], 1000)
    assert pps[0] == 0 and pps[200] == 0 and pps[201] == 3800 and pps[600] == 0
    assert np.count_nonzero(pps >= 0) == 4


def test_the_simulation_becomes_a_stimulus(drive):
    sim = board_input.simulate("static", 20.0, seed=2)
    s = sim.stimulus
    assert len(s) == 4000 and s.header["scenario"] == "static" and s.header["seed"] == 2
    assert s.config["gnss_baud"] == 9600 and s.config["lever_b_m"] == [0.0, 0.5, 1.0]
    from common.proto import stimulus

    assert np.array_equal(stimulus.gyro_counts(s.gyro_regs), sim.imu.gyro_counts[:4000])
    assert np.array_equal(stimulus.accel_counts(s.accel_regs), sim.imu.accel_counts[:4000])
    assert np.count_nonzero(s.pps_before_us >= 0) == 20  # one per second, t = 0 included
    assert s.temp_raw[0] == 4 and s.temp_raw[-1] > 4  # 25 degC, warming
    assert s.uart_bytes.count(b"GGA") == 20
