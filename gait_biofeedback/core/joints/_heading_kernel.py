"""Per-sample kernels of the joint headings (issue 46), pure Python, numba-able: one source, two runtimes.

:func:`step` is one sample of :class:`~gait_biofeedback.core.joints.relative_heading.RelativeHeadingEstimator`
(its module docstring: steps 2-4, the world turns of step 3 and the centred high-pass of step 2),
:func:`add_row` one joint-centre window row into its heading (after the fit of step 1, which stays in
numpy), :func:`axis_step` one sample of
:class:`~gait_biofeedback.core.joints.axis_heading.AxisHeadingEstimator`. They use only ``math``,
``cmath``, complex numbers and indexing of flat sequences (float state ``f``, int state ``i``, the
ring ``ring`` of recent products, parameters ``p``), so they run as plain Python on lists (the twin,
when numba is missing) and, unchanged, compiled by :func:`gait_biofeedback.core.jit.fast` on numpy
arrays. Both give the same numbers, bit for bit (test_heading_kernel.py): only IEEE operations that
CPython and numba evaluate alike (the 3-norm, which CPython rounds correctly, is :func:`_norm` here).
Stamps are int ns (the int state holds them). Quaternions (w, x, y, z), Hamilton, sensor → world.
"""

from __future__ import annotations

import cmath
import math
from typing import Any

from gait_biofeedback.core.orientation.filters._scalar import half_turn

# ---- float state (f): reset by a restart below KEEP -------------------------------------------------
TURN = 0  # 0..1  E₁, E₂: each filter's own world turn (rad, step 3)
KDELTA = 2  # δ between the gyro-only worlds (step 2)
SUM = 3  # 3..4  exponential sum Σ w·h₁·conj(h₂) (re, im)
MAGNITUDE = 5  # exponential sum of |product|
INFORMATION = 6  # Σ |product| dt since the start
WIN = 7  # 7..10 sums of h₁ (re, im) and h₂ (re, im) over the centred window
LAST = 11  # 11..24 the last sample: q₁ (4), ω₁ (3), q₂ (4), ω₂ (3), for the world turns
BEFORE = 25  # 25..44 the sample before the middle one: turned q₁, ω₁, a₁, turned q₂, ω₂, a₂ (20)
MIDDLE = 45  # 45..64 the middle sample (its row is made when the next one comes)
KEEP = 65
CENTRE = 65  # 65..70 r₁, r₂: sensor → joint centre (m), kept by a restart
AXES = 71  # 71..76 the hip's calibrated medio-lateral axes (sensor coordinates), kept by a restart
N_FLOAT = 77

# ---- int state (i) -------------------------------------------------------------------------------
HAS_LAST, LAST_NS, HAS_BEFORE, BEFORE_NS, HAS_MIDDLE, MIDDLE_NS, ESTABLISHED = range(7)
START, COUNT, CENTRE_AT, EDGE = range(7, 11)  # ring: first row, rows, next centre, newest row in its mean
IKEEP = 11
FITTED, HAS_AXES = 11, 12  # a joint centre is known; the axes are given (kept by a restart)
N_INT = 13

# ---- parameters (p) ------------------------------------------------------------------------------
P_TIME_CONSTANT, P_HALF, P_MIN_INFORMATION, P_MIN_COHERENCE = range(4)
N_PARAM = 4

# ---- ring rows and window rows -------------------------------------------------------------------
RING_WIDTH = 7  # t s, h₁ (re, im), h₂ (re, im), weight, dt
ROW_WIDTH = 29  # q₁ 0..3, ω₁ 4..6, ω̇₁ 7..9, a₁ 10..12, q₂ 13..16, ω₂ 17..19, ω̇₂ 20..22, a₂ 23..25, step,
# t s, motion time (step when either |ω| exceeds MOVING, else 0)

# ---- result bits ---------------------------------------------------------------------------------
RESTARTED, ROW_MADE, NOW_ESTABLISHED = 1, 2, 4

