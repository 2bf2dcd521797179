"""BMI055-class IMU model: truth rates and specific forces -> register counts (float64 maths).

Measurement model, per axis triad, body axes (x right, y forward, z up):
    w_meas = M_g w_ib_b + b_g(t) + n_g        M = I + diag(scale error) + off-diagonal
    f_meas = M_a f_b    + b_a(t) + n_a            misalignment / cross-axis terms
    b(t)   = turn-on bias (constant per run) + first-order Gauss-Markov bias instability
    counts = clip(round(meas x sensitivity), register limits)
Each 5 ms sample is the *instantaneous* value at the truth sample time t_k (not an average
over the interval): the navigator multiplies by dt. The white noise n is the discrete-time
equivalent of the datasheet noise density, sigma = density / sqrt(dt), so that integrating the
samples gives the stated angle/velocity random walk. (The chip's digital low-pass filter
would lower the per-sample spread and correlate neighbouring samples without changing the
low-frequency density; it is not modelled.)

Defaults and their sources (docs/requirements.md, BMI055 facts and reference figures, Bosch BMI055
datasheet figures):
    gyro  +-250 deg/s, 131.2 LSB/(deg/s) (datasheet; the output frame's 131.07 is FRAME_*);
          counts clip at the int16 limits (+-249.7 deg/s at this range)
    accel +-2 g, 1024 LSB/g after the 12-bit shift; counts here are the shifted 12-bit
          values (-2048..2047): the register word is counts << 4 (bit 0 = new_data)
    (other ranges: gyro_range_dps / accel_range_g pick the datasheet sensitivity)
    gyro noise 0.014 deg/s/sqrt(Hz) = ARW 0.84 deg/sqrt(h)
    accel noise 150 ug/sqrt(Hz) = VRW 0.088 m/s/sqrt(h)
    turn-on bias magnitude per axis uniform in 0.1-0.2 deg/s (gyro), 2-4 mg (accel), random
          sign (the KF-GINS benchmark set-up of DESIGN 10; the datasheet allows +-1 deg/s
          and +-70 mg, which a calibrated board does not see)
    bias instability: first-order Gauss-Markov, steady-state sigma 10 deg/h (gyro) and
          0.1 mg (accel), correlation time 300 s (typical of MEMS of this class; no datasheet
          figure)
    scale factor error 0.3 % (1 sigma per axis), misalignment/cross-axis 1 mrad (1 sigma per
          off-diagonal element)
    temperature: the board warms up from 25 degC by 6 K with a 400 s time constant; the
          biases drift with it, 0.002 deg/s/K (gyro) and 0.05 mg/K (accel) per axis, with
          the sign of each axis' turn-on bias (the datasheet's typical 0.015 deg/s/K and 1 mg/K
          are for an uncompensated part; the same, deterministic, in every run); the
          temperature register reads round((T - 23) * 2)
    sampling: at the tick, the truth of that instant

`ImuModel.uncalibrated()` is a student's board as it comes, the datasheet's part with nobody's
calibration (`model_for` gives it to scenarios whose sensor_grade says so, the realistic walk):
    turn-on bias per axis uniform in 0.2-1.0 deg/s (gyro; datasheet zero-rate offset +-1 deg/s
          typ) and 10-50 mg (accel; datasheet zero-g offset +-60 mg typ over life), random sign
    temperature coefficients per axis 0.3-1 x the datasheet's typical 0.015 deg/s/K and 1 mg/K
    g-sensitivity of the gyro: a 3x3 matrix, 0.1 deg/s/g (1 sigma) per element (the gyro die's
          datasheet, BMG160, 0.1 deg/s/g typ): w += G f
    free-running sample clocks: the dies sample on their own oscillators (the driver sets the
          gyro to 400 Hz, the accel to 250 Hz data updates), so the sample a tick reads is up
          to 2.5 ms (gyro) and 4 ms (accel) old, the age sliding as the clocks beat against the
          timer; each oscillator is off by 1 % (1 sigma; no datasheet figure). The truth at
          those instants comes from 4-point Lagrange interpolation of the 200 Hz truth (error
          ~1e-4 of a 10 Hz component). The dies' digital low-pass filters are not modelled.
The extra draws come from a stream of their own, so the default model's data are unchanged.
"""

from dataclasses import dataclass

import numpy as np

