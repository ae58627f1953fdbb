"""Rows of a path segment → one scaled SOCP (Verscheure et al. 2009, collocation discretisation).

Variables, scaled (notes/SCHEDULE-PROTOTYPE.md pitfall 1: raw units make the cones degenerate):
β = b/vref² (N), α = a/aref (N−1, only when StepRows couple neighbouring a; otherwise a is
eliminated through a_i = (b_{i+1} − b_i)/(2·ds_i), 25–30 % faster), c ≤ √β (N), d ≥ 1/(c_i + c_{i+1})
(N−1), σ ≥ 0 soft-floor slacks. Objective Σ (2·ds_i/L)·d_i = traversal time · vref/L.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from millpost.schedule.problem import SOC, ConicProblem
from millpost.schedule.rows import Block, LocalRows, PathGrid, SoftFloor, SpeedBounds, StepRows


def merged_bounds(blocks: list[Block], n: int) -> tuple[np.ndarray, np.ndarray]:
    """(b_lo, b_hi) over all SpeedBounds, mm²/s²; b_lo ≥ 0."""
    lo, hi = np.zeros(n), np.full(n, np.inf)
    for blk in blocks:
        if isinstance(blk, SpeedBounds):
            lo = np.maximum(lo, blk.b_lo)
            hi = np.minimum(hi, blk.b_hi)
    return lo, hi


def soft_floor(blocks: list[Block], n: int) -> np.ndarray:
    f = np.zeros(n)
    for blk in blocks:
        if isinstance(blk, SoftFloor):
            f = np.maximum(f, blk.b_floor)
    return f


def linear_rows(blocks: list[Block], b_hi: np.ndarray, v0: np.ndarray, *, convex_exact: bool
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Stack LocalRows as U·a + W·b + G·√b ≤ H with the non-convex g > 0 part replaced by its tangent
    at v0 (√b ≤ (b + v0²)/(2 v0)). With convex_exact=False (the reachability pass, which needs pure
    linear rows) g < 0 is replaced by the chord √b ≥ b/√b_hi, also conservative. Returns U, W, G, H."""
    rows = [blk for blk in blocks if isinstance(blk, LocalRows)]
    if not rows:
        z = np.zeros((0, len(b_hi)))
        return z, z, z, z
    U = np.concatenate([r.u for r in rows])
    W = np.concatenate([r.w for r in rows]).astype(float, copy=True)
    # round-off of unit tangents (cos 90° = 6e-17) would give rows with absurd right-hand sides
    U = np.where(np.abs(U) < 1e-12 * np.abs(U).max(initial=0.0), 0.0, U)
    W = np.where(np.abs(W) < 1e-12 * np.abs(W).max(initial=0.0), 0.0, W)
    G = np.concatenate([r.g for r in rows]).astype(float, copy=True)
    H = np.concatenate([r.h for r in rows]).astype(float, copy=True)
    pos = G > 0
    v0m = np.broadcast_to(np.maximum(v0, 1e-9), G.shape)
    W[pos] += G[pos] / (2 * v0m[pos])
    H[pos] -= G[pos] * v0m[pos] / 2
    G[pos] = 0.0
    if not convex_exact:
        neg = G < 0
        cap = np.broadcast_to(np.sqrt(b_hi), G.shape)
        finite = neg & np.isfinite(cap) & (cap > 0)
        W[finite] += G[finite] / cap[finite]
        G[neg] = 0.0  # with an unbounded speed the chord degenerates to dropping the (helping) term
    return U, W, G, H


@dataclass
class Layout:
    n: int
    explicit_a: bool
    vref: float
    aref: float
    length_mm: float
    soft_idx: np.ndarray  # samples carrying a floor slack

    @property
    def na(self) -> int:
        return self.n - 1 if self.explicit_a else 0

    @property
    def c0(self) -> int:
        return self.n + self.na

    @property
    def d0(self) -> int:
        return self.c0 + self.n

    @property
    def s0(self) -> int:
        return self.d0 + self.n - 1

    @property
    def nvar(self) -> int:
        return self.s0 + len(self.soft_idx)

    def b(self, x: np.ndarray) -> np.ndarray:
        return self.vref**2 * np.maximum(x[: self.n], 0.0)

    def slack(self, x: np.ndarray) -> np.ndarray:
        out = np.zeros(self.n)
        out[self.soft_idx] = self.vref**2 * x[self.s0:]
        return out

    def time_s(self, objective: float) -> float:
        return objective * self.length_mm / self.vref


