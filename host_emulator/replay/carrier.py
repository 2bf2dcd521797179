"""Who carries the board, from its accelerometer: a person walking, or a vehicle.

The board's profile (firmware/lib/config.py `profile`: 0 car, 1 handheld) decides how it
navigates: a car's body moves along its forward axis (the non-holonomic constraint) and stands
truly still; a hand does neither. A recording replayed with the wrong profile navigates badly
without saying why, so the host looks at the data first.

A walker's steps are the signature: heel strikes put 0.3-1 g peaks into the specific force at
1.6-2.2 steps/s, with harmonics; a car's body bounces at its suspension's ~1-1.5 Hz by
hundredths of a g and its vibration is broadband above 10 Hz; a bicycle's pedalling is a few
hundredths of a g. `gait` cuts the magnitude of the specific force into 4 s windows (the mean
taken out) and calls a window a step window when its strongest component between 0.5 and 5 Hz
lies at 1.4-2.6 Hz with an amplitude of 0.15 g or more (0.25 Hz bins: a rate between two bins
reads up to 15 % low). A recording walks when a fifth of its windows do (a walk with stops,
turns and a still start still has most of its windows stepping; a drive has none).

Measured (tests/replay/test_carrier.py): the simulated walks step in 70-80 % of their windows;
the simulated drives, the bicycle and the real drive_0708 in none (drive_0708's strongest
window at a step's rate: 0.11 g). Only the cadence is tested: a board riding a vehicle in the
hand of a passenger who does not walk is a vehicle's.
"""

from dataclasses import dataclass

import numpy as np

G_M_S2 = 9.80665
WINDOW_S = 4.0
STEP_BAND_HZ = (1.4, 2.6)
SEARCH_BAND_HZ = (0.5, 5.0)
MIN_STEP_G = 0.15
MIN_SHARE = 0.2


@dataclass(frozen=True)
class Gait:
    windows: int  # 4 s windows looked at
    stepping: int  # of them, with a walker's steps
    cadence_hz: float  # median step rate over the stepping windows (nan if none)
    amplitude_g: float  # median amplitude of the step component (nan if none)
    strongest_g: float = 0.0  # the largest amplitude at 1.4-2.6 Hz in any window

    @property
    def share(self):
        return self.stepping / self.windows if self.windows else 0.0

    @property
    def walking(self):
        return self.windows > 0 and self.share >= MIN_SHARE

    def describe(self):
        if not self.stepping:
            return (f"no walking steps in the accelerometer ({self.windows} windows of 4 s, "
                    f"the strongest at a step's rate {self.strongest_g:.2f} g)")  # fmt: skip
        return (
            f"a walker's steps in {100 * self.share:.0f} % of the accelerometer's 4 s windows "
            f"({self.cadence_hz:.1f} steps/s, {self.amplitude_g:.2f} g)"
        )


def gait(f_b_m_s2, dt_s):
    """Gait of a specific-force series (N, 3), m/s^2, sampled every dt_s."""
    f = np.asarray(f_b_m_s2, float)
    n = max(int(round(WINDOW_S / dt_s)), 8)
    k = len(f) // n
    if k == 0:
        return Gait(0, 0, float("nan"), float("nan"))
    mag = np.linalg.norm(f[: k * n], axis=1).reshape(k, n)
    mag = mag - mag.mean(axis=1, keepdims=True)
    spec = np.abs(np.fft.rfft(mag * np.hanning(n), axis=1)) * (4.0 / n)  # Hann: amplitude
    freq = np.fft.rfftfreq(n, dt_s)
    band = (freq >= SEARCH_BAND_HZ[0]) & (freq <= SEARCH_BAND_HZ[1])
    idx = np.flatnonzero(band)
    peak = idx[np.argmax(spec[:, band], axis=1)]
    peak_hz = freq[peak]
    peak_g = spec[np.arange(k), peak] / G_M_S2
    steps = (peak_hz >= STEP_BAND_HZ[0]) & (peak_hz <= STEP_BAND_HZ[1]) & (peak_g >= MIN_STEP_G)
    step_band = (freq >= STEP_BAND_HZ[0]) & (freq <= STEP_BAND_HZ[1])
    strongest = float(spec[:, step_band].max()) / G_M_S2
    if not steps.any():
        return Gait(k, 0, float("nan"), float("nan"), strongest)
    return Gait(
        k,
        int(steps.sum()),
        float(np.median(peak_hz[steps])),
        float(np.median(peak_g[steps])),
        strongest,
    )


def of_stimulus(stim):
    """Gait of what a stimulus feeds the board's accelerometer (its counts at its range)."""
    from common.proto import stimulus as stim_mod
    from host_emulator.sim import imu as imu_mod

    counts = stim_mod.accel_counts(stim.accel_regs).astype(float)
    lsb = imu_mod.ACCEL_LSB_PER_G_BY_RANGE[stim.config.get("accel_range_g", 2)]
    return gait(counts / lsb * G_M_S2, stim.header.get("tick_us", stim_mod.TICK_US) * 1e-6)
