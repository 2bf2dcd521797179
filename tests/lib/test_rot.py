"""firmware/lib/rot.py: against docs/requirements.md written out directly (eq. 5-6, 5-11), bit for
bit against the NumPy model, inside the MicroPython VM, and what it allocates there."""

import json

import numpy as np
import pytest

import f32
import rot
from host_emulator.model import rot as model
from host_emulator.runtimes.mpy_unix import vm as mpvm

F32 = np.float32
U32 = np.uint32
RNG = np.random.default_rng(20261121)


# ---- independent float64 oracles, typed from the seed


def seed_c_nb(yaw, pitch, roll):
    """docs/requirements.md eq. 5-6 as printed: C_n^b = R(theta_y) R(theta_x) R(theta_z), with
    theta_y the roll about the forward axis, theta_x the pitch about the right axis, theta_z the
    yaw."""
    cy, sy = np.cos(yaw), np.sin(yaw)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    r_y = np.array([[cr, 0, -sr], [0, 1, 0], [sr, 0, cr]])
    r_x = np.array([[1, 0, 0], [0, cp, sp], [0, -sp, cp]])
    r_z = np.array([[cy, sy, 0], [-sy, cy, 0], [0, 0, 1]])
    return r_y @ r_x @ r_z


def seed_c_bn(yaw, pitch, roll):
    return seed_c_nb(yaw, pitch, roll).T


def seed_exp(theta):
    """Seed eq. 5-11: exp([theta]) = I + sin|t|/|t| [t] + (1 - cos|t|)/|t|^2 [t]^2."""
    t = np.linalg.norm(theta)
    k = np.array([[0, -theta[2], theta[1]], [theta[2], 0, -theta[0]], [-theta[1], theta[0], 0]])
    return np.eye(3) + np.sin(t) / t * k + (1 - np.cos(t)) / t**2 * (k @ k)


def angle_between(c_a, c_b):
    """Rotation angle (rad) of c_a^T c_b, as atan2(|sin|, cos) from its antisymmetric part and
    trace: well conditioned at small angles, where arccos((tr - 1) / 2) is not."""
    d = np.asarray(c_a, dtype=float).T @ np.asarray(c_b, dtype=float)
    vee = np.array([d[2, 1] - d[1, 2], d[0, 2] - d[2, 0], d[1, 0] - d[0, 1]]) / 2
    return float(np.arctan2(np.linalg.norm(vee), (np.trace(d) - 1) / 2))


# ---- helpers running the firmware on float32 buffers


def buf(values):
    b = f32.zeros(len(values))
    b[:] = np.asarray(values, dtype=F32)
    return b


def fw_euler_to_dcm(ypr):
    c = f32.zeros(9)
    rot.euler_to_dcm(c, buf(ypr))
    return c.reshape(3, 3)


def fw_dcm_to_euler(c_bn):
    ypr = f32.zeros(3)
    rot.dcm_to_euler(ypr, buf(np.ravel(c_bn)))
    return ypr


def fw_euler_to_q(ypr):
    q = f32.zeros(4)
    rot.euler_to_q(q, buf(ypr))
    return q


def fw_q_to_dcm(q):
    c = f32.zeros(9)
    rot.q_to_dcm(c, buf(q))
    return c.reshape(3, 3)


def fw_dcm_to_q(c_bn):
    q = f32.zeros(4)
    rot.dcm_to_q(q, buf(np.ravel(c_bn)))
    return q


def random_ypr(n, max_pitch_deg=85.0):
    return np.stack(
        [
            RNG.uniform(-np.pi, np.pi, n),
            RNG.uniform(-np.radians(max_pitch_deg), np.radians(max_pitch_deg), n),
            RNG.uniform(-np.pi, np.pi, n),
        ],
        axis=-1,
    ).astype(F32)


def random_unit_q(n):
    q = RNG.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0] *= -1
    return q.astype(F32)


# ---- the seed's conventions, in words


def test_euler_signs_follow_the_seed():
    deg = np.radians
    fwd, right = np.array([0, 1, 0]), np.array([1, 0, 0])
    # yaw +90: rotating about up (right-handed) turns the nose from north to west.
    assert np.allclose(fw_euler_to_dcm([deg(90), 0, 0]) @ fwd, [-1, 0, 0], atol=1e-6)
    # pitch +30: the nose rises.
    assert np.allclose(fw_euler_to_dcm([0, deg(30), 0]) @ fwd, [0, np.cos(deg(30)), 0.5], atol=1e-6)
    # roll +30 about forward: the right side goes down.
    assert np.allclose(
        fw_euler_to_dcm([0, 0, deg(30)]) @ right, [np.cos(deg(30)), 0, -0.5], atol=1e-6
    )


# ---- accuracy against the seed's equations


def test_euler_to_dcm_matches_eq_5_6():
    worst = 0.0
    for ypr in random_ypr(300, max_pitch_deg=90.0):
        err = np.abs(fw_euler_to_dcm(ypr) - seed_c_bn(*ypr.astype(float))).max()
        worst = max(worst, err)
    # Entries are products of 2-3 float32 sin/cos (each within a few ulp) plus one add:
    # a handful of float32 ulps of 1.0 (1.2e-7).
    assert worst < 6e-7


