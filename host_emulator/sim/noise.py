"""Random processes shared by the sensor models (float64, vectorised).

Every generator takes a `numpy.random.Generator`, so a model's draws depend only on its seed.
"""

import numpy as np


def gauss_markov(rng, n, dt_s, tau_s, sigma, shape=(), x0=None):
    """n samples of a stationary first-order Gauss-Markov process, shape (n, *shape).

    Exact discretisation: x[k+1] = phi x[k] + sigma sqrt(1 - phi^2) w[k], phi = exp(-dt/tau),
    w ~ N(0, 1), and x[0] ~ N(0, sigma^2) unless x0 is given. The recursion is evaluated in
    closed form, x[k] = phi^k (x[0] + sum_{j<k} phi^-(j+1) c w[j]), over blocks short enough
    (k dt <= 4 tau) that phi^-k stays below e^4, so it costs a few array operations per block
    instead of a Python loop per sample.
    """
    shape = tuple(shape)
    sigma = np.broadcast_to(np.asarray(sigma, dtype=float), shape)
    out = np.empty((n, *shape))
    if n == 0:
        return out
    phi = np.exp(-dt_s / tau_s)
    c = np.sqrt(-np.expm1(-2.0 * dt_s / tau_s))  # sqrt(1 - phi^2) without cancellation
    x = rng.standard_normal(shape) * sigma if x0 is None else np.asarray(x0, dtype=float)
    out[0] = x
    w = rng.standard_normal((n - 1, *shape)) * (c * sigma)
    block = max(1, int(4.0 * tau_s / dt_s))
    k0 = 0
    while k0 < n - 1:
        k1 = min(n - 1, k0 + block)
        m = k1 - k0
        j = np.arange(1, m + 1, dtype=float).reshape(-1, *([1] * len(shape)))
        grow = phi ** (-j)  # phi^-(j) for j = 1..m
        acc = np.cumsum(w[k0:k1] * grow, axis=0)
        seg = (x + acc) / grow  # x[k0 + j] = phi^j (x[k0] + sum_{i<j} phi^-(i+1) w[k0+i])
        out[k0 + 1 : k1 + 1] = seg
        x = seg[-1]
        k0 = k1
    return out