JUMP_BACK_NS = 1_000_000_000  # a stamp this much older than the last one restarts the estimate
MAX_TURN_STEP_NS = 100_000_000  # the longest sample interval over which a heading correction is read
GAP_NS = 250_000_000  # no rate derivative across a longer interval
MOVING = 0.2  # rad/s: a sample counts as motion for the joint-centre window when either |ω| exceeds it
HUBER = 1.0  # m/s²: norm mismatches larger than this weigh as |e| (robust fit)
_SPLIT = 134217729.0  # 2²⁷ + 1 (Dekker's split of a double into two halves)


def _norm(x: float, y: float, z: float) -> float:
    """‖(x, y, z)‖ correctly rounded, as CPython's ``math.hypot``: the squares summed exactly in two
    doubles (Dekker's product, Knuth's sum), the square root corrected by one Newton step."""
    hi = 0.0
    lo = 0.0
    for v in (x, y, z):
        sq = v * v
        big = _SPLIT * v
        vh = big - (big - v)
        vl = v - vh
        err = ((vh * vh - sq) + 2.0 * vh * vl) + vl * vl
        total = hi + sq
        back = total - sq
        lo += ((hi - back) + (sq - (total - back))) + err
        hi = total
    h = math.sqrt(hi)
    if h == 0.0:
        return h
    hh = h * h
    big = _SPLIT * h
    hv = big - (big - h)
    hl = h - hv
    hh_err = ((hv * hv - hh) + 2.0 * hv * hl) + hl * hl
    return h + (((hi - hh) - hh_err) + lo) / (2.0 * h)


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _turned_back(qw: float, qx: float, qy: float, qz: float,
                 turn: float) -> tuple[float, float, float, float]:
    """``R_z(−turn) ⊗ q`` (the products of ``_scalar.multiply``, the same operations)."""
    pw, pz = math.cos(0.5 * turn), -math.sin(0.5 * turn)
    return (pw * qw - 0.0 * qx - 0.0 * qy - pz * qz,
            pw * qx + 0.0 * qw + 0.0 * qz - pz * qy,
            pw * qy - 0.0 * qz + 0.0 * qw + pz * qx,
            pw * qz + 0.0 * qy - 0.0 * qx + pz * qw)


def _vertical_correction(f: Any, at: int, qw: float, qx: float, qy: float, qz: float, gx: float, gy: float,
                         gz: float, dt: float) -> float:
    """Twist about the world vertical (rad) of ``q ⊗ conj(q_last ⊗ exp(ω̄ dt))`` (relative_heading step
    3), ``q_last`` and its rate at ``f[at:at + 7]``; the strap-down step of thesis Eq 7-8."""
    lw, lx, ly, lz = f[at], f[at + 1], f[at + 2], f[at + 3]
    mx, my, mz = (f[at + 4] + gx) * 0.5, (f[at + 5] + gy) * 0.5, (f[at + 6] + gz) * 0.5
    c, s = half_turn(mx, my, mz, dt)
    ex, ey, ez = mx * s, my * s, mz * s
    pw = lw * c - lx * ex - ly * ey - lz * ez
    px = lw * ex + lx * c + ly * ez - lz * ey
    py = lw * ey - lx * ez + ly * c + lz * ex
    pz = lw * ez + lx * ey - ly * ex + lz * c
    cw = qw * pw - qx * -px - qy * -py - qz * -pz
    cz = qw * -pz + qx * -py - qy * -px + qz * pw
    return 2.0 * math.atan2(cz, cw) if cw >= 0 else 2.0 * math.atan2(-cz, -cw)


def _turn_worlds(f: Any, i: Any, ns: int, q1w: float, q1x: float, q1y: float, q1z: float, g1x: float,
                 g1y: float, g1z: float, q2w: float, q2x: float, q2y: float, q2z: float, g2x: float,
                 g2y: float, g2z: float, mag1: bool, mag2: bool) -> None:
    """Each magnetic filter's heading correction since the last sample into its world turn (step 3)."""
    if i[HAS_LAST] != 0 and 0 < ns - i[LAST_NS] <= MAX_TURN_STEP_NS:
        dt = (ns - i[LAST_NS]) * 1e-9
        if mag1:
            f[TURN] = _wrap(f[TURN] + _vertical_correction(f, LAST, q1w, q1x, q1y, q1z, g1x, g1y, g1z, dt))
        if mag2:
            f[TURN + 1] = _wrap(f[TURN + 1]
                                + _vertical_correction(f, LAST + 7, q2w, q2x, q2y, q2z, g2x, g2y, g2z, dt))
    i[HAS_LAST] = 1
    i[LAST_NS] = ns
    for k, v in enumerate((q1w, q1x, q1y, q1z, g1x, g1y, g1z, q2w, q2x, q2y, q2z, g2x, g2y, g2z)):
        f[LAST + k] = v


