"""Who carries the board, from its accelerometer: a person walking, or a vehicle.

The board's profile (firmware/lib/config.py `profile`: 0 car, 1 handheld) decides how it
navigates: a car's body moves along its forward axis (the non-holonomic constraint) and stands
truly still; a hand does neither. A recording replayed with the wrong profile navigates badly
without saying why, so the host looks at the data first.

Two signatures of a person, either enough (cut into 4 s windows):
- heel strikes: 0.3-1 g peaks in the specific force at 1.6-2.2 steps/s, with harmonics (a
  window steps when its strongest component of the magnitude, mean taken out, between 0.5 and
  5 Hz lies at 1.4-2.6 Hz with an amplitude of 0.15 g or more; 0.25 Hz bins: a rate between
  two bins reads up to 15 % low); a car's body bounces at its suspension's ~1-1.5 Hz by
  hundredths of a g, its vibration is broadband above 10 Hz, a bicycle's pedalling is a few
  hundredths of a g. A recording walks when a fifth of its windows step.
- a hand's tilting: a hand held in front steps by 0.02-0.2 g only (too little for the first
  signature) but pitches and rolls all the time, with every step, look and turn. A window
  tilts when the gyro's rate about the horizontal axes (perpendicular to the window's mean
  specific force; 0.1 s means, which the sensor's white noise averages out of; the window's
  mean taken out, so a bias or a steady turn does not count) is 8 deg/s rms or more. A car
  turns about the vertical and its body pitches and rolls by a degree or two a second; a
  bicycle leans into turns and sways as it is pedalled. A recording is carried by hand when
  60 % of its windows tilt.

Measured (tests/replay/test_carrier.py): the simulated heel-striking walks step in 70-80 % of
their windows; the simulated hands as held (walk_real, seeds 0-7) step in none and tilt in
83-100 %; the real hand-held phone walks (ipin_handheld) tilt in 69-82 %; the simulated
bicycle (seeds 0-7) tilts in 19-44 %, the real car drives (drive_0708, tokyo_1105) in 0-1 %,
the simulated drives in none. The bicycle sits nearest: a real bicycle that tilts more than
the simulated one would be taken for a walker (the handheld profile: no non-holonomic
constraint), which the replay says, with the way out (--set profile=0). Only the motion is
read: a board riding a vehicle in the hand of a passenger who does not walk is a vehicle's.
"""

from dataclasses import dataclass

import numpy as np

G_M_S2 = 9.80665
WINDOW_S = 4.0
STEP_BAND_HZ = (1.4, 2.6)
SEARCH_BAND_HZ = (0.5, 5.0)
MIN_STEP_G = 0.15
MIN_SHARE = 0.2
TILT_MEAN_S = 0.1  # the gyro averaged over this before the tilt rate is taken
MIN_TILT_DPS = 8.0
MIN_TILT_SHARE = 0.6


@dataclass(frozen=True)
class Gait:
    windows: int  # 4 s windows looked at
    stepping: int  # of them, with a walker's steps
    cadence_hz: float  # median step rate over the stepping windows (nan if none)
    amplitude_g: float  # median amplitude of the step component (nan if none)
    strongest_g: float = 0.0  # the largest amplitude at 1.4-2.6 Hz in any window
    tilting: int = 0  # windows with a hand's tilting (0 when no gyro was given)
    tilt_dps: float = float("nan")  # median tilt rate over the windows, deg/s rms

    @property
    def share(self):
        return self.stepping / self.windows if self.windows else 0.0

    @property
    def tilt_share(self):
        return self.tilting / self.windows if self.windows else 0.0

    @property
    def stepping_walker(self):
        return self.windows > 0 and self.share >= MIN_SHARE

    @property
    def held(self):
        return self.windows > 0 and self.tilt_share >= MIN_TILT_SHARE

    @property
    def walking(self):
        return self.stepping_walker or self.held

    def describe(self):
        steps = (
            f"a walker's steps in {100 * self.share:.0f} % of the accelerometer's 4 s windows "
            f"({self.cadence_hz:.1f} steps/s, {self.amplitude_g:.2f} g)"
            if self.stepping_walker
            else f"{'no' if not self.stepping else 'too few'} walking steps in the "
            f"accelerometer ({self.stepping} of {self.windows} windows of 4 s, the strongest "
            f"at a step's rate {self.strongest_g:.2f} g)"
        )
        if self.tilt_dps != self.tilt_dps:  # no gyro looked at
            return steps
        tilt = (
            f"a hand's tilting in {100 * self.tilt_share:.0f} % of the gyro's windows "
            f"({MIN_TILT_DPS:g} "
            f"deg/s or more about the horizontal; median {self.tilt_dps:.1f} deg/s; a hand "
            f"from {100 * MIN_TILT_SHARE:.0f} %)"
        )
        return f"{tilt}, {steps}" if self.held and not self.stepping_walker else f"{steps}, {tilt}"