def test_dcm_to_euler_inverts_eq_5_6():
    worst = 0.0
    for ypr in random_ypr(300):
        c = seed_c_bn(*ypr.astype(float)).astype(F32)
        back = fw_dcm_to_euler(c).astype(float)
        d = back - ypr.astype(float)
        d = (d + np.pi) % (2 * np.pi) - np.pi
        worst = max(worst, np.abs(d).max())
    # asin/atan2 of float32 entries: the angle error is the entries' rounding (6e-8) amplified
    # by at most 1/cos(85 deg) = 11.5 in pitch.
    assert worst < 2e-6


def test_quaternion_and_dcm_agree_with_eq_5_6():
    for ypr in random_ypr(200, max_pitch_deg=90.0):
        oracle = seed_c_bn(*ypr.astype(float))
        q = fw_euler_to_q(ypr)
        assert abs(np.linalg.norm(q.astype(float)) - 1) < 3e-7
        assert np.abs(fw_q_to_dcm(q) - oracle).max() < 6e-7
        q2 = fw_dcm_to_q(oracle.astype(F32))
        assert np.abs(fw_q_to_dcm(q2) - oracle).max() < 6e-7


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_dcm_to_q_near_half_turns(axis):
    """Trace < 0 exercises Shepperd's x, y and z branches; w must stay canonical (>= 0)."""
    for angle in (np.pi, np.pi - 1e-3, -(np.pi - 0.3)):
        theta = np.zeros(3)
        theta[axis] = angle
        oracle = seed_exp(theta)
        q = fw_dcm_to_q(oracle.astype(F32))
        assert q[0] >= 0
        assert np.abs(fw_q_to_dcm(q) - oracle).max() < 6e-7


def test_q_update_one_step_matches_eq_5_11():
    """Series branch (|theta| < 1/8 rad) and trig branch, one step from identity."""
    for mag in (0.0, 1e-30, 1e-6, 1e-3, 0.05, 0.12499, 0.12501, 0.5, 2.0, 3.1):
        axis = RNG.normal(size=3)
        theta = (mag * axis / np.linalg.norm(axis)).astype(F32)
        q = buf([1, 0, 0, 0])
        assert rot.q_update(q, buf(theta)) is True
        oracle = seed_exp(theta.astype(float)) if mag > 0 else np.eye(3)
        assert angle_between(fw_q_to_dcm(q), oracle) < 4e-7, mag


def test_q_update_integrates_a_coning_free_rotation():
    """1000 steps of 5 ms at 100 deg/s about a fixed tilted axis equal one rotation of 5 s:
    this checks both the update and that float32 rounding does not build up a bias."""
    rate = np.radians(100.0) * np.array([0.36, -0.48, 0.8])
    theta = (rate * 0.005).astype(F32)
    q = buf([1, 0, 0, 0])
    th = buf(theta)
    for _ in range(1000):
        rot.q_update(q, th)
    oracle = seed_exp(theta.astype(float) * 1000)
    err = angle_between(fw_q_to_dcm(q), oracle)
    # Each step rounds at ~1e-7 rad; a random walk over 1000 steps is ~3e-6 rad.
    assert err < 1e-5, err


def test_series_and_trig_branches_meet():
    """At |theta|^2 = 1/64 the series and sin/cos forms of eq. 5-17 agree to ~1 ulp."""
    n = F32(0.125)
    lo = np.nextafter(n, F32(0))
    qs = []
    for mag in (lo, n):
        q = buf([1, 0, 0, 0])
        rot.q_update(q, buf([mag, 0, 0]))
        qs.append(np.array(q, dtype=float))
    assert np.abs(qs[0] - qs[1]).max() < 3e-7


def test_q_normalize_recovers_from_invalid_quaternions():
    for bad in ([0, 0, 0, 0], [np.nan, 0, 0, 0], [np.inf, 1, 0, 0]):
        q = buf(bad)
        assert rot.q_normalize(q) is False
        assert list(q) == [1, 0, 0, 0]


# ---- bit for bit against the NumPy model

EDGE_SCALARS = np.array(
    [0.0, -0.0, 1e-30, -1e-38, 1.2e-38, 1.0, -1.0, 0.125, 3.1415927, 1e20], dtype=F32
)


def edge_vectors(width):
    """Vectors mixing zeros, negative zeros, tiny, denormal-adjacent and large components."""
    rows = [RNG.choice(EDGE_SCALARS, size=width) for _ in range(60)]
    rows += [np.zeros(width, F32), -np.zeros(width, F32)]
    return np.array(rows, dtype=F32)


def same_bits(a, b):
    return np.array_equal(np.asarray(a, F32).view(U32), np.asarray(b, F32).view(U32))