def _restart(f: Any, i: Any) -> None:
    """Forget everything but the joint centre and the axes (time went back)."""
    for k in range(KEEP):
        f[k] = 0.0
    for k in range(IKEEP):
        i[k] = 0
    i[EDGE] = -1


def _rotate(qw: float, qx: float, qy: float, qz: float, vx: float, vy: float, vz: float) -> complex:
    """x + iy of q ⊗ v ⊗ q* (the horizontal part of a sensor vector in the world)."""
    tx = 2.0 * (qy * vz - qz * vy)
    ty = 2.0 * (qz * vx - qx * vz)
    tz = 2.0 * (qx * vy - qy * vx)
    return complex(vx + qw * tx + (qy * tz - qz * ty), vy + qw * ty + (qz * tx - qx * tz))


def _centre_force(r: Any, at: int, c: Any, rc: int) -> tuple[float, float, float]:
    """a + ω × (ω × r) + ω̇ × r (step 1): the specific force at the joint centre ``c[rc:rc + 3]``, in
    sensor coordinates, of the row's ω, ω̇, a at ``r[at:at + 9]``."""
    wx, wy, wz = r[at], r[at + 1], r[at + 2]
    dx, dy, dz = r[at + 3], r[at + 4], r[at + 5]
    rx, ry, rz = c[rc], c[rc + 1], c[rc + 2]
    cx, cy, cz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx  # ω × r
    return (r[at + 6] + wy * cz - wz * cy + dy * rz - dz * ry,
            r[at + 7] + wz * cx - wx * cz + dz * rx - dx * rz,
            r[at + 8] + wx * cy - wy * cx + dx * ry - dy * rx)


def _coherence(f: Any) -> float:
    return abs(complex(f[SUM], f[SUM + 1])) / f[MAGNITUDE] if f[MAGNITUDE] > 0 else 0.0


def _add_product(f: Any, i: Any, p: Any, product: complex, dt: float) -> int:
    """One high-passed product h₁·conj(h₂) into the exponential sum (step 2); NOW_ESTABLISHED when the
    estimate became established by it (step 4), else 0."""
    a = min(1.0, dt / p[P_TIME_CONSTANT])
    total = complex(f[SUM], f[SUM + 1])
    total += a * (product - total)
    f[SUM], f[SUM + 1] = total.real, total.imag
    size = abs(product)
    f[MAGNITUDE] += a * (size - f[MAGNITUDE])
    f[INFORMATION] += size * dt
    if total != 0:
        f[KDELTA] = cmath.phase(total)
    if i[ESTABLISHED] == 0 and f[INFORMATION] >= p[P_MIN_INFORMATION] and _coherence(f) >= p[P_MIN_COHERENCE]:
        i[ESTABLISHED] = 1
        return NOW_ESTABLISHED
    return 0


