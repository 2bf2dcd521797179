"""A board carried in a person's hand: the gait, the hand's tremor and sway, and the way the
board is held (float64, closed form like sim/trajectory.py).

`Hand` takes the place of trajectory.Sway in a DriveScript: `channel(name, t, v, dv, d2v)` gives
(x, dx/dt, d2x/dt2) of six channels: positions along the path's horizontal forward axis (surge),
its right axis (lateral) and up (bob), and angles added to the path's yaw, pitch and roll. Every
channel is a sum of four parts:

gait    harmonics of the step phase phi(t), gated by the pace g = v / v_ref (0 at a stop, growing
        with the first steps): surge, bob and pitch at whole multiples of the step frequency,
        lateral, yaw and roll at odd multiples of the stride frequency (half of it: the weight
        goes from foot to foot, the arm swings once per stride). Heel strikes are sharp, so the
        accelerations carry harmonics up to the fourth; each channel's harmonics are scaled so
        that its acceleration (or angle) peaks at a value drawn per walker. The cadence is not
        a clock: phi(t) = w t + sum_i b_i sin(n_i t + theta_i) wanders by a few percent.
tremor  always on: three sinusoids per channel at 6-11 Hz.
sway    always on: three sinusoids per channel at 0.04-0.4 Hz, a person never stands still.
hold    a constant angle: the board pitched up towards the face, a little roll, a heading a few
        degrees off the direction of travel.

Figures, and where they come from:
- cadence 1.6-2.2 steps/s and heel-strike peaks of 0.3-1 g vertically, 0.2-0.6 g fore and aft
  at the hand: the range hand-held phone recordings of walkers show (pedestrian dead-reckoning
  studies); the hand bobs 2-4 cm, pitches 1.5-4 deg per step and rolls and yaws 2-5 deg per
  stride.
- tremor: physiological postural tremor of the hand peaks at 0.0015-0.035 g, 0.01 g the most
  common, at 6-12 Hz (Marsden and colleagues' normative accelerometer study of 97 subjects,
  Arch. Neurol. 1982; Lakie et al., J. Physiol. 2015); its angular part here, 0.2-0.8 deg/s, is
  what 0.01 g at 7 Hz gives at a forearm's 0.3 m lever.
- sway: quiet standing sways below 1 Hz by a centimetre or two; a held board wanders by
  0.3-1.5 deg (rates of 1-3 deg/s).
"""

import numpy as np

TWO_PI = 2.0 * np.pi
G_M_S2 = 9.80665
_DEG = np.pi / 180.0

CHANNELS = ("surge", "lateral", "bob", "yaw", "pitch", "roll")
_LINEAR = ("surge", "lateral", "bob")
# Gait: (multiple of the step phase, relative amplitude of the acceleration or angle) per
# channel; lateral, yaw and roll run at odd multiples of the stride (half the step phase).
_GAIT_HARMONICS = {
    "surge": ((1.0, 1.0), (2.0, 0.6), (3.0, 0.3)),
    "bob": ((1.0, 1.0), (2.0, 0.5), (3.0, 0.3), (4.0, 0.15)),
    "pitch": ((1.0, 1.0), (2.0, 0.3)),
    "lateral": ((0.5, 1.0), (1.5, 0.3)),
    "yaw": ((0.5, 1.0), (1.5, 0.2)),
    "roll": ((0.5, 1.0), (1.5, 0.2)),
}


