"""The zero-velocity detector's per-sample arithmetic (:mod:`.zero_velocity`), numba-able (issue 46).

One source, two runtimes: plain Python on numpy arrays (the twin) and, unchanged, numba ``njit``
(:func:`gait_biofeedback.core.jit.fast`). The state lives in ring buffers indexed by absolute sample
number modulo their length, so that :func:`update` (one sample, the stream) and :func:`run` (whole
arrays, the array function) share it: after either, the detector is where the other would leave it.

Per sample: Suh's per-sample thresholds (Suh 2014 Eq 4), the gait scale's causal percentile
(:class:`~.zero_velocity.GaitScale`), the fixed rule (Suh, or Skog 2010's SHOE) and the gait-scaled
SHOE test of the sample ``h`` behind, the valley statistic ``c`` of the sample ``s`` behind, and the
release of every sample no undecided valley can reach any more (:class:`~.zero_velocity.StanceDetector`).
Sums are numpy's (pairwise over the flattened window, rows in order), so that the decisions are those of
the numpy code; norms are ``sqrt(x² + y² + z²)`` (numpy's BLAS dot may fuse a multiply-add: these norms
only meet thresholds here).
"""

from __future__ import annotations

import math

import numpy as np

GRAVITY_SHOE = 9.81  # m/s², :data:`.zero_velocity.GRAVITY_SHOE`

# ---- parameters (p, float64) -------------------------------------------------------------------
(P_RULE_HALF, P_TEST_HALF, P_HALF, P_LAG, P_GYRO_LIMIT, P_ACC_LIMIT, P_ACC_SCALE, P_GYRO_SCALE, P_SHOE,
 P_GAIT, P_ADAPTIVE, P_EVERY, P_SPAN, P_VALLEY, P_VALLEY_MAX, P_VALLEY_SWING, P_VHALF, P_BEFORE, P_AFTER,
 P_GAP, P_GAIT_ACC, P_SCALE_LOW, P_SCALE_HIGH, P_KAPPA, P_VALLEY_KAPPA, P_PERCENTILE) = range(26)
N_PARAMS = 26

# ---- counters (z, int64) -----------------------------------------------------------------------
SEEN = 0  # samples in
NF = 1  # fixed-rule decisions known (samples 0 .. NF - 1)
NC = 2  # valley statistics known
NEXT = 3  # the next sample to release
ENDED = 4  # 1 once flushed
PAST_HEAD = 5  # the gait scale's oldest entry in ``past``
PAST_N = 6  # its entries
N_COUNTERS = 7
# ``scale`` (float64, 1): the gait scale σ_ω now
# ``win`` (W, 8): quiet, ω, a, σ_ω of the last W = 2 h + 1 samples; ``acc_ring`` (lag, 3)
# ``past`` (P, 2): sample number and | |a| - g | of the moving samples the scale is learnt from
# ``ring`` (R, 3): c, the decision, the fixed rule's alone; ``status`` (R, 2): valley m, its status


