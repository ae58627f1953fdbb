"""Time-optimal feed along a path segment: monolithic or windowed SOCP, with an O(N) fallback.

Long segments are solved as receding windows (W samples, overlap O): each window starts from the
committed b (two samples when StepRows need a fixed a) and ends inside the controllable set
b ≤ K_hi of the reachability pass, which keeps every later window feasible (notes/SCHEDULE-PROTOTYPE
§4.8). With several processes the segment is first cut at cruise anchors (samples where the greedy
profile sits on the speed cap over ±3 samples, so the optimum does too) and the chunks are solved
independently with b fixed at the anchors. The cuts depend only on the segment (about one per
`chunk` samples), never on the number of processes, so that any number of processes gives the same
schedule; `schedule_samples` hands whole segments to the processes when there are several.
"""

from __future__ import annotations

import contextlib
import dataclasses
import multiprocessing
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from millpost.schedule.assemble import build, linear_rows, merged_bounds, soft_floor
from millpost.schedule.certify import certify
from millpost.schedule.constraints import window_blocks
from millpost.schedule.problem import SolverOptions, Status
from millpost.schedule.reach import Reach, reach, traversal_time
from millpost.schedule.rows import Block, LocalRows, PathGrid, SpeedBounds, StepRows
from millpost.progress import current
from millpost.toolpath import RAPID, Samples


@dataclass
class ScheduleOptions:
    """window/overlap in samples; segments up to `monolithic_max` samples are solved in one piece.
    `relinearize`: extra solves re-taking the tangents (√b terms of LocalRows, 1/√b of StepRows)
    at the last solution (speeds below 5 % of the top speed keep the tangent there).
    `floor_penalty`: weight of soft-floor slack (time units per unit of scaled b per unit length).
    `certify_gap`: accept the O(N) reachability profile without a conic solve where it is provably
    within this relative time of the optimum, on the whole segment or on a stretch between cruise
    anchors (certify.py, `_patch`; 0 always solves the SOCP). The default 0.1 % is the optimality
    budget of issue 5; measured loss is about a quarter of the bound.
    Iterative refinement is off (1.4–1.8× faster); a window whose largest row violation (rows
    normalised to unit coefficients, b scaled to ≤ 1) exceeds `max_residual` is re-solved with it;
    after the retries the best solution is kept if its violation is within `accept_residual` (1e-4 of
    the top speed squared: far inside the 0.5 % the replay check allows).
    `chunk`: samples per independently solved chunk of a long segment (cut at cruise anchors).
    `processes`: worker processes for segments and chunks (default: all cores; one inside a daemonic
    process such as a multiprocessing pool's worker, which may not start processes); the result
    does not depend on it (the chunks are cut the same way whatever the count).
    Build from the user's words with `from_choices`."""

    window: int = 2000
    overlap: int = 100
    monolithic_max: int = 4000
    chunk: int = 8000
    processes: int = field(default_factory=lambda: 1 if multiprocessing.current_process().daemon else os.cpu_count() or 1)
    relinearize: int = 1
    floor_penalty: float = 10.0
    max_residual: float = 1e-6
    accept_residual: float = 1e-4
    certify_gap: float = 1e-3
    solver: SolverOptions = field(default_factory=lambda: SolverOptions(iterative_refinement=False))

    SOLVERS = ("auto", "clarabel")

    @classmethod
    def from_choices(cls, *, solver: str | None = None, jobs: int | None = None) -> "ScheduleOptions":
        """solver "auto" (certified O(N) profile where its proven gap is within `certify_gap`,
        Clarabel elsewhere) or "clarabel" (Clarabel on every segment, for comparison); jobs: worker
        processes (None: all cores)."""
        if solver not in (None, *cls.SOLVERS):
            raise ValueError(f"solver {solver!r}: expected one of {', '.join(cls.SOLVERS)}")
        if jobs is not None and jobs < 1:
            raise ValueError(f"jobs {jobs}: expected a whole number >= 1")
        opts = cls() if jobs is None else cls(processes=jobs)
        return dataclasses.replace(opts, certify_gap=0.0) if solver == "clarabel" else opts