def tilt_rates_dps(w_b_rad_s, f_b_m_s2, dt_s):
    """Per 4 s window, the rms rate about the horizontal axes, deg/s (module docstring)."""
    n = max(int(round(WINDOW_S / dt_s)), 8)
    k = len(f_b_m_s2) // n
    m = max(1, int(round(TILT_MEAN_S / dt_s)))
    b = n // m
    w = np.asarray(w_b_rad_s, float)[: k * n].reshape(k, n, 3)[:, : b * m]
    w = w.reshape(k, b, m, 3).mean(axis=2)  # (k, b, 3) 0.1 s means
    up = np.asarray(f_b_m_s2, float)[: k * n].reshape(k, n, 3).mean(axis=1)
    up /= np.maximum(np.linalg.norm(up, axis=1, keepdims=True), 1e-9)
    w_h = w - np.einsum("kbi,ki->kb", w, up)[:, :, None] * up[:, None, :]
    w_h -= w_h.mean(axis=1, keepdims=True)
    return np.degrees(np.sqrt((w_h**2).sum(axis=2).mean(axis=1)))


def gait(f_b_m_s2, dt_s, w_b_rad_s=None):
    """Gait of a specific-force series (N, 3), m/s^2, sampled every dt_s, and with the gyro's
    w_b_rad_s (N, 3), rad/s, the hand's tilting too."""
    f = np.asarray(f_b_m_s2, float)
    n = max(int(round(WINDOW_S / dt_s)), 8)
    k = len(f) // n
    if k == 0:
        return Gait(0, 0, float("nan"), float("nan"))
    tilting, tilt_dps = 0, float("nan")
    if w_b_rad_s is not None:
        t = tilt_rates_dps(w_b_rad_s, f, dt_s)
        tilting, tilt_dps = int((t >= MIN_TILT_DPS).sum()), float(np.median(t))
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
        return Gait(k, 0, float("nan"), float("nan"), strongest, tilting, tilt_dps)
    return Gait(
        k,
        int(steps.sum()),
        float(np.median(peak_hz[steps])),
        float(np.median(peak_g[steps])),
        strongest,
        tilting,
        tilt_dps,
    )


def of_stimulus(stim):
    """Gait of what a stimulus feeds the board's IMU (its counts at its ranges)."""
    from common.proto import stimulus as stim_mod
    from host_emulator.sim import imu as imu_mod

    counts = stim_mod.accel_counts(stim.accel_regs).astype(float)
    lsb = imu_mod.ACCEL_LSB_PER_G_BY_RANGE[stim.config.get("accel_range_g", 2)]
    gyro = stim_mod.gyro_counts(stim.gyro_regs).astype(float)
    lsb_g = imu_mod.GYRO_LSB_PER_DPS_BY_RANGE[stim.config.get("gyro_range_dps", 250)]
    dt_s = stim.header.get("tick_us", stim_mod.TICK_US) * 1e-6
    return gait(counts / lsb * G_M_S2, dt_s, np.radians(gyro / lsb_g))