from .noise import gauss_markov
from .trajectory import DT_S

STANDARD_GRAVITY_M_S2 = 9.80665  # the "g" of accelerometer datasheets

GYRO_LSB_PER_DPS = 131.2  # BMI055 datasheet sensitivity at +-250 deg/s (the default range)
FRAME_GYRO_LSB_PER_DPS = 131.07  # the output frame's nominal scale (DESIGN 6), not the sensor's
ACCEL_LSB_PER_G = 1024.0  # at +-2 g (the default range), after the 12-bit right shift
# Datasheet sensitivities of every range (range reg 0x0F of each die, DESIGN 7).
GYRO_LSB_PER_DPS_BY_RANGE = {2000: 16.4, 1000: 32.8, 500: 65.6, 250: GYRO_LSB_PER_DPS, 125: 262.4}
ACCEL_LSB_PER_G_BY_RANGE = {2: ACCEL_LSB_PER_G, 4: 512.0, 8: 256.0, 16: 128.0}
# The outputs clip at the register limits at every range.
GYRO_COUNT_MIN, GYRO_COUNT_MAX = -32768, 32767  # int16
ACCEL_COUNT_MIN, ACCEL_COUNT_MAX = -2048, 2047  # 12-bit two's complement

_DEG = np.pi / 180.0
_STREAM_IMU = 0x494D55  # seeds the IMU's random stream apart from the trajectory's


@dataclass(frozen=True)
class ImuModel:
    """Error parameters of one BMI055 (see the module docstring for sources)."""

    gyro_range_dps: int = 250  # a key of GYRO_LSB_PER_DPS_BY_RANGE
    accel_range_g: int = 2  # a key of ACCEL_LSB_PER_G_BY_RANGE
    gyro_noise_dps_rt_hz: float = 0.014
    accel_noise_ug_rt_hz: float = 150.0
    gyro_turn_on_bias_dps: tuple = (0.1, 0.2)  # per-axis magnitude range, random sign
    accel_turn_on_bias_mg: tuple = (2.0, 4.0)
    gyro_bias_instability_dph: float = 10.0  # Gauss-Markov steady-state sigma
    accel_bias_instability_mg: float = 0.1
    bias_tau_s: float = 300.0
    gyro_scale_error: float = 3e-3  # 1 sigma
    accel_scale_error: float = 3e-3
    gyro_misalignment_rad: float = 1e-3  # 1 sigma per off-diagonal element
    accel_misalignment_rad: float = 1e-3
    temp_start_c: float = 25.0
    temp_rise_c: float = 6.0
    temp_tau_s: float = 400.0
    gyro_tempco_dps_per_k: float = 0.002
    accel_tempco_mg_per_k: float = 0.05
    tempco_spread: tuple | None = None  # per-axis factor range on the tempcos (None: 1)
    gyro_g_sensitivity_dps_per_g: float = 0.0  # 1 sigma per element of G
    gyro_odr_hz: float | None = None  # None: sampled at the tick
    accel_odr_hz: float | None = None
    odr_clock_error: float = 0.0  # 1 sigma, relative, per die

    @classmethod
    def uncalibrated(cls):
        """The datasheet's part as it comes (see the module docstring)."""
        return cls(
            gyro_turn_on_bias_dps=(0.2, 1.0),
            accel_turn_on_bias_mg=(10.0, 50.0),
            gyro_tempco_dps_per_k=0.015,
            accel_tempco_mg_per_k=1.0,
            tempco_spread=(0.3, 1.0),
            gyro_g_sensitivity_dps_per_g=0.1,
            gyro_odr_hz=400.0,
            accel_odr_hz=250.0,
            odr_clock_error=0.01,
        )

    @classmethod
    def ideal(cls):
        """No errors at all but quantisation and saturation."""
        return cls(
            gyro_noise_dps_rt_hz=0.0,
            accel_noise_ug_rt_hz=0.0,
            gyro_turn_on_bias_dps=(0.0, 0.0),
            accel_turn_on_bias_mg=(0.0, 0.0),
            gyro_bias_instability_dph=0.0,
            accel_bias_instability_mg=0.0,
            gyro_scale_error=0.0,
            accel_scale_error=0.0,
            gyro_misalignment_rad=0.0,
            accel_misalignment_rad=0.0,
            temp_rise_c=0.0,
            gyro_tempco_dps_per_k=0.0,
            accel_tempco_mg_per_k=0.0,
        )

    @property
    def gyro_lsb_per_dps(self):
        return GYRO_LSB_PER_DPS_BY_RANGE[self.gyro_range_dps]

    @property
    def accel_lsb_per_g(self):
        return ACCEL_LSB_PER_G_BY_RANGE[self.accel_range_g]

    @property
    def gyro_rad_s_per_count(self):
        return _DEG / self.gyro_lsb_per_dps

    @property
    def accel_m_s2_per_count(self):
        return STANDARD_GRAVITY_M_S2 / self.accel_lsb_per_g

    @property
    def gyro_noise_rad_s(self):
        """Per-sample white-noise sigma at 200 Hz, rad/s (= ARW / sqrt(dt))."""
        return self.gyro_noise_dps_rt_hz * _DEG / np.sqrt(DT_S)

    @property
    def accel_noise_m_s2(self):
        """Per-sample white-noise sigma at 200 Hz, m/s^2 (= VRW / sqrt(dt))."""
        return self.accel_noise_ug_rt_hz * 1e-6 * STANDARD_GRAVITY_M_S2 / np.sqrt(DT_S)