# The ranges a walker is drawn from (Hand.draw). HEEL_STRIKES: the module docstring's, a board
# gripped firmly enough to carry the heel strikes. AS_HELD: a phone or board held in front of
# the walker as the real hand-held walks bench-real replays show it (gyro p99 2-3 rad/s,
# screens pitched up 50-65 deg; docs/benchmarks/realdata.md): the hand damps the steps to
# 0.02-0.2 g at the step rate, the board is pitched up 40-70 deg to be read, pointed anywhere
# against the walking direction, and re-pointed by tens of degrees while walking (the slow
# yaw sway here: 15-60 deg over three sines at 0.04-0.4 Hz).
HEEL_STRIKES = {
    "bob_g": (0.3, 1.0), "surge_g": (0.2, 0.6), "lateral_g": (0.05, 0.15),
    "pitch_deg": (1.5, 4.0), "roll_deg": (2.0, 5.0), "yaw_deg": (2.0, 5.0),
    "sway_deg": {}, "hold_pitch_deg": (10.0, 35.0), "hold_roll_deg": (-5.0, 5.0),
    "hold_yaw_deg": (-8.0, 8.0),
}  # fmt: skip
AS_HELD = {
    "bob_g": (0.02, 0.2), "surge_g": (0.02, 0.15), "lateral_g": (0.01, 0.05),
    "pitch_deg": (1.0, 3.0), "roll_deg": (3.0, 8.0), "yaw_deg": (3.0, 8.0),
    "sway_deg": {"yaw": (15.0, 60.0), "pitch": (2.0, 8.0), "roll": (2.0, 8.0)},
    "hold_pitch_deg": (40.0, 70.0), "hold_roll_deg": (-10.0, 10.0),
    "hold_yaw_deg": (-180.0, 180.0),
}  # fmt: skip


class _Sines:
    """sum_i a_i sin(w_i t + p_i) with its derivatives, vectorised over t."""

    def __init__(self, amplitudes, omegas, phases):
        self.a = np.asarray(amplitudes, float)
        self.w = np.asarray(omegas, float)
        self.p = np.asarray(phases, float)

    def eval(self, t):
        ph = np.multiply.outer(t, self.w) + self.p
        s, c = np.sin(ph), np.cos(ph)
        return s @ self.a, c @ (self.a * self.w), -(s @ (self.a * self.w * self.w))