def _expr(lay: Layout, ds: np.ndarray, idx: np.ndarray, u: np.ndarray, w: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """COO (row, col, val) of u·a_i + w·b_i for samples idx (row k ↔ idx[k]); a at the last sample is 0."""
    n, v2 = lay.n, lay.vref**2
    k = np.arange(len(idx))
    has_a = (idx < n - 1) & (u != 0)
    rr, cc, vv = [k], [idx], [w * v2]
    ka, ia, ua = k[has_a], idx[has_a], u[has_a]
    if lay.explicit_a:
        rr.append(ka), cc.append(n + ia), vv.append(ua * lay.aref)
    else:
        f = ua * v2 / (2 * ds[ia])
        rr += [ka, ka]
        cc += [ia, ia + 1]
        vv += [-f, f]
    return np.concatenate(rr), np.concatenate(cc), np.concatenate(vv)


def _add_normalised_le(prob: ConicProblem, rows, cols, vals, h: np.ndarray) -> None:
    """Append A x ≤ h after dividing each row by its largest |coefficient|. Drops rows that cannot
    bind: all-zero rows whose bound holds, and rows whose normalised bound exceeds 1e6 (the scaled
    variables are O(1))."""
    A = sp.csr_matrix((vals, (rows, cols)), shape=(len(h), prob.n))
    rowmax = np.asarray(abs(A).max(axis=1).todense()).ravel()
    scale = np.where(rowmax > 0, rowmax, 1.0)
    keep = (h / scale < 1e6) & ((rowmax > 0) | (h < 0))
    D = sp.diags(1.0 / scale)
    prob.add_le((D @ A)[keep], (h / scale)[keep])


def build(grid: PathGrid, blocks: list[Block], *, b_fixed_start: np.ndarray, b_end: tuple[float, float],
          v0: np.ndarray, vref: float, aref: float, floor_penalty: float = 10.0,
          b_fixed_end: np.ndarray | None = None) -> tuple[ConicProblem, Layout]:
    """The SOCP of one window. b_fixed_start/b_fixed_end fix b (mm²/s²) at the first/last samples;
    b_end = (lo, hi) bounds b at the last sample otherwise (the controllable set for a window).
    Variables (`Layout`): β = b/vref² per sample, c ≤ √β, d ≥ 1/(c_i + c_{i+1}) per step (the time of a
    step is 2·ds·d/vref), α the path acceleration where rate rows need it, and slacks of the soft
    minimum-chip floor; the objective is the traversal time plus the floor's penalty."""
    n = len(grid)
    b_lo, b_hi = merged_bounds(blocks, n)
    floor = soft_floor(blocks, n)
    steps = [blk for blk in blocks if isinstance(blk, StepRows)]
    soft_idx = np.flatnonzero(floor > np.maximum(b_lo, 0))
    lay = Layout(n, bool(steps), vref, aref, grid.length_mm, soft_idx)
    prob = ConicProblem(lay.nvar)
    _objective(prob, lay, grid.ds, floor_penalty)
    fixed = _boundary(prob, lay, b_fixed_start, b_fixed_end, b_end)
    _cones(prob, lay, fixed)
    _speed_bounds(prob, lay, b_lo, b_hi, floor, fixed)
    if lay.explicit_a:
        _acceleration(prob, lay, grid.ds)
    _local_rows(prob, lay, grid.ds, blocks, b_hi, v0, fixed)
    for blk in steps:
        _step_rows(prob, lay, grid, blk, v0)
    return prob, lay


def _objective(prob: ConicProblem, lay: Layout, ds: np.ndarray, floor_penalty: float) -> None:
    """Traversal time Σ 2·ds·d_i (per length of the window) plus the soft floor's slacks weighted by
    their samples' path length."""
    n = lay.n
    prob.q[lay.d0: lay.d0 + n - 1] = 2 * ds / lay.length_mm
    if len(lay.soft_idx):
        node_len = np.zeros(n)
        node_len[:-1] += ds / 2
        node_len[1:] += ds / 2
        prob.q[lay.s0:] = floor_penalty * node_len[lay.soft_idx] / lay.length_mm


def _boundary(prob: ConicProblem, lay: Layout, b_fixed_start: np.ndarray, b_fixed_end: np.ndarray | None,
              b_end: tuple[float, float]) -> np.ndarray:
    """Fixed b at the window's ends (and c = √β there) or the bounds on the last sample's b; returns
    the mask of fixed samples."""
    n, v2, vref = lay.n, lay.vref ** 2, lay.vref
    # boundary conditions: fixed b, and c = √β there (no cone at a known value: at b = 0 the cone's
    # degenerate apex slows the interior-point method down to ~1e-6 accuracy)
    fix_idx = [np.arange(len(b_fixed_start))]
    fix_val = [np.asarray(b_fixed_start, float)]
    if b_fixed_end is not None:
        fix_idx.append(np.arange(n - len(b_fixed_end), n))
        fix_val.append(np.asarray(b_fixed_end, float))
    elif b_end[0] == b_end[1]:
        fix_idx.append(np.array([n - 1]))
        fix_val.append(np.array([b_end[1]]))
    fi, fv = np.concatenate(fix_idx), np.maximum(np.concatenate(fix_val), 0.0)
    k = np.arange(len(fi))
    prob.add_eq(sp.csr_matrix((np.ones(len(fi)), (k, fi)), shape=(len(fi), lay.nvar)), fv / v2)
    prob.add_eq(sp.csr_matrix((np.ones(len(fi)), (k, lay.c0 + fi)), shape=(len(fi), lay.nvar)), np.sqrt(fv) / vref)
    if b_fixed_end is None and b_end[0] != b_end[1]:
        lo_e, hi_e = b_end
        if np.isfinite(hi_e):
            prob.add_le(sp.csr_matrix(([1.0], ([0], [n - 1])), shape=(1, lay.nvar)), [hi_e / v2])
        if lo_e > 0:
            prob.add_le(sp.csr_matrix(([-1.0], ([0], [n - 1])), shape=(1, lay.nvar)), [-lo_e / v2])
    fixed = np.zeros(n, bool)
    fixed[fi] = True
    return fixed


def _cones(prob: ConicProblem, lay: Layout, fixed: np.ndarray) -> None:
    """The epigraph cones: c_i ≤ √β_i ⇔ ‖(2c, β−1)‖ ≤ β+1 at the free samples, and
    d_i ≥ 1/(c_i + c_{i+1}) on every step."""
    n = lay.n
    free = np.flatnonzero(~fixed)
    nf = len(free)
    r = np.arange(3 * nf)
    cols = np.stack([free, free, lay.c0 + free], axis=1).ravel()
    vals = np.tile([-1.0, -1.0, -2.0], nf)
    prob.add(SOC, sp.csr_matrix((vals, (r, cols)), shape=(3 * nf, lay.nvar)), np.tile([1.0, -1.0, 0.0], nf), 3)
    # d_i ≥ 1/(c_i + c_{i+1})  ⇔ ‖(2, σ − d)‖ ≤ σ + d, σ = c_i + c_{i+1}
    m = n - 1
    ci = lay.c0 + np.arange(m)
    di = lay.d0 + np.arange(m)
    rows = np.repeat(np.arange(3 * m).reshape(m, 3)[:, :2], 3, axis=1).ravel()
    cols = np.stack([ci, ci + 1, di, ci, ci + 1, di], axis=1).ravel()
    vals = np.tile([-1.0, -1.0, -1.0, -1.0, -1.0, 1.0], m)
    prob.add(SOC, sp.csr_matrix((vals, (rows, cols)), shape=(3 * m, lay.nvar)), np.tile([0.0, 0.0, 2.0], m), 3)


def _speed_bounds(prob: ConicProblem, lay: Layout, b_lo: np.ndarray, b_hi: np.ndarray, floor: np.ndarray,
                  fixed: np.ndarray) -> None:
    """b_lo ≤ b ≤ b_hi at the samples not fixed, and the soft floor b + slack ≥ floor, slack ≥ 0."""
    v2, soft_idx = lay.vref ** 2, lay.soft_idx
    # Rows whose every variable is fixed are constants: the window before already obeyed them, and
    # its solution's round-off (≤ the accepted residual) must not make this window infeasible.
    fin = np.flatnonzero(np.isfinite(b_hi) & ~fixed)
    prob.add_le(sp.csr_matrix((np.ones(len(fin)), (np.arange(len(fin)), fin)), shape=(len(fin), lay.nvar)),
                b_hi[fin] / v2)
    pos = np.flatnonzero((b_lo > 0) & ~fixed)
    prob.add_le(sp.csr_matrix((-np.ones(len(pos)), (np.arange(len(pos)), pos)), shape=(len(pos), lay.nvar)),
                -b_lo[pos] / v2)
    if len(soft_idx):
        k = np.arange(len(soft_idx))
        A = sp.csr_matrix((np.r_[-np.ones(len(k)), -np.ones(len(k))], (np.r_[k, k], np.r_[soft_idx, lay.s0 + k])),
                          shape=(len(k), lay.nvar))
        prob.add_le(A, -floor[soft_idx] / v2)
        prob.add_le(sp.csr_matrix((-np.ones(len(k)), (k, lay.s0 + k)), shape=(len(k), lay.nvar)), np.zeros(len(k)))


def _acceleration(prob: ConicProblem, lay: Layout, ds: np.ndarray) -> None:
    """The explicit path acceleration: β_{i+1} − β_i − (2 ds aref/vref²) α_i = 0."""
    n, v2, aref = lay.n, lay.vref ** 2, lay.aref
    m = n - 1
    i = np.arange(m)
    vals = np.r_[np.ones(m), -np.ones(m), -2 * ds * aref / v2]
    A = sp.csr_matrix((vals, (np.r_[i, i, i], np.r_[i + 1, i, n + i])), shape=(m, lay.nvar))
    prob.add_eq(A, np.zeros(m))


def _local_rows(prob: ConicProblem, lay: Layout, ds: np.ndarray, blocks: list[Block], b_hi: np.ndarray,
                v0: np.ndarray, fixed: np.ndarray) -> None:
    """The blocks' linear rows in (b, a) at each sample (`linear_rows`), normalised; a row of fixed
    samples only is a constant and left out."""
    n, vref = lay.n, lay.vref
    nb = np.arange(n)
    U, W, G, H = linear_rows(blocks, b_hi, v0, convex_exact=True)
    if len(U):
        M = U.shape[0]
        idx = np.tile(nb, M)
        rr, cc, vv = _expr(lay, ds, idx, U.ravel(), W.ravel())
        g = G.ravel()
        neg = np.flatnonzero(g < 0)
        rr = np.r_[rr, neg]
        cc = np.r_[cc, lay.c0 + idx[neg]]
        vv = np.r_[vv, g[neg] * vref]
        h = H.ravel()
        uses_next = (U != 0).ravel() & (idx < n - 1)
        active = np.isfinite(h) & ~(fixed[idx] & (~uses_next | fixed[np.minimum(idx + 1, n - 1)]))
        if not active.all():
            sel = np.flatnonzero(active)
            remap = -np.ones(len(h), int)
            remap[sel] = np.arange(len(sel))
            keep = active[rr]
            rr, cc, vv, h = remap[rr[keep]], cc[keep], vv[keep], h[sel]
        _add_normalised_le(prob, rr, cc, vv, h)


def _step_rows(prob: ConicProblem, lay: Layout, grid: PathGrid, blk: StepRows, v0: np.ndarray) -> None:
    """A rate block's rows ±(e_{i+1} − e_i) + kb·b_{i+1} ≤ rhs (tangent of the rate bound at v0)."""
    n, ds = lay.n, grid.ds
    if n < 3:
        return
    kb, rhs = blk.linearised(grid, v0)  # (M, n−2)
    M = blk.u.shape[0]
    i = np.tile(np.arange(n - 2), M)
    mrow = np.repeat(np.arange(M), n - 2)
    r1, c1, v1 = _expr(lay, ds, i + 1, blk.u[mrow, i + 1], blk.w[mrow, i + 1])
    r0, c0_, v0_ = _expr(lay, ds, i, blk.u[mrow, i], blk.w[mrow, i])
    rb, cb, vb = _expr(lay, ds, i + 1, np.zeros(len(i)), kb.ravel())
    rr, cc, vv = np.r_[r1, r0], np.r_[c1, c0_], np.r_[v1, -v0_]
    h = rhs.ravel()
    _add_normalised_le(prob, np.r_[rr, rb], np.r_[cc, cb], np.r_[vv, vb], h)
    _add_normalised_le(prob, np.r_[rr, rb], np.r_[cc, cb], np.r_[-vv, vb], h)