def add_row(f: Any, i: Any, ring: Any, p: Any, r: Any) -> int:
    """One window row ``r`` (``ROW_WIDTH``) into the heading: its horizontal joint-centre forces into the
    ring, and every sample whose centred mean is complete now high-passed into the sum (step 2). The
    ring must have room for one row. NOW_ESTABLISHED or 0."""
    c1 = _centre_force(r, 4, f, CENTRE)
    c2 = _centre_force(r, 17, f, CENTRE + 3)
    mismatch = (_norm(c1[0], c1[1], c1[2]) - _norm(c2[0], c2[1], c2[2])) / HUBER
    h1 = _rotate(r[0], r[1], r[2], r[3], c1[0], c1[1], c1[2])
    h2 = _rotate(r[13], r[14], r[15], r[16], c2[0], c2[1], c2[2])
    cap = len(ring) // RING_WIDTH
    at = (i[START] + i[COUNT]) % cap * RING_WIDTH
    ring[at], ring[at + 1], ring[at + 2] = r[27], h1.real, h1.imag
    ring[at + 3], ring[at + 4] = h2.real, h2.imag
    ring[at + 5], ring[at + 6] = 1.0 / (1.0 + mismatch * mismatch), r[26]
    i[COUNT] += 1
    half = p[P_HALF]
    out = 0
    newest = ring[at]
    while i[CENTRE_AT] < i[COUNT] and newest >= ring[(i[START] + i[CENTRE_AT]) % cap * RING_WIDTH] + half:
        t_centre = ring[(i[START] + i[CENTRE_AT]) % cap * RING_WIDTH]
        while i[EDGE] + 1 < i[COUNT] and ring[(i[START] + i[EDGE] + 1) % cap * RING_WIDTH] <= t_centre + half:
            i[EDGE] += 1
            e = (i[START] + i[EDGE]) % cap * RING_WIDTH
            f[WIN] += ring[e + 1]
            f[WIN + 1] += ring[e + 2]
            f[WIN + 2] += ring[e + 3]
            f[WIN + 3] += ring[e + 4]
        while ring[i[START] * RING_WIDTH] < t_centre - half:
            o = i[START] * RING_WIDTH
            f[WIN] -= ring[o + 1]
            f[WIN + 1] -= ring[o + 2]
            f[WIN + 2] -= ring[o + 3]
            f[WIN + 3] -= ring[o + 4]
            i[START] = (i[START] + 1) % cap
            i[COUNT] -= 1
            i[CENTRE_AT] -= 1
            i[EDGE] -= 1
        count = i[EDGE] + 1
        c = (i[START] + i[CENTRE_AT]) % cap * RING_WIDTH
        i[CENTRE_AT] += 1
        mean1 = complex(f[WIN], f[WIN + 1]) / count
        mean2 = complex(f[WIN + 2], f[WIN + 3]) / count
        product = (complex(ring[c + 1], ring[c + 2]) - mean1) * (complex(ring[c + 3], ring[c + 4])
                                                                  - mean2).conjugate() * ring[c + 5]
        out |= _add_product(f, i, p, product, ring[c + 6])
    return out


def step(f: Any, i: Any, ring: Any, p: Any, row: Any, ns: int, q1w: float, q1x: float, q1y: float,
         q1z: float, g1x: float, g1y: float, g1z: float, a1x: float, a1y: float, a1z: float, q2w: float,
         q2x: float, q2y: float, q2z: float, g2x: float, g2y: float, g2z: float, a2x: float, a2y: float,
         a2z: float, mag1: bool, mag2: bool) -> int:
    """One synchronised sample of a joint's two sensors (relative_heading's module docstring): a
    non-finite one is skipped, a repeated or late one too, one more than ``JUMP_BACK_NS`` back restarts
    (RESTARTED); the world turns (step 3); the middle sample's row (ω̇ the central difference) goes
    into ``row`` (ROW_MADE) while no joint centre is known, else into the heading (:func:`add_row`; the
    ring must have room for one row). Result bits: RESTARTED, ROW_MADE, NOW_ESTABLISHED."""
    total = (((((q1w + q1x + q1y + q1z) + (g1x + g1y + g1z)) + (a1x + a1y + a1z)) + (q2w + q2x + q2y + q2z))
             + (g2x + g2y + g2z)) + (a2x + a2y + a2z)
    if not math.isfinite(total):
        return 0
    out = 0
    if i[HAS_MIDDLE] != 0 and ns <= i[MIDDLE_NS]:
        if ns > i[MIDDLE_NS] - JUMP_BACK_NS:
            return 0  # a repeated or late sample
        _restart(f, i)
        out = RESTARTED
    _turn_worlds(f, i, ns, q1w, q1x, q1y, q1z, g1x, g1y, g1z, q2w, q2x, q2y, q2z, g2x, g2y, g2z, mag1, mag2)
    t1 = _turned_back(q1w, q1x, q1y, q1z, f[TURN])
    t2 = _turned_back(q2w, q2x, q2y, q2z, f[TURN + 1])
    has_before, before_ns, middle_ns = i[HAS_BEFORE], i[BEFORE_NS], i[MIDDLE_NS]
    made = has_before != 0 and ns - before_ns <= GAP_NS  # else the start or a gap: no derivative across it
    if made:  # the middle sample's row, ω̇ the central difference around it
        dt = (ns - before_ns) * 1e-9
        for k in range(4):
            row[k] = f[MIDDLE + k]
            row[13 + k] = f[MIDDLE + 10 + k]
        for k, (new1, new2) in enumerate(((g1x, g2x), (g1y, g2y), (g1z, g2z))):
            row[4 + k] = f[MIDDLE + 4 + k]
            row[7 + k] = (new1 - f[BEFORE + 4 + k]) / dt
            row[10 + k] = f[MIDDLE + 7 + k]
            row[17 + k] = f[MIDDLE + 14 + k]
            row[20 + k] = (new2 - f[BEFORE + 14 + k]) / dt
            row[23 + k] = f[MIDDLE + 17 + k]
        row[26] = (middle_ns - before_ns) * 1e-9
        row[27] = middle_ns * 1e-9
        moving = (_norm(row[4], row[5], row[6]) > MOVING or _norm(row[17], row[18], row[19]) > MOVING)
        row[28] = row[26] if moving else 0.0
    for k in range(20):  # the middle sample becomes the one before
        f[BEFORE + k] = f[MIDDLE + k]
    i[HAS_BEFORE], i[BEFORE_NS] = i[HAS_MIDDLE], middle_ns
    for k, v in enumerate((t1[0], t1[1], t1[2], t1[3], g1x, g1y, g1z, a1x, a1y, a1z,
                           t2[0], t2[1], t2[2], t2[3], g2x, g2y, g2z, a2x, a2y, a2z)):
        f[MIDDLE + k] = v
    i[HAS_MIDDLE], i[MIDDLE_NS] = 1, ns
    if not made:
        return out
    if i[FITTED] == 0:
        return out | ROW_MADE
    return out | add_row(f, i, ring, p, row)