def _block(x: np.ndarray, lo: int, n: int) -> float:
    """numpy's pairwise sum of ``x[lo:lo + n]``, ``n`` <= 128: one block (8 accumulators)."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += x[i]
        return res
    r0, r1, r2, r3 = x[lo], x[lo + 1], x[lo + 2], x[lo + 3]
    r4, r5, r6, r7 = x[lo + 4], x[lo + 5], x[lo + 6], x[lo + 7]
    i = 8
    while i < n - n % 8:
        r0 += x[lo + i]
        r1 += x[lo + i + 1]
        r2 += x[lo + i + 2]
        r3 += x[lo + i + 3]
        r4 += x[lo + i + 4]
        r5 += x[lo + i + 5]
        r6 += x[lo + i + 6]
        r7 += x[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += x[lo + i]
        i += 1
    return res


def _split(n: int) -> int:
    """Where numpy splits a sum over more than 128 values: half, down to a multiple of 8."""
    half = n // 2
    return half - half % 8


def _pairwise_1(x: np.ndarray, lo: int, n: int) -> float:
    if n <= 128:
        return _block(x, lo, n)
    half = _split(n)
    return _block(x, lo, half) + _block(x, lo + half, n - half)


def _pairwise_2(x: np.ndarray, lo: int, n: int) -> float:
    if n <= 128:
        return _block(x, lo, n)
    half = _split(n)
    return _pairwise_1(x, lo, half) + _pairwise_1(x, lo + half, n - half)


def _pairwise_3(x: np.ndarray, lo: int, n: int) -> float:
    if n <= 128:
        return _block(x, lo, n)
    half = _split(n)
    return _pairwise_2(x, lo, half) + _pairwise_2(x, lo + half, n - half)


def _pairwise(x: np.ndarray, lo: int, n: int) -> float:
    """numpy's sum of ``x[lo:lo + n]``: its pairwise summation (blocks of at most 128 values, 8
    accumulators each), the same for up to 1,929 values (3 × a window of 643 samples: 0.5 s at 1,280 Hz;
    beyond, a few ulps off numpy's). Four levels written out: numba's cache cannot load a recursive
    function (it crashed the process)."""
    if n <= 128:
        return _block(x, lo, n)
    half = _split(n)
    return _pairwise_3(x, lo, half) + _pairwise_3(x, lo + half, n - half)


def _shoe(win: np.ndarray, lo: int, hi: int, acc_scale: float, gyro_scale: float) -> float:
    """Skog 2010's SHOE statistic over samples ``lo .. hi`` (:func:`.zero_velocity._shoe_statistic`)."""
    w = win.shape[0]
    n = hi - lo + 1
    tx, ty, tz = 0.0, 0.0, 0.0
    sq_acc = np.empty(3 * n)
    sq_gyr = np.empty(3 * n)
    for j in range(lo, hi + 1):
        row = j % w
        ax, ay, az = win[row, 4], win[row, 5], win[row, 6]
        tx += ax
        ty += ay
        tz += az
        i = 3 * (j - lo)
        sq_acc[i], sq_acc[i + 1], sq_acc[i + 2] = ax * ax, ay * ay, az * az
        gx, gy, gz = win[row, 1], win[row, 2], win[row, 3]
        sq_gyr[i], sq_gyr[i + 1], sq_gyr[i + 2] = gx * gx, gy * gy, gz * gz
    norm = math.sqrt(tx * tx + ty * ty + tz * tz)
    acc_part = _pairwise(sq_acc, 0, 3 * n) - 2.0 * GRAVITY_SHOE * norm + n * GRAVITY_SHOE ** 2
    return (acc_part / acc_scale ** 2 + _pairwise(sq_gyr, 0, 3 * n) / gyro_scale ** 2) / n


def _percentile(values: np.ndarray, q: float) -> float:
    """numpy's ``percentile(values, q)``, its default linear method."""
    s = np.sort(values)
    n = s.shape[0]
    virtual = (n - 1) * (q / 100.0)
    if virtual >= n - 1:
        return s[n - 1]
    below = math.floor(virtual)
    a, b = s[int(below)], s[int(below) + 1]
    t = virtual - below
    diff = b - a
    if t >= 0.5:
        return b - diff * (1.0 - t)
    return a + diff * t


def _gait_scale(p: np.ndarray, z: np.ndarray, scale: np.ndarray, past: np.ndarray, ax: float, ay: float,
                az: float, moving: bool) -> float:
    """:meth:`.zero_velocity.GaitScale.update` of sample ``z[SEEN]``."""
    seen = z[SEEN]
    every, span, cap = int(p[P_EVERY]), int(p[P_SPAN]), past.shape[0]
    if seen and seen % every == 0:
        while z[PAST_N] and past[z[PAST_HEAD], 0] < seen - span:
            z[PAST_HEAD] = (z[PAST_HEAD] + 1) % cap
            z[PAST_N] -= 1
        if z[PAST_N] >= every:
            values = np.empty(z[PAST_N])
            for i in range(z[PAST_N]):
                values[i] = past[(z[PAST_HEAD] + i) % cap, 1]
            a = _percentile(values, p[P_PERCENTILE])
            if a >= p[P_GAIT_ACC]:
                scale[0] = min(max(p[P_ADAPTIVE] * a, p[P_SCALE_LOW]), p[P_SCALE_HIGH])
    if moving:
        tail = (z[PAST_HEAD] + z[PAST_N]) % cap
        past[tail, 0] = seen
        past[tail, 1] = abs(math.sqrt(ax * ax + ay * ay + az * az) - GRAVITY_SHOE)
        z[PAST_N] += 1
    return scale[0]


def _judge(p: np.ndarray, win: np.ndarray, k: int, last: int) -> int:
    """(the fixed rule's decision) + 2 (the decision) of sample ``k``, its windows cut at 0 and ``last``."""
    w = win.shape[0]
    rule_half = int(p[P_RULE_HALF])
    lo, hi = max(0, k - rule_half), min(last, k + rule_half)
    if p[P_SHOE]:
        still = _shoe(win, lo, hi, p[P_ACC_SCALE], p[P_GYRO_SCALE]) <= 1.0
    else:
        still = True
        for j in range(lo, hi + 1):
            if not win[j % w, 0]:
                still = False
                break
    if not still:
        return 0
    if not p[P_GAIT]:
        return 3
    test_half = int(p[P_TEST_HALF])
    scale = win[k % w, 7]
    tested = _shoe(win, max(0, k - test_half), min(last, k + test_half), p[P_KAPPA] * scale, scale) <= 1.0
    return 3 if tested else 1


def _valley_value(p: np.ndarray, win: np.ndarray, k: int, last: int) -> float:
    """``c`` of sample ``k`` (:func:`.zero_velocity.valley_value`), its window cut at 0 and ``last``."""
    vhalf = int(p[P_VHALF])
    stat = _shoe(win, max(0, k - vhalf), min(last, k + vhalf), p[P_VALLEY_KAPPA], 1.0)
    return math.sqrt(max(0.0, stat))


def _fixed_in(p: np.ndarray, z: np.ndarray, ring: np.ndarray, both: int, out: np.ndarray, n_out: int) -> int:
    """Take the fixed rule's pair of the next sample (``both``: the rule's decision + 2 × the decision);
    without the valley rule it is released as it is."""
    if not p[P_VALLEY]:
        out[n_out] = both
        z[NF] += 1
        z[NEXT] += 1
        return n_out + 1
    row = z[NF] % ring.shape[0]
    ring[row, 1] = 1.0 if both >= 2 else 0.0
    ring[row, 2] = 1.0 if both % 2 else 0.0
    z[NF] += 1
    return n_out


def _judge_valley(p: np.ndarray, z: np.ndarray, ring: np.ndarray, m: int) -> int:
    """Status of the valley candidate ``m``: 1 accepted, 0 not, -1 undecided (StanceDetector._judge)."""
    r = ring.shape[0]
    nc, nf = z[NC], z[NF]
    if m >= nc:
        return 0 if z[ENDED] else -1
    value = ring[m % r, 0]
    if value > p[P_VALLEY_MAX]:
        return 0
    lo = max(0, m - int(p[P_BEFORE]))
    if m == lo:
        return 0
    top = ring[lo % r, 0]
    for j in range(lo + 1, m):
        top = max(top, ring[j % r, 0])
    if top < p[P_VALLEY_SWING]:
        return 0
    after, gap = int(p[P_AFTER]), int(p[P_GAP])
    for j in range(lo, min(nc, m + after + 1)):
        if ring[j % r, 0] < value:
            return 0
    for j in range(max(0, m - gap), min(nf, m + gap + 1)):
        if ring[j % r, 2]:
            return 0
    return 1 if z[ENDED] or (m + after < nc and m + gap < nf) else -1


def _marked(p: np.ndarray, z: np.ndarray, ring: np.ndarray, status: np.ndarray, k: int) -> int:
    """1 if an accepted valley covers ``k``, 0 if none can, -1 while undecided."""
    vhalf, r = int(p[P_VHALF]), ring.shape[0]
    waiting = False
    for m in range(max(0, k - vhalf), k + vhalf + 1):
        row = m % r
        if status[row, 0] == m:
            s = int(status[row, 1])
        else:
            s = _judge_valley(p, z, ring, m)
            if s >= 0:
                status[row, 0], status[row, 1] = m, s
        if s == 1:
            return 1
        waiting = waiting or s < 0
    return -1 if waiting else 0


def _release(p: np.ndarray, z: np.ndarray, ring: np.ndarray, status: np.ndarray, out: np.ndarray,
             n_out: int) -> int:
    r = ring.shape[0]
    while z[NEXT] < z[NF]:
        k = z[NEXT]
        decision = 1 if ring[k % r, 1] else _marked(p, z, ring, status, k)
        if decision < 0:
            break
        out[n_out] = 2 * decision
        n_out += 1
        z[NEXT] += 1
    return n_out


def update(p: np.ndarray, z: np.ndarray, scale: np.ndarray, acc_ring: np.ndarray, win: np.ndarray,
           past: np.ndarray, ring: np.ndarray, status: np.ndarray, gx: float, gy: float, gz: float, ax: float,
           ay: float, az: float, out: np.ndarray, n_out: int) -> int:
    """One sample in; the decisions released written to ``out`` from ``n_out`` on (2 × the decision, + the
    fixed rule's alone without the valley rule); returns the new end."""
    j = z[SEEN]
    lag, w = int(p[P_LAG]), win.shape[0]
    quiet = math.sqrt(gx * gx + gy * gy + gz * gz) <= p[P_GYRO_LIMIT]
    if j >= lag:
        old = j % lag
        dx, dy, dz = ax - acc_ring[old, 0], ay - acc_ring[old, 1], az - acc_ring[old, 2]
        quiet = quiet and math.sqrt(dx * dx + dy * dy + dz * dz) <= p[P_ACC_LIMIT]
    acc_ring[j % lag, 0], acc_ring[j % lag, 1], acc_ring[j % lag, 2] = ax, ay, az
    sigma = _gait_scale(p, z, scale, past, ax, ay, az, not quiet) if p[P_GAIT] else 0.0
    row = j % w
    win[row, 0] = 1.0 if quiet else 0.0
    win[row, 1], win[row, 2], win[row, 3] = gx, gy, gz
    win[row, 4], win[row, 5], win[row, 6] = ax, ay, az
    win[row, 7] = sigma
    z[SEEN] = j + 1
    half = int(p[P_HALF])
    if j + 1 > half:
        n_out = _fixed_in(p, z, ring, _judge(p, win, j - half, j), out, n_out)
    if not p[P_VALLEY]:
        return n_out
    vhalf = int(p[P_VHALF])
    if j + 1 > vhalf:
        ring[z[NC] % ring.shape[0], 0] = _valley_value(p, win, j - vhalf, j)
        z[NC] += 1
    return _release(p, z, ring, status, out, n_out)


def flush(p: np.ndarray, z: np.ndarray, ring: np.ndarray, win: np.ndarray, status: np.ndarray,
          out: np.ndarray, n_out: int) -> int:
    """The decisions of the samples still waiting for their look-ahead (the end of the data), judged on
    the part of their windows that exists."""
    seen = z[SEEN]
    waiting = min(int(p[P_HALF]), seen)
    for k in range(seen - waiting, seen):
        n_out = _fixed_in(p, z, ring, _judge(p, win, k, seen - 1), out, n_out)
    if not p[P_VALLEY]:
        return n_out
    for k in range(z[NC], seen):
        ring[k % ring.shape[0], 0] = _valley_value(p, win, k, seen - 1)
        z[NC] += 1
    z[ENDED] = 1
    return _release(p, z, ring, status, out, n_out)


def run(p: np.ndarray, z: np.ndarray, scale: np.ndarray, acc_ring: np.ndarray, win: np.ndarray,
        past: np.ndarray, ring: np.ndarray, status: np.ndarray, gyr: np.ndarray, acc: np.ndarray,
        out: np.ndarray, released: np.ndarray) -> int:
    """:func:`update` of each row of ``gyr``/``acc`` (n, 3): the decisions in ``out`` (at least n + the
    samples waiting long), how many each row released in ``released`` (n,); returns their number."""
    n_out = 0
    for i in range(gyr.shape[0]):
        before = n_out
        n_out = update(p, z, scale, acc_ring, win, past, ring, status, gyr[i, 0], gyr[i, 1], gyr[i, 2],
                       acc[i, 0], acc[i, 1], acc[i, 2], out, n_out)
        released[i] = n_out - before
    return n_out