@dataclass
class Schedule:
    """b (N,) mm²/s² and a (N−1,) mm/s² along the segment; feed_mm_s = √b.

    status: Status (FALLBACK when the reachability profile replaced a failed solve, INFEASIBLE when
    not even that exists, then b is zero and `message` says why). floor_unmet: samples where a soft
    floor could not be met. excess: {block name: worst (value − bound)/bound over the samples}.
    binding: per sample the name of the tightest limit ('' when none within 1e-3).
    method/gap_bound: how it was solved and, for the reachability profile, the proven gap.
    """

    b: np.ndarray
    a: np.ndarray
    status: Status
    time_s: float
    message: str = ""
    floor_unmet: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    excess: dict = field(default_factory=dict)
    binding: np.ndarray = field(default_factory=lambda: np.zeros(0, object))
    solver_s: float = 0.0
    windows: int = 0
    method: str = "socp"  # or "reach": the certified O(N) profile
    gap_bound: float = float("nan")  # proven bound on (time − optimum)/optimum when method is reach

    @property
    def feed_mm_s(self) -> np.ndarray:
        return np.sqrt(np.maximum(self.b, 0.0))


def _parallel(opts: ScheduleOptions) -> bool:
    """Whether to use worker processes (a daemonic process may not start any: then one, same result)."""
    return opts.processes > 1 and not multiprocessing.current_process().daemon


def _window_blocks(blocks: list[Block], lo: int, hi: int) -> list[Block]:
    return [blk.window(lo, hi) for blk in blocks]


def _solve_window(grid: PathGrid, blocks: list[Block], v0: np.ndarray, vref: float, aref: float,
                  opts: ScheduleOptions, b_fixed_start: np.ndarray, b_end: tuple[float, float],
                  b_fixed_end: np.ndarray | None = None):
    prob, lay = build(grid, blocks, b_fixed_start=b_fixed_start, b_end=b_end, v0=v0, vref=vref, aref=aref,
                      floor_penalty=opts.floor_penalty, b_fixed_end=b_fixed_end)
    # retries: iterative refinement on, then a 10× looser tolerance (Clarabel occasionally stops with
    # InsufficientProgress on long windows; notes/SCHEDULE-PROTOTYPE.md pitfall 2)
    attempts = [opts.solver, dataclasses.replace(opts.solver, iterative_refinement=True),
                dataclasses.replace(opts.solver, iterative_refinement=True, tol=opts.solver.tol * 10,
                                    tol_ktratio=opts.solver.tol_ktratio * 10)]
    secs, best = 0.0, None
    for settings in attempts:
        sol = prob.solve(settings)
        secs += sol.solve_s
        if sol.status.ok and (best is None or sol.primal_residual < best.primal_residual):
            best = sol
        if sol.status == Status.INFEASIBLE or (sol.status.ok and sol.primal_residual <= opts.max_residual):
            break
    sol = best if best is not None else sol
    sol.solve_s = secs
    if not sol.status.ok or not sol.primal_residual <= opts.accept_residual:
        return None, None, sol
    return lay.b(sol.x), lay.slack(sol.x), sol


def _failure(sol, opts: ScheduleOptions) -> str:
    """Why a window's solution was refused: the solver's status, or (solved) its residual too large."""
    if sol.status.ok:
        return f"{sol.raw_status} with a constraint violation {sol.primal_residual:.2g} above {opts.accept_residual:g}"
    return str(sol.raw_status)