def axis_step(f: Any, i: Any, p: Any, ns: int, q1w: float, q1x: float, q1y: float, q1z: float, g1x: float,
              g1y: float, g1z: float, q2w: float, q2x: float, q2y: float, q2z: float, g2x: float, g2y: float,
              g2z: float, mag1: bool, mag2: bool) -> int:
    """One sample of the hip's axis heading (axis_heading's module docstring; the accelerations are not
    used): non-finite skipped, a repeated or late stamp too, one more than ``JUMP_BACK_NS`` back restarts
    (RESTARTED: the axes kept); the world turns; with axes, the product of the two calibrated
    medio-lateral axes' horizontal parts into the exponential sum. Result bits: RESTARTED,
    NOW_ESTABLISHED."""
    total = ((q1w + q1x + q1y + q1z) + (g1x + g1y + g1z) + (q2w + q2x + q2y + q2z)) + (g2x + g2y + g2z)
    if not math.isfinite(total):
        return 0
    out = 0
    if i[HAS_MIDDLE] != 0 and ns <= i[MIDDLE_NS]:
        if ns > i[MIDDLE_NS] - JUMP_BACK_NS:
            return 0
        _restart(f, i)
        out = RESTARTED
    _turn_worlds(f, i, ns, q1w, q1x, q1y, q1z, g1x, g1y, g1z, q2w, q2x, q2y, q2z, g2x, g2y, g2z, mag1, mag2)
    dt = 0.0 if i[HAS_MIDDLE] == 0 else min(ns - i[MIDDLE_NS], MAX_TURN_STEP_NS) * 1e-9
    i[HAS_MIDDLE], i[MIDDLE_NS] = 1, ns
    if i[HAS_AXES] != 0 and dt > 0.0:
        t1 = _turned_back(q1w, q1x, q1y, q1z, f[TURN])
        t2 = _turned_back(q2w, q2x, q2y, q2z, f[TURN + 1])
        h1 = _rotate(t1[0], t1[1], t1[2], t1[3], f[AXES], f[AXES + 1], f[AXES + 2])
        h2 = _rotate(t2[0], t2[1], t2[2], t2[3], f[AXES + 3], f[AXES + 4], f[AXES + 5])
        out |= _add_product(f, i, p, h1 * h2.conjugate(), dt)
    return out