class Hand:
    """A walker's hand (see the module docstring); `Hand.draw(rng, ...)` makes one at random."""

    CHANNELS = CHANNELS

    def __init__(self, step_hz, v_ref_m_s, gait, wander, tremor, sway, hold):
        """gait: {channel: [(multiple, amplitude, phase), ...]} (amplitudes of the position, m,
        or angle, rad); wander: _Sines of the step phase's wander (rad); tremor, sway:
        {channel: _Sines}; hold: {channel: constant angle, rad}."""
        self.step_hz = float(step_hz)
        self.v_ref_m_s = float(v_ref_m_s)
        self.gait = gait
        self.wander = wander
        self.tremor = tremor
        self.sway = sway
        self.hold = {k: float(hold.get(k, 0.0)) for k in CHANNELS}

    @classmethod
    def draw(cls, rng, v_ref_m_s=1.3, style=None):
        """A walker and the way they hold the board, from the ranges of `style` (HEEL_STRIKES,
        the default: the module docstring's; AS_HELD: what real hand-held recordings show)."""
        r = HEEL_STRIKES if style is None else style
        step_hz = rng.uniform(1.6, 2.2)
        w = TWO_PI * step_hz
        peaks = {
            "bob": rng.uniform(*r["bob_g"]) * G_M_S2,  # m/s^2 at v_ref
            "surge": rng.uniform(*r["surge_g"]) * G_M_S2,
            "lateral": rng.uniform(*r["lateral_g"]) * G_M_S2,
            "pitch": rng.uniform(*r["pitch_deg"]) * _DEG,  # rad
            "roll": rng.uniform(*r["roll_deg"]) * _DEG,
            "yaw": rng.uniform(*r["yaw_deg"]) * _DEG,
        }
        gait = {}
        for name, harmonics in _GAIT_HARMONICS.items():
            phases = rng.uniform(-np.pi, np.pi, len(harmonics))
            rel = np.array([r for _, r in harmonics])
            mult = np.array([m for m, _ in harmonics])
            # the peak is the acceleration's for a position (amplitudes a / (m w)^2), the
            # angle's for an angle
            rel_x = rel / (mult * w) ** 2 if name in _LINEAR else rel
            scale = peaks[name] / _peak(rel, mult, phases)
            gait[name] = [(m, a * scale, p) for m, a, p in zip(mult, rel_x, phases, strict=True)]
        # cadence wander: three slow sines (periods 10-50 s) moving the step rate by ~2-4 %
        n = TWO_PI * rng.uniform(0.02, 0.1, 3)
        wander = _Sines(rng.uniform(0.007, 0.013, 3) * w / n, n, rng.uniform(-np.pi, np.pi, 3))
        tremor, sway = {}, {}
        for name in CHANNELS:
            wt = TWO_PI * rng.uniform(6.0, 11.0, 3)
            ws = TWO_PI * rng.uniform(0.04, 0.4, 3)
            split = rng.dirichlet(np.ones(3))
            if name in _LINEAR:
                a_peak = rng.uniform(0.003, 0.02) * G_M_S2  # tremor's acceleration, m/s^2
                tremor[name] = _Sines(a_peak * split / wt**2, wt, rng.uniform(-np.pi, np.pi, 3))
                amp = rng.uniform(0.005, 0.02) if name != "bob" else rng.uniform(0.003, 0.01)
            else:
                r_peak = rng.uniform(0.2, 0.8) * _DEG  # tremor's rate, rad/s
                tremor[name] = _Sines(r_peak * split / wt, wt, rng.uniform(-np.pi, np.pi, 3))
                amp = rng.uniform(*r["sway_deg"].get(name, (0.3, 1.5))) * _DEG
            sway[name] = _Sines(amp * rng.dirichlet(np.ones(3)), ws, rng.uniform(-np.pi, np.pi, 3))
        hold = {
            "pitch": rng.uniform(*r["hold_pitch_deg"]) * _DEG,  # tilted up towards the face
            "roll": rng.uniform(*r["hold_roll_deg"]) * _DEG,
            "yaw": rng.uniform(*r["hold_yaw_deg"]) * _DEG,  # the hand's heading off the walk's
        }
        return cls(step_hz, v_ref_m_s, gait, wander, tremor, sway, hold)

    def step_phase(self, t):
        """(phi, dphi/dt, d2phi/dt2) of the step phase, rad."""
        w = TWO_PI * self.step_hz
        x, dx, d2x = self.wander.eval(t)
        return w * t + x, w + dx, d2x

    def channel(self, name, t, v, dv, d2v):
        """(x, dx/dt, d2x/dt2) of one channel at times t, given the path speed and its
        derivatives there."""
        t = np.asarray(t, float)
        g, g1, g2 = v / self.v_ref_m_s, dv / self.v_ref_m_s, d2v / self.v_ref_m_s
        phi, dphi, d2phi = self.step_phase(t)
        x = np.full(t.shape, self.hold[name])
        dx = np.zeros(t.shape)
        d2x = np.zeros(t.shape)
        for m, a, p in self.gait.get(name, ()):
            th = m * phi + p
            s, c = np.sin(th), np.cos(th)
            dth, d2th = m * dphi, m * d2phi
            x += a * g * s
            dx += a * (g1 * s + g * dth * c)
            d2x += a * (g2 * s + 2.0 * g1 * dth * c + g * (d2th * c - dth * dth * s))
        for part in (self.tremor, self.sway):
            y, dy, d2y = part[name].eval(t)
            x += y
            dx += dy
            d2x += d2y
        return x, dx, d2x


def _peak(rel, mult, phases):
    """Peak over one stride of |sum_k rel_k sin(mult_k theta + phase_k)| (the shape's peak)."""
    theta = np.linspace(0.0, 2.0 * TWO_PI, 2049)  # a stride: two steps
    return np.abs(np.sin(np.multiply.outer(theta, mult) + phases) @ rel).max()
