"""Smoothers of the foot filter's trajectory (gait.md §4.4-4.5): Suh 2014's quadratic program and the
Rauch-Tung-Striebel backward pass, both on the error model of :mod:`.kalman`.

Both estimate the errors of the filter's post-update trajectory from all the samples of a window,
not only the past ones; the flat floor and the zero velocity of every stance then act on the swing
between them as well.

- :func:`suh_smooth` is Suh's smoother (Eq 16-30), with the normal equations as corrected in
  gait.md §4.5 (the paper's Appendix has index and factor errors). The error is 9 × 1 per sample
  plus one time-invariant bias error relative to the filter's final bias (Eq 16-17). ``M₁₁`` is
  block-tridiagonal, a band of width 17, so it is solved by banded Cholesky and a Schur complement
  for the 6 bias columns (Eq 36-41, signs as corrected).
  - READING (Eq 20, gait.md §6.4 item 36): ``f_k`` is evaluated with the final bias. To first
    order ``ζ_k = δx_{k+1} - Ψ_k (b̂_N - b̂_k)``: the update injected at k+1, minus what the bias
    change would have moved.
  - READING: ``X_init`` is the initial state relative to the first post-update sample,
    ``-δx_1`` (0 when the first sample is not updated; the printed ``[q̂; 0; 0]`` cannot be meant).
- :func:`rts_smooth` is the RTS pass over the 15-state model (biases as states):
  ``e_k = C_k (δx_{k+1} + e_{k+1})`` with ``C_k = P⁺_k Φ_k' (P⁻_{k+1})⁻¹``, starting from
  ``e = 0`` at the window's last sample. It is O(N) and needs no band solver, so the live stream
  smooths each stride with it; offline both are available (``benchmarks/spatial.py`` compares them).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.linalg import cho_solve_banded, cholesky_banded

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.spatial.kalman import NAV, STATES, KalmanStep

BAND = 2 * NAV - 1  # upper bandwidth of M₁₁: 17 (Suh §5)
RTS_BLOCK = 1024  # steps whose RTS gains are solved together


def apply(steps: Sequence[KalmanStep], errors: np.ndarray,
          bias: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The filter's states corrected by ``errors`` (N, ≥ 9): orientation, position, velocity, bias."""
    q = np.array([s.q for s in steps])
    r = np.array([s.r for s in steps])
    v = np.array([s.v for s in steps])
    b = np.array([s.b for s in steps]) if bias is None else np.broadcast_to(bias, (len(steps), 6))
    if errors.shape[1] == STATES:
        b = b + errors[:, 9:15]
    return {"orientation": quat.normalize(quat.multiply(q, quat.from_rotvec(errors[:, 0:3]))),
            "position": r + errors[:, 3:6], "velocity": v + errors[:, 6:9], "bias": np.array(b)}


def rts_smooth(steps: Sequence[KalmanStep]) -> dict[str, np.ndarray]:
    """RTS over ``steps`` (each but the last with its ``phi``); the last sample is kept as filtered."""
    n = len(steps)
    errors = np.zeros((n, STATES))
    e = np.zeros(STATES)
    for hi in range(n - 1, 0, -RTS_BLOCK):
        lo = max(0, hi - RTS_BLOCK)
        # C_k' of the block's k in one stacked solve (the same LAPACK call per matrix as one at a time;
        # blocks keep a whole session's offline pass from stacking gigabytes)
        block = steps[lo:hi]
        gains_t = np.linalg.solve(np.array([s.p_prior for s in steps[lo + 1:hi + 1]]),
                                  np.array([s.phi for s in block]) @ np.array([s.p_post for s in block]))
        for k in range(hi - 1, lo - 1, -1):
            e = gains_t[k - lo].T @ (steps[k + 1].dx + e)
            errors[k] = e
    return apply(steps, errors)