def delta(f: Any) -> float:
    """The heading offset in force (rad): the kinematic one plus the worlds' own turns (step 3)."""
    return _wrap(f[KDELTA] + f[TURN] - f[TURN + 1])


def coherence(f: Any) -> float:
    """``|Σ| / Σ|·|`` of the products so far (0 before any)."""
    return _coherence(f)


# ---- the joint-angle stream's synchronised instant (issue 46) ---------------------------------------
# Segment slots: angles.JOINT_SLOTS (the stream's segments); a sample row is q (4), ω (3), a (3).
SAMPLE_WIDTH = 10
PRESENT, RECOVERING, MAGNETIC, CALIBRATED, LIMB = 1, 2, 4, 8, 16  # segment flags (LIMB: a thigh or shank)
RELATIVE, AXIS = 0, 1  # a joint's heading kind (-1: none, the filters' heading is trusted)
# joint table rows (angles.joint_table): proximal slot, distal slot, the three angle signs
NEED_ROOM = -1  # a joint-centre estimator's ring is full: grow it, then call again
# result bits of :func:`instant`: joint j left without a heading (1 << j), its angles computed
# (1 << (ANGLES_AT + j)), every present segment still and every calibrated limb upright (QUIET), and
# ROWS_PENDING (an estimator made a joint-centre window row: the stream takes it, then calls again
# without the steps)
ANGLES_AT = 8
QUIET = 1 << 6
ROWS_PENDING = 1 << 7


def segment_angles(table: Any, q: Any, flags: Any, rot: Any, out: Any) -> int:
    """Clinical (flexion, adduction, internal rotation) of every joint of ``table`` whose two segments
    are present and calibrated into ``out[3j:3j + 3]`` (angles.py's module docstring, gait.md §1.8): the
    segment orientations ``q ⊗ r`` (thesis Eq 17), ``q_rel = conj(q_prox) ⊗ q_dist`` normalised and
    decomposed Z-X'-Y''. The bits ``1 << j`` of the joints computed."""
    done = 0
    for j in range(len(table)):
        a, b = int(table[j][0]), int(table[j][1])
        both = flags[a] & flags[b]
        if both & PRESENT == 0 or both & CALIBRATED == 0:
            continue
        pw, px, py, pz = _multiply(q[a][0], q[a][1], q[a][2], q[a][3],
                                   rot[a][0], rot[a][1], rot[a][2], rot[a][3])
        dw, dx, dy, dz = _multiply(q[b][0], q[b][1], q[b][2], q[b][3],
                                   rot[b][0], rot[b][1], rot[b][2], rot[b][3])
        w, x, y, z = _multiply(pw, -px, -py, -pz, dw, dx, dy, dz)
        n = math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w / n, x / n, y / n, z / n
        out[3 * j] = table[j][2] * math.atan2(-(2 * (x * y - w * z)), 1 - 2 * (x * x + z * z))
        out[3 * j + 1] = table[j][3] * math.asin(min(max(2 * (y * z + w * x), -1.0), 1.0))
        out[3 * j + 2] = table[j][4] * math.atan2(-(2 * (x * z - w * y)), 1 - 2 * (x * x + y * y))
        done |= 1 << j
    return done


def _multiply(pw: float, px: float, py: float, pz: float, qw: float, qx: float, qy: float,
              qz: float) -> tuple[float, float, float, float]:
    """Hamilton product ``p ⊗ q`` (the operations of ``_scalar.multiply``)."""
    return (pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw)


def _upright(q: Any, k: int, rot: Any, least: float) -> bool:
    """The segment's long axis (anatomical y, ``R(q ⊗ r) ŷ``) within ``acos(least)`` of vertical
    (quaternion.rotate's operations)."""
    w, x, y, z = _multiply(q[k][0], q[k][1], q[k][2], q[k][3],
                           rot[k][0], rot[k][1], rot[k][2], rot[k][3])
    a, b, c = 0.0, 1.0, 0.0
    tx, ty, tz = 2.0 * (y * c - z * b), 2.0 * (z * a - x * c), 2.0 * (x * b - y * a)
    return c + w * tz + (x * ty - y * tx) >= least


