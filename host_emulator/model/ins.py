"""NumPy float32 model of `firmware/lib/ins.py`: the strapdown mechanization, bit for bit.

Written at vector level where the firmware loops over i = 0, 1, 2, with every float32
operation in the firmware's order and grouping (f32ops.py says how); frames, units and
constants are the firmware module's.
"""

import numpy as np

from common import firmware_env
from host_emulator.model import rot as ref_rot
from host_emulator.model.f32ops import F32, HALF, ONE, ZERO, cross, mat_vec, vec

firmware_env.install()
import geo as fw_geo  # noqa: E402
import ins as fw_ins  # noqa: E402  (constants shared with the firmware, not retyped)


class InsModel:
    """Nominal state in the Earth-fixed ENU frame of the origin.

        q_bn' = 1/2 q_bn (x) w_ib_b - 1/2 w_ie_n (x) q_bn
        v_n'  = C_bn f_b - 2 w_ie_n x v_n + g_n(p_n)
        p_n'  = v_n
    per tick: theta = (w - b_g) dt, dv = (f - b_a) dt, optional two-sample coning/sculling,
    dv += theta x dv / 2, v += C_bn(k-1) dv + a_n dt, q <- q (x) q(theta), and the trapezoidal
    position step with Kahan compensation. a_n = g_n - 2 w_ie x v and the Earth rotation of
    the attitude are refreshed by `slow_update`.
    """

    def __init__(self, dt_s, earth_terms=True, coning=True):
        self.dt = F32(dt_s)
        self.half_dt = self.dt * HALF
        self.earth_terms = earth_terms
        self.coning = coning
        self.p_n = np.zeros(3, F32)  # m
        self.v_n = np.zeros(3, F32)  # m/s
        self.q_bn = vec(1, 0, 0, 0)
        self.c_bn = ref_rot.q_to_dcm(self.q_bn)  # (3, 3)
        self.bg = np.zeros(3, F32)  # rad/s
        self.ba = np.zeros(3, F32)  # m/s^2
        self.dvn_sum = np.zeros(3, F32)  # sum of C_bn dv since take_dvn, m/s
        self.a_n = np.zeros(3, F32)  # gravity + Coriolis, m/s^2
        self.w_ie_n = np.zeros(3, F32)  # Earth rate, rad/s
        self.p_comp = np.zeros(3, F32)  # Kahan compensation of p_n
        self.theta_prev = np.zeros(3, F32)
        self.dv_prev = np.zeros(3, F32)
        self.g0 = ZERO  # normal gravity at the origin
        self.inv_rn = ZERO
        self.inv_rm = ZERO
        self.h0 = ZERO

    def set_frame(self, coef):
        """Earth model of the origin: g0 = gamma_e (1 + k sin^2 L) / sqrt(1 - e^2 sin^2 L)."""
        s = coef[fw_geo.SIN_LAT]
        co = coef[fw_geo.COS_LAT]
        s2 = s * s
        self.g0 = fw_ins.GAMMA_E * (ONE + fw_ins.SOMIGLIANA_K * s2) / np.sqrt(ONE - fw_geo.E2 * s2)
        self.inv_rn = coef[fw_geo.INV_RN]
        self.inv_rm = coef[fw_geo.INV_RM]
        self.h0 = coef[fw_geo.H0]
        if self.earth_terms:
            self.w_ie_n = vec(0, fw_ins.OMEGA_E * co, fw_ins.OMEGA_E * s)
        else:
            self.w_ie_n = vec(0, 0, 0)
        self.slow_update(ZERO)

    def reset_kinematics(self, p_n, v_n):
        self.p_n = np.array(p_n, F32)
        self.v_n = np.array(v_n, F32)
        self.p_comp = np.zeros(3, F32)
        self.theta_prev = np.zeros(3, F32)
        self.dv_prev = np.zeros(3, F32)

    def step(self, w_b, f_b):
        """One tick with body rate w_b (rad/s) and specific force f_b (m/s^2)."""
        theta = (w_b - self.bg) * self.dt
        dv = (f_b - self.ba) * self.dt
        if self.coning:
            th_prev, dv_prev = self.theta_prev, self.dv_prev
            self.theta_prev, self.dv_prev = theta, dv
            # sculling (th_prev x dv + dv_prev x theta) / 12 and coning th_prev x theta / 12,
            # both from the uncorrected increments
            scull = (cross(th_prev, dv) + cross(dv_prev, theta)) * fw_ins.TWELFTH
            cone = cross(th_prev, theta) * fw_ins.TWELFTH
            theta = theta + cone
            dv = dv + scull
        u = dv + cross(theta, dv) * HALF  # rotation of dv within the tick
        dv_n = mat_vec(self.c_bn, u)  # with C_bn of the previous tick
        self.dvn_sum = self.dvn_sum + dv_n
        self.q_bn = ref_rot.q_update(self.q_bn, theta)[0]
        self.c_bn = ref_rot.q_to_dcm(self.q_bn)
        # v1 = v0 + dv_n + a_n dt; p += (v0 + v1) dt/2, Kahan-compensated
        v0 = self.v_n
        v1 = (v0 + dv_n) + self.a_n * self.dt
        self.v_n = v1
        y = (v0 + v1) * self.half_dt - self.p_comp
        t = self.p_n + y
        self.p_comp = (t - self.p_n) - y
        self.p_n = t

    def take_dvn(self):
        out = self.dvn_sum
        self.dvn_sum = np.zeros(3, F32)
        return out

    def slow_update(self, t_s):
        """Earth rate on the attitude over t_s (q <- q(-w_ie t) (x) q), then
        a_n = -g [E/(R_N+h), N/(R_M+h), 1] - 2 w_ie x v with w_ie = (0, wy, wz)."""
        p, v = self.p_n, self.v_n
        g = self.g0 - fw_ins.FREE_AIR * (self.h0 + p[2])
        if not self.earth_terms:
            self.a_n = vec(0, 0, -g)
            return
        w = self.w_ie_n
        if t_s > 0.0:
            r = vec(1, 0, -(w[1] * t_s) * HALF, -(w[2] * t_s) * HALF)
            self.q_bn = ref_rot.q_normalize(ref_rot.q_mul(r, self.q_bn))[0]
            self.c_bn = ref_rot.q_to_dcm(self.q_bn)
        wy2 = w[1] + w[1]
        wz2 = w[2] + w[2]
        self.a_n = vec(
            -(g * p[0] * self.inv_rn) - (wy2 * v[2] - wz2 * v[1]),
            -(g * p[1] * self.inv_rm) - wz2 * v[0],
            wy2 * v[0] - g,
        )

    def shift_origin(self, dp_n, rho_n):
        """Re-express the state in the frame whose origin is the old frame's dp_n, rotated by
        the small rho_n: x_new = x_old - rho x x_old, q_new = q(-rho) (x) q_old."""
        p = self.p_n - dp_n
        self.p_n = p - cross(rho_n, p)
        self.v_n = self.v_n - cross(rho_n, self.v_n)
        r = vec(1, -rho_n[0] * HALF, -rho_n[1] * HALF, -rho_n[2] * HALF)
        self.q_bn = ref_rot.q_normalize(ref_rot.q_mul(r, self.q_bn))[0]
        self.c_bn = ref_rot.q_to_dcm(self.q_bn)
        self.p_comp = np.zeros(3, F32)