def _floor_rows(flat_floor: bool) -> tuple[np.ndarray, np.ndarray]:
    rows = 4 if flat_floor else 3
    h = np.zeros((rows, NAV))
    h[0:3, 6:9] = np.eye(3)
    if flat_floor:
        h[3, 5] = 1.0
    return h, np.arange(rows)


def suh_smooth(steps: Sequence[KalmanStep], noise, flat_floor: bool = True,
               bias_prior: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Suh's smoother on ``steps`` (Eq 27-30, §5): the minimiser of J by banded Cholesky + Schur."""
    n = len(steps)
    phi = np.array([s.phi for s in steps[:-1]])
    big_phi, psi = phi[:, :NAV, :NAV], phi[:, :NAV, NAV:]
    q_inv = np.linalg.inv(np.array([s.q_noise[:NAV, :NAV] for s in steps[:-1]]))
    b_k = np.array([s.b for s in steps[:-1]])
    b_final = steps[-1].b
    dx_next = np.array([s.dx[:NAV] for s in steps[1:]])
    zeta = dx_next - np.einsum("kij,kj->ki", psi, b_final - b_k)  # Eq 19-20, READING above

    phit_qi = np.einsum("kji,kjl->kil", big_phi, q_inv)  # Φ' Q⁻¹
    diag = np.zeros((n, NAV, NAV))
    diag[:-1] += phit_qi @ big_phi
    diag[1:] += q_inv
    upper = -phit_qi  # M₁₁[k, k+1]
    m12 = np.zeros((n, NAV, 6))
    m12[:-1] += phit_qi @ psi
    m12[1:] -= q_inv @ psi
    m13 = np.einsum("kji,kjl,klm->im", psi, q_inv, psi)
    m21 = np.zeros((n, NAV))
    m21[:-1] -= np.einsum("kij,kj->ki", phit_qi, zeta)
    m21[1:] += np.einsum("kij,kj->ki", q_inv, zeta)
    m22 = -np.einsum("kji,kjl,kl->i", psi, q_inv, zeta)

    h, _ = _floor_rows(flat_floor)
    r_diag = [noise.zero_velocity] * 3 + ([noise.floor] if flat_floor else [])
    h_ri = h.T / np.array(r_diag)  # H' R⁻¹
    zv = np.array([s.zero_velocity for s in steps])
    z = np.array([np.append(-s.v, -s.r[2]) if flat_floor else -s.v for s in steps])
    diag[zv] += h_ri @ h
    m21[zv] -= z[zv] @ h_ri.T

    p0 = steps[0].p_prior
    p0_inv = np.linalg.inv(p0[:NAV, :NAV])
    diag[0] += p0_inv
    m21[0] -= p0_inv @ -steps[0].dx[:NAV]
    pb_inv = np.linalg.inv(p0[NAV:, NAV:])
    prior = np.zeros(6) if bias_prior is None else np.asarray(bias_prior, float)
    m13 = m13 + pb_inv
    m22 = m22 + pb_inv @ (b_final - prior)

    chol = cholesky_banded(_band(diag, upper), lower=False)
    y1 = cho_solve_banded((chol, False), m12.reshape(n * NAV, 6))
    y2 = cho_solve_banded((chol, False), m21.reshape(n * NAV))
    m12_flat = m12.reshape(n * NAV, 6)
    bias_error = np.linalg.solve(m13 - m12_flat.T @ y1, -m22 + m12_flat.T @ y2)
    x = (-y2 - y1 @ bias_error).reshape(n, NAV)
    return apply(steps, x, bias=b_final + bias_error)


def _band(diag: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Upper band storage ``ab[BAND + i - j, j] = M[i, j]`` of the block-tridiagonal M₁₁."""
    n = len(diag)
    ab = np.zeros((BAND + 1, n * NAV))
    blocks = np.arange(n) * NAV
    for a in range(NAV):
        for c in range(a, NAV):
            ab[BAND + a - c, blocks + c] = diag[:, a, c]
        for c in range(NAV):
            ab[BAND + a - NAV - c, blocks[1:] + c] = upper[:, a, c]
    return ab
