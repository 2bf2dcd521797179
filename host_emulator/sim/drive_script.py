"""The commanded profiles a truth trajectory is evaluated from (trajectory.py says how).

`Ramps`: a profile as a sum of smooth steps S(u) = u - sin(2 pi u) / (2 pi), whose value, first
and second derivative are continuous, evaluated in closed form with its integral. `DriveScript`:
the commands of a drive (speed and yaw rate over time, road grade and bank over distance),
appended in time order, with the carried sensor's sway, its IMU grade, antenna and profile.
"""

import numpy as np

TWO_PI = 2.0 * np.pi
CAR_ANTENNA_B_M = (0.0, 0.5, 1.0)  # IMU -> GNSS antenna on a car's roof, body axes (r, f, u), m


class Ramps:
    """A profile x -> base + sum_i d_i S((x - x0_i) / L_i) of smooth steps.

    S(u) = u - sin(2 pi u) / (2 pi) on [0, 1] (0 before, 1 after): its rate 1 - cos(2 pi u) is a
    raised cosine, so value, first and second derivative are continuous everywhere.
    """

    def __init__(self, base=0.0):
        self.base = float(base)
        self.steps = []  # (x0, length, delta)

    def add(self, x0, length, delta):
        if not length > 0.0:
            raise ValueError("a step needs a positive length")
        self.steps.append((float(x0), float(length), float(delta)))

    def final(self):
        """The value after every step."""
        return self.base + sum(d for _, _, d in self.steps)

    def eval(self, x):
        """(value, d/dx, d2/dx2, integral from 0 to x) at ascending x >= 0."""
        x = np.asarray(x, dtype=float)
        n = x.size
        val = np.full(n, self.base)
        d1 = np.zeros(n)
        d2 = np.zeros(n)
        integ = self.base * x
        # After a step ends it adds d to the value and d (x - x0 - L/2) to the integral:
        # accumulate those as piecewise-constant coefficients with difference arrays.
        tail_slope = np.zeros(n + 1)
        tail_const = np.zeros(n + 1)
        for x0, length, d in self.steps:
            i0 = np.searchsorted(x, x0)
            i1 = np.searchsorted(x, x0 + length)
            if i1 > i0:
                u = (x[i0:i1] - x0) / length
                s2, c2 = np.sin(TWO_PI * u), np.cos(TWO_PI * u)
                val[i0:i1] += d * (u - s2 / TWO_PI)
                d1[i0:i1] += d * (1.0 - c2) / length
                d2[i0:i1] += d * TWO_PI * s2 / length**2
                integ[i0:i1] += d * length * (0.5 * u * u + (c2 - 1.0) / TWO_PI**2)
            tail_slope[i1] += d
            tail_const[i1] -= d * (x0 + 0.5 * length)
        slope = np.cumsum(tail_slope)[:n]
        val += slope
        integ += slope * x + np.cumsum(tail_const)[:n]
        return val, d1, d2, integ


class DriveScript:
    """Commands for a car, appended in time order with a cursor `t_s`.

    speed (m/s) and yaw_rate (rad/s) are `Ramps` over time; grade and bank (rad) are `Ramps`
    over distance travelled (m), so the road shape stays put when the car stops.
    """

    # Suspension: pitch per forward acceleration, roll per lateral acceleration (rad per m/s^2).
    # Passenger cars pitch ~1-2 deg/g and roll ~3-7 deg/g.
    PITCH_PER_ACCEL = np.deg2rad(0.15)
    ROLL_PER_ACCEL = np.deg2rad(0.4)

    def __init__(self, yaw0_rad=0.0, grade0_rad=0.0, bank0_rad=0.0):
        self.yaw0_rad = float(yaw0_rad)
        self.speed = Ramps(0.0)
        self.yaw_rate = Ramps(0.0)
        self.grade = Ramps(grade0_rad)
        self.bank = Ramps(bank0_rad)
        self.t_s = 0.0
        self.sway = None  # a Sway or hand.Hand: the carried sensor's own motion on the path
        # the IMU that goes with it (sim/imu.py `model_for`): "calibrated" or "uncalibrated"
        self.sensor_grade = "calibrated"
        self.antenna_b_m = CAR_ANTENNA_B_M  # IMU -> GNSS antenna, body axes
        self.board_profile = 0  # the board's profile setting for it: 0 car, 1 handheld
        # the receiver that goes with it: sim/gnss.py GnssModel fields over its defaults
        self.receiver = {}

    @property
    def v_m_s(self):
        """Commanded speed once every step so far has finished."""
        return self.speed.final()

    def hold(self, duration_s):
        self.t_s += max(0.0, float(duration_s))

    def speed_to(self, v_m_s, accel_m_s2=1.2, min_s=0.0):
        """Change speed at a mean acceleration (peak = 2x mean), over min_s at least (a small
        change would otherwise be a jerk no body makes); advances the cursor."""
        dv = float(v_m_s) - self.v_m_s
        if dv != 0.0:
            length = max(abs(dv) / accel_m_s2, min_s)
            self.speed.add(self.t_s, length, dv)
            self.t_s += length

    def turn(self, angle_rad, rate_rad_s, ramp_s=2.0):
        """Turn by angle_rad (> 0 left) at constant speed: yaw rate ramps to +-rate_rad_s over
        ramp_s, holds, ramps back. The angle is exact; the rate is lowered for small angles."""
        if angle_rad == 0.0:
            return
        rate = min(abs(rate_rad_s), abs(angle_rad) / ramp_s)
        hold_s = abs(angle_rad) / rate - ramp_s
        r = np.copysign(rate, angle_rad)
        self.yaw_rate.add(self.t_s, ramp_s, r)
        self.yaw_rate.add(self.t_s + ramp_s + hold_s, ramp_s, -r)
        self.t_s += 2.0 * ramp_s + hold_s

    def add_road(self, rng, length_m, grade_max_rad, bank_max_rad, spacing_m, transition_m):
        """Random gentle road shape out to length_m: every spacing_m (range) the grade and bank
        move to new uniform values within +-max over a transition of transition_m (range)."""
        s = 0.0
        grade, bank = self.grade.final(), self.bank.final()
        while s < length_m:
            s += rng.uniform(*spacing_m)
            length = rng.uniform(*transition_m)
            new_grade = rng.uniform(-grade_max_rad, grade_max_rad)
            new_bank = rng.uniform(-bank_max_rad, bank_max_rad)
            self.grade.add(s, length, new_grade - grade)
            self.bank.add(s, length, new_bank - bank)
            grade, bank = new_grade, new_bank
            s += length
