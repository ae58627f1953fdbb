"""O(N) reachability pass (TOPP-RA, Pham & Pham, IEEE T-RO 34(3) 2018) on the collocation grid.

Backward: the controllable set K_i = {b_i : some a_i satisfies the rows of sample i and
b_i + 2·ds_i·a_i ∈ K_{i+1}}, an interval found by exact Fourier–Motzkin elimination of a_i from the
2-D polygon of sample i. Forward: from b_0, take the largest a_i that keeps b_{i+1} in K_{i+1}.

Uses: (1) K_hi is the terminal bound of a solve window, which guarantees every later window stays
feasible; (2) the forward profile is the always-feasible fallback when the conic solve fails. It
honours SpeedBounds and LocalRows (linearised conservatively); SoftFloor and StepRows are not
represented (the profile may miss chip-load floors and is not jerk limited).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from millpost._kernels import compiling


@numba.njit(cache=True)
def _project(p, q, r, m):
    """Interval of b over {(a, b): p_j a + q_j b ≤ r_j, j < m}. Returns (lo, hi); lo > hi if empty."""
    lo, hi = -np.inf, np.inf
    for j in range(m):
        if p[j] == 0.0:
            if q[j] > 0.0:
                hi = min(hi, r[j] / q[j])
            elif q[j] < 0.0:
                lo = max(lo, r[j] / q[j])
            elif r[j] < 0.0:
                return np.inf, -np.inf
    for j in range(m):
        if p[j] <= 0.0:
            continue
        for k in range(m):
            if p[k] >= 0.0:
                continue
            c = -p[k] * q[j] + p[j] * q[k]
            e = -p[k] * r[j] + p[j] * r[k]
            if c > 0.0:
                hi = min(hi, e / c)
            elif c < 0.0:
                lo = max(lo, e / c)
            elif e < 0.0:
                return np.inf, -np.inf
    return lo, hi


@numba.njit(cache=True)
def _backward(ds, b_lo, b_hi, U, W, H, k_lo_end, k_hi_end):
    N = b_lo.shape[0]
    M = U.shape[0]
    klo = np.empty(N)
    khi = np.empty(N)
    klo[N - 1] = max(b_lo[N - 1], k_lo_end)
    khi[N - 1] = min(b_hi[N - 1], k_hi_end)
    p = np.empty(M + 4)
    q = np.empty(M + 4)
    r = np.empty(M + 4)
    for i in range(N - 2, -1, -1):
        m = 0
        for j in range(M):
            if U[j, i] != 0.0 or W[j, i] != 0.0:
                p[m], q[m], r[m] = U[j, i], W[j, i], H[j, i]
                m += 1
        p[m], q[m], r[m] = 2.0 * ds[i], 1.0, khi[i + 1]
        p[m + 1], q[m + 1], r[m + 1] = -2.0 * ds[i], -1.0, -klo[i + 1]
        p[m + 2], q[m + 2], r[m + 2] = 0.0, 1.0, b_hi[i]
        p[m + 3], q[m + 3], r[m + 3] = 0.0, -1.0, -b_lo[i]
        lo, hi = _project(p, q, r, m + 4)
        klo[i] = lo
        khi[i] = hi
        if lo > hi:  # empty: nothing before i is controllable either
            for k in range(i - 1, -1, -1):
                klo[k] = np.inf
                khi[k] = -np.inf
            break
    return klo, khi


@numba.njit(cache=True)
def _forward(ds, U, W, H, klo, khi, b0):
    N = klo.shape[0]
    M = U.shape[0]
    b = np.empty(N)
    a = np.empty(N - 1)
    b[0] = min(max(b0, klo[0]), khi[0])
    for i in range(N - 1):
        amax, amin = np.inf, -np.inf
        for j in range(M):
            u = U[j, i]
            rhs = H[j, i] - W[j, i] * b[i]
            if u > 0.0:
                amax = min(amax, rhs / u)
            elif u < 0.0:
                amin = max(amin, rhs / u)
        # the rows win over round-off in K: largest a keeping b_{i+1} in K_{i+1}, within the rows
        ai = min(amax, (khi[i + 1] - b[i]) / (2.0 * ds[i]))
        ai = max(ai, min(amax, (klo[i + 1] - b[i]) / (2.0 * ds[i])))
        ai = max(ai, amin) if amin <= amax else ai
        bn = b[i] + 2.0 * ds[i] * ai
        bn = min(max(bn, klo[i + 1]), khi[i + 1])
        b[i + 1] = max(bn, 0.0)
        a[i] = (b[i + 1] - b[i]) / (2.0 * ds[i])
    return b, a


@dataclass
class Reach:
    """Controllable sets [k_lo, k_hi] (mm²/s²) and the greedy forward profile b, a."""

    k_lo: np.ndarray
    k_hi: np.ndarray
    b: np.ndarray
    a: np.ndarray

    @property
    def feasible(self) -> bool:
        return bool(self.k_lo[0] <= self.k_hi[0] * (1 + 1e-9) + 1e-12)


def reach(ds: np.ndarray, b_lo: np.ndarray, b_hi: np.ndarray, U: np.ndarray, W: np.ndarray, H: np.ndarray,
          b_start: float = 0.0, b_end_max: float = 0.0, b_end_min: float = 0.0) -> Reach:
    """Backward controllable sets and forward greedy profile for linear rows U·a + W·b ≤ H (M, N)."""
    f = lambda x: np.ascontiguousarray(x, dtype=np.float64)  # noqa: E731
    with compiling(_backward):
        klo, khi = _backward(f(ds), f(b_lo), f(b_hi), f(U), f(W), f(H), float(b_end_min), float(b_end_max))
    if not np.isfinite(khi[0]) or klo[0] > khi[0]:
        return Reach(klo, khi, np.zeros(len(b_lo)), np.zeros(len(ds)))
    with compiling(_forward):
        b, a = _forward(f(ds), f(U), f(W), f(H), klo, khi, float(b_start))
    return Reach(klo, khi, b, a)


def traversal_time(ds: np.ndarray, b: np.ndarray) -> float:
    """Σ 2·ds/(√b_i + √b_{i+1}) in s (collocation: constant acceleration on each interval)."""
    v = np.sqrt(np.maximum(b, 0.0))
    den = v[:-1] + v[1:]
    with np.errstate(divide="ignore"):
        return float(np.sum(np.where(den > 0, 2 * ds / den, np.inf)))