@dataclass(frozen=True, eq=False)
class ImuData:
    """One run of IMU samples, aligned one for one with the Truth samples."""

    t_s: np.ndarray  # (N,) sample times, s
    gyro_counts: np.ndarray  # (N, 3) int16 gyro register values
    accel_counts: np.ndarray  # (N, 3) int16 accel values after the 12-bit shift
    w_b_rad_s: np.ndarray  # (N, 3) what the gyro counts represent, rad/s
    f_b_m_s2: np.ndarray  # (N, 3) what the accel counts represent, m/s^2
    saturated: np.ndarray  # (N,) bool: some axis hit its register limit
    bg_rad_s: np.ndarray  # (N, 3) gyro bias applied (turn-on + instability + thermal), rad/s
    ba_m_s2: np.ndarray  # (N, 3) accel bias applied, m/s^2
    gyro_matrix: np.ndarray  # (3, 3) M_g applied (scale and misalignment)
    accel_matrix: np.ndarray  # (3, 3) M_a
    model: ImuModel
    temp_c: np.ndarray = None  # (N,) die temperature, degC
    temp_raw: np.ndarray = None  # (N,) int8 temperature register (0.5 K per LSB, 0 = 23 degC)
    gyro_g_matrix: np.ndarray = None  # (3, 3) G applied, rad/s per m/s^2 (None: none)


def _turn_on(rng, lo_hi, unit):
    lo, hi = lo_hi
    return rng.uniform(lo, hi, 3) * rng.choice([-1.0, 1.0], 3) * unit


def _error_matrix(rng, scale_sigma, misalignment_sigma):
    m = np.eye(3) + np.diag(rng.standard_normal(3) * scale_sigma)
    off = ~np.eye(3, dtype=bool)
    m[off] += rng.standard_normal(6) * misalignment_sigma
    return m


def _quantise(x, per_count, lo, hi):
    raw = np.rint(x / per_count)
    return np.clip(raw, lo, hi).astype(np.int16), (raw < lo) | (raw > hi)


def model_for(truth):
    """The IMU model that goes with a scenario (its sensor_grade)."""
    grade = getattr(truth, "sensor_grade", "calibrated")
    return ImuModel.uncalibrated() if grade == "uncalibrated" else ImuModel()


def _sample_ages(rng, t_s, odr_hz, clock_error):
    """(N,) age in s of the sample a read at each tick gets from a die sampling at odr_hz on an
    oscillator off by a N(0, clock_error) fraction, from a random phase."""
    period = 1.0 / (odr_hz * (1.0 + clock_error * rng.standard_normal()))
    t0 = rng.uniform(0.0, period)
    return np.mod(t_s - t0, period)


def _at(x, t_s, ages):
    """x (N, 3), sampled at t_s (uniform), at t_s - ages by 4-point Lagrange interpolation
    (clamped at the ends)."""
    n = len(t_s)
    dt = t_s[1] - t_s[0]
    u = np.clip(t_s - ages, t_s[0], t_s[-1]) / dt
    i = np.clip(np.floor(u).astype(np.int64), 1, n - 3)
    f = (u - i)[:, None]
    xm, x0, x1, x2 = x[i - 1], x[i], x[i + 1], x[i + 2]
    return (
        -f * (f - 1.0) * (f - 2.0) / 6.0 * xm
        + (f + 1.0) * (f - 1.0) * (f - 2.0) / 2.0 * x0
        - (f + 1.0) * f * (f - 2.0) / 2.0 * x1
        + (f + 1.0) * f * (f - 1.0) / 6.0 * x2
    )


