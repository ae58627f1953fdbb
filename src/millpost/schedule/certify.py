"""An O(N) schedule with a certified optimality gap, for problems the reachability pass can solve.

With only speed bounds and linear rows u·a_i + w·b_i ≤ h (no jerk/slew rows, no √b terms, no
floors), a row in the neighbouring states reads α·b_{i+1} + β·b_i ≤ h with α = u/(2·ds_i),
β = w − α. If α·β ≤ 0 for every row the feasible set is a lattice (closed under componentwise
max), its componentwise-largest element exists, and since the traversal time decreases in every b
it is the optimum; the greedy reachability (TOPP-RA) profile is that element. Rows with α, β > 0
(tight curvature against a small tangent component, 2·ds·κ_k > t_k) break this. Two lattice
problems bracket the optimum T*:
- restriction: the row replaced by b_i, b_{i+1} ≤ h/(α + β) (implies the row); its greedy profile
  is feasible, T_R ≥ T*;
- relaxation: the row replaced by b_i ≤ h/β, b_{i+1} ≤ h/α (implied by the row, b ≥ 0); its greedy
  profile is optimal for it, T_X ≤ T*.
The restricted profile is returned with the proven gap T_R/T_X − 1 (0 when no such row binds).
Rows with α, β < 0 and h ≥ 0 hold for every b ≥ 0 and are dropped.
"""

from __future__ import annotations

import numpy as np

from millpost.schedule.assemble import linear_rows, merged_bounds, soft_floor
from millpost.schedule.reach import reach, traversal_time
from millpost.schedule.rows import Block, LocalRows, PathGrid, StepRows


def certified_reach(grid: PathGrid, blocks: list[Block]) -> tuple[np.ndarray, float] | None:
    """(b, gap bound) for a rest-to-rest segment, or None when the problem is not of this kind."""
    n = len(grid)
    if any(isinstance(blk, StepRows) for blk in blocks):
        return None
    if any(isinstance(blk, LocalRows) and (blk.g != 0).any() for blk in blocks):
        return None
    b_lo, b_hi = merged_bounds(blocks, n)
    if (b_lo > 0).any() or (soft_floor(blocks, n) > 0).any():
        return None
    U, W, _, H = linear_rows(blocks, b_hi, np.sqrt(b_hi), convex_exact=False)
    ds = grid.ds
    cap_r, cap_x = b_hi.copy(), b_hi.copy()
    Ur, Wr, Hr = U.copy(), W.copy(), H.copy()
    if len(U):
        al = U[:, :-1] / (2 * ds)
        be = W[:, :-1] - al
        bad = al * be > 0
        if (bad & (H[:, :-1] < 0)).any():
            return None
        pos = bad & (al > 0)
        h = H[:, :-1]
        with np.errstate(divide="ignore", invalid="ignore"):
            both = np.where(pos, h / (al + be), np.inf).min(axis=0)
            cap_r[:-1] = np.minimum(cap_r[:-1], both)
            cap_r[1:] = np.minimum(cap_r[1:], both)
            cap_x[:-1] = np.minimum(cap_x[:-1], np.where(pos, h / be, np.inf).min(axis=0))
            cap_x[1:] = np.minimum(cap_x[1:], np.where(pos, h / al, np.inf).min(axis=0))
        Ur[:, :-1][bad] = 0.0
        Wr[:, :-1][bad] = 0.0
        Hr[:, :-1][bad] = np.inf
    restricted = reach(ds, b_lo, cap_r, Ur, Wr, Hr)
    relaxed = reach(ds, b_lo, cap_x, Ur, Wr, Hr)
    if not (restricted.feasible and relaxed.feasible):
        return None
    t_r, t_x = traversal_time(ds, restricted.b), traversal_time(ds, relaxed.b)
    if not (np.isfinite(t_r) and t_x > 0):
        return None
    return restricted.b, max(t_r / t_x - 1, 0.0)