def _solve_chunk(args) -> tuple[np.ndarray | None, np.ndarray, float, int, str]:
    """Receding windows over one chunk. Returns (b, slack, solver seconds, windows, error message)."""
    grid, blocks, v0, vref, aref, opts, k_lo, k_hi, b_first, b_last, nfix = args
    n = len(grid)
    b = np.full(n, np.nan)
    slack = np.zeros(n)
    b[:len(b_first)] = b_first
    W, O = max(opts.window, 4 * nfix + 2), min(opts.overlap, opts.window // 2)
    pos = len(b_first) - 1  # last committed sample
    secs, count = 0.0, 0
    while True:
        s0 = max(0, pos - nfix + 1)
        end = s0 + W if n - (s0 + W) > W // 4 else n  # no short leftover window
        last = end == n
        sl = slice(s0, end)
        bl = _window_blocks(blocks, s0, end)
        fixed_end = b_last if last else None
        bend = (k_lo[end - 1], k_hi[end - 1])
        bw, sw, sol = _solve_window(grid.window(s0, end), bl, v0[sl], vref, aref, opts,
                                    b[s0:pos + 1], bend, fixed_end)
        secs += sol.solve_s
        count += 1
        if bw is None:
            return None, slack, secs, count, f"window [{s0}, {end}) {_failure(sol, opts)}"
        commit = end if last else max(end - O, pos + 2)
        b[pos + 1:commit] = bw[pos + 1 - s0:commit - s0]
        slack[pos + 1:commit] = sw[pos + 1 - s0:commit - s0]
        if last:
            return b, slack, secs, count, ""
        pos = commit - 1


def _anchors(b: np.ndarray, b_hi: np.ndarray, parts: int, margin: int) -> list[int]:
    """Cruise anchors near equally spaced positions: the greedy profile b on the cap over ±3 samples."""
    n = len(b_hi)
    on_cap = np.isfinite(b_hi) & (b >= b_hi * (1 - 1e-9)) & (b_hi > 0)
    flat = on_cap.copy()
    for k in range(1, 4):
        flat[k:] &= on_cap[:-k]
        flat[:-k] &= on_cap[k:]
    cand = np.flatnonzero(flat)
    cand = cand[(cand > margin) & (cand < n - 1 - margin)]
    out: list[int] = []
    for p in range(1, parts):
        if not len(cand):
            break
        j = int(cand[np.argmin(np.abs(cand - p * n // parts))])
        if not out or j > out[-1] + margin:
            out.append(j)
    return out


def _excess(grid: PathGrid, blocks: list[Block], b: np.ndarray, a: np.ndarray) -> dict:
    """Worst relative excess per named limit, evaluated exactly (√b, not the linearisation)."""
    out: dict[str, float] = {}
    for blk in blocks:
        if isinstance(blk, LocalRows):
            val = float(blk.excess(b, a).max()) if len(b) else 0.0
        elif isinstance(blk, StepRows):
            val = float(blk.excess(grid, b, a).max()) if len(b) > 2 else 0.0
        elif isinstance(blk, SpeedBounds):
            with np.errstate(divide="ignore", invalid="ignore"):
                r = np.sqrt(np.maximum(b, 0)) / np.sqrt(blk.b_hi) - 1
            val = float(np.nanmax(np.where(blk.b_hi > 0, r, np.where(b > 0, np.inf, -1.0))))
        else:
            continue
        out[blk.name] = max(out.get(blk.name, -np.inf), val)
    return out


def _binding(grid: PathGrid, blocks: list[Block], b: np.ndarray, a: np.ndarray, tol: float = 1e-3) -> np.ndarray:
    """Name of the limit with the smallest slack per sample (within tol of its bound), else ''."""
    n = len(b)
    best = np.full(n, -np.inf)
    name = np.full(n, "", dtype=object)
    for blk in blocks:
        if isinstance(blk, LocalRows):
            e = blk.excess(b, a)
        elif isinstance(blk, SpeedBounds):
            with np.errstate(divide="ignore", invalid="ignore"):
                e = np.where(blk.b_hi > 0, np.sqrt(np.maximum(b, 0) / blk.b_hi) - 1, -np.inf)
        else:
            continue
        upd = (e > best) & (e > -tol)
        best = np.where(upd, e, best)
        name[upd] = blk.name
    return name


def solve_path(grid: PathGrid, blocks: list[Block], options: ScheduleOptions | None = None, *,
               b_start: float = 0.0, b_end: float = 0.0, on_window: Callable[[int], None] | None = None) -> Schedule:
    """Minimum-time b(s) on one segment under the blocks, rest to rest by default. on_window: called
    with the sample count of each window or stretch solved (progress).

    With `certify_gap` > 0 a rest-to-rest segment first gets the certified O(N) profile (certify.py):
    accepted whole when its proven gap is within `certify_gap`; otherwise it is cut at cruise anchors
    of that profile (samples on the speed cap, where both bracketing profiles sit, so the optimum does
    too) and only the stretches whose own proven gap exceeds `certify_gap` go to Clarabel, with b
    fixed to the profile at their ends (`_patch`)."""
    opts = options or ScheduleOptions()
    n = len(grid)
    if n < 2:
        return Schedule(np.zeros(n), np.zeros(0), Status.SOLVED, 0.0)
    ds = grid.ds
    b_lo, b_hi = merged_bounds(blocks, n)
    if not np.isfinite(b_hi).all():
        raise ValueError("every sample needs a finite speed cap (add a FeedLimit)")
    vref = float(np.sqrt(b_hi.max())) or 1.0
    t0 = time.perf_counter()
    if opts.certify_gap > 0 and b_start == 0 and b_end == 0:
        cert = certify(grid, blocks, opts.floor_penalty)
        if cert is not None and cert.gap <= opts.certify_gap:
            b = cert.b
            a = np.diff(b) / (2 * ds)
            floor_unmet = soft_floor(blocks, n) > b * (1 + 1e-6) + 1e-9
            return Schedule(b, a, Status.SOLVED, traversal_time(ds, b), "", floor_unmet,
                            _excess(grid, blocks, b, a), _binding(grid, blocks, b, a), time.perf_counter() - t0, 0,
                            "reach", cert.gap)
        if cert is not None:
            return _patch(grid, blocks, opts, cert, b_lo, b_hi, vref, t0, on_window)
    result_b, result_slack, rc, secs, windows, message = _solve_socp(
        grid, blocks, opts, b_lo, b_hi, vref, np.array([b_start]), np.full(1, b_end), on_window)
    if rc is None:
        return Schedule(np.zeros(n), np.zeros(n - 1), Status.INFEASIBLE, float("inf"),
                        "no speed profile satisfies the limits (empty controllable set at the start)",
                        solver_s=time.perf_counter() - t0)
    floor = soft_floor(blocks, n)
    if result_b is None:
        b, status = rc.b, Status.FALLBACK
        floor_unmet = floor > b * (1 + 1e-6) + 1e-9
        message = message or "conic solve failed"
    else:
        b, status, message = np.clip(result_b, 0.0, b_hi), Status.SOLVED, ""
        floor_unmet = (floor > 0) & (result_slack > 1e-6 * np.maximum(floor, 1e-12)) & (b < floor * (1 - 1e-6))
    a = np.diff(b) / (2 * ds)
    return Schedule(b, a, status, traversal_time(ds, b), message, floor_unmet, _excess(grid, blocks, b, a),
                    _binding(grid, blocks, b, a), secs, windows)


def _nfix(blocks: list[Block]) -> int:
    """Samples of b fixed at a cut: two where StepRows tie neighbouring accelerations, else one."""
    return 2 if any(isinstance(blk, StepRows) for blk in blocks) else 1


def _solve_socp(grid: PathGrid, blocks: list[Block], opts: ScheduleOptions, b_lo: np.ndarray, b_hi: np.ndarray,
                vref: float, first: np.ndarray, last: np.ndarray, on_window: Callable[[int], None] | None = None):
    """The SOCP from b fixed to `first` at the first samples to `last` at the last ones, re-linearised
    (`relinearize`). Returns (b or None, floor slack, the last reachability pass or None when even
    that is infeasible, solver seconds, windows, failure message)."""
    ds = grid.ds
    has_steps = any(isinstance(blk, StepRows) for blk in blocks)
    nonconvex = has_steps or any(isinstance(blk, LocalRows) and (blk.g > 0).any() for blk in blocks)
    v0 = np.sqrt(np.maximum(b_hi, 1e-12))
    secs, windows = 0.0, 0
    result_b, result_slack, message = None, None, ""
    for it in range(1 + (opts.relinearize if nonconvex else 0)):
        U, Wm, _, H = linear_rows(blocks, b_hi, v0, convex_exact=False)
        rc = reach(ds, b_lo, b_hi, U, Wm, H, b_start=float(first[-1]), b_end_max=float(last[-1]),
                   b_end_min=float(last[-1]))
        if not rc.feasible:
            if result_b is not None:
                break
            return None, None, None, secs, windows, ""
        b_new, slack, sec, cnt, message = _solve_linearised(grid, blocks, opts, v0, vref, rc, (U, Wm, H),
                                                            b_lo, b_hi, first, last, _nfix(blocks), on_window)
        secs += sec
        windows += cnt
        if b_new is None:
            break
        result_b, result_slack = b_new, slack
        if not _tangents_bind(grid, blocks, result_b, v0):
            break  # re-taking the tangents cannot move the optimum: no linearised row is active off its tangent
        v0 = np.maximum(np.sqrt(result_b), 0.05 * vref)  # tangent point of the next linearisation
    return result_b, result_slack, rc, secs, windows, message


def _patch(grid: PathGrid, blocks: list[Block], opts: ScheduleOptions, cert, b_lo: np.ndarray, b_hi: np.ndarray,
           vref: float, t0: float, on_window: Callable[[int], None] | None = None) -> Schedule:
    """The certified profile with the stretches whose proven gap exceeds `certify_gap` solved by
    Clarabel (b fixed to the profile at the stretch's ends: the profile is feasible and sits on the
    speed cap there, so the result is feasible everywhere). A stretch whose solve fails keeps the
    certified profile (feasible, within its proven gap of the optimum): status ALMOST_SOLVED, and the
    message says where and why. Stretches run in parallel processes."""
    n, ds = len(grid), grid.ds
    nfix = _nfix(blocks)
    cuts = [0, *_anchors(cert.b, b_hi, max(1, round(n / opts.window)), margin=nfix + 3), n - 1]
    spans = [(cuts[k], cuts[k + 1] + 1) for k in range(len(cuts) - 1)]
    bad = [(lo, hi) for lo, hi in spans if cert.gap_between(lo, hi) > opts.certify_gap]
    one = dataclasses.replace(opts, processes=1)
    jobs = [(grid.window(lo, hi), _window_blocks(blocks, lo, hi), one, b_lo[lo:hi], b_hi[lo:hi], vref,
             cert.b[lo:lo + nfix], cert.b[hi - nfix:hi]) for lo, hi in bad]
    outs = _run_jobs(_solve_stretch, jobs, opts, [hi - lo for lo, hi in bad], on_window)
    b, floor = cert.b.copy(), soft_floor(blocks, n)
    floor_unmet = floor > b * (1 + 1e-6) + 1e-9
    secs, windows, failed = 0.0, 0, []
    for (lo, hi), (bb, slack, sec, cnt, msg) in zip(bad, outs):
        secs += sec
        windows += cnt
        if bb is None:
            failed.append(f"samples [{lo}, {hi}): {msg or 'conic solve failed'}")
            continue
        b[lo:hi] = np.clip(bb, 0.0, b_hi[lo:hi])
        fl = floor[lo:hi]
        floor_unmet[lo:hi] = (fl > 0) & (slack > 1e-6 * np.maximum(fl, 1e-12)) & (b[lo:hi] < fl * (1 - 1e-6))
    a = np.diff(b) / (2 * ds)
    message = ("certified profile kept where the conic solve failed: " + "; ".join(failed[:3])) if failed else ""
    return Schedule(b, a, Status.ALMOST_SOLVED if failed else Status.SOLVED, traversal_time(ds, b), message, floor_unmet,
                    _excess(grid, blocks, b, a), _binding(grid, blocks, b, a), secs, windows)


def _solve_stretch(args) -> tuple:
    grid, blocks, opts, b_lo, b_hi, vref, first, last = args
    b, slack, _, secs, windows, message = _solve_socp(grid, blocks, opts, b_lo, b_hi, vref, first, last)
    return b, slack, secs, windows, message


def _tangents_bind(grid: PathGrid, blocks: list[Block], b: np.ndarray, v0: np.ndarray, tol: float = 1e-3) -> bool:
    """Whether a row linearised at the tangent speeds v0 (LocalRows with g > 0, StepRows) is active
    (within `tol` of its right-hand side, relative to it) at a sample whose speed differs from its
    tangent point by more than 1 %. Only there is the linearisation tighter than the row itself, so
    only then can another pass at the solution's speeds gain time."""
    v = np.sqrt(np.maximum(b, 0.0))
    off = np.abs(v - v0) > 1e-2 * v0
    a = np.diff(b) / (2 * grid.ds)
    aa = np.append(a, 0.0)
    for blk in blocks:
        if isinstance(blk, LocalRows) and (blk.g > 0).any():
            pos = blk.g > 0
            w = blk.w + np.where(pos, blk.g / (2 * v0), 0.0)
            h = blk.h - np.where(pos, blk.g * v0 / 2, 0.0)
            lin = blk.u * aa + w * b + np.where(pos, 0.0, blk.g) * v
            active = lin >= h - tol * np.maximum(np.abs(h), blk.scale)
            if (active & pos & off).any():
                return True
        elif isinstance(blk, StepRows) and len(b) > 2:
            kb, rhs = blk.linearised(grid, v0)
            e = blk.u[:, :-1] * a + blk.w[:, :-1] * b[:-1]
            lin = np.abs(np.diff(e, axis=1)) + kb * b[1:-1]
            if ((lin >= rhs - tol * np.abs(rhs)) & off[1:-1]).any():
                return True
    return False


def _run_jobs(fn: Callable, jobs: list, opts: ScheduleOptions, sizes: list[int],
              on_window: Callable[[int], None] | None) -> list:
    """fn over jobs, in forked processes when opts allow and there are several, results in order;
    on_window(size) after each (the progress of that many samples)."""
    outs = []
    with contextlib.ExitStack() as stack:
        if _parallel(opts) and len(jobs) > 1:
            ex = stack.enter_context(ProcessPoolExecutor(max_workers=opts.processes,
                                                         mp_context=multiprocessing.get_context("fork")))
            results = ex.map(fn, jobs)
        else:
            results = map(fn, jobs)
        for size, out in zip(sizes, results):  # in order, as they come
            outs.append(out)
            if on_window is not None:
                on_window(int(size))
    return outs


def _solve_linearised(grid: PathGrid, blocks: list[Block], opts: ScheduleOptions, v0: np.ndarray, vref: float,
                      rc: Reach, rows: tuple, b_lo: np.ndarray, b_hi: np.ndarray, first: np.ndarray,
                      last: np.ndarray, nfix: int, on_window: Callable[[int], None] | None = None
                      ) -> tuple[np.ndarray | None, np.ndarray, float, int, str]:
    """One SOCP solve at fixed tangent points: monolithic, or chunks of receding windows.
    Returns (b or None, floor slack, solver seconds, windows, failure message)."""
    n, ds = len(grid), grid.ds
    U, Wm, H = rows
    aref = float(max(np.abs(rc.a).max(), 1e-6 * vref**2 / grid.length_mm))
    if n <= opts.monolithic_max:
        bw, sw, sol = _solve_window(grid, blocks, v0, vref, aref, opts, first, (last[-1], last[-1]),
                                    last if len(last) > 1 else None)
        return bw, sw, sol.solve_s, 1, "" if bw is not None else f"conic solve: {_failure(sol, opts)}"
    parts = max(1, round(n / opts.chunk))
    cuts = [0, *_anchors(rc.b, b_hi, parts, margin=opts.window // 4 + nfix), n - 1]
    jobs = []
    for k in range(len(cuts) - 1):
        lo, hi = cuts[k], cuts[k + 1] + 1
        head = rc.b[lo:lo + nfix] if k > 0 else first
        tail = rc.b[hi - nfix:hi] if k < len(cuts) - 2 else last
        # controllable sets toward this chunk's own end (b fixed at an anchor, not free ≤ K)
        rk = reach(ds[lo:hi - 1], b_lo[lo:hi], b_hi[lo:hi], U[:, lo:hi], Wm[:, lo:hi], H[:, lo:hi],
                   b_start=float(head[-1]), b_end_max=float(tail[-1]), b_end_min=float(tail[-1]))
        jobs.append((grid.window(lo, hi), _window_blocks(blocks, lo, hi), v0[lo:hi], vref, aref, opts,
                     rk.k_lo, rk.k_hi, head, tail, nfix))
    outs = _run_jobs(_solve_chunk, jobs, opts, list(np.diff(cuts)), on_window)
    b, slack = np.zeros(n), np.zeros(n)
    secs, count = 0.0, 0
    for k, (bb, sw, sec, cnt, msg) in enumerate(outs):
        secs += sec
        count += cnt
        if bb is None:
            return None, slack, secs, count, msg
        b[cuts[k]:cuts[k + 1] + 1] = bb
        slack[cuts[k]:cuts[k + 1] + 1] = sw
    return b, slack, secs, count, ""


def cutting_segments(samples: Samples) -> list[tuple[int, int]]:
    """Sample ranges [lo, hi) of contiguous cutting motion (rapids excluded). A range starts at the
    sample where the first cutting move begins (the preceding sample, unless the path jumps there)."""
    cut = samples.kind != RAPID
    out: list[tuple[int, int]] = []
    k, n = 1, len(samples)
    while k < n:
        if not cut[k]:
            k += 1
            continue
        lo = k if samples.segment_start[k] else k - 1
        k += 1
        while k < n and cut[k] and not samples.segment_start[k]:
            k += 1
        out.append((lo, k))
    return out


@dataclass
class ProgramSchedule:
    """Per sample of a resampled program: feed_mm_s (nan on rapids), and the segment schedules."""

    feed_mm_s: np.ndarray
    segments: list[tuple[int, int, Schedule]]

    @property
    def time_s(self) -> float:
        return float(sum(s.time_s for _, _, s in self.segments))

    @property
    def ok(self) -> bool:
        return all(s.status.ok for _, _, s in self.segments)


def schedule_samples(samples: Samples, limits: list, options: ScheduleOptions | None = None) -> ProgramSchedule:
    """Schedule every cutting segment of `samples` rest to rest. `limits` are constraint objects
    whose per-sample arrays span all samples; each segment's rows are built on its own samples
    (`window_blocks`), so memory follows the longest segment, not the program. Reports the stage
    "schedule" (samples of the segments and windows solved) to `millpost.progress.current()`."""
    opts = options or ScheduleOptions()
    progress = current()
    grid = PathGrid.from_samples(samples)
    ranges = cutting_segments(samples)
    sizes = [hi - lo for lo, hi in ranges]
    big = sorted(range(len(ranges)), key=lambda k: -sizes[k])
    total, finished, inside = sum(sizes), 0, 0

    def window(samples_done: int) -> None:  # a window of the segment being solved (passes may repeat them)
        nonlocal inside
        inside += samples_done
        progress("schedule", finished + min(inside, sizes[k] - 1), total)

    if _parallel(opts) and len(ranges) > 1 and total > 2 * opts.monolithic_max:
        # whole segments to the workers, largest first; each solves its chunks in turn. The workers are
        # forked with the grid and limits (initargs are not pickled under fork): only (lo, hi) travel
        with ProcessPoolExecutor(max_workers=min(opts.processes, len(ranges)),
                                 mp_context=multiprocessing.get_context("fork"), initializer=_share,
                                 initargs=(grid, limits, dataclasses.replace(opts, processes=1))) as ex:
            done = {}
            for k, sch in zip(big, ex.map(_solve_shared, [ranges[k] for k in big],
                                          chunksize=max(1, len(big) // (8 * opts.processes)))):
                done[k] = sch
                finished += sizes[k]
                progress("schedule", finished, total)
        schedules = [done[k] for k in range(len(ranges))]
    else:  # one long segment (its chunks in parallel), or only short ones
        schedules = []
        for k, (lo, hi) in enumerate(ranges):
            inside = 0
            schedules.append(_solve_segment(grid, limits, lo, hi, opts, window))
            finished += sizes[k]
            progress("schedule", finished, total)
    progress("schedule", total, total)
    feed = np.full(len(samples), np.nan)
    for (lo, hi), sch in zip(ranges, schedules):
        feed[lo:hi] = sch.feed_mm_s
    return ProgramSchedule(feed, [(lo, hi, sch) for (lo, hi), sch in zip(ranges, schedules)])


def _solve_segment(grid: PathGrid, limits: list, lo: int, hi: int, opts: ScheduleOptions,
                   on_window: Callable[[int], None] | None = None) -> Schedule:
    return solve_path(grid.window(lo, hi), window_blocks(grid, limits, lo, hi), opts, on_window=on_window)


_shared: tuple = ()  # a worker's (grid, limits, options), set by `_share` when the pool forks it


def _share(*state) -> None:
    global _shared
    _shared = state


def _solve_shared(segment: tuple[int, int]) -> Schedule:
    grid, limits, opts = _shared
    return _solve_segment(grid, limits, *segment, opts)