def simulate(truth, model=None, seed=0):
    """Sample truth.w_ib_b and truth.f_b through the model (None: `model_for(truth)`). Same
    seed -> same data."""
    model = model_for(truth) if model is None else model
    rng = np.random.default_rng([seed, _STREAM_IMU])
    extra = np.random.default_rng([seed, _STREAM_IMU, 2])  # the uncalibrated part's draws
    n = len(truth.t_s)
    g = STANDARD_GRAVITY_M_S2

    bg0 = _turn_on(rng, model.gyro_turn_on_bias_dps, _DEG)
    ba0 = _turn_on(rng, model.accel_turn_on_bias_mg, 1e-3 * g)
    m_g = _error_matrix(rng, model.gyro_scale_error, model.gyro_misalignment_rad)
    m_a = _error_matrix(rng, model.accel_scale_error, model.accel_misalignment_rad)
    bg = bg0 + gauss_markov(
        rng, n, DT_S, model.bias_tau_s, model.gyro_bias_instability_dph * _DEG / 3600.0, (3,)
    )
    ba = ba0 + gauss_markov(
        rng, n, DT_S, model.bias_tau_s, model.accel_bias_instability_mg * 1e-3 * g, (3,)
    )
    temp_c = model.temp_start_c + model.temp_rise_c * -np.expm1(-truth.t_s / model.temp_tau_s)
    warm = (temp_c - model.temp_start_c)[:, None]
    spread_g = spread_a = 1.0
    if model.tempco_spread is not None:
        spread_g, spread_a = extra.uniform(*model.tempco_spread, (2, 3))
    bg = bg + warm * (model.gyro_tempco_dps_per_k * _DEG) * np.sign(bg0) * spread_g
    ba = ba + warm * (model.accel_tempco_mg_per_k * 1e-3 * g) * np.sign(ba0) * spread_a
    temp_raw = np.clip(np.rint((temp_c - 23.0) * 2.0), -128, 127).astype(np.int8)
    w_true, f_true = truth.w_ib_b, truth.f_b
    if model.gyro_odr_hz:
        ages = _sample_ages(extra, truth.t_s, model.gyro_odr_hz, model.odr_clock_error)
        w_true = _at(w_true, truth.t_s, ages)
    if model.accel_odr_hz:
        ages = _sample_ages(extra, truth.t_s, model.accel_odr_hz, model.odr_clock_error)
        f_true = _at(f_true, truth.t_s, ages)
    w = w_true @ m_g.T + bg + rng.standard_normal((n, 3)) * model.gyro_noise_rad_s
    g_sens = None
    if model.gyro_g_sensitivity_dps_per_g:
        g_sens = extra.standard_normal((3, 3)) * (model.gyro_g_sensitivity_dps_per_g * _DEG / g)
        w = w + f_true @ g_sens.T
    f = f_true @ m_a.T + ba + rng.standard_normal((n, 3)) * model.accel_noise_m_s2

    gyro_counts, gyro_sat = _quantise(w, model.gyro_rad_s_per_count, GYRO_COUNT_MIN, GYRO_COUNT_MAX)
    accel_counts, accel_sat = _quantise(
        f, model.accel_m_s2_per_count, ACCEL_COUNT_MIN, ACCEL_COUNT_MAX
    )
    return ImuData(
        t_s=truth.t_s,
        gyro_counts=gyro_counts,
        accel_counts=accel_counts,
        w_b_rad_s=gyro_counts * model.gyro_rad_s_per_count,
        f_b_m_s2=accel_counts * model.accel_m_s2_per_count,
        saturated=(gyro_sat | accel_sat).any(axis=1),
        bg_rad_s=bg,
        ba_m_s2=ba,
        gyro_matrix=m_g,
        accel_matrix=m_a,
        model=model,
        temp_c=temp_c,
        temp_raw=temp_raw,
        gyro_g_matrix=g_sens,
    )
