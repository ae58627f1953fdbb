"""The F-word policy: from the schedule's solution to piecewise-constant feeds a controller can follow.

`emission_limit` turns the schedule's v(s) into the per-sample F-word limit (the controller's own
dynamics left to it, runs of moves one F where one fits, `hold_runs`); `piecewise_feeds` cuts it into
fragments per move, settled into runs (`settle`), short peaks the controller cannot reach joined to
their neighbours (`reachable`); `cluster` gives lines that run several times one F each.

Each cutting move is cut into fragments of at least `min_fragment_mm` (shorter only when the move
is), at most `1 + floor(L·max_changes_per_mm)` per move, each with the smallest limit over the
samples it touches (mm/s, as the schedule's; the writer rounds the F words down): the feed never
exceeds the limit anywhere (the limit is piecewise linear in b between samples, so its minimum over a
fragment is at a sample). Fragments start as equal cells; adjacent ones are merged where that costs the
least time until the count bound holds.

Pass the schedule's feed (or just its process caps: loads, chip load, max feed). Samples where the
limit is 0 are rest points (segment ends, exact-stop corners) that the controller produces itself;
they do not pull a fragment's feed to zero.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..schedule.assemble import merged_bounds
from ..schedule.constraints import window_blocks
from ..schedule.rows import PathGrid
from ..schedule.solve import ProgramSchedule
from ..toolpath import RAPID, Samples


@dataclass(frozen=True)
class Fragment:
    """Part [u_start, u_end] (fractions of the move's length) of move `move` at feed_mm_s."""

    move: int
    u_start: float
    u_end: float
    feed_mm_s: float


def _merge(length: np.ndarray, v: np.ndarray, max_count: int) -> tuple[np.ndarray, np.ndarray]:
    """Merge adjacent cells (length, speed) until at most max_count remain, cheapest time first."""
    length, v = list(length), list(v)
    # merge equal neighbours for free
    i = 0
    while i < len(v) - 1:
        if v[i] == v[i + 1]:
            length[i] += length.pop(i + 1)
            v.pop(i + 1)
        else:
            i += 1
    L, V = np.array(length), np.array(v)
    while len(V) > max_count:
        m = np.minimum(V[:-1], V[1:])
        cost = (L[:-1] + L[1:]) / m - L[:-1] / V[:-1] - L[1:] / V[1:]
        k = int(np.argmin(cost))
        L = np.r_[L[:k], L[k] + L[k + 1], L[k + 2:]]
        V = np.r_[V[:k], m[k], V[k + 2:]]
    return L, V


SLOWEST_FEED_MM_MIN = 1.0  # the slowest F word written (F0 would be no feed at all)


def _at_least_slowest(v_mm_s: np.ndarray) -> np.ndarray:
    """Feeds (mm/s) raised to the slowest F word: max(v·60, SLOWEST_FEED_MM_MIN)/60. Through mm/min, as
    the policy always has: cells' feeds one ulp apart can split a move elsewhere (max(v, 1/60) moved a
    split point of fabex_parallel_ocl by 0.0001 mm)."""
    return np.maximum(v_mm_s * 60.0, SLOWEST_FEED_MM_MIN) / 60.0


def settle(feeds: np.ndarray, step: float, keep: np.ndarray | None = None) -> np.ndarray:
    """Feeds in program order lowered into runs of one feed each, so that F words change only where
    the feed changes meaningfully: a feed joins the current run while the run's largest member stays
    within `step` (relative) of its smallest, and the run takes its smallest (never above any
    member's limit). `keep`: each feed's programmed one (the feeds' unit); a run takes a member under it only
    where its smallest member is itself under its own (a limit holds it there: one F for a run a
    limit slows in part), never for a run of feeds all at or above their programmed ones (only a
    limit lowers a feed below the programmed one, not the settling). Repeated until no two
    neighbouring runs lie within `step` of each other (a run pulled down by a later member may land
    next to the one before)."""
    out = np.asarray(feeds, float).copy()
    if step <= 0 or len(out) == 0:
        return out
    keep = np.zeros_like(out) if keep is None else np.nan_to_num(keep, nan=0.0)
    floor = np.minimum(out, keep).tolist()  # Python numbers: the loop reads them one by one
    while True:
        held = (out < keep * (1 - 1e-9)).tolist()  # a limit holds it under its keep (its own, or its run's)
        f = out.tolist()  # the loop reads at i and writes only behind it
        start, lo, hi, need, lo_held = 0, f[0], f[0], floor[0], held[0]
        for i in range(1, len(f) + 1):
            if i < len(f):
                low, low_held = (f[i], held[i]) if f[i] < lo else (lo, lo_held)
                if max(hi, f[i]) <= low * (1 + step) and (low_held or max(need, floor[i]) <= low):
                    lo, hi, need, lo_held = low, max(hi, f[i]), max(need, floor[i]), low_held
                    continue
            f[start:i] = [lo] * (i - start)
            if i < len(f):
                start, lo, hi, need, lo_held = i, f[i], f[i], floor[i], held[i]
        settled = np.array(f)
        if np.array_equal(settled, out):
            return settled
        out = settled


def cluster(feeds: np.ndarray, step: float) -> np.ndarray:
    """Feeds in any order lowered to the smallest of their cluster: ascending, a cluster holds the
    feeds within `step` (relative) of its smallest; so any two different results differ by more
    than `step`."""
    f = np.asarray(feeds, float)
    values, out = f.tolist(), [math.nan] * len(f)  # Python numbers: the loop reads them one by one
    lo = -math.inf
    for k in np.argsort(f).tolist():
        if not values[k] <= lo * (1 + step):
            lo = values[k]
        out[k] = lo
    return np.array(out, float)


def reachable(feeds_mm_s: np.ndarray, length_mm: np.ndarray, accel_mm_s2: np.ndarray, joined: np.ndarray,
              step: float, keep_mm_s: np.ndarray | None = None) -> np.ndarray:
    """Feeds of pieces too short to reach them taken down to their faster neighbour's: a piece of
    length L between neighbours at lower feeds v_prev, v_next, accelerating and braking at most at a,
    peaks at v² = (v_prev² + v_next²)/2 + a·L; where that is within `step` of the faster neighbour the
    piece's own F changes nothing meaningful on the machine and is not written (a bounds the path
    acceleration from above, so the loss is under `step`), unless that neighbour's feed is under the
    piece's programmed one (`keep_mm_s`: only a limit lowers a feed below the programmed one, not
    the writing of F words). joined[i]: piece i continues piece i − 1."""
    v = np.asarray(feeds_mm_s, float)
    nxt_joined = np.r_[joined[1:], False]
    prev = np.r_[np.inf, v[:-1]]
    nxt = np.r_[v[1:], np.inf]
    inner = joined & nxt_joined & (v > prev) & (v > nxt)
    peak = np.sqrt((prev**2 + nxt**2) / 2 + accel_mm_s2 * length_mm)
    faster = np.maximum(prev, nxt)
    take = inner & (peak <= faster * (1 + step))
    if keep_mm_s is not None:
        take &= faster >= np.nan_to_num(keep_mm_s, nan=0.0) * (1 - 1e-9)
    return np.where(take, faster, v)


def _move_cells(s: np.ndarray, v: np.ndarray, L: float, min_fragment_mm: float,
                max_changes_per_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """(lengths, speeds) of one move's fragments: equal cells, each at the smallest limit over the
    samples it touches, merged down to the count bound (`_merge`). s: arc length from the move's first
    sample (mm), v: the limit there (mm/s)."""
    ncell = max(1, int(L // min_fragment_mm))
    edges = np.linspace(0.0, L, ncell + 1)
    # a cell touches the samples bounding every sample interval that overlaps it
    lo = np.clip(np.searchsorted(s, edges[:-1], side="right") - 1, 0, len(s) - 1)
    hi = np.clip(np.searchsorted(s, edges[1:], side="left"), 0, len(s) - 1)
    cell_v = np.array([v[i:j + 1].min() for i, j in zip(lo, hi)])
    cell_v = np.where(np.isfinite(cell_v), cell_v, np.nanmin(np.where(np.isfinite(v), v, np.nan)))
    q = _at_least_slowest(cell_v)
    return _merge(np.diff(edges), q, 1 + int(np.floor(L * max_changes_per_mm)))


def piecewise_feeds(samples: Samples, limit_mm_s: np.ndarray, *, min_fragment_mm: float = 2.0,
                    max_changes_per_mm: float = 0.2, step: float = 0.05,
                    accel_mm_s2: tuple[float, float, float] | None = None) -> list[Fragment]:
    """Fragments of every cutting move whose samples carry a finite limit (mm/s), at most the limit
    and never below the slowest F word (`SLOWEST_FEED_MM_MIN`); settled into runs (`settle`: under a
    fragment's programmed feed only in a run a limit slows in part) and, with the axes'
    accelerations (mm/s²), short peaks the controller cannot reach joined to their neighbours
    (`reachable`), repeated until stable; equal neighbours within a move merged.

    A move shorter than 2·min_fragment_mm is one cell (its smallest limit): those are done for all
    moves at once, the longer ones one by one (`_move_cells`)."""
    lim = np.asarray(limit_mm_s, float)
    amax = np.asarray(accel_mm_s2 if accel_mm_s2 is not None else (np.inf,) * 3, float)
    mv = samples.move
    if not len(mv):
        return []
    starts = np.r_[0, np.flatnonzero(np.diff(mv) != 0) + 1]
    ends = np.r_[starts[1:], len(mv)]
    # a move's samples run from the one it starts at (the previous move's last, unless the path jumps);
    # that corner sample's limit is the previous move's (its step arrives there): the previous F word
    # holds it, and the corner's blend `blend_limit`, so it does not hold this move's first fragment
    first = np.where((starts > 0) & ~np.asarray(samples.segment_start, bool)[starts], starts - 1, starts)
    L = samples.s_mm[ends - 1] - samples.s_mm[first]
    v_min = np.minimum.reduceat(lim, starts)  # nan where a sample is nan
    finite = np.where(np.isfinite(lim), lim, np.inf)
    v_fin = np.minimum.reduceat(finite, starts)  # inf: no finite limit
    keep = (samples.kind[starts] != RAPID) & (L > 0) & np.isfinite(v_fin)
    t = np.abs(samples.tangent)
    with np.errstate(divide="ignore"):  # the path acceleration the axes allow along the move, at most
        accel = np.maximum.reduceat(np.min(np.where(t > 1e-12, amax / np.maximum(t, 1e-12), np.inf), axis=1),
                                    starts)
    # one cell: shorter than 2·min_fragment_mm, and no zero-length step (where the cell bounds would
    # leave a sample out; such moves take the general way, which reproduces that)
    repeat = np.r_[True, np.diff(samples.s_mm) <= 0].astype(np.int8)
    one = keep & (np.floor_divide(L, min_fragment_mm) <= 1) & (np.maximum.reduceat(repeat, starts) == 0)
    q = _at_least_slowest(np.where(np.isfinite(v_min), v_min, v_fin))
    k1 = np.flatnonzero(one)
    parts = [(k1, np.zeros(len(k1)), np.ones(len(k1)), q[k1], L[k1])]  # move, u0, u1, feed, length
    for k in np.flatnonzero(keep & ~one):
        b, f = ends[k], first[k]
        Lf, Vf = _move_cells(samples.s_mm[f:b] - samples.s_mm[f], np.r_[np.inf, lim[f + 1:b]] if f < starts[k]
                             else lim[f:b], float(L[k]), min_fragment_mm, max_changes_per_mm)
        u = np.r_[0.0, np.cumsum(Lf) / L[k]]
        u[-1] = 1.0
        parts.append((np.full(len(Lf), k), u[:-1], u[1:], Vf, Lf))
    cols = [np.concatenate(c) for c in zip(*parts)]
    order = np.argsort(cols[0], kind="stable")
    k_of, u0, u1, feeds, length = (c[order] for c in cols)
    if not len(k_of):  # no cutting move carries a limit (a program of rapids only)
        return []
    k_of = k_of.astype(np.int64)
    move = np.asarray(mv)[starts[k_of]]
    joined = np.r_[False, (move[1:] == move[:-1]) | (move[1:] == move[:-1] + 1)]
    programmed = samples.feed_mm_s[starts[k_of]]  # of each fragment's move
    for _ in range(20):
        before = feeds
        feeds = reachable(settle(feeds, step, programmed), length, accel[k_of], joined, step, programmed)
        if np.array_equal(feeds, before):
            break
    # equal neighbours within a move merged
    new = np.r_[True, (move[1:] != move[:-1]) | (feeds[1:] != feeds[:-1])]
    head = np.flatnonzero(new)
    tail = np.r_[head[1:], len(move)] - 1
    return [Fragment(m, a, b, f) for m, a, b, f in zip(move[head].tolist(), u0[head].tolist(), u1[tail].tolist(),
                                                        feeds[head].tolist())]


def emission_limit(samples: Samples, limits: list, schedule: ProgramSchedule,
                   controller_enforced: tuple[str, ...], ramp_owned: tuple[str, ...] = (),
                   clamps: tuple[str, ...] = ()) -> np.ndarray:
    """Per-sample feed limit (mm/s) for `piecewise_feeds`: the schedule's speed where a limit the
    controller does not know binds (loads, chip load, current at steady speed...), and the speed caps
    of the limits it does not enforce itself where only its own dynamics (named in
    controller_enforced, and those in ramp_owned while the schedule ramps: the drives' current, whose
    binding share during a ramp is the acceleration) bind — the controller ramps there on its own,
    and programming the ramp as F words would only slow it (a ladder of them ends in F≈0 at a
    stop). There the F word only needs to reach the speed the controller's steady clamps (named in
    clamps: axis rates, block rate) leave, so runs of such moves share one F (`hold_runs`). nan on
    rapids."""
    grid = PathGrid.from_samples(samples)
    out = np.full(len(samples), np.nan)
    need = np.full(len(samples), np.nan)
    for lo, hi, sch in schedule.segments:
        blocks = window_blocks(grid, limits, lo, hi, caps_only=True)
        _, b_hi = merged_bounds([blk for blk in blocks if blk.name not in controller_enforced], hi - lo)
        _, b_clamp = merged_bounds([blk for blk in blocks if blk.name in clamps], hi - lo)
        binding = sch.binding.astype(str)
        a = np.abs(sch.a)
        a_ref = 1e-3 * max(float(a.max(initial=0.0)), 1e-9)
        ramping = np.r_[a > a_ref, False] | np.r_[False, a > a_ref]
        own = np.isin(binding, controller_enforced + ("",)) | (np.isin(binding, ramp_owned) & ramping)
        out[lo:hi] = np.where(own, np.sqrt(b_hi), sch.feed_mm_s)
        need[lo:hi] = np.where(own, np.sqrt(np.minimum(b_clamp, b_hi)), sch.feed_mm_s)
    return hold_runs(samples, out, need)


def hold_runs(samples: Samples, limit_mm_s: np.ndarray, need_mm_s: np.ndarray) -> np.ndarray:
    """The per-sample F-word limit `limit_mm_s` made one value over runs of consecutive moves where
    one F fits them all: a move may take any F in [max of `need_mm_s`, min of `limit_mm_s`] over its
    samples (need: the speed the controller runs it at whatever higher F it is given, e.g. the axis
    rate of its direction, or a short move's block rate). Runs are grown in program order while their
    intersection is not empty and take the value in it nearest the F in force before them (the last
    limit of the feed move before; the intersection's lowest, the fastest speed a move of the run
    needs, at the start), so an F word changes where a limit does, not where the direction of a move does.
    A move whose own interval is empty (a load that varies along it), a rapid (nan) or a move off the
    schedule keeps its limit and ends the run."""
    mv = samples.move
    out = np.asarray(limit_mm_s, float).copy()
    if not len(mv):
        return out
    starts = np.r_[0, np.flatnonzero(np.diff(mv) != 0) + 1]
    counts = np.diff(np.r_[starts, len(mv)])
    with np.errstate(invalid="ignore"):
        hi = np.minimum.reduceat(out, starts)  # nan where any sample is nan
        lo = np.maximum.reduceat(np.asarray(need_mm_s, float), starts)
        free = np.isfinite(hi) & np.isfinite(lo) & (lo <= hi)
    last = np.where(samples.kind[starts] != RAPID, out[starts + counts - 1], np.nan)  # F is modal over rapids
    value = [math.nan] * len(starts)
    first, run_lo, run_hi, carry = 0, -math.inf, math.inf, math.nan
    free_k, lo_k, hi_k, last_k = free.tolist(), lo.tolist(), hi.tolist(), last.tolist()  # read one by one
    for k in range(len(starts) + 1):
        if k < len(starts) and free_k[k] and max(run_lo, lo_k[k]) <= min(run_hi, hi_k[k]):
            run_lo, run_hi = max(run_lo, lo_k[k]), min(run_hi, hi_k[k])
            continue
        if k > first:
            carry = min(max(carry, run_lo), run_hi) if math.isfinite(carry) else run_lo
            value[first:k] = [carry] * (k - first)
        if k < len(starts) and free_k[k]:
            first, run_lo, run_hi = k, lo_k[k], hi_k[k]
        else:
            first, run_lo, run_hi = k + 1, -math.inf, math.inf
            if k < len(starts) and math.isfinite(last_k[k]):
                carry = last_k[k]
    held = np.repeat(free, counts)
    out[held] = np.repeat(np.array(value), counts)[held]
    return out
