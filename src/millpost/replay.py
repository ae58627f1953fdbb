"""Checking a schedule the way the machine will run it: the honest baseline, the limit ratios of the
executed speeds, and which limits bound for how much of the time.

The executed speed comes from the controller model (`millpost.controller`) running the emitted
program; the forward model (`millpost.signals.predict`) gives the signals there, with the loads the
schedule was bounded with (affine in the path speed v, mm/s: exact for the mechanistic model, the
upper tangent of the concave Kienzle and end-cutting laws); each limit's load (its `signal`) is
compared with the bound the schedule was given (after the feed policy of `millpost.limits`).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from .controller import Execution
from .emit import cycle_feeds, emitted_positions
from .engagement import Engagement
from .gcode.interpret import Program
from .job import Job
from .limits import LOAD_CHUNK, JobLimits, static_caps
from .schedule import PathGrid, SpeedLoad
from .schedule.constraints import rows_at, window_blocks
from .signals import Load, predict, step_times_s
from .toolpath import RAPID, Samples, Toolpath


def baseline_feeds(program: Program, samples: Samples, limits: JobLimits) -> tuple[np.ndarray, dict, np.ndarray]:
    """The honest baseline: per tool and per programmed feed (the moves of one tool programmed at the
    same F form a group: a CAM user's separate cutting, plunge, ramp and lead-in feeds, which a careful
    machinist tunes each) one constant feed (mm/min, floored to a whole mm/min), the highest that
    exceeds no speed-only limit anywhere the group cuts; a group with no sampled move keeps its
    programmed feed. On the moves a cap from the program's own feeds applies to (the limits the group's
    F does not obey: the plunge feed cap on ramps and plunges, the air clearance on approaches) the feed
    is at most that cap. A tapping cycle keeps its programmed feed and a boring cycle's is never raised
    (`emit.cycle_feeds`), as in the optimized program. Rapids are untouched. Returns the feed per move, per tool {programmed F: the
    highest feed that group's moves run at}, and the cap per sample (mm/s) all its feeds keep (inf
    where none)."""
    tp = program.toolpath
    cap = static_caps(samples, limits, baseline=True) * 60.0
    feeds = tp.feed_mm_min.copy()
    moving = np.flatnonzero(tp.kind != RAPID)
    groups, group = np.unique(np.column_stack([tp.tool[moving], tp.feed_mm_min[moving]]), axis=0,
                              return_inverse=True)
    group = group.reshape(-1)
    of_move = np.full(len(tp), -1)
    of_move[moving] = group
    at = of_move[samples.move]
    on = at >= 0
    lowest = np.full(len(groups), np.inf)
    np.minimum.at(lowest, at[on], cap[on])
    # floored to a whole mm/min, with a relative 1e-9 so a cap that is the programmed feed (a bound the
    # feed policy held at its load) is not lost to rounding; nothing sampled: as programmed
    base = np.where(np.isfinite(lowest), np.floor(lowest * (1 + 1e-9)), groups[:, 1])
    feeds[moving] = base[group]
    own = [lim for lim in limits if not lim.baseline]
    if own:
        own_cap = static_caps(samples, own)
        move_cap = np.full(len(tp), np.inf)
        np.minimum.at(move_cap, samples.move, own_cap * 60.0)
        feeds = np.where(tp.kind != RAPID, np.minimum(feeds, move_cap), feeds)
        cap = np.fmin(cap, own_cap * 60.0)
    feeds, _ = cycle_feeds(program, feeds)  # tapping and boring feeds, as the optimized program keeps them
    runs = np.zeros(len(groups))
    np.maximum.at(runs, group, feeds[moving])
    per_tool: dict[int, dict[float, float]] = {}
    for (number, programmed), f in zip(groups, runs):
        per_tool.setdefault(int(number), {})[float(programmed)] = float(f)
    return feeds, per_tool, cap / 60.0


def feed_at_samples(original: Toolpath, emitted: Toolpath, samples: Samples) -> np.ndarray:
    """The F in force (mm/min) of an emitted program at each sample of the original resampling, read at
    the same place of the emitted (split) moves (`emit.emitted_positions`), not by the total arc length
    (rounded split points shift it into the neighbouring piece)."""
    k, _ = emitted_positions(original, emitted, samples.move, Execution.sample_fractions(samples))
    return emitted.feed_mm_min[k]


@dataclass
class Replay:
    """A schedule checked at the executed speeds. ratios: per limit the largest value / bound over the
    cutting samples (bounds after the feed policy); physical: per load limit the largest value / its
    bound before the policy (over 1 where the policy held a cut too heavy at any feed it may write);
    loads: per load limit, per sample (its value, its bound before the policy), of the row with the
    highest ratio where several rows share the name; load_of: per load limit the signal it bounds
    (`millpost.signals.Load`); current_ratio: per sample the largest axis motor current over its drive's
    limit; cut_loads: per sample the forward model's peak in-plane force (N), cutting power (W), thrust
    on the tool (N, +Z) and cutting torque (N·m), 0 off the cut; cut: the cutting samples. (loads,
    current_ratio and cut_loads are empty where `replay` was asked for the ratios only.)"""

    ratios: dict[str, float]
    physical: dict[str, float]
    loads: dict[str, tuple[np.ndarray, np.ndarray]]
    load_of: dict[str, Load]
    current_ratio: np.ndarray
    cut_loads: dict[str, np.ndarray]
    cut: np.ndarray

    def trace_columns(self) -> dict[str, np.ndarray]:
        """Per-sample columns for the optimize trace (0 off the cut; a bound is nan where there is none):
        the loads and their bounds the job report plots."""
        cut = self.cut

        def of(load: Load) -> tuple[np.ndarray, np.ndarray]:
            (name,) = (name for name, bounded in self.load_of.items() if bounded is load)
            return self.loads[name]

        def bound(load: Load) -> np.ndarray:
            b = of(load)[1]
            return np.where(cut & np.isfinite(b), b, np.nan)

        force, power, deflection, chip = Load.PEAK_FORCE, Load.POWER, Load.DEFLECTION, Load.CHIP
        return {**self.cut_loads, force.bound_column: bound(force), power.bound_column: bound(power),
                deflection.column: np.where(cut, of(deflection)[0], 0.0), chip.column: np.where(cut, of(chip)[0], 0.0),
                chip.bound_column: bound(chip), Load.DRIVE_CURRENT.column: np.where(cut, self.current_ratio, 0.0)}


def replay(job: Job, samples: Samples, eng: Engagement, limits: JobLimits, v_mm_s: np.ndarray,
           columns: bool = True) -> Replay:
    """The signals at the executed speeds (mm/s per sample) from the forward model (`signals.predict`
    with the schedule's affine loads), every limit's value there against its bound, and the drives'
    motor currents against their limits (off the samples where the policy held the cutting current).
    In chunks of LOAD_CHUNK samples (memory: the signals of the whole program are never held at once),
    each predicted with one neighbour on either side so the path acceleration (central differences of
    v² over s) is the whole program's. columns: keep the per-sample values (`Replay.loads`,
    `cut_loads`, `current_ratio`: the trace's); without them those are empty and only the ratios are
    computed."""
    n = len(samples)
    v_mm_s = np.asarray(v_mm_s, float)
    grid = PathGrid.from_samples(samples)
    cut = samples.kind != RAPID
    keep_current = cut & ~limits.held_on(Load.DRIVE_CURRENT)
    limit_A = np.array([job.machine.axes[a].motor.current_limit_A for a in "xyz"])
    loads = [lim for lim in limits if isinstance(lim.constraint, SpeedLoad)]
    caps = limits.f_word_caps()
    rows_of = Counter(lim.name for lim in loads)
    m = n if columns else 0  # per-sample columns: kept only when asked for
    value = {name: np.zeros(m) for name in rows_of}
    # per name the bound of its row, of several the bound of the highest per sample (chunk by chunk: a
    # Derived bound is computed once, for the rows the chunk reads)
    bound = {name: np.zeros(m) for name in rows_of}
    cut_loads = {key: np.zeros(m) for key in ("peak_force_N", "power_W", "thrust_N", "torque_Nm")}
    current, ratios, physical, current_max = np.zeros(m), {}, {}, 0.0
    for lo in range(0, n, LOAD_CHUNK):
        hi = min(lo + LOAD_CHUNK, n)
        a, b = max(lo - 1, 0), min(hi + 1, n)
        sig = predict(job, samples.select(slice(a, b)), eng.select(slice(a, b)), v_mm_s[a:b],
                      loads=limits.loads.select(slice(a, b))).select(slice(lo - a, hi - a))
        at, on = slice(lo, hi), cut[lo:hi]
        raw_best: dict[str, np.ndarray] = {}  # per name: the highest value / raw bound so far in the chunk
        for lim in loads:
            c = lim.constraint
            val, lim_bound = lim.signal(sig, at), lim.bound[at]
            with np.errstate(divide="ignore", invalid="ignore"):  # 0/0 off the cut: masked
                ratio = np.where(on, val / rows_at(c.limit, at, n), 0.0)
                raw = np.where(on, val / lim_bound, 0.0)
            ratios[lim.name] = max(ratios.get(lim.name, 0.0), float(np.nanmax(ratio, initial=0)))
            physical[lim.name] = max(physical.get(lim.name, 0.0), float(np.nanmax(raw, initial=0)))
            if not columns:
                continue
            if lim.name in raw_best:  # several rows of one name (per axis): the highest per sample
                higher = raw > raw_best[lim.name]
                value[lim.name][at] = np.where(higher, val, value[lim.name][at])
                bound[lim.name][at] = np.where(higher, lim_bound, bound[lim.name][at])
                raw_best[lim.name] = np.maximum(raw, raw_best[lim.name])
            else:
                value[lim.name][at] = val
                bound[lim.name][at] = lim_bound
                raw_best[lim.name] = raw
        for blk in window_blocks(grid, caps, lo, hi, caps_only=True):  # speed caps only millpost holds
            with np.errstate(divide="ignore", invalid="ignore"):
                r = np.where(on & (blk.b_hi > 0), sig.speed_mm_s / np.sqrt(blk.b_hi), 0.0)
            ratios[blk.name] = max(ratios.get(blk.name, 0.0), float(np.nanmax(r, initial=0.0)))
        chunk_current = np.max(np.abs(sig.axis_current_A) / limit_A, axis=1)
        current_max = max(current_max, float(np.max(chunk_current[keep_current[at]], initial=0.0)))
        if not columns:
            continue
        current[at] = chunk_current
        for key, x in (("peak_force_N", sig.peak_force_xy_N), ("power_W", sig.cutting_power_W),
                       ("thrust_N", sig.force_tool_N[:, 2]), ("torque_Nm", sig.torque_Nm)):
            cut_loads[key][at] = np.where(on, x, 0.0)
    ratios["current"] = current_max
    return Replay(ratios, physical, {name: (value[name], bound[name]) for name in rows_of},
                  {lim.name: lim.load for lim in loads}, current, cut_loads, cut)


def binding_shares(samples: Samples, sched, limits: JobLimits, speed_mm_s: np.ndarray
                   ) -> tuple[dict[str, float], dict[str, float]]:
    """Share of the feed moves' time each limit binds in the schedule, grouped by effect and by limit
    name. Time weights (`signals.step_times_s`) are taken at speed_mm_s (mm/s per sample), the program
    as it runs: the schedule's own speed at a standstill's first step can be far below what the
    controller runs there, and a step's time grows as 1/v."""
    total = 0.0
    by_effect: dict[str, float] = {}
    by_name: dict[str, float] = {}
    owner = limits.by_block(PathGrid.from_samples(samples))
    for lo, hi, s in sched.segments:
        dt = step_times_s(samples.s_mm[lo:hi], speed_mm_s[lo:hi])
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
