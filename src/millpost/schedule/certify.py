"""An O(N) schedule with a certified optimality gap, for problems the reachability pass can solve.

Two problems made only of speed bounds and linear rows u·a_i + w·b_i ≤ h bracket the schedule's
problem: a restriction (every feasible point of it is feasible) and a relaxation (every feasible
point of the problem is feasible for it):
- LocalRows u·a + w·b + g·√b ≤ h: for b ≤ b_hi, b/√b_hi ≤ √b ≤ (b + v0²)/(2·v0) (chord and tangent
  at v0 = √b_hi). The restriction takes the upper side where g > 0 and the lower where g < 0, the
  relaxation the other way round.
- StepRows (current slew, jerk): the relaxation drops them; the restriction keeps them by checking
  them exactly (√b, not linearised) on the restricted profile, which is then feasible, or gives up.
- SoftFloor: unmet floors add their penalty `floor_penalty`·Σ node length·(floor − b)⁺/vref³ (s; the
  conic objective's own weight) to a profile's cost. Every feasible b lies below the relaxed greedy
  profile (componentwise), so its unmet floors cost at least the relaxed profile's: that penalty
  is part of the lower bound.

A problem of linear rows in the neighbouring states reads α·b_{i+1} + β·b_i ≤ h with α = u/(2·ds_i),
β = w − α. If α·β ≤ 0 for every row the feasible set is a lattice (closed under componentwise max),
its componentwise-largest element exists, and since the traversal time decreases in every b it is
the optimum; the greedy reachability (TOPP-RA) profile is that element. Rows with α, β > 0 (tight
curvature against a small tangent component, 2·ds·κ_k > t_k) break this and are bracketed again:
in the restriction by b_i, b_{i+1} ≤ h/(α + β) (implies the row), in the relaxation by b_i ≤ h/β,
b_{i+1} ≤ h/α (implied by the row, b ≥ 0). Rows with α, β < 0 and h ≥ 0 hold for every b ≥ 0 and
are dropped. The restricted greedy profile costs J_R ≥ J*, the relaxed greedy one J_X ≤ J*; the
restricted profile is returned with the proven gap J_R/J_X − 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from millpost.schedule.assemble import linear_rows, merged_bounds, soft_floor
from millpost.schedule.reach import reach, traversal_time
from millpost.schedule.rows import Block, LocalRows, PathGrid, StepRows


def _relaxed_rows(blocks: list[Block], b_hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """LocalRows with g·√b bounded from below for b ≤ b_hi: chord where g > 0, tangent at √b_hi where g < 0."""
    rows = [blk for blk in blocks if isinstance(blk, LocalRows)]
    if not rows:
        z = np.zeros((0, len(b_hi)))
        return z, z, z
    U, W, _, H = linear_rows(rows, b_hi, np.sqrt(b_hi), convex_exact=True)  # g > 0 → tangent (undone below)
    G = np.concatenate([r.g for r in rows]).astype(float)
    v = np.broadcast_to(np.sqrt(b_hi), G.shape)
    ok = np.isfinite(v) & (v > 0)
    pos, neg = (G > 0) & ok, (G < 0) & ok
    W, H = W.copy(), H.copy()
    # undo the tangent of linear_rows where g > 0, then put the chord g·b/√b_hi
    W[pos] += G[pos] / v[pos] - G[pos] / (2 * v[pos])
    H[pos] += G[pos] * v[pos] / 2
    W[neg] += G[neg] / (2 * v[neg])
    H[neg] -= G[neg] * v[neg] / 2
    return U, W, H


def _lattice(ds: np.ndarray, b_hi: np.ndarray, U: np.ndarray, W: np.ndarray, H: np.ndarray, restrict: bool):
    """The rows with α, β > 0 replaced by speed caps (restriction or relaxation, see the module
    docstring). Returns (cap, U, W, H) or None when such a row has h < 0."""
    cap = b_hi.copy()
    if not len(U):
        return cap, U, W, H
    U, W, H = U.copy(), W.copy(), H.copy()
    al = U[:, :-1] / (2 * ds)
    be = W[:, :-1] - al
    bad = al * be > 0
    if (bad & (H[:, :-1] < 0)).any():
        return None
    pos = bad & (al > 0)
    h = H[:, :-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        if restrict:
            both = np.where(pos, h / (al + be), np.inf).min(axis=0)
            cap[:-1] = np.minimum(cap[:-1], both)
            cap[1:] = np.minimum(cap[1:], both)
        else:
            cap[:-1] = np.minimum(cap[:-1], np.where(pos, h / be, np.inf).min(axis=0))
            cap[1:] = np.minimum(cap[1:], np.where(pos, h / al, np.inf).min(axis=0))
    U[:, :-1][bad] = 0.0
    W[:, :-1][bad] = 0.0
    H[:, :-1][bad] = np.inf
    return cap, U, W, H


@dataclass
class Certificate:
    """The restricted profile `b` (feasible), the relaxed one `b_relaxed` (no feasible b exceeds it at
    any sample) and their costs per interval and per node (s): traversal time of each interval and
    soft-floor penalty of each node. `gap` is the proven bound over the whole segment."""

    b: np.ndarray
    b_relaxed: np.ndarray
    cost: np.ndarray          # (2, N): restricted and relaxed, interval i's time + node i's penalty
    gap: float

    def gap_between(self, lo: int, hi: int) -> float:
        """Proven bound on the stretch of samples [lo, hi) (intervals lo … hi − 2, nodes lo … hi − 1,
        the segment's last node with the last stretch): every feasible b lies below the relaxed profile
        there too, so its cost on the stretch is at least the relaxed one's."""
        j_r, j_x = self.cost[:, lo:hi - 1].sum(axis=1) + (self.cost[:, hi - 1] if hi == self.cost.shape[1] else 0)
        return max(j_r / j_x - 1, 0.0) if j_x > 0 else (0.0 if j_r <= 0 else np.inf)


def certified_reach(grid: PathGrid, blocks: list[Block], floor_penalty: float = 10.0
                    ) -> tuple[np.ndarray, float] | None:
    """(b, gap bound) for a rest-to-rest segment, or None when the bracket does not close (hard speed
    floors, a slew or jerk row the restricted profile breaks, an infeasible restriction)."""
    cert = certify(grid, blocks, floor_penalty)
    return None if cert is None else (cert.b, cert.gap)


def certify(grid: PathGrid, blocks: list[Block], floor_penalty: float = 10.0) -> Certificate | None:
    """The certificate of a rest-to-rest segment (see `certified_reach`), or None."""
    n = len(grid)
    b_lo, b_hi = merged_bounds(blocks, n)
    if (b_lo > 0).any():
        return None
    ds = grid.ds
    U, W, _, H = linear_rows(blocks, b_hi, np.sqrt(b_hi), convex_exact=False)
    lat_r = _lattice(ds, b_hi, U, W, H, restrict=True)
    lat_x = _lattice(ds, b_hi, *_relaxed_rows(blocks, b_hi), restrict=False)
    if lat_r is None or lat_x is None:
        return None
    restricted, relaxed = reach(ds, b_lo, *lat_r), reach(ds, b_lo, *lat_x)
    if not (restricted.feasible and relaxed.feasible):
        return None
    b = restricted.b
    a = np.diff(b) / (2 * ds)
    for blk in blocks:
        if isinstance(blk, StepRows) and n > 2 and blk.excess(grid, b, a).max() > 0:
            return None
    t_r, t_x = traversal_time(ds, b), traversal_time(ds, relaxed.b)
    if not (np.isfinite(t_r) and t_x > 0):
        return None
    cost = np.zeros((2, n))
    for row, prof in zip(cost, (b, relaxed.b)):  # each interval's term of `traversal_time`
        v = np.sqrt(np.maximum(prof, 0.0))
        den = v[:-1] + v[1:]
        with np.errstate(divide="ignore"):
            row[:-1] = np.where(den > 0, 2 * ds / den, np.inf)
    floor = soft_floor(blocks, n)
    if (floor > 0).any():
        node_len = np.zeros(n)
        node_len[:-1] += ds / 2
        node_len[1:] += ds / 2
        weight = floor_penalty * node_len / (float(np.sqrt(b_hi.max())) or 1.0) ** 3
        # every feasible b is ≤ the relaxed profile, so its unmet floors cost at least the relaxed one's
        pen_r, pen_x = weight * np.maximum(floor - b, 0.0), weight * np.maximum(floor - relaxed.b, 0.0)
        cost[0] += pen_r
        cost[1] += pen_x
        t_r += float(np.sum(pen_r))
        t_x += float(np.sum(pen_x))
    return Certificate(b, relaxed.b, cost, max(t_r / t_x - 1, 0.0))
