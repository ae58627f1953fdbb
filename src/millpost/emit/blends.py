"""The controller's blend arcs and the F words: a controller that rounds a corner with an arc run at the
faster of the two moves' feeds carries that feed into the slower move. The arcs' limits over the
samples (`blend_excess`, `blend_limit`, `run_limit`) and the emission passes that keep every blend arc
of the written program within the feed limit (`emit_within`), and the baseline's (`baseline_within`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import controller
from ..controller.blends import zone_samples
from ..gcode import read_text
from ..gcode.interpret import Program
from ..job import Job
from ..progress import Progress
from ..toolpath import RAPID, Samples
from .pieces import original_arc_length
from .policy import piecewise_feeds
from .write import SNAP_TO_PROGRAMMED, FeedPlan, whole_moves, write_feeds


@dataclass
class Emission:
    """A written program: its text, what the reader makes of it, how the controller runs it, the feed
    plan written and the blend passes it took ({"passes": emissions, "over": arcs over the limit in
    the returned program, "runs_lowered": arcs whose runs were lowered})."""

    text: str
    program: Program
    execution: controller.Execution
    plan: FeedPlan
    blends: dict = field(default_factory=lambda: {"passes": 1, "over": 0})


def emit_programmed(job: Job, program: Program, model: controller.ControllerModel) -> Emission:
    """The program with its programmed feeds (a failed schedule), read back and run."""
    plan = FeedPlan.programmed(program)
    text = write_feeds(program, plan)
    emitted = read_text(text, str(job.program), job.reader_options())  # what will run
    return Emission(text, emitted, controller.execute_program(emitted, model), plan)


ARC_SLACK = 1e-6  # relative: an arc's top speed over a limit by less is float rounding (an F word read back)


def _zone_minima(samples: Samples, limit_mm_s: np.ndarray, zones: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per zone (start, end (mm of the samples' arc length), top speed): the samples it covers
    (`controller.blends.zone_samples`), as (sample index, zone index) pairs, and each zone's lowest finite limit there
    (mm/s; inf: none)."""
    zones = np.asarray(zones, float).reshape(-1, 3)
    idx, owner = zone_samples(samples, zones)
    vals = np.where(np.isfinite(limit_mm_s[idx]), limit_mm_s[idx], np.inf)
    zone_min = np.full(len(zones), np.inf)
    np.minimum.at(zone_min, owner, vals)
    return idx, owner, zone_min


def blend_excess(samples: Samples, limit_mm_s: np.ndarray, zones: np.ndarray, slack: float = ARC_SLACK) -> np.ndarray:
    """The zones (rows of `zones`, see `blend_limit`) whose top speed exceeds the lowest limit they cover
    by more than `slack` (relative)."""
    zones = np.asarray(zones, float).reshape(-1, 3)
    _, _, zone_min = _zone_minima(samples, np.asarray(limit_mm_s, float), zones)
    return zones[zones[:, 2] > zone_min * (1 + slack)]


def blend_limit(samples: Samples, limit_mm_s: np.ndarray, zones: np.ndarray, widen: float = 0.0,
                within: np.ndarray | None = None) -> np.ndarray:
    """The feed limit (mm/s) with the controller's blend arcs: a controller that rounds a corner with an
    arc run at the faster of the two moves' feeds carries that feed into the slower move. zones (k, 3):
    where an arc may start and end (mm, the samples' arc length) and its top speed (mm/s)
    (`controller.blend_zones`, `controller.Execution.blends`), first widened by `widen` times its length
    on either side. Where the top speed exceeds the lowest limit over the zone (the samples within it,
    and the next one on each side) of `within` (the limit the arcs must keep; default `limit_mm_s`
    itself), the zone's samples take at most that lowest limit, so that every F word the arc's feeds
    come from fits it."""
    zones = np.asarray(zones, float).reshape(-1, 3).copy()
    grow = widen * (zones[:, 1] - zones[:, 0])
    zones[:, 0] -= grow
    zones[:, 1] += grow
    out = np.asarray(limit_mm_s, float).copy()
    idx, owner, zone_min = _zone_minima(samples, out if within is None else np.asarray(within, float), zones)
    lower = (zones[owner, 2] > zone_min[owner] * (1 + ARC_SLACK)) & np.isfinite(out[idx])
    np.minimum.at(out, idx[lower], zone_min[owner][lower])
    return out


def run_limit(samples: Samples, limit_mm_s: np.ndarray, zones: np.ndarray, within: np.ndarray) -> np.ndarray:
    """The feed limit (mm/s) with every run that a zone (rows as in `blend_limit`) touches lowered to the
    run's lowest limit of `within` (the limit the arcs must keep). A run: consecutive samples of
    positive finite limit, between rest points (0: the controller stops there, so no blend arc crosses)
    and rapids (nan). One feed over a whole run leaves no blend arc in it faster than the run's lowest
    limit, however the controller merges its moves."""
    out = np.asarray(limit_mm_s, float).copy()
    within = np.asarray(within, float)
    moving = np.isfinite(out) & (out > 0)
    run = np.cumsum(~moving)  # one id per run (and per rest point or rapid sample between runs)
    run_min = np.full(int(run[-1]) + 1 if len(run) else 0, np.inf)
    np.minimum.at(run_min, run[moving], np.where(np.isnan(within[moving]), np.inf, within[moving]))
    idx, _, _ = _zone_minima(samples, out, zones)
    touched = np.zeros(len(run_min), bool)
    touched[run[idx[moving[idx]]]] = True
    on = moving & touched[run]
    out[on] = np.minimum(out[on], run_min[run[on]])
    return out


BLEND_PASSES = 6  # emissions at most while blend arcs of the emitted program exceed the feed limit


