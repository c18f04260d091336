"""Per-sample kernel of the inertial complementary filter (``inertial_cf``), pure Python, numba-able.

One source, two runtimes: :func:`step` uses only ``math`` and indexing of two flat float sequences
(state ``s`` and parameters ``p``), so it runs as plain Python on lists (the fallback) and, unchanged,
as a numba ``njit`` function on float64 arrays (compiled by :func:`gait_biofeedback.core.jit.compiled` on
first use, with numba's disk cache; ``import gait_biofeedback.core.orientation.filters`` never imports numba).
Both give the same numbers (test_filters.py checks it to 1e-12).

The algorithm is documented in :mod:`~gait_biofeedback.core.orientation.filters.inertial_cf`; the indices
below are the state layout. Quaternions (w, x, y, z), Hamilton, sensor → world (ENU).
"""

from __future__ import annotations

import math
from typing import Any

# ---- state layout (s) ----------------------------------------------------------------------------
QG = 0  # 0..3   gyro strap-down quaternion, sensor → almost-inertial frame I
QA = 4  # 4..7   inclination correction, I → 6D earth frame (accelerometer only)
DELTA = 8  # heading offset (rad) about world z, 6D earth frame → ENU (magnetometer only)
ALP = 9  # 9..11  low-pass filtered accelerometer in frame I (g)
BIAS = 12  # 12..14 online gyro bias (rad/s), on top of the static start-up bias
GLP = 15  # 15..17 low-pass gyro (sensor frame) for rest detection and rest bias
ACCLP = 18  # 18..20 low-pass accelerometer (sensor frame) for rest detection
REST_T = 21  # time at rest (s)
MREF_N = 22  # reference field norm (units of ‖y_M,stat‖)
MREF_DIP = 23  # reference dip angle (rad, positive up)
MREF_SET = 24  # 1.0 once the magnetic reference exists
MDIST = 25  # 1.0 while the magnetometer is rejected
MREJ_T = 26  # time (s) the magnetometer has been rejected without interruption
CAND_N = 27  # candidate new reference: norm
CAND_DIP = 28  # candidate new reference: dip
CAND_T = 29  # time the field has stayed at the candidate
OUT = 30  # 30..33 output quaternion sensor → ENU
REST = 34  # 1.0 while at rest
SBIAS = 35  # 35..37 static gyro bias (rad/s, start-up step)
ACC_NORM = 38  # ‖y_A,stat‖
MAG_NORM = 39  # ‖y_M,stat‖ (0 = not known yet)
FAST_T = 40  # remaining time (s) of fast heading convergence after a rejection
UND_T = 41  # time (s) the field has been undisturbed without interruption
ALP1 = 42  # 42..44 first low-pass stage of the accelerometer in frame I (two-stage mode)
N_STATE = 45

# ---- parameter layout (p) ------------------------------------------------------------------------
PARAM_NAMES = (
    "tau_acc", "tau_mag", "tau_bias", "tau_rest", "rest_gyr", "rest_acc", "rest_time", "bias_max",
    "mag_norm_th", "mag_dip_th", "mag_new_time", "mag_max_reject", "tau_mag_fast", "fast_time",
    "tau_rest_lp", "mag_accept_time", "acc_stages",
)
(P_TAU_ACC, P_TAU_MAG, P_TAU_BIAS, P_TAU_REST, P_REST_GYR, P_REST_ACC, P_REST_TIME, P_BIAS_MAX,
 P_MAG_NORM_TH, P_MAG_DIP_TH, P_MAG_NEW_TIME, P_MAG_MAX_REJECT, P_TAU_MAG_FAST, P_FAST_TIME,
 P_TAU_REST_LP, P_MAG_ACCEPT_TIME, P_ACC_STAGES) = range(len(PARAM_NAMES))


