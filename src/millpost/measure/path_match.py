"""Where on the program's path each logged position lies: a monotone match of log rows to path arc length.

The path is the predicted tool-tip polyline (samples k = 0..N−1 at arc length s_k). A logged row at
position p may lie near several places of the path (a pass retraced at the same XY and another Z, a rapid
run twice); the match picks, for every row, one place such that

- the places never go back along the path (the machine runs the program forwards),
- between two rows the path advances no faster than the machine can move (v_max·Δt + slack, a soft
  bound: a jump costs its excess in mm),
- the summed distance of the rows from their places is least,

by dynamic programming over a few candidate places per row (the nearest path samples, each refined to the
foot of the perpendicular on its neighbouring segments). A stationary row (a pause, a feed hold, a dwell)
keeps the place of the row before it. The log's own clock only enters through Δt in the speed bound, so
a log with its own time origin, rate, feed holds, override, lost rows, another planner or covering part of
the program is matched all the same; without positions there is nothing to match (see `xcorr`).
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.spatial import cKDTree

CANDIDATES = 12          # nearest path samples tried per row
JUMP_COST_PER_MM = 1.0   # cost of each mm the path would advance beyond what the machine can move
ADVANCE_COST_PER_MM = 1e-3   # of every mm advanced: among places equally near, the earliest is taken
FOLLOW = 4               # the best places of the row before that the next row may stay at or follow on from
AHEAD_SAMPLES = 256      # the continuation of the previous place is sought this many samples ahead


def match(xyz_mm: np.ndarray, t_s: np.ndarray, path_mm: np.ndarray, s_mm: np.ndarray, v_max_mm_s: float,
          slack_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """(fractional path index per row, distance from the path in mm per row) for logged positions xyz_mm
    (n, 3) at log times t_s (n,), path samples path_mm (N, 3) at arc lengths s_mm (N,). Rows with a
    non-finite position get nan."""
    ok = np.isfinite(xyz_mm).all(1)
    rows = np.flatnonzero(ok)
    f = np.full(len(xyz_mm), np.nan)
    d = np.full(len(xyz_mm), np.nan)
    if len(rows) == 0 or len(path_mm) < 2:
        return f, d
    k = min(CANDIDATES, len(path_mm))
    _, cand = cKDTree(path_mm).query(xyz_mm[rows], k=k, workers=-1)
    cand = np.asarray(cand, np.int32).reshape(len(rows), k)
    frac, dist = _dp(np.ascontiguousarray(xyz_mm[rows], np.float64), np.asarray(t_s, float)[rows],
                     np.ascontiguousarray(path_mm, np.float64), np.asarray(s_mm, np.float64), cand,
                     float(v_max_mm_s), float(slack_mm), JUMP_COST_PER_MM)
    f[rows], d[rows] = frac, dist
    return f, d


@numba.njit(cache=True)
def _foot(p, path, j):
    """Foot of the perpendicular from p on the segments around sample j: (fractional index, distance)."""
    n = path.shape[0]
    best_f, best_d = float(j), 1e300
    for a in range(j - 1, j + 1):
        if a < 0 or a + 1 >= n:
            continue
        sx, sy, sz = path[a + 1, 0] - path[a, 0], path[a + 1, 1] - path[a, 1], path[a + 1, 2] - path[a, 2]
        L2 = sx * sx + sy * sy + sz * sz
        u = 0.0
        if L2 > 0:
            u = ((p[0] - path[a, 0]) * sx + (p[1] - path[a, 1]) * sy + (p[2] - path[a, 2]) * sz) / L2
            u = min(max(u, 0.0), 1.0)
        dx, dy, dz = p[0] - path[a, 0] - u * sx, p[1] - path[a, 1] - u * sy, p[2] - path[a, 2] - u * sz
        dd = np.sqrt(dx * dx + dy * dy + dz * dz)
        if dd < best_d:
            best_f, best_d = a + u, dd
    if best_d == 1e300:
        dx, dy, dz = p[0] - path[j, 0], p[1] - path[j, 1], p[2] - path[j, 2]
        best_d = np.sqrt(dx * dx + dy * dy + dz * dz)
    return best_f, best_d


@numba.njit(cache=True)
def _s_at(s, f):
    a = min(int(f), s.shape[0] - 2)
    return s[a] + (f - a) * (s[a + 1] - s[a])


@numba.njit(cache=True)
def _dp(xyz, t, path, s, cand, v_max, slack, jump_cost):
    n, k = cand.shape
    # slots: k nearest places; then, for each of the FOLLOW best places of the row before, the same place
    # (a tool standing still, or noise just behind it) and the nearest place ahead of it within reach (one
    # pass of a path that retraces itself, whose other passes crowd the nearest places)
    m = k + 2 * FOLLOW
    places = np.empty((n, m))       # candidate places (fractional path index) per row
    back = np.zeros((n, m), np.int16)
    prev_cost, prev_s = np.full(m, 1e300), np.empty(m)
    cost, cur_s, cur_d = np.empty(m), np.empty(m), np.empty(m)
    best = np.empty(FOLLOW, np.int64)
    for i in range(n):
        for c in range(k):
            places[i, c], cur_d[c] = _foot(xyz[i], path, cand[i, c])
            cur_s[c] = _s_at(s, places[i, c])
        if i > 0:
            _smallest(prev_cost, places[i - 1], best)
        else:
            best[:] = 0
        reach = v_max * max(t[i] - t[i - 1], 0.0) + slack if i > 0 else 0.0
        for r in range(FOLLOW):
            q = best[r]
            here = places[i - 1, q] if i > 0 else places[i, 0]
            places[i, k + 2 * r] = here
            cur_d[k + 2 * r] = _distance(xyz[i], path, here)
            places[i, k + 2 * r + 1], cur_d[k + 2 * r + 1] = _ahead(xyz[i], path, s, here, reach)
            for c in (k + 2 * r, k + 2 * r + 1):
                cur_s[c] = _s_at(s, places[i, c])
        if i == 0:
            for c in range(m):
                cost[c] = cur_d[c] if c < k else 1e300
        else:
            for c in range(k):
                lowest, arg = 1e300, -1
                for q in range(m):
                    if prev_cost[q] >= 1e299 or places[i - 1, q] > places[i, c] + 1e-9:
                        continue
                    excess = cur_s[c] - prev_s[q] - reach
                    v = prev_cost[q] + ADVANCE_COST_PER_MM * (cur_s[c] - prev_s[q]) + (
                        jump_cost * excess if excess > 0 else 0.0)
                    if v < lowest:
                        lowest, arg = v, q
                cost[c] = lowest + cur_d[c] if arg >= 0 else 1e300
                back[i, c] = max(arg, 0)
            for r in range(FOLLOW):
                q = best[r]
                for c in (k + 2 * r, k + 2 * r + 1):
                    cost[c] = (prev_cost[q] + cur_d[c] + ADVANCE_COST_PER_MM * (cur_s[c] - prev_s[q])
                               if prev_cost[q] < 1e299 else 1e300)
                    back[i, c] = q
        for c in range(m):
            prev_cost[c], prev_s[c] = cost[c], cur_s[c]
    out_f = np.empty(n)
    out_d = np.empty(n)
    c, lowest = 0, 1e300
    for q in range(m):
        if prev_cost[q] < lowest:
            c, lowest = q, prev_cost[q]
    for i in range(n - 1, -1, -1):
        out_f[i] = places[i, c]
        out_d[i] = _distance(xyz[i], path, out_f[i])
        c = back[i, c]
    return out_f, out_d


@numba.njit(cache=True)
def _smallest(values, places, out):
    """Indices of the len(out) smallest finite values at places at least a sample apart (ascending;
    repeats of the last where there are fewer)."""
    taken = np.zeros(len(values), np.bool_)
    found = 0
    for r in range(len(out)):
        j, v = -1, 1e299
        for q in range(len(values)):
            if taken[q] or values[q] >= v:
                continue
            seen = False
            for u in range(found):
                if abs(places[q] - places[out[u]]) < 1.0:
                    seen = True
            if not seen:
                j, v = q, values[q]
        if j < 0:
            out[r] = out[r - 1] if r > 0 else 0
        else:
            taken[j] = True
            out[r] = j
            found += 1


@numba.njit(cache=True)
def _ahead(p, path, s, f, reach):
    """The nearest place to p on the path from fractional index f forwards, at most `reach` mm of path
    (and `AHEAD_SAMPLES` samples) on: (fractional index, distance)."""
    n = path.shape[0]
    a0 = min(int(f), n - 2)
    best_f, best_d = f, _distance(p, path, f)
    a = a0
    while a < n - 1 and a - a0 < AHEAD_SAMPLES and s[a] - s[a0] <= reach:
        g, d = _foot(p, path, a + 1)
        if d < best_d and g >= f:
            best_f, best_d = g, d
        a += 1
    return best_f, best_d


@numba.njit(cache=True)
def _distance(p, path, f):
    """Distance (mm) of p from the path at fractional index f."""
    a = min(int(f), path.shape[0] - 2)
    u = f - a
    d2 = 0.0
    for q in range(3):
        e = p[q] - (path[a, q] + u * (path[a + 1, q] - path[a, q]))
        d2 += e * e
    return np.sqrt(d2)
