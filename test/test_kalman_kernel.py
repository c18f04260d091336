"""The foot Kalman filter's covariance kernel (core/spatial/_kalman_kernel.py) against Suh 2014's
equations written with numpy matrices here, and compiled against plain Python."""

from __future__ import annotations

import numpy as np
import pytest

from gait_biofeedback.core.spatial import _kalman_kernel as kernel
from gait_biofeedback.core.spatial.kalman import _ROWS_FLOOR, kernels


def _covariance_kernels():
    """(propagate, measure): compiled once :func:`kernels` has compiled the foot's step that calls them."""
    kernels()
    return kernel.propagate, kernel.measure


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _case(seed):
    rng = np.random.default_rng(seed)
    m = rng.normal(size=(15, 15)) * 1e-2
    p = m @ m.T + np.eye(15) * 1e-6
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    rot = q * np.sign(np.linalg.det(q))  # a rotation
    density = np.array([1e-3] * 3 + [1e-6] * 3 + [1e-2 * (1 + rng.random())] * 3)
    return p, rng.normal(size=3) * 3, rng.normal(size=3) * 10, rot, 0.01, density, rng.normal(size=4) * 0.1


def _by_numpy(p, omega, f, rot, dt, density, residual):
    """Suh Eq 10-12 (Φ = I + AT + (AT)²/2), the second-order Q and Eq 13-14 in the Joseph form."""
    a = np.zeros((15, 15))
    a[0:3, 0:3] = -_skew(omega)
    a[0:3, 9:12] = -np.eye(3)
    a[3:6, 6:9] = np.eye(3)
    a[6:9, 0:3] = -rot @ _skew(f)
    a[6:9, 12:15] = -rot
    phi = np.eye(15) + a * dt + (a * dt) @ (a * dt) / 2
    a1, qc = a[:9, :9], np.diag(density)
    q_noise = np.zeros((15, 15))
    q_noise[:9, :9] = qc * dt + (a1 @ qc + qc @ a1.T) * dt**2 / 2 + a1 @ qc @ a1.T * dt**3 / 3
    p_next = phi @ p @ phi.T + q_noise
    h = np.zeros((4, 15))
    h[[0, 1, 2, 3], [6, 7, 8, 5]] = 1.0
    r = np.diag([1e-4, 1e-4, 1e-4, 2e-4])
    gain = p_next @ h.T @ np.linalg.inv(h @ p_next @ h.T + r)
    ikh = np.eye(15) - gain @ h
    return phi, q_noise, p_next, gain @ residual, ikh @ p_next @ ikh.T + gain @ r @ gain.T


@pytest.mark.parametrize("seed", range(20))
def test_the_kernel_gives_suh_s_equations(seed):
    p, omega, f, rot, dt, density, residual = _case(seed)
    propagate, measure = _covariance_kernels()
    phi, q_noise, p_next = (np.empty((15, 15)) for _ in range(3))
    propagate(p, omega, f, rot, dt, density, phi, q_noise, p_next)
    dx, p_post = np.empty(15), np.empty((15, 15))
    measure(p_next, _ROWS_FLOOR, residual, np.array([1e-4, 1e-4, 1e-4, 2e-4]), dx, p_post)
    # measured: within 9e-16 of the largest entry (dx; the others within 5e-16)
    want = _by_numpy(p, omega, f, rot, dt, density, residual)
    for got, truth in zip((phi, q_noise, p_next, dx, p_post), want, strict=True):
        assert np.max(np.abs(got - truth)) <= 2e-15 * np.max(np.abs(truth))
    assert np.allclose(p_post, p_post.T, rtol=0, atol=1e-18)  # the Joseph form keeps P symmetric


def test_compiled_and_plain_python_give_the_same_bits(monkeypatch):
    propagate, measure = _covariance_kernels()
    if not hasattr(propagate, "py_func"):
        pytest.skip("numba is not available: the plain-Python kernel is the only one")
    p, omega, f, rot, dt, density, residual = _case(99)
    outputs = []
    for compiled in (True, False):
        if not compiled:
            monkeypatch.setattr(kernel, "_product", kernel._product.py_func)
        run_p = propagate if compiled else propagate.py_func
        run_m = measure if compiled else measure.py_func
        phi, q_noise, p_next = (np.empty((15, 15)) for _ in range(3))
        run_p(p, omega, f, rot, dt, density, phi, q_noise, p_next)
        dx, p_post = np.empty(15), np.empty((15, 15))
        run_m(p_next, _ROWS_FLOOR, residual, np.array([1e-4] * 4), dx, p_post)
        outputs.append((phi, q_noise, p_next, dx, p_post))
    for a, b in zip(*outputs, strict=True):
        assert np.array_equal(a, b)
