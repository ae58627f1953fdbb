"""Velocity profiles of planned blocks (lengths mm, speeds mm/s, accelerations mm/s², times s): the
look-ahead passes over the junction speeds, a block's trapezoid, the axis-limited path rates."""

from __future__ import annotations

import numba
import numpy as np


def axis_limited(u: np.ndarray, limits) -> np.ndarray:
    """Largest path rate (speed or acceleration) along unit directions u that no axis exceeds."""
    au = np.abs(u)
    with np.errstate(divide="ignore"):
        return np.min(np.where(au > 1e-12, np.asarray(limits, float) / np.maximum(au, 1e-300), np.inf), axis=1)


@numba.njit(cache=True)
def plan_speeds(L, vnom, acc, vj, depth):
    """Squared junction speeds (n+1, start and end at rest) honouring the caps vj (already ≤ the
    nominal speeds of both neighbours), the look-ahead depth (from junction i the planner sees blocks
    i..i+depth−1 and must be able to stop after them) and reachability (forward/backward passes)."""
    n = L.shape[0]
    v2 = np.empty(n + 1)
    v2[0] = 0.0
    v2[n] = 0.0
    for i in range(1, n):
        v2[i] = vj[i]
    for i in range(1, n):
        last = min(i + depth, n)
        w = 0.0
        for k in range(last - 1, i - 1, -1):
            w = min(w + 2.0 * acc[k] * L[k], v2[k] if k > i else np.inf)
        v2[i] = min(v2[i], w)
    for i in range(n - 1, 0, -1):  # backward: can decelerate to the next junction
        v2[i] = min(v2[i], v2[i + 1] + 2.0 * acc[i] * L[i])
    for i in range(n):  # forward: can accelerate from the previous junction
        v2[i + 1] = min(v2[i + 1], v2[i] + 2.0 * acc[i] * L[i])
    return v2


def peak_speed(L, vin, vout, vmax, a):
    """Top speed of a trapezoidal (or triangular) profile from vin to vout over L at acceleration a,
    at most vmax."""
    return np.minimum(np.sqrt(np.maximum((2 * a * L + vin**2 + vout**2) / 2, 0)), vmax)


def trapezoid_time(L, vin, vout, vmax, a):
    """Time of a trapezoidal (or triangular) profile from vin to vout over L at acceleration a."""
    vp = peak_speed(L, vin, vout, vmax, a)
    d_acc = (vp**2 - vin**2) / (2 * a)
    d_dec = (vp**2 - vout**2) / (2 * a)
    cruise = np.maximum(L - d_acc - d_dec, 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return (vp - vin) / a + (vp - vout) / a + np.where(vp > 0, cruise / vp, 0.0)