def emit_within(job: Job, program: Program, samples: Samples, limit_mm_s: np.ndarray, zones: np.ndarray,
                 hard_cap: np.ndarray, model: controller.ControllerModel, progress: Progress
                 ) -> Emission:
    """The program with F words within the per-sample feed limit (mm/s; `piecewise_feeds`, hard_cap: per
    move, mm/s) where the controller's blend arcs carry them, what the reader makes of it and how the
    controller runs it. A blend arc runs at up to the faster of two F words over a reach set by the
    segments the controller is given: for LinuxCNC the chains of straight feeds its canon layer merges
    at the F words written (far longer than one programmed move), and a short line before an arc runs
    at the arc's speed. First the feeds fit the zones of the programmed corners (`blend_zones`, (k, 3)
    in the samples' arc length); then every arc of the emitted program (`Execution.blends`) faster than
    the lowest limit it covers (beyond the emission's snap to a programmed feed held by a bound) has
    that limit laid over its reach (`blend_limit`) and the program is written again; an arc still
    over on a later emission has its reach widened 2, 4, ... times. The
    arcs are always checked against `limit_mm_s` itself (the F words only fall). After BLEND_PASSES
    emissions, every arc still over lowers the whole run it lies on (between the controller's stops) to
    the run's lowest limit (`run_limit`), and the summary says so."""
    tp = program.toolpath
    step = job.settings.feed_step
    accel = tuple(job.machine.axes[a].amax_mm_s2 for a in "xyz")
    feeds_mm_s = blend_limit(samples, limit_mm_s, zones)
    stubborn = 0
    for passes in range(1, BLEND_PASSES + 2):
        progress("emission", 2, 4)
        fragments = whole_moves(program, piecewise_feeds(samples, feeds_mm_s, step=step, accel_mm_s2=accel))
        plan = FeedPlan.from_fragments(program, fragments, step, hard_cap,
                                       tuple(job.machine.axes[a].vmax_mm_min for a in "xyz"))
        text = write_feeds(program, plan)
        progress("emission", 3, 4)
        emitted = read_text(text, str(job.program), job.reader_options())  # what will run
        after = controller.execute_program(emitted, model)
        arcs = after.blends.copy()
        arcs[:, :2] = original_arc_length(tp, emitted.toolpath, arcs[:, :2])
        over = blend_excess(samples, limit_mm_s, arcs, SNAP_TO_PROGRAMMED)  # a feed held at the programmed one
        if not len(over) or passes > BLEND_PASSES:
            break
        stubborn = len(over) if passes == BLEND_PASSES else 0
        feeds_mm_s = _arcs_kept(samples, feeds_mm_s, over, limit_mm_s, passes)
    progress("emission", 4, 4)
    return Emission(text, emitted, after, plan, {"passes": passes, "over": int(len(over)), "runs_lowered": stubborn})


def baseline_within(program: Program, samples: Samples, feeds: np.ndarray, cap_mm_s: np.ndarray,
                     zones: np.ndarray, model: controller.ControllerModel, modes: controller.PathModes
                     ) -> tuple[np.ndarray, controller.Execution]:
    """The baseline's feeds (per move, mm/min) and its run, with its blend arcs kept within the caps it
    was tuned under (mm/s per sample) as the optimized program's are (`emit_within`): a blend arc runs
    the faster of its two feeds into the slower move, so every move an arc faster than the lowest cap
    it covers reaches runs at that cap (a CAM user's separate lead-in feed there). First the arcs of
    the programmed corners (`zones`, `controller.blend_zones`) at the faster of the two moves' feeds,
    then those of each run, their reach widened on later runs; after BLEND_PASSES runs, the whole run
    between stops at its lowest cap."""
    moving = program.toolpath.kind != RAPID

    def lowered_to(limit: np.ndarray) -> np.ndarray:
        move_cap = np.full(len(feeds), np.inf)
        np.fmin.at(move_cap, samples.move, limit * 60.0)
        return np.where(moving, np.fmin(feeds, np.floor(move_cap * (1 + 1e-9))), feeds)

    ends = np.clip(np.searchsorted(samples.s_mm, zones[:, :2]), 0, len(samples) - 1)
    arcs = np.column_stack([zones[:, :2], np.minimum(zones[:, 2], np.fmax(*feeds[samples.move[ends]].T) / 60.0)])
    over = blend_excess(samples, cap_mm_s, arcs, SNAP_TO_PROGRAMMED)
    if len(over):
        feeds = lowered_to(blend_limit(samples, cap_mm_s, over))
    for passes in range(1, BLEND_PASSES + 2):
        run = controller.execute_program(program, model, feeds / 60.0, modes=modes)  # F words → mm/s
        over = blend_excess(samples, cap_mm_s, run.blends, SNAP_TO_PROGRAMMED)
        if not len(over) or passes > BLEND_PASSES:
            return feeds, run
        feeds = lowered_to(_arcs_kept(samples, cap_mm_s, over, cap_mm_s, passes))
    return feeds, run


def _arcs_kept(samples: Samples, limit_mm_s: np.ndarray, over: np.ndarray, within: np.ndarray, passes: int
               ) -> np.ndarray:
    """The feed limit (mm/s) lowered for the blend arcs `over` found on run `passes`: over each arc's
    reach widened (2^(passes−1) − 1)/2 times on either side (`blend_limit`), after BLEND_PASSES runs
    over the whole run between stops it lies on (`run_limit`); `within`: the limit the arcs must keep."""
    if passes < BLEND_PASSES:
        return blend_limit(samples, limit_mm_s, over, (2.0 ** (passes - 1) - 1.0) / 2.0, within)
    return run_limit(samples, limit_mm_s, over, within)