def test_q_mul_update_normalize_bit_exact():
    qs = np.concatenate([random_unit_q(300), edge_vectors(4)])
    ps = np.concatenate([random_unit_q(300), edge_vectors(4)[::-1]])
    # Random steps over every branch, then edge vectors: |theta|^2 underflowing to 0 or
    # overflowing to inf (the update then fails safe to identity and reports False).
    thetas = np.concatenate(
        [
            RNG.normal(size=(300, 3)) * RNG.choice([1e-6, 1e-3, 0.05, 0.5, 3.0], size=(300, 1)),
            edge_vectors(3),
        ]
    ).astype(F32)
    want_mul = model.q_mul(ps, qs)
    want_upd, want_ok = model.q_update(qs, thetas)
    want_norm, _ = model.q_normalize(ps)
    for i in range(len(qs)):
        out = f32.zeros(4)
        rot.q_mul(out, buf(ps[i]), buf(qs[i]))
        assert same_bits(out, want_mul[i]), i
        q = buf(qs[i])
        ok = rot.q_update(q, buf(thetas[i]))
        assert same_bits(q, want_upd[i]) and ok == bool(want_ok[i]), (i, qs[i], thetas[i])
        p = buf(ps[i])
        rot.q_normalize(p)
        assert same_bits(p, want_norm[i]), i


def test_conversions_bit_exact():
    yprs = np.concatenate(
        [
            random_ypr(300, 90.0),
            edge_vectors(3)[:, :3] * F32(1e-20),
            np.array([[np.pi, np.pi / 2, -np.pi], [0, -np.pi / 2, 0]], F32),
        ]
    )
    qs = np.concatenate([random_unit_q(300), edge_vectors(4)])
    dcm_from_ypr = model.euler_to_dcm(yprs)
    q_from_ypr = model.euler_to_q(yprs)
    ypr_back = model.dcm_to_euler(dcm_from_ypr)
    dcm_from_q = model.q_to_dcm(qs)
    q_back = model.dcm_to_q(dcm_from_q)
    skews = model.skew(yprs)
    for i, ypr in enumerate(yprs):
        c = fw_euler_to_dcm(ypr)
        assert same_bits(c, dcm_from_ypr[i]), i
        assert same_bits(fw_euler_to_q(ypr), q_from_ypr[i]), i
        assert same_bits(fw_dcm_to_euler(c), ypr_back[i]), i
        s = f32.zeros(9)
        rot.skew(s, buf(ypr))
        assert same_bits(s, skews[i].ravel()), i
    for i, q in enumerate(qs):
        c = fw_q_to_dcm(q)
        assert same_bits(c, dcm_from_q[i]), i
        assert same_bits(fw_dcm_to_q(c), q_back[i]), i


# ---- inside the MicroPython VM


def test_micropython_vm_agrees_with_the_float32_model():
    """The VM (double arithmetic, float32 storage) integrates 400 updates and converts the
    result. Its answer differs from the float32 model only by float32 rounding: each step
    rounds the stored quaternion once (<= 6e-8 per component), so after 400 steps the two
    differ by a random walk of ~1e-6, bounded here at 2e-5."""
    theta = (np.radians([40.0, -25.0, 90.0]) * 0.005).astype(F32)
    ypr0 = np.radians([30.0, 10.0, -5.0]).astype(F32)
    q_model = model.euler_to_q(ypr0)
    for _ in range(400):
        q_model, _ = model.q_update(q_model, theta)
    ypr_model = model.dcm_to_euler(model.q_to_dcm(q_model))
    out = mpvm.run_json(f"""
import json, rot, f32
q = f32.zeros(4)
rot.euler_to_q(q, _buf({mpvm.hex_of(ypr0)!r}))
th = _buf({mpvm.hex_of(theta)!r})
for _ in range(400):
    rot.q_update(q, th)
c = f32.zeros(9)
rot.q_to_dcm(c, q)
ypr = f32.zeros(3)
rot.dcm_to_euler(ypr, c)
print(json.dumps([_hex(q), _hex(ypr)]))
""")
    assert np.abs(mpvm.from_hex(out[0]) - q_model).max() < 2e-5
    assert np.abs(mpvm.from_hex(out[1]) - ypr_model).max() < 4e-5


def test_allocations_in_the_micropython_vm():
    """Only float boxes are allocated, as many as the code has float reads and operations:
    q_mul reads 8 and does 28 operations (4 x (4 products + 3 sums)); q_to_dcm reads 4, forms
    9 products, 3 x 3 for the diagonal and 6 x 2 for the rest (34); skew reads 3 and negates
    3 (6). q_identity only stores constants: nothing at all, even under heap_lock."""
    out = json.loads(
        mpvm.run(f"""
import json, rot, f32
p = _buf({mpvm.hex_of([0.5, 0.5, -0.5, 0.5])!r})
q = _buf({mpvm.hex_of([0.8, 0.6, 0.0, 0.0])!r})
o = f32.zeros(9)
print(json.dumps({{
    "q_mul": _blocks(lambda: rot.q_mul(o, p, q)),
    "q_to_dcm": _blocks(lambda: rot.q_to_dcm(o, q)),
    "skew": _blocks(lambda: rot.skew(o, p)),
    "q_identity_locked": _locked(lambda: rot.q_identity(o)),
}}))
""")
        .strip()
        .splitlines()[-1]
    )
    assert out == {"q_mul": 36, "q_to_dcm": 34, "skew": 6, "q_identity_locked": True}
