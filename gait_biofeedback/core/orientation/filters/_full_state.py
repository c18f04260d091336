"""Model pieces shared by the thesis' full-state filters (state x = [q, a, b_G, d], 13 entries).

Thesis §5.2.1 (orientation.md §5–6): q (4) orientation, a (3) external acceleration in the sensor
frame (AR(1), c_a), b_G (3) gyro bias (random walk), d (3) magnetic disturbance in the sensor frame
(AR(1), c_d). Accelerometer in g (÷‖y_A,stat‖), magnetometer ÷‖y_M,stat‖, ᴳg = (0, 0, 1).
"""

from __future__ import annotations

import numpy as np

Q, A, B, D = slice(0, 4), slice(4, 7), slice(7, 10), slice(10, 13)


def xi(q: np.ndarray) -> np.ndarray:
    """Ξ(q) of thesis Eq 40 (4×3); ``-Ξ`` maps ω to 2 q̇."""
    q0, q1, q2, q3 = q
    return np.array([[q1, q2, q3], [-q0, q3, -q2], [-q3, -q0, q1], [q2, -q1, -q0]])


def omega_matrix(w: np.ndarray) -> np.ndarray:
    """Ω(ω) of thesis Eq 8/27 (4×4): q̇ = Ω(ω) q = ½ q ⊗ [0 ω]."""
    x, y, z = w
    return 0.5 * np.array([[0.0, -x, -y, -z], [x, 0.0, z, -y], [y, -z, 0.0, x], [z, y, -x, 0.0]])


def transition(q: np.ndarray, w: np.ndarray, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Φ = I + ΩT_s + ½Ω²T_s² (thesis Eq 38) and ∂q⁻/∂b_G = T_s²/4 q ωᵀ + T_s/2 Ξ(q) (thesis Eq 40)."""
    om = omega_matrix(w) * ts
    phi = np.eye(4) + om + 0.5 * om @ om
    dq_db = (0.25 * ts * ts) * np.outer(q, w) + (0.5 * ts) * xi(q)
    return phi, dq_db


def predict(x: np.ndarray, P: np.ndarray, w: np.ndarray, ts: float, sigma_g: float,
            p: dict) -> tuple[np.ndarray, np.ndarray]:
    """Prediction shared by both full-state filters: x⁻ (q by Φ, not normalised; external acceleration
    and magnetic disturbance decayed by the AR(1) coefficients c_a, c_d) and P⁻ = F P Fᵀ + 𝒬 with the
    Jacobian F of thesis Eq 39–40 (Eq 26–28 for the linear KF)."""
    q = x[Q]
    phi, dq_db = transition(q, w, ts)
    xp = x.copy()
    xp[Q] = phi @ q
    xp[A] *= p["c_a"]
    xp[D] *= p["c_d"]
    F = np.eye(13)
    F[Q, Q] = phi
    F[Q, B] = dq_db
    F[A, A] *= p["c_a"]
    F[D, D] *= p["c_d"]
    return xp, F @ P @ F.T + process_noise(q, ts, sigma_g, p["sigma_aw"], p["sigma_bw"], p["sigma_dw"])


def process_noise(q: np.ndarray, ts: float, sigma_g: float, sigma_aw: float, sigma_bw: float,
                  sigma_dw: float) -> np.ndarray:
    """𝒬_k of thesis Eq 28 (13×13), Ξ evaluated at q⁺_k."""
    out = np.zeros((13, 13))
    x = xi(q)
    out[Q, Q] = (0.25 * ts * ts * sigma_g * sigma_g) * (x @ x.T)
    out[A, A] = np.eye(3) * (sigma_aw * sigma_aw * ts)
    out[B, B] = np.eye(3) * (sigma_bw * sigma_bw * ts)
    out[D, D] = np.eye(3) * (sigma_dw * sigma_dw * ts)
    return out


def predicted_acc(q: np.ndarray) -> np.ndarray:
    """R(q)ᵀ ᴳg with ᴳg = (0, 0, 1): rows 1–3 of thesis Eq 31/42 without a and y_A."""
    q0, q1, q2, q3 = q
    return np.array([2.0 * (q1 * q3 - q0 * q2), 2.0 * (q0 * q1 + q2 * q3), 1.0 - 2.0 * (q1 * q1 + q2 * q2)])


def predicted_mag(q: np.ndarray, m: np.ndarray) -> np.ndarray:
    """R(q)ᵀ ᴳm: rows 4–6 of thesis Eq 31/42 without d and y_M."""
    q0, q1, q2, q3 = q
    mx, my, mz = m
    return 2.0 * np.array([
        mx * (0.5 - q2 * q2 - q3 * q3) + my * (q0 * q3 + q1 * q2) + mz * (q1 * q3 - q0 * q2),
        mx * (q1 * q2 - q0 * q3) + my * (0.5 - q1 * q1 - q3 * q3) + mz * (q0 * q1 + q2 * q3),
        mx * (q0 * q2 + q1 * q3) + my * (q2 * q3 - q0 * q1) + mz * (0.5 - q1 * q1 - q2 * q2),
    ])


def jacobian_acc(q: np.ndarray) -> np.ndarray:
    """H_A of thesis Eq 34 (3×4)."""
    q0, q1, q2, q3 = q
    return 2.0 * np.array([[-q2, q3, -q0, q1], [q1, q0, q3, q2], [0.0, -2.0 * q1, -2.0 * q2, 0.0]])


def jacobian_mag(q: np.ndarray, m: np.ndarray) -> np.ndarray:
    """H_M of thesis Eq 34 (3×4) for the Earth-frame field m = (m_x, m_y, m_z)."""
    q0, q1, q2, q3 = q
    mx, my, mz = m
    return 2.0 * np.array([
        [my * q3 - mz * q2, my * q2 + mz * q3,
         -2 * mx * q2 + my * q1 - mz * q0, -2 * mx * q3 + my * q0 + mz * q1],
        [-mx * q3 + mz * q1, mx * q2 - 2 * my * q1 + mz * q0,
         mx * q1 + mz * q3, -mx * q0 - 2 * my * q3 + mz * q2],
        [mx * q2 - my * q1, mx * q3 - my * q0 - 2 * mz * q1,
         mx * q0 + my * q3 - 2 * mz * q2, mx * q1 + my * q2],
    ])
