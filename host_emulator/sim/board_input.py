"""A simulated scenario as the board's peripherals would see it: a `host_emulator.stimulus`.

    sim = simulate("urban_drive", duration_s=600, seed=0)
    sim.stimulus     # per tick: BMI055 registers, temperature, PPS, GNSS UART bytes
    sim.truth, sim.imu, sim.gnss     # for evaluation

Record k (timer tick at k * 5 ms) carries IMU sample k (the truth at k dt), the PPS edge of
((k-1) dt, k dt] and the NMEA bytes that finished arriving in that interval (sim/nmea.py).
The last truth sample is the state after the last tick, so a run of N ticks uses N + 1
truth samples.
"""

from dataclasses import dataclass

import numpy as np

from common.proto import stimulus as stim_mod
from host_emulator.sim import gnss as gnss_mod
from host_emulator.sim import imu as imu_mod
from host_emulator.sim import nmea, trajectory

TICK_US = stim_mod.TICK_US


@dataclass(eq=False)
class Simulation:
    name: str
    seed: int
    truth: object
    imu: object
    gnss: object
    stimulus: object
    damaged_sentences: int


def pps_per_tick(pps_s, ticks, tick_us=TICK_US):
    """(ticks,) int32: for each tick, how many us before its timer moment the PPS edge came
    (-1 if none in its interval)."""
    out = np.full(ticks, -1, np.int32)
    t_us = np.rint(np.asarray(pps_s, float) * 1e6).astype(np.int64)
    k = -(-t_us // tick_us)  # ceil: the edge belongs to the tick at or after it
    ok = (k >= 0) & (k < ticks)
    out[k[ok]] = (k[ok] * tick_us - t_us[ok]).astype(np.int32)
    return out


def to_stimulus(truth, imu, gnss, header=None, seed=0):
    """(Stimulus, damaged sentence count) for simulated truth/IMU/GNSS."""
    ticks = len(truth.t_s) - 1
    tick_s = TICK_US * 1e-6
    epochs, damaged = nmea.stream(gnss, seed)
    offs, data = nmea.per_tick(epochs, gnss.model.baud, ticks, tick_s)
    head = {
        "source": "simulation",
        "tick_us": TICK_US,
        "config": {
            "gyro_range_dps": int(imu.model.gyro_range_dps),
            "accel_range_g": int(imu.model.accel_range_g),
            "gnss_baud": int(gnss.model.baud),
            "lever_b_m": [float(x) for x in gnss.model.lever_b_m],
        },
        "outages": [[float(s), float(n)] for s, n in gnss.outages],
        "utc_start": gnss.model.utc_start,
        "gnss_rate_hz": float(gnss.model.rate_hz),
    }
    if truth.board_profile:  # the walk: the board in hand (firmware/lib/config.py "profile")
        head["config"]["profile"] = int(truth.board_profile)
    head.update(header or {})
    temp = imu.temp_raw[:ticks] if imu.temp_raw is not None else np.zeros(ticks, np.int8)
    s = stim_mod.from_arrays(
        head,
        imu.gyro_counts[:ticks],
        imu.accel_counts[:ticks],
        temp,
        pps_per_tick(gnss.pps_s, ticks),
        (offs, data),
    )
    return s, damaged


def simulate(name, duration_s=None, seed=0, imu_model=None, gnss_model=None):
    """Truth, sensors and stimulus of a named scenario (trajectory.SCENARIOS)."""
    if name not in trajectory.SCENARIOS:
        known = ", ".join(sorted(trajectory.SCENARIOS))
        raise KeyError(f"unknown scenario {name!r} (known: {known})")
    truth = trajectory.SCENARIOS[name](duration_s, seed)
    imu = imu_mod.simulate(truth, imu_model, seed)
    gnss = gnss_mod.simulate(truth, gnss_model, seed)
    header = {"scenario": name, "seed": int(seed), "duration_s": float(truth.duration_s)}
    stimulus, damaged = to_stimulus(truth, imu, gnss, header, seed)
    return Simulation(name, seed, truth, imu, gnss, stimulus, damaged)
