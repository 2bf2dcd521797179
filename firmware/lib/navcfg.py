"""Navigator configuration: every tunable in one place, in SI units, with its source.

Floats are float32 values built from exact integer ratios below 2**24 (the float32
contract: larger ints are long ints on the board, converted with extra roundings); a value set
from elsewhere (a configuration file) is converted with f32.f32 by the navigator. Two
profiles: `car` (zero-velocity updates at standstill and the non-holonomic constraint) and
`handheld` (a board in a person's hand: zero-velocity updates with a standstill detector that
allows for the hand's tremor and sway, a longer levelling window, no non-holonomic constraint).
"""

import f32

_DEG = f32.from_bits(0x3C8EFA35)  # pi / 180
G0_M_S2 = f32.from_bits(0x411CE80A)  # 9.80665 m/s^2, standard gravity (the unit g)


def _deg(num, den=1):
    return f32.ratio(num, den) * _DEG


class NavConfig:
    def __init__(self, profile="car"):
        """Every setting with its value and where the value comes from, one after another:
        one flat list on purpose (about 150 lines), read top to bottom like a table; the
        profiles' differences are the branches at their settings."""
        self.profile = profile
        # IMU period (docs/requirements.md, board and features: a 5 ms timer)
        self.dt_s = f32.ratio(1, 200)
        self.earth_terms = True  # Earth rate, Coriolis, gravity tilt (False: board's model)
        # Two-sample coning and sculling corrections: a small gain on the car drive, measured
        # together with 2 filter slices per tick (0.70 vs 0.72 m horizontal RMS for 503 vs 397
        # float operations per tick, docs/benchmarks/navigation.md), so off by default.
        self.coning = False
        # search how late the fixes are against their stamps (their velocity against the
        # track at candidate lags) and compare them with the state of that moment
        # (nav_kern.lag_search)
        self.gnss_lag_learn = True

        # Sensor noise: BMI055 datasheet figures (docs/requirements.md, BMI055 facts) with a
        # margin of 2 for vibration and quantisation: gyro 0.014 deg/s/sqrt(Hz), accel 150
        # ug/sqrt(Hz).
        self.gyro_arw = _deg(28, 1000)  # rad/s/sqrt(Hz) = rad/sqrt(s)
        self.accel_vrw = f32.ratio(2942, 1000000)  # m/s^2/sqrt(Hz) (300 ug)
        # Bias instability as first-order Gauss-Markov processes (sigma, correlation time).
        self.gyro_bias_sigma = _deg(1, 100)  # rad/s (36 deg/h)
        self.gyro_bias_tau_s = f32.f32(600)
        self.accel_bias_sigma = f32.ratio(4903, 1000000)  # m/s^2 (0.5 mg)
        self.accel_bias_tau_s = f32.f32(600)

        # Initial uncertainty when navigation starts (1 sigma).
        self.init_vel_sigma = f32.ratio(1, 2)  # m/s
        self.init_tilt_sigma = _deg(2)  # rad, roll and pitch from levelling
        # the heading's, beyond the course's own noise (nav_align._start_navigation): how far
        # the body may point away from its direction of travel (a car: its slip and the
        # mounting; a board in hand: the hand)
        self.init_yaw_sigma = _deg(10) if profile == "car" else _deg(15)
        self.init_gyro_bias_sigma = _deg(1, 10)  # rad/s residual after the static average
        self.init_accel_bias_sigma = f32.ratio(1961, 10000)  # m/s^2 (20 mg)

        # GNSS: 1-sigma = HDOP x UERE horizontally, twice that vertically, unless the caller
        # gives sigmas; never below the floor (a receiver reporting 0 must not make R singular).
        self.gnss_uere_m = f32.f32(2)
        self.gnss_vert_factor = f32.f32(2)
        self.gnss_sigma_floor_m = f32.ratio(1, 20)
        # m/s, speed/course velocity: the floor, and the start, of the receiver's velocity noise
        # the navigator learns (nav_kern.vel_noise). In hand, the receiver's ~0.05 plus the lever
        # velocity C (w x l) of the antenna, taken at the tick the fix is processed, not its epoch
        # (up to 0.035 m/s with a 5 cm lever at the hand's 40 deg/s): 0.08. A car's 0.1 is
        # the same receiver with margin (`bench-nav --trial walk --nav gnss_vel_sigma=S`: NEES
        # 0.48 / 0.55 / 0.62 / 1.12 with 0.1 / 0.08 / 0.07 / 0.05, horizontal RMS 0.67 / 0.69 /
        # 0.71 / 0.85 m)
        self.gnss_vel_sigma = f32.ratio(1, 10) if profile == "car" else f32.ratio(8, 100)
        # reject fixes with HDOP above (docs/requirements.md, FR003)
        self.gnss_hdop_max = f32.f32(2)
        self.gnss_min_quality = 1
        self.gnss_latency_s = f32.ratio(1, 10)  # fix time = arrival - latency when no PPS
        # a receiver that stamps its fixes late (its solution is older than the time in the
        # sentence, with or without a PPS): the fix time is the stamp's less this
        self.gnss_stamp_lag_s = f32.f32(0)
        self.gnss_stable_fixes = 5  # consecutive good fixes before GNSS counts as stable
        self.gnss_timeout_s = f32.f32(2)  # no accepted fix for this long: health 1
        self.gate_sigma = f32.f32(5)  # innovation gate, sigmas
        # consecutive fixes with E or N gated out: reset to GNSS; with the height gated out:
        # reset the vertical channel
        self.reset_after_rejects = 5
        self.lever_b_m = f32.zeros(3)  # IMU -> antenna, body axes, m

        # Alignment: static averaging for roll, pitch and gyro bias. A hand is never still: its
        # sway turns the board by up to ~1.5 deg back and forth, so the mean rate over a window
        # of T s errs by up to 3 deg / T: 10 s (0.3 deg/s at worst) against a car's 2 s
        # (`bench-nav --trial walk --nav level_s=T` with 2 / 5 / 10 / 20 s: horizontal RMS
        # 0.72 / 0.68 / 0.69 / 0.73 m, yaw 4.8 / 2.7 / 2.4 / 2.5 deg, standing 0.11 / 0.08 /
        # 0.07 / 0.08 m/s at most).
        self.level_s = f32.f32(2) if profile == "car" else f32.f32(10)
        # the course over ground becomes the heading from this speed on: a walk (0.8 m/s);
        # its noise, larger as the speed falls, sets the heading's initial variance
        self.heading_speed_m_s = f32.ratio(4, 5)
        # Without a course from the receiver (GGA only, position-only data) the heading comes
        # from the track: the chord from an anchor fix once it is track_min_m long (within
        # track_s to track_max_s, at a mean speed from heading_speed_m_s on), corrected by half the
        # gyros' yaw change over it; a turn of more than track_turn_max within the window is
        # not used. 12 m against fixes of 2 m 1-sigma: sqrt(2) 2 / 12 = 13 deg (the
        # heading's initial sigma adds it); a walker covers it in ~10 s. The chord's mean
        # speed lags an accelerating car by a T / 2 (3-7 m/s measured on simulated starts from
        # a stop, with 4 s windows): the filter starts with the horizontal velocity sigma
        # track_vel_sigma (2 m/s: 1 m/s gave 6.4 m vs 4.9 m horizontal RMS over the first 10 s
        # of highway_outage, 3 m/s no better than 2 after that; docs/navigation.md).
        self.track_min_m = f32.f32(12)
        # windows from track_s (a car accelerating away from a stop covers more than 12 m in
        # them: a longer chord, a better heading) to track_max_s (longer ones hold more turns
        # and pace changes)
        self.track_s = f32.f32(4)
        self.track_max_s = f32.f32(20)
        self.track_turn_max = _deg(30)  # rad
        self.track_vel_sigma = f32.f32(2)  # m/s
        # The heading from motion alone (yaw_gsf.py, docs/navigation.md "The yaw estimator"):
        # a bank of yaw hypotheses weighed by how well each explains the fixes' positions and
        # velocities. On (True), navigation starts when the bank's yaw 1-sigma is under
        # yaw_gsf_ready_sigma, from its heading and velocity, whatever the course says (the
        # course and track starts above serve only with it off); while navigating, a bank
        # that disagrees by more than 3 sigma and yaw_gsf_reset_min for yaw_gsf_reset_s, while
        # the navigator's own fixes are rejected or gated or drift, resets the heading.
        self.yaw_gsf = True
        # with it, the course and track starts too, whichever comes first: a car points where
        # it goes; a board in hand need not (then the bank resets a wrong start)
        self.heading_from_course = True
        # m/s^2 / sqrt(Hz): what the summed specific force misses beyond the error the bank
        # estimates (the IMU's noise, a hand's lever), rad / sqrt(s): the offsets' random
        # walk (a gyro bias of 0.1 deg/s after levelling, with margin)
        self.yaw_gsf_accel_sigma = f32.ratio(1, 10)
        self.yaw_gsf_rate_sigma = _deg(1, 2)
        # m/s^2 / sqrt(s): how fast the specific force's error in the navigator's frame may
        # change (a body-fixed accelerometer bias turns with the board)
        self.yaw_gsf_bias_walk = f32.ratio(1, 20)
        # a board in hand: 30 deg, a start the filter refines (a hand's course is no
        # heading); a car: 15 deg, sooner than its course only when sure
        # m/s: a velocity's 1-sigma to the bank, at least gnss_vel_sigma. The bank compares
        # it with its hypotheses' velocity at the fix's arrival, later than its measurement
        # by the latency (0.1 s: a hand's 2 m/s^2 make 0.2 m/s), yet widening it for that
        # loses more than it gains (`bench-nav --trial walk_real --nav yaw_gsf_vel_sigma=V`:
        # 2.10 m with 0.08, 2.67 m with 0.3)
        self.yaw_gsf_vel_sigma = f32.ratio(8, 100)
        self.yaw_gsf_ready_sigma = _deg(15) if profile == "car" else _deg(30)
        self.yaw_gsf_reset_min = _deg(20)
        self.yaw_gsf_reset_s = f32.f32(2)

        # Standstill detection (zero-velocity update) and non-holonomic constraint.
        self.zupt = True
        self.nhc = profile == "car"
        if profile == "car":
            self.still_gyro = _deg(1, 2)  # rad/s rms below which the vehicle may be still
            self.still_accel = f32.ratio(1, 20)  # m/s^2 rms of specific-force changes (BMI055
            # noise alone: ~0.035 at 200 Hz)
        else:
            # a person standing with the board in hand: tremor (up to 0.02 g at 6-11 Hz) and
            # sway (1-3 deg/s) stay under 3 deg/s and 0.5 m/s^2; a walking hand's steps are
            # over 10 deg/s and 2 m/s^2 rms (the simulated walk: tests/sim/test_sim.py)
            self.still_gyro = _deg(3)
            self.still_accel = f32.ratio(1, 2)
        self.still_s = f32.ratio(1, 2)  # both must hold this long
        self.still_gnss_speed = f32.ratio(1, 2)  # m/s: a recent fix faster than this vetoes
        # m/s: and so does the navigator's own speed, for a car (a smooth road is as quiet as a
        # stop). A hand that moves is never quiet, and a veto by an INS drifting without a
        # receiver speed (an outage, a GGA-only receiver) locks the update out exactly when it
        # is needed: none for a hand (`bench-nav --trial walk --receiver "GGA only"`: 4.87 m
        # with none, 34.9 m with `--nav still_max_speed=3`). The price: a board held in a
        # smoothly riding car stops on the map in outages (`--trial urban_drive --profile
        # handheld`: 4.29 m, 37.4 m after the 30 s outage; 1.50 m and 10.1 m with the 3 m/s
        # veto), the car profile's case.
        self.still_max_speed = f32.ratio(1, 2) if profile == "car" else f32.f32(1000)
        # m/s: a hand's sway moves the board by 1-3 cm/s while its owner stands
        self.zupt_sigma = f32.ratio(2, 100) if profile == "car" else f32.ratio(5, 100)
        self.zupt_period_s = f32.ratio(1, 4)
        self.nhc_sigma = f32.ratio(1, 10)  # m/s, lateral and vertical body velocity
        self.nhc_period_s = f32.ratio(1, 2)

        # Time distribution (see eskf.py): covariance propagation every prop_period_s at the
        # earliest, slices of filter work per tick.
        self.prop_period_s = f32.ratio(1, 5)
        self.slices_per_tick = 1
        self.reanchor_m = f32.f32(2000)  # move the origin beyond this horizontal distance

        # Faults (docs/health.md). Health 2 while the filter's own position 1-sigma exceeds
        # fault_sigma_m east or north (3-sigma at 10 m, the accuracy a solution of this class
        # must keep to be trusted), or fault_sigma_v_m vertically (twice that: GNSS heights
        # are twice as noisy). An IMU whose samples are unusable, or unchanged (a real
        # BMI055's noise moves every axis every few samples), for imu_stuck_s in a row is
        # dead: health 2 until it recovers.
        self.fault_sigma_m = f32.ratio(10, 3)
        self.fault_sigma_v_m = f32.ratio(20, 3)
        self.imu_stuck_s = f32.ratio(1, 10)

        # IMU calibration (docs/requirements.md, IMU deterministic errors), sensor -> body:
        # x_b = M (x_raw - b0). Identity M (None) skips the matrix product. Raw scale: counts per
        # SI unit at the ranges.
        self.gyro_bias0 = f32.zeros(3)  # rad/s
        self.accel_bias0 = f32.zeros(3)  # m/s^2
        self.gyro_matrix = None  # 9 values, row-major, or None for identity
        self.accel_matrix = None
        # BMI055 at +-250 deg/s: 131.2 LSB/(deg/s); at +-2 g: 1024 LSB/g (docs/requirements.md,
        # BMI055 facts)
        self.gyro_counts_per_rad_s = f32.ratio(1312, 10) / _DEG
        self.accel_counts_per_m_s2 = f32.f32(1024) / G0_M_S2