def step(s: Any, p: Any, gx: float, gy: float, gz: float, ax: float, ay: float, az: float,
         mx: float, my: float, mz: float, has_mag: bool, dt: float) -> int:
    """One sample (raw gyro rad/s, acc m/s², mag any unit); updates ``s`` in place.

    Returns 0 when the sample was used, 1 when it was skipped (non-finite gyro/acc or dt ≤ 0; the
    state is untouched). A non-finite or all-zero magnetometer only drops the magnetometer.
    """
    chk = gx + gy + gz + ax + ay + az
    if chk - chk != 0.0 or not dt > 0.0:
        return 1
    if has_mag:
        cm = mx + my + mz
        if cm - cm != 0.0 or (mx == 0.0 and my == 0.0 and mz == 0.0):
            has_mag = False
    # --- conditioning: static bias, accelerometer in g (thesis §5.2.1.2), magnetometer ÷ ‖y_M,stat‖
    gx -= s[SBIAS]
    gy -= s[SBIAS + 1]
    gz -= s[SBIAS + 2]
    ka = 1.0 / s[ACC_NORM]
    ax *= ka
    ay *= ka
    az *= ka

    # --- rest detection (low-pass gyro and acc, deviations below thresholds for rest_time) -------
    kr = dt / (p[P_TAU_REST_LP] + dt)
    s[GLP] += kr * (gx - s[GLP])
    s[GLP + 1] += kr * (gy - s[GLP + 1])
    s[GLP + 2] += kr * (gz - s[GLP + 2])
    s[ACCLP] += kr * (ax - s[ACCLP])
    s[ACCLP + 1] += kr * (ay - s[ACCLP + 1])
    s[ACCLP + 2] += kr * (az - s[ACCLP + 2])
    dgx = gx - s[GLP]
    dgy = gy - s[GLP + 1]
    dgz = gz - s[GLP + 2]
    dax = ax - s[ACCLP]
    day = ay - s[ACCLP + 1]
    daz = az - s[ACCLP + 2]
    glp2 = s[GLP] * s[GLP] + s[GLP + 1] * s[GLP + 1] + s[GLP + 2] * s[GLP + 2]
    rg = p[P_REST_GYR]
    ra = p[P_REST_ACC]
    bm = p[P_BIAS_MAX]
    if (dgx * dgx + dgy * dgy + dgz * dgz < rg * rg and dax * dax + day * day + daz * daz < ra * ra
            and glp2 < bm * bm):
        s[REST_T] += dt
    else:
        s[REST_T] = 0.0
    rest = s[REST_T] >= p[P_REST_TIME]
    s[REST] = 1.0 if rest else 0.0
    if rest:  # block 2: at rest the low-passed gyro is the bias
        kb = dt / (p[P_TAU_REST] + dt)
        s[BIAS] += kb * (s[GLP] - s[BIAS])
        s[BIAS + 1] += kb * (s[GLP + 1] - s[BIAS + 1])
        s[BIAS + 2] += kb * (s[GLP + 2] - s[BIAS + 2])

    # --- strap-down in the almost-inertial frame I: q_g ← q_g ⊗ exp(½ ω dt) (block 3, exact) ------
    wx = gx - s[BIAS]
    wy = gy - s[BIAS + 1]
    wz = gz - s[BIAS + 2]
    nw = math.sqrt(wx * wx + wy * wy + wz * wz)
    half = 0.5 * nw * dt
    if half < 1e-8:
        c = 1.0
        sn = 0.5 * dt
    else:
        c = math.cos(half)
        sn = math.sin(half) / nw
    px = wx * sn
    py = wy * sn
    pz = wz * sn
    w0 = s[QG]
    x0 = s[QG + 1]
    y0 = s[QG + 2]
    z0 = s[QG + 3]
    w = w0 * c - x0 * px - y0 * py - z0 * pz
    x = w0 * px + x0 * c + y0 * pz - z0 * py
    y = w0 * py - x0 * pz + y0 * c + z0 * px
    z = w0 * pz + x0 * py - y0 * px + z0 * c
    n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    w *= n
    x *= n
    y *= n
    z *= n
    s[QG] = w
    s[QG + 1] = x
    s[QG + 2] = y
    s[QG + 3] = z

    # --- accelerometer in frame I, low-pass there (segment accelerations average out) ------------
    aix = (1.0 - 2.0 * (y * y + z * z)) * ax + 2.0 * (x * y - w * z) * ay + 2.0 * (x * z + w * y) * az
    aiy = 2.0 * (x * y + w * z) * ax + (1.0 - 2.0 * (x * x + z * z)) * ay + 2.0 * (y * z - w * x) * az
    aiz = 2.0 * (x * z - w * y) * ax + 2.0 * (y * z + w * x) * ay + (1.0 - 2.0 * (x * x + y * y)) * az
    if p[P_ACC_STAGES] >= 2.0:  # two cascaded first-order stages of τ_acc/2 each (-40 dB/decade)
        kacc = dt / (0.5 * p[P_TAU_ACC] + dt)
        s[ALP1] += kacc * (aix - s[ALP1])
        s[ALP1 + 1] += kacc * (aiy - s[ALP1 + 1])
        s[ALP1 + 2] += kacc * (aiz - s[ALP1 + 2])
        aix = s[ALP1]
        aiy = s[ALP1 + 1]
        aiz = s[ALP1 + 2]
    else:
        kacc = dt / (p[P_TAU_ACC] + dt)
    s[ALP] += kacc * (aix - s[ALP])
    s[ALP + 1] += kacc * (aiy - s[ALP + 1])
    s[ALP + 2] += kacc * (aiz - s[ALP + 2])

    # --- inclination correction: rotate q_a so that R(q_a)·a_lp is vertical (full step) ---------
    aw = s[QA]
    axq = s[QA + 1]
    ayq = s[QA + 2]
    azq = s[QA + 3]
    lx = s[ALP]
    ly = s[ALP + 1]
    lz = s[ALP + 2]
    ex = (1.0 - 2.0 * (ayq * ayq + azq * azq)) * lx + 2.0 * (axq * ayq - aw * azq) * ly \
        + 2.0 * (axq * azq + aw * ayq) * lz
    ey = 2.0 * (axq * ayq + aw * azq) * lx + (1.0 - 2.0 * (axq * axq + azq * azq)) * ly \
        + 2.0 * (ayq * azq - aw * axq) * lz
    ez = 2.0 * (axq * azq - aw * ayq) * lx + 2.0 * (ayq * azq + aw * axq) * ly \
        + (1.0 - 2.0 * (axq * axq + ayq * ayq)) * lz
    hor = math.sqrt(ex * ex + ey * ey)
    cx = 0.0
    cy = 0.0
    if hor > 1e-12:
        ang = math.atan2(hor, ez)  # well conditioned near 0 (acos(ez/‖a‖) would amplify rounding)
        ux = ey / hor  # axis a_E × e_z / ‖·‖ = (a_y, −a_x, 0) / ‖·‖
        uy = -ex / hor
        cx = ang * ux
        cy = ang * uy
        hc = math.cos(0.5 * ang)
        hs = math.sin(0.5 * ang)
        qcx = hs * ux
        qcy = hs * uy
        # q_a ← q_c ⊗ q_a (world-frame rotation, q_c = (hc, qcx, qcy, 0))
        nw_ = hc * aw - qcx * axq - qcy * ayq
        nx_ = hc * axq + qcx * aw + qcy * azq
        ny_ = hc * ayq - qcx * azq + qcy * aw
        nz_ = hc * azq + qcx * ayq - qcy * axq
        n = 1.0 / math.sqrt(nw_ * nw_ + nx_ * nx_ + ny_ * ny_ + nz_ * nz_)
        aw = nw_ * n
        axq = nx_ * n
        ayq = ny_ * n
        azq = nz_ * n
        s[QA] = aw
        s[QA + 1] = axq
        s[QA + 2] = ayq
        s[QA + 3] = azq

    # --- 6D orientation q6 = q_a ⊗ q_g ---------------------------------------------------------------
    q6w = aw * w - axq * x - ayq * y - azq * z
    q6x = aw * x + axq * w + ayq * z - azq * y
    q6y = aw * y - axq * z + ayq * w + azq * x
    q6z = aw * z + axq * y - ayq * x + azq * w

    # --- bias during motion from the inclination correction (Mahony-type integral, block 2) --------
    if not rest and p[P_TAU_BIAS] > 0.0:
        # correction c (world, horizontal) seen in the sensor frame: R(q6)ᵀ c
        csx = (1.0 - 2.0 * (q6y * q6y + q6z * q6z)) * cx + 2.0 * (q6x * q6y + q6w * q6z) * cy
        csy = 2.0 * (q6x * q6y - q6w * q6z) * cx + (1.0 - 2.0 * (q6x * q6x + q6z * q6z)) * cy
        csz = 2.0 * (q6x * q6z + q6w * q6y) * cx + 2.0 * (q6y * q6z - q6w * q6x) * cy
        kbm = 1.0 / p[P_TAU_BIAS]
        bx = s[BIAS] - kbm * csx
        by = s[BIAS + 1] - kbm * csy
        bz = s[BIAS + 2] - kbm * csz
        nb = math.sqrt(bx * bx + by * by + bz * bz)
        if nb > bm:
            bx *= bm / nb
            by *= bm / nb
            bz *= bm / nb
        s[BIAS] = bx
        s[BIAS + 1] = by
        s[BIAS + 2] = bz

    # --- magnetometer: heading only, with disturbance detection and rejection (blocks 6, 7) --------
    if has_mag:
        if s[MAG_NORM] <= 0.0:
            s[MAG_NORM] = math.sqrt(mx * mx + my * my + mz * mz)
        km = 1.0 / s[MAG_NORM]
        mx *= km
        my *= km
        mz *= km
        mex = (1.0 - 2.0 * (q6y * q6y + q6z * q6z)) * mx + 2.0 * (q6x * q6y - q6w * q6z) * my \
            + 2.0 * (q6x * q6z + q6w * q6y) * mz
        mey = 2.0 * (q6x * q6y + q6w * q6z) * mx + (1.0 - 2.0 * (q6x * q6x + q6z * q6z)) * my \
            + 2.0 * (q6y * q6z - q6w * q6x) * mz
        mez = 2.0 * (q6x * q6z - q6w * q6y) * mx + 2.0 * (q6y * q6z + q6w * q6x) * my \
            + (1.0 - 2.0 * (q6x * q6x + q6y * q6y)) * mz
        mh = math.sqrt(mex * mex + mey * mey)
        nm = math.sqrt(mh * mh + mez * mez)
        dip = math.atan2(mez, mh)
        psi = math.atan2(mex, mey)  # rotation about z that brings the horizontal field onto +y
        if s[MREF_SET] == 0.0:
            s[MREF_N] = nm
            s[MREF_DIP] = dip
            s[MREF_SET] = 1.0
            s[DELTA] = psi
        disturbed = (abs(nm - s[MREF_N]) > p[P_MAG_NORM_TH] * s[MREF_N]
                     or abs(dip - s[MREF_DIP]) > p[P_MAG_DIP_TH])
        correct = False
        if disturbed:
            s[MREJ_T] += dt
            s[UND_T] = 0.0
            # a field that stays constant (norm and dip) for mag_new_time becomes the new reference
            if (abs(nm - s[CAND_N]) < p[P_MAG_NORM_TH] * s[CAND_N]
                    and abs(dip - s[CAND_DIP]) < p[P_MAG_DIP_TH]):
                s[CAND_T] += dt
                kc = dt / (1.0 + dt)
                s[CAND_N] += kc * (nm - s[CAND_N])
                s[CAND_DIP] += kc * (dip - s[CAND_DIP])
            else:
                s[CAND_N] = nm
                s[CAND_DIP] = dip
                s[CAND_T] = 0.0
            if s[CAND_T] >= p[P_MAG_NEW_TIME]:
                s[MREF_N] = s[CAND_N]
                s[MREF_DIP] = s[CAND_DIP]
                s[FAST_T] = p[P_FAST_TIME]
                s[MREJ_T] = 0.0
                s[UND_T] = p[P_MAG_ACCEPT_TIME]
                correct = True
        else:
            s[UND_T] += dt
            if s[UND_T] >= p[P_MAG_ACCEPT_TIME]:  # undisturbed long enough: accept again
                if s[MREJ_T] >= p[P_MAG_ACCEPT_TIME]:  # after a real rejection: catch up quickly
                    s[FAST_T] = p[P_FAST_TIME]
                s[MREJ_T] = 0.0
                s[CAND_T] = 0.0
                correct = True
        if not correct and s[MREJ_T] >= p[P_MAG_MAX_REJECT]:
            correct = True  # rejected too long: the gyro heading is no better any more
        if correct:
            tau = p[P_TAU_MAG]
            if s[FAST_T] > 0.0:
                s[FAST_T] -= dt
                tau = p[P_TAU_MAG_FAST]
            e = psi - s[DELTA]
            e = (e + math.pi) % (2.0 * math.pi) - math.pi
            s[DELTA] += dt / (tau + dt) * e
        s[MDIST] = 0.0 if correct else 1.0

    # --- output q = R_z(δ) ⊗ q6 -----------------------------------------------------------------------
    hcz = math.cos(0.5 * s[DELTA])
    hsz = math.sin(0.5 * s[DELTA])
    ow = hcz * q6w - hsz * q6z
    ox = hcz * q6x - hsz * q6y
    oy = hcz * q6y + hsz * q6x
    oz = hcz * q6z + hsz * q6w
    n = 1.0 / math.sqrt(ow * ow + ox * ox + oy * oy + oz * oz)
    s[OUT] = ow * n
    s[OUT + 1] = ox * n
    s[OUT + 2] = oy * n
    s[OUT + 3] = oz * n
    return 0


def run(s: Any, p: Any, g: Any, a: Any, m: Any, has_mag: Any, dt: Any, out: Any) -> int:
    """:func:`step` over n samples (the batch twin of a loop of steps, as vqf's ``updateBatch``): ``g``,
    ``a``, ``m`` flat (3n) gyro, accelerometer, magnetometer, ``has_mag`` and ``dt`` (n); writes each
    sample's output quaternion and total gyro bias (static + online) into ``out`` (flat 7n: w, x, y, z,
    bx, by, bz). Returns the number of samples skipped."""
    skipped = 0
    for i in range(len(dt)):
        j = 3 * i
        skipped += step(s, p, g[j], g[j + 1], g[j + 2], a[j], a[j + 1], a[j + 2], m[j], m[j + 1], m[j + 2],
                        has_mag[i], dt[i])
        k = 7 * i
        for c in range(4):
            out[k + c] = s[OUT + c]
        for c in range(3):
            out[k + 4 + c] = s[SBIAS + c] + s[BIAS + c]
    return skipped