def instant(f: Any, i: Any, ring: Any, p: Any, row: Any, kind: Any, table: Any, s: Any, flags: Any,
            rot: Any, out_q: Any, out_angles: Any, codes: Any, steps: bool, ns: int, still_gyro: float,
            least: float) -> int:
    """One synchronised instant of the joint-angle stream (stream.py's class docstring), the estimators'
    state stacked one joint a row (``f``, ``i``, ``ring``, ``p``, ``row``; ``kind`` RELATIVE or AXIS or
    -1), the samples ``s`` one slot a row with their ``flags``. With ``steps``: each joint whose two
    samples are present and not recovering steps its heading estimator (:func:`step` or
    :func:`axis_step`, result bits into ``codes``; NEED_ROOM first if a ring is full, ROWS_PENDING after
    when a row was made). Then the chain: each distal segment turned about the vertical into the pelvis
    sensor's world by the established headings down its leg (relative_heading step 3's
    ``δ = δ_kinematic + E₁ − E₂``), into ``out_q``; the joint angles of :func:`segment_angles` into
    ``out_angles``; whether the instant is quiet (|ω| < ``still_gyro`` everywhere, every calibrated limb
    upright). Result bits: module constants above. (Indexed ``x[a][b]``: the plain twin runs on lists of
    Python floats, as the estimators' own state.)"""
    n_joints = len(table)
    if steps:
        for j in range(n_joints):
            if kind[j] == RELATIVE and i[j][COUNT] >= len(ring[j]) // RING_WIDTH:
                return NEED_ROOM
        pending = 0
        for j in range(n_joints):
            codes[j] = 0
            a, b = int(table[j][0]), int(table[j][1])
            if kind[j] < 0 or (flags[a] & flags[b] & PRESENT) == 0:
                continue
            if ((flags[a] | flags[b]) & RECOVERING) != 0:
                continue
            m1, m2 = (flags[a] & MAGNETIC) != 0, (flags[b] & MAGNETIC) != 0
            if kind[j] == AXIS:
                codes[j] = axis_step(f[j], i[j], p[j], ns, s[a][0], s[a][1], s[a][2], s[a][3], s[a][4],
                                     s[a][5], s[a][6], s[b][0], s[b][1], s[b][2], s[b][3], s[b][4], s[b][5],
                                     s[b][6], m1, m2)
            else:
                codes[j] = step(f[j], i[j], ring[j], p[j], row[j], ns, s[a][0], s[a][1], s[a][2],
                                s[a][3], s[a][4], s[a][5], s[a][6], s[a][7], s[a][8], s[a][9], s[b][0],
                                s[b][1], s[b][2], s[b][3], s[b][4], s[b][5], s[b][6], s[b][7], s[b][8],
                                s[b][9], m1, m2)
            pending |= codes[j] & ROW_MADE
        if pending != 0:
            return ROWS_PENDING
    out = 0
    turn = [0.0] * len(s)
    for j in range(n_joints):
        if kind[j] < 0:
            continue
        a, b = int(table[j][0]), int(table[j][1])
        if i[j][ESTABLISHED] != 0:
            turn[b] = turn[a] + delta(f[j])
        else:
            turn[b] = 0.0  # its own world: the joints below it still work
            out |= 1 << j
    quiet = True
    for k in range(len(s)):
        if flags[k] & PRESENT == 0:
            continue
        if turn[k] != 0.0:
            tw, tx, ty, tz = _turned_back(s[k][0], s[k][1], s[k][2], s[k][3], -turn[k])
            out_q[k, 0], out_q[k, 1], out_q[k, 2], out_q[k, 3] = tw, tx, ty, tz
        else:
            out_q[k, 0], out_q[k, 1], out_q[k, 2], out_q[k, 3] = s[k][0], s[k][1], s[k][2], s[k][3]
        if quiet and not _norm(s[k][4], s[k][5], s[k][6]) < still_gyro:
            quiet = False
    for k in range(len(s)):
        both = LIMB | CALIBRATED | PRESENT
        if quiet and flags[k] & both == both and not _upright(out_q, k, rot, least):
            quiet = False
    if quiet:
        out |= QUIET
    return out | segment_angles(table, out_q, flags, rot, out_angles) << ANGLES_AT
