"""Checking a schedule the way the machine will run it: the honest baseline, the limit ratios of the
executed speeds, and which limits bound for how much of the time.

The executed speed comes from the controller model (`millpost.controller`) running the emitted
program; every load is affine in the path speed v (mm/s), so its value at the executed speed is
a·v + b, compared with the bound the schedule was given (after the feed policy of `millpost.limits`).
"""

from __future__ import annotations

import numpy as np

from .gcode.interpret import Program
from .job import Job
from .limits import LOAD_CHUNK, JobLimits, static_caps
from .schedule import PathGrid, SpeedLoad
from .schedule.constraints import window_blocks
from .toolpath import RAPID, Samples, Toolpath


def baseline_feeds(program: Program, samples: Samples, limits: JobLimits) -> tuple[np.ndarray, dict]:
    """The honest baseline: per tool one constant feed (mm/min), the highest that exceeds no
    speed-only limit anywhere that tool cuts (what a careful CAM user would program)."""
    tp = program.toolpath
    cap = static_caps(samples, limits) * 60.0
    feeds = tp.feed_mm_min.copy()
    per_tool = {}
    for number in np.unique(tp.tool[tp.kind != RAPID]):
        sel = (samples.tool == number) & (samples.kind != RAPID)
        if not sel.any():  # no move of this tool is long enough to be sampled: its feeds stay
            per_tool[int(number)] = None
            continue
        f = float(np.floor(cap[sel].min()))
        per_tool[int(number)] = f
        feeds[(tp.tool == number) & (tp.kind != RAPID)] = f
    return feeds, per_tool


def feed_at_samples(emitted: Toolpath, samples: Samples) -> np.ndarray:
    """The F in force (mm/min) of an emitted program at each sample of the original resampling, by
    arc length (splitting moves does not change the path's length)."""
    s_end = np.cumsum(emitted.lengths())
    k = np.clip(np.searchsorted(s_end, samples.s_mm - 1e-9), 0, max(len(emitted) - 1, 0))
    return emitted.feed_mm_min[k]


def limit_ratios(samples: Samples, limits: JobLimits, v_mm_s: np.ndarray, job: Job) -> dict[str, float]:
    """Largest value/bound of every limit over the cutting samples at the executed speeds (mm/s)."""
    grid = PathGrid.from_samples(samples)
    cut = samples.kind != RAPID
    out: dict[str, float] = {}
    v = v_mm_s
    for lim in limits:
        c = lim.constraint
        if isinstance(c, SpeedLoad):
            value = c.alpha * v + c.beta
            with np.errstate(divide="ignore", invalid="ignore"):  # 0/0 off the cut: masked below
                ratio = value / np.broadcast_to(np.asarray(c.limit, float), value.shape)
            out[lim.name] = max(out.get(lim.name, 0.0), float(np.nanmax(np.where(cut, ratio, 0.0), initial=0)))
        elif lim.f_word and not lim.controller:  # speed caps only millpost holds (in chunks: memory)
            for lo in range(0, len(samples), LOAD_CHUNK):
                hi = min(lo + LOAD_CHUNK, len(samples))
                for blk in window_blocks(grid, [lim], lo, hi, caps_only=True):
                    with np.errstate(divide="ignore", invalid="ignore"):
                        r = np.where(cut[lo:hi] & (blk.b_hi > 0), v[lo:hi] / np.sqrt(blk.b_hi), 0.0)
                    out[blk.name] = max(out.get(blk.name, 0.0), float(np.nanmax(r, initial=0.0)))
    # motor current from the executed speed profile: a = v dv/ds along the path
    ds = np.gradient(samples.s_mm)
    a_path = v * np.gradient(v) / np.where(ds > 0, ds, 1.0)
    worst = 0.0
    keep = cut & ~limits.held["cutting_current"]
    for k, name in enumerate("xyz"):
        axis = job.machine.axes[name]
        vel = samples.tangent[:, k] * v
        acc = samples.tangent[:, k] * a_path + samples.curvature[:, k] * v**2
        cut_force = -(limits.loads["force_a"][:, k] * v + limits.loads["force_b"][:, k])
        d = axis.demand(vel, acc, cut_force_N=cut_force)
        worst = max(worst, float(np.max(np.abs(d.current_A[keep]), initial=0.0)) / axis.motor.current_limit_A)
    out["current"] = worst
    return out


def binding_shares(samples: Samples, sched, limits: JobLimits) -> tuple[dict[str, float], dict[str, float]]:
    """Share of the scheduled cutting time each limit binds, grouped by effect and by limit name
    (time weights: trapezoid Δt = 2·Δs/(v₀ + v₁))."""
    total = 0.0
    by_effect: dict[str, float] = {}
    by_name: dict[str, float] = {}
    owner = limits.by_block(PathGrid.from_samples(samples))
    for lo, hi, s in sched.segments:
        v = s.feed_mm_s
        dt = np.zeros(hi - lo)
        with np.errstate(divide="ignore", invalid="ignore"):
            dt[1:] = np.where(v[1:] + v[:-1] > 0, 2 * np.diff(samples.s_mm[lo:hi]) / (v[1:] + v[:-1]), 0.0)
        total += float(dt.sum())
        blocks, which = np.unique(s.binding.astype(str), return_inverse=True)
        for block, w in zip(blocks, np.bincount(which.reshape(-1), weights=dt, minlength=len(blocks))):
            if block:
                lim = owner.get(block)
                effect, name = (lim.effect, lim.name) if lim is not None else (block, block)
                by_effect[effect] = by_effect.get(effect, 0.0) + float(w)
                by_name[name] = by_name.get(name, 0.0) + float(w)
    if total <= 0:
        return {}, {}
    return ({k: round(v / total, 4) for k, v in sorted(by_effect.items())},
            {k: round(v / total, 4) for k, v in sorted(by_name.items())})
