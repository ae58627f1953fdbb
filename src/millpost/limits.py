"""The limits a job's feeds obey, each with its identity, and the feed policy that sets their bounds.

A `Limit` is a constraint object of `millpost.schedule` (it produces rows) plus what it is:
- `kind` (`Kind`): hard (exceeding it breaks or stalls something: tool breakage, spindle power and torque,
  the end's thrust and torque on the tool, drive current, the machine's and the user's maxima (the
  plunge feed cap included), the controller's block rate ("block_rate": the controller holds it by
  itself, no F word carries it)) or quality (exceeding it spoils the part
  or the tool's life: deflection, maximum chip load, the chip floor);
- `effect`: the physical effect the summary groups it under;
- `controller`: the controller holds it by itself while it runs the program (axis rates,
  accelerations, corners, jerk), so the baseline program's single F need not;
- `baseline`: the baseline's single F obeys it (false for the caps set from the program's own
  feeds, the plunge feed cap and the air clearance: the baseline's moves obey those as a CAM user's
  separate plunge and lead-in feeds would, `millpost.replay.baseline_feeds`);
- `f_word`: the emitted F words obey its speed cap (false for the block rate, the axis rates per
  sample, accelerations, jerk and corner caps, which the controller clamps or ramps to on its own, and
  for the centripetal cap of an arc on a planner that runs arcs whole, clamping each at √(a_n·r); true
  for the axis rates over a whole move, "axis_rate", which the controller clamps too, but an F word
  above what its move runs at reads as a typo);
- `clamp`: the controller holds its speed cap as a steady clamp (the axis rates, the block rate): an
  F word above it runs at it, so the F word need only reach it (`millpost.emit.policy.hold_runs`);
- `default`: how its bound was chosen when the job did not give one (named in the summary where the
  limit binds);
- for a load limit, `load`: the signal it bounds (`millpost.signals.Load`), `signal(signals, at)`: that
  load, from the forward model's signals of the samples `at` (a slice: `millpost.signals.Signals` of those samples → their values; the replay check
  evaluates it at the executed speed, in chunks),
  and `bound`: its bound per sample before the feed policy.

The feed policy (`[limits] lower`): millpost raises feeds freely under every limit. With
lower = "hard" (the default) it lowers a feed below the programmed one only where a hard limit
would be exceeded, and only as far as that limit needs; a quality limit that the programmed feed
already exceeds is held at the programmed feed's load (or, in a corner, at the speed the program's
own blend arc passes it, the faster of its two feeds) and reported. With lower = "all" quality
limits may lower the feed too. Either way no limit lowers a feed below the minimum-chip feed
f_min = z·n·h_min / max(sin φ·sin κ) (below it the edge rubs and wood burns) or the programmed
feed if that is lower: where a limit would need less, its bound is held at the load of that feed
and the samples are listed (for a hard limit: the cut itself, not the feed, is too heavy for the
tool). The bound therefore gives the feed max(v_cap, v_keep), v_cap the speed where the load
reaches the limit: never increasing in the load, so a heavier cut never gets a higher feed than a
lighter one for the same reason.

End cutting: where the tool moves down into material (plunges, ramps, helices, drilling, pecks) its
end cuts too (`millpost.forces.endcut`). Its thrust and torque add to the axial force (so to the Z
drive's current) and to the spindle torque and power; the thrust stays under the tool's Euler
buckling load and the torque under its torsional strength, both over the tool safety factor (hard:
"thrust", "tool_torque"). The end's axial chip f_z·descent·sin κ joins the chip-load limit (quality),
up to the material's `plunge_fz_ratio` of the chip load for a milling cutter entering along its axis
with the end enclosed. The user's `plunge_feed_max_mm_min` caps the feed there, and so does
`plunge_raise_max` (default 2) times the programmed feed, or on a corner the controller blends the
speed the programmed program's arc runs into the plunge's end (the faster of its two feeds, up to the
arc's top speed: the programmed program never reads over it) (hard, "plunge_feed", a cap like the
maximum feed: never held by the policy); a material without end-cutting data keeps the programmed feed there
(its end loads are unknown).

Air clearance (`air_clearance_mm`, c): where the tool cuts nothing it is raised up to the machine's
maximum feed, except in the shell of width c around the stock as loaded (`Engagement.near_stock`: the
tool grown by c meets the original stock, its tip disc is not inside it; the surfaces the program cut
are known, air over them is raised; a retract straight up is raised too: it meets no material the tool
is not already in; so is air in space the tool itself swept before, at or below it, beside the stock
too: `Engagement.swept_air`, e.g. a trochoid's return beside the block it enters). There a block that
cuts nothing (an approach, a plunge or lead-in beside the stock, a link just over it) keeps its
programmed feed at most; the air part of a block that cuts (a move, or a canned cycle's moves at one
hole), its programmed feed or the lowest cap of its cut if higher (hard, "air_clearance": a cap like
the plunge feed cap, lowered further only by the other hard limits). The stock model is a guess (the
blank may be larger, the sheet thicker or bowed) and CAM posts approaches at the entry feed because
the tool is about to cut: within c of the modelled stock the tool would otherwise meet unmodelled
material at up to the machine's maximum feed.

Arcs: the flank cuts at the feed of its edge, the centre's times `Engagement.edge_ratio` (r_e/ρ: larger
on an inside arc, smaller on an outside one), so every flank load and the chip are those of that feed;
a corner tighter than the tool (ρ < R) takes a full slot's chip at its wall whatever the stock model
shows.

Restarts (`restart_descents`): a feed move going down below the top of the stock as loaded keeps the
plunge rules (the chip of an end entering solid material, the plunge feed cap) even where the program
cut that space before, since a restart from a later line, a skipped operation or a broken tool leaves
it solid; `[limits] trust_cut_space = true` lifts it. Air moves through cut space below the top are
capped at `air_feed_max_mm_min` when given ("air_feed").

Deflection default (`deflection_mm` not given): a roughing limit per tool, max(0.025 mm, 0.4 % of
the diameter). CNCCookbook (B. Warfield, "Tool Deflection Control", G-Wizard) takes 0.001 in
(0.025 mm) as suitable for roughing with a 1/8 in end mill and 0.0002 in (0.005 mm) for
finishing; from 1/4 in (6.35 mm) up the limit grows with the diameter, 0.001 in per 1/4 in
(engineering judgement: a larger tool leaves a proportionally larger finishing allowance). It is a
quality limit, so on small tools it never lowers a programmed feed. A single sample cannot tell a
finishing pass from adaptive roughing (both cut a narrow width), so finishing accuracy is the
user's `deflection_mm`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from enum import StrEnum
from typing import Any, Callable

import numpy as np

from .errors import MillpostError
from .forces import LinearLoads
from .forces.endcut import EndCut, end_chip_factor, entry_chip_factor, thrust_limit_N, torque_limit_Nm
from .forces.timedomain import reusing_runs
from .job import Job
from .controller import ControllerModel, PathModes, block_lengths, blend_zones, corner_speeds, programmed_arcs
from .progress import Progress, silent
from .schedule import (AxisAcceleration, AxisVelocity, Centripetal, CornerSpeed, CurrentSlew, FeedLimit, Junction,
                       MinSpeed, MotorCurrent, PathGrid, PathJerk, SpeedLoad)
from .schedule.assemble import merged_bounds
from .schedule.constraints import Derived, window_blocks
from .safety import spindle_off_message
from .signals import Load, running_rpm
from .engagement import path_radius
from .toolpath import RAPID, Samples, Toolpath
from .tools.beam import ToolBeam, default_safety_factor



class Kind(StrEnum):
    """What exceeding a limit does, and so how far the feed policy lets it lower a feed (module docstring):
    HARD breaks or stalls something, QUALITY spoils the part or the tool's life."""

    HARD = "hard"
    QUALITY = "quality"


HARD, QUALITY = Kind.HARD, Kind.QUALITY
DEFLECTION_ROUGH_MM = 0.025  # 0.001 in
DEFLECTION_ROUGH_RATIO = 0.004  # 0.001 in per 1/4 in of diameter
RETRACT_COS = 0.999  # a feed move within 2.6° of straight up is a retract (the air clearance lets it go)
DESCENDING = 1e-9  # a sample whose tangent points down by more (dz/ds) goes down
LOAD_CHUNK = 5_000  # samples per force-model call (bounds the per-slice temporaries, ~3 KB a sample)


@dataclass(frozen=True)
class Limit:
    """A constraint with its identity (see the module docstring)."""

    constraint: Any
    kind: Kind
    effect: str
    controller: bool = False
    baseline: bool = True
    f_word: bool = True
    clamp: bool = False
    default: str = ""
    signal: Callable[[Any, slice], np.ndarray] | None = None
    bound: np.ndarray | Derived | None = None
    load: Load | None = None

    @property
    def name(self) -> str:
        return self.constraint.name

    def blocks(self, grid: PathGrid) -> list:
        return self.constraint.blocks(grid)


@dataclass
class JobLimits:
    """The limits of a whole resampled program and what the replay and summary need about them.

    loads: per-sample loads as affine functions of the path speed v (mm/s), the flank's and the end's
    summed (`LinearLoads`: peak_a/_b (N), power_a/_b (W), torque_a/_b (N·m), force_a/_b (N, 3)). held: {limit name: samples where the
    policy held the bound at the programmed or minimum-chip feed's load}; forced: the subset where a
    hard limit needed a feed below the minimum-chip feed. floor_mm_s: the minimum-chip feed per
    sample (0 where nothing cuts); deflection_mm: the deflection bound per sample (inf off the cut)."""

    limits: list[Limit]
    loads: LinearLoads
    held: dict[str, np.ndarray]
    forced: dict[str, np.ndarray]
    floor_mm_s: np.ndarray
    deflection_mm: np.ndarray
    lower: str = HARD
    defaults: dict[str, str] = field(default_factory=dict)

    def __iter__(self):
        return iter(self.limits)

    def by_block(self, grid: PathGrid) -> dict[str, Limit]:
        """The limit each row block (by its name) comes from."""
        return {blk.name: lim for lim in self.limits for blk in window_blocks(grid, [lim], 0, min(len(grid), 1))}

    def f_word_caps(self) -> list[Limit]:
        """The limits whose speed caps the emitted F words hold (the maximum feed, the plunge feed cap,
        the air clearance, the drives' voltage...): not loads, not held by the controller itself."""
        return [lim for lim in self.limits if not isinstance(lim.constraint, SpeedLoad) and lim.f_word
                and not lim.controller]

    def f_word_cap_names(self, grid: PathGrid) -> tuple[str, ...]:
        """Names of the speed caps (row blocks) of `f_word_caps`, as the replay reports their ratios."""
        return tuple(sorted({blk.name for blk in window_blocks(grid, self.f_word_caps(), 0, min(len(grid), 1),
                                                               caps_only=True)}))

    def held_on(self, load: Load) -> np.ndarray:
        """Per sample: the policy held the bound of a limit on this load (any of its rows)."""
        held = np.zeros(len(self.floor_mm_s), bool)
        for name in {lim.name for lim in self.limits if lim.load is load}:
            held |= self.held[name]
        return held

    def names(self, **identity) -> tuple[str, ...]:
        """Names of the limits (and of their row blocks) whose identity fields have these values."""
        return tuple(lim.name for lim in self.limits if all(getattr(lim, k) == v for k, v in identity.items()))


def max_sin(eng) -> np.ndarray:
    """Per sample: the largest sin φ·sin κ over the engaged arcs (0 where nothing cuts): the chip
    thickness per unit feed per tooth (chip thinning)."""
    cuts = np.isfinite(eng.phi_st) & np.isfinite(eng.phi_ex) & (eng.dz_mm > 0)
    st, ex = eng.phi_st[cuts], eng.phi_ex[cuts]  # (only the slices that cut are computed)
    s = np.zeros(cuts.shape)
    s[cuts] = np.where((st <= np.pi / 2) & (ex >= np.pi / 2), 1.0, np.maximum(np.sin(st), np.sin(ex)))
    s[cuts] *= np.sin(eng.kappa[cuts])
    return s.max(axis=1, initial=0.0)


def _policed(a, b, bound, v_keep: np.ndarray) -> tuple[np.ndarray | Derived, np.ndarray]:
    """Bound of a load a·v + b ≤ bound after the policy: where the load reaches its bound below
    v_keep (mm/s), the bound becomes the load at v_keep. Returns (bound, held). a, b, bound: per-sample
    arrays or `Derived` (read in chunks of LOAD_CHUNK samples); the bound is `Derived` where something is
    held, else the bound itself (memory: no array of its own per limit)."""
    n = len(v_keep)
    held = np.empty(n, bool)
    for lo in range(0, n, LOAD_CHUNK):
        at = slice(lo, min(lo + LOAD_CHUNK, n))
        a_, b_, bound_ = a[at], b[at], bound[at]
        with np.errstate(divide="ignore", invalid="ignore"):
            v_cap = np.where(a_ > 0, (bound_ - b_) / a_, np.where(b_ <= bound_, np.inf, -np.inf))
        held[at] = v_cap < v_keep[at]
    if not held.any():
        return bound, held
    return Derived(lambda h, a, v, b, bound: np.where(h, a * v + b, bound), (held, a, v_keep, b, bound), (n,)), held


def _corners(model: ControllerModel, samples: Samples, toolpath: Toolpath, modes: PathModes):
    """The corner rule of the machine's own planner `model`: grbl's junction deviation, or the speeds a
    blending planner passes corners at (`controller.corner_speeds` in the path modes `modes`), on the
    last sample before each corner."""
    if not model.planner.blends_corners:
        return Junction(model.accel_mm_s2, model.junction_deviation_mm)
    corner = corner_speeds(toolpath, model, modes)
    cap = np.full(len(samples), np.inf)
    last = np.flatnonzero(samples.move[:-1] != samples.move[1:])
    cap[last] = corner[samples.move[last + 1]]
    return CornerSpeed(cap)


def axis_rates(toolpath: Toolpath, samples: Samples, axes) -> np.ndarray:
    """Per sample the highest speed (mm/s) at which no axis exceeds its rate anywhere on the sample's
    move (min_i vmax_i / share_i, `Toolpath.axis_shares`); inf on rapids."""
    vmax = np.array([a.vmax_mm_s for a in axes])
    share = toolpath.axis_shares()
    with np.errstate(divide="ignore"):
        rate = np.min(np.where(share > 1e-12, vmax / share, np.inf), axis=1)
    return np.where(samples.kind != RAPID, rate[samples.move], np.inf)


def axis_rate_caps(toolpath: Toolpath, samples: Samples, axes, feed_max_mm_s: float) -> np.ndarray:
    """The F-word cap of the axis rates per sample (mm/s): the controller clamps an F above them by itself,
    but an F word millpost writes above what its move runs at reads as a typo (F39395 on an X axis of
    24000), so it is `axis_rates`; except that the program's own F above them stays where it is within the
    maximum feed (LinuxCNC blends a corner up to the faster requested F: lowered to the rates, a raster
    programmed at F4000 on 3000 mm/min axes would run slower)."""
    v_prog = np.nan_to_num(samples.feed_mm_s, nan=0.0)
    rate = axis_rates(toolpath, samples, axes)
    return np.where(v_prog <= feed_max_mm_s, np.maximum(rate, v_prog), rate)


def feed_cap_mm_s(job: Job) -> float:
    """The highest feed an F word asks for (mm/s): the machine's (`Machine.feed_cap_mm_s`, the fastest any
    direction runs; the axis rates of each move's direction are a limit of their own) and the user's
    `feed_max_mm_min`."""
    cap = job.machine.feed_cap_mm_s
    return cap if job.settings.feed_max_mm_s is None else min(cap, job.settings.feed_max_mm_s)


def build_limits(job: Job, samples: Samples, eng, toolpath: Toolpath, progress: Progress = silent, *,
                 release_slices: bool = False, modes: PathModes, zones: np.ndarray | None = None) -> JobLimits:
    """Every limit of the job over the resampled program, with the feed policy applied. progress: a
    `millpost.progress` callback (stage "forces", in samples). release_slices: once the loads are
    computed, `eng` (changed in place) keeps only what `Engagement.per_sample` keeps (memory: its
    per-slice arrays, ~0.4 KB a sample, are freed before the limits' own arrays are built). modes: the
    program's path modes (`controller.path_modes`: where its corners blend and its straight feeds
    merge), required: the program's G61/G64 decide its corner caps. zones: the blend arcs of the
    programmed corners (`controller.blend_zones` of `toolpath` in `modes`; computed here unless given)."""
    lower = job.settings.lower
    planner = ControllerModel.from_machine(job.machine)
    limits = _machine_limits(job, samples, toolpath, modes, planner)
    cutting = samples.kind != RAPID
    restart = restart_descents(job, samples, eng)
    with reusing_runs():  # a steady cut's engagement repeats: its time-domain runs are made once
        cut = _cut_loads(job, samples, eng, toolpath, restart, progress)
    if release_slices:  # below, only the per-sample fields are read
        lean = eng.per_sample()
        for f in fields(eng):
            setattr(eng, f.name, getattr(lean, f.name))
        del lean
    v_prog = np.where(cutting, np.nan_to_num(samples.feed_mm_s, nan=0.0), 0.0)
    # the speed the programmed program's own blend arcs pass each sample at (a bound set from the
    # programmed feeds never reads the programmed program over it: it runs that fast there)
    carried = programmed_arcs(samples, v_prog, blend_zones(toolpath, planner, modes) if zones is None else zones)
    keep_hard = np.minimum(cut.floor, v_prog)
    keep_quality = np.maximum(v_prog, carried) if lower == HARD else keep_hard
    policy = _Policy(limits, cutting, keep_hard, keep_quality)
    _cut_limits(policy, job, cut)
    _plunge_limits(policy, job, cut, restart, v_prog, carried)
    v_cap = _drive_limits(policy, job, samples, cut.loads, cut.engaged)
    _air_limits(policy, job, samples, eng, toolpath, cut.engaged, v_prog, v_cap, carried)
    return JobLimits(limits, cut.loads, policy.held, policy.forced, cut.floor, cut.defl_limit, lower, cut.defaults)


def _machine_limits(job: Job, samples: Samples, toolpath: Toolpath, modes: PathModes,
                    planner: ControllerModel) -> list[Limit]:
    """The machine's and the user's limits on motion, whatever is cut: the maximum feed, the controller's
    block rate, the axis rates, accelerations, the centripetal acceleration on
    arcs, the corner rule of the machine's planner `planner` in the path modes `modes`, and the path
    jerk when the job gives one."""
    m = job.machine
    ax = [m.axes[a] for a in "xyz"]
    amax = tuple(a.amax_mm_s2 for a in ax)
    feed_max = feed_cap_mm_s(job)
    # the controller reads at most block_rate blocks per second: a block of length L runs at most L·rate,
    # a block being a move or the chain of straight feeds it merges them into (`block_lengths`). It slows
    # by itself there (an F word cannot make it faster or need make it slower): no F word carries this
    # cap, which on a micro-segment would write a crawl into the moves around it
    block_cap = np.where(samples.kind != RAPID,
                         block_lengths(toolpath, modes)[samples.move] * m.controller.block_rate_Hz, np.inf)
    limits = [Limit(FeedLimit(feed_max), HARD, "feed"),
              Limit(FeedLimit(block_cap, name="block_rate"), HARD, "feed", controller=True, f_word=False, clamp=True),
              Limit(AxisVelocity(tuple(a.vmax_mm_s for a in ax)), HARD, "inertia", controller=True,
                    f_word=False, clamp=True),
              # the same rates over each whole move (an arc's every direction)
              Limit(FeedLimit(axis_rate_caps(toolpath, samples, ax, feed_max), name="axis_rate"),
                    HARD, "inertia", controller=True, clamp=True),
              Limit(AxisAcceleration(amax), HARD, "inertia", controller=True, f_word=False),
              # LinuxCNC's planner (`controller`) runs an arc as one segment clamped at √(a_n·r) by itself;
              # grbl runs it as chords whose F word it keeps, so the F word carries the cap there
              Limit(Centripetal(amax), HARD, "inertia", controller=True, f_word=not planner.planner.runs_arcs_whole),
              Limit(_corners(planner, samples, toolpath, modes), HARD, "inertia", controller=True, f_word=False)]
    if job.settings.jerk_mm_s3 is not None:
        limits.append(Limit(PathJerk(job.settings.jerk_mm_s3), HARD, "inertia", controller=True,
                            f_word=False))
    return limits


@dataclass
class _CutLoads:
    """Per sample, the cut's loads and their bounds before the feed policy (`_cut_loads`): loads as in
    `JobLimits.loads`; rpm the running spindle speed (1 where it stands); peak_limit the tool's breaking
    force (N); defl_per_N the tool's and the machine's compliance (mm/N) and defl_limit the deflection
    bound (mm); chip_a the chip thickness per mm/s (mm·s/mm) under h_max (mm); floor the minimum-chip
    feed (mm/s); sin_end the end's chip factor (> 0 where the end cuts); thrust_limit (N) and
    tool_torque_limit (N·m) the tool's buckling and torsional strength; engaged: the tool meets
    material; spin: the spindle turns; defaults: how the bounds the job did not give were chosen."""

    loads: LinearLoads
    rpm: np.ndarray
    engaged: np.ndarray
    spin: np.ndarray
    peak_limit: Derived
    defl_per_N: Derived
    defl_limit: np.ndarray
    chip_a: np.ndarray
    h_max: np.ndarray
    floor: np.ndarray
    sin_end: np.ndarray
    thrust_limit: Derived
    tool_torque_limit: Derived
    defaults: dict[str, str]


def _cut_loads(job: Job, samples: Samples, eng, toolpath: Toolpath, restart: np.ndarray | None,
               progress: Progress) -> _CutLoads:
    """Per tool, the force models' loads affine in the speed (the flank's at its edge's feed, and the
    end's where it descends), the chip per unit speed and the minimum-chip feed, and the tool's and the
    machine's bounds on them (see `_CutLoads`). restart: the descents that keep the plunge rules
    (`restart_descents`). progress: stage "forces", in samples."""
    n = len(samples)
    m = job.machine
    models = (job.material.force_model(job.settings.model), EndCut.from_material(job.material))
    cutting = samples.kind != RAPID
    engaged = eng.ap_mm > 1e-9
    spin = samples.rpm > 0
    # the force models' tangent (Kienzle, the end cut) at the programmed F word (mm/min)
    f_word = np.nan_to_num(toolpath.feed_mm_min[samples.move], nan=100.0)
    if np.any(engaged & ~spin):
        k = int(np.flatnonzero(engaged & ~spin)[0])
        raise MillpostError(spindle_off_message(str(job.program), int(samples.line[k])))
    loads = LinearLoads.zeros(n)
    rpm = np.where(spin, running_rpm(job, samples.rpm), 1.0)
    defl_limit = np.full(n, np.inf)
    chip_a, h_max, floor = np.zeros(n), np.full(n, np.inf), np.zeros(n)
    # chip thickness per unit feed per tooth: flank (chip thinning) and end (axial chip over its share)
    chips = _Chips(np.zeros(n), np.zeros(n), np.zeros(n))
    # per tool (`_per_tool`): the breaking force and the compliance of the cut's depth, buckling, torsion
    peak_by, defl_by, thrust_by, torque_by = {}, {}, {}, {}
    defaults: dict[str, str] = {}
    rough_by_tool: dict[int, float] = {}
    done = 0
    for number in np.unique(samples.tool[cutting]):
        tool = job.tools.get(int(number))
        if tool is None:
            line = int(samples.line[np.flatnonzero(cutting & (samples.tool == number))[0]])
            raise MillpostError(f"{job.program}:{line}: tool T{number} cuts but the job has no [tools.{number}]")
        idx = np.flatnonzero(samples.tool == number)
        h_min, h_chip = job.material.min_chip_mm(tool.edge_radius_mm, tool.diameter_mm), job.material.chip_load_mm(tool.diameter_mm)[1]
        # in chunks: the models' per-slice temporaries (kilobytes a sample) stay bounded by the chunk
        for part in np.array_split(idx, max(1, -(-len(idx) // LOAD_CHUNK))):
            progress("forces", done, n)
            done += len(part)
            at = slice(part[0], part[-1] + 1) if part[-1] - part[0] + 1 == len(part) else part  # (a slice: views)
            _chunk_loads(job, models, tool, samples, eng, at, rpm, f_word, restart, h_chip, loads, chips)
        thrust_by[int(number)] = lambda ap, v=thrust_limit_N(tool, job.settings.tool_safety_factor): v
        torque_by[int(number)] = lambda ap, v=torque_limit_Nm(tool, job.settings.tool_safety_factor): v
        beam = ToolBeam.of(tool, safety_factor=job.settings.tool_safety_factor)
        if job.settings.tool_safety_factor is None:
            sf = f"T{number} {default_safety_factor(tool):g} (by diameter and slenderness)"
            defaults.setdefault("cutting_force", f"tool safety factor on the bending strength: {sf}")
            defaults.setdefault("thrust", f"tool safety factor on the buckling load: {sf}")
            defaults.setdefault("tool_torque", f"tool safety factor on the torsional strength: {sf}")
        peak_by[int(number)] = beam.breaking_force_N  # the cut's depth sets the lever arm
        defl_by[int(number)] = lambda ap, beam=beam: (beam.compliance_mm_per_N(ap, at_tip=True)
                                                      + m.lateral_compliance_mm_per_N)
        if job.settings.deflection_mm is not None:
            defl_limit[idx] = job.settings.deflection_mm
        else:
            defl_limit[idx] = rough_by_tool[int(number)] = max(DEFLECTION_ROUGH_MM,
                                                               DEFLECTION_ROUGH_RATIO * tool.diameter_mm)
        cut_here = idx[chips.factor[idx] > 0]
        per_tooth = tool.flutes * rpm[cut_here] / 60.0  # mm/s per mm of feed per tooth
        chip_a[cut_here] = chips.factor[cut_here] / per_tooth  # chip thickness (over its share) per mm/s
        h_max[cut_here] = h_chip
        # the floor: the thickest chip, flank's or end's, reaches the minimum chip (none where the tool
        # cuts nothing: a restart's descent)
        thickest = np.maximum(chips.flank[cut_here], chips.end[cut_here])
        with np.errstate(divide="ignore"):
            floor[cut_here] = np.where(thickest > 0, h_min / thickest * per_tooth, 0.0)
    progress("forces", n, n)
    if rough_by_tool:
        defaults["deflection"] = ("roughing, max(0.025 mm, 0.4 % of D): "
                                  + ", ".join(f"T{t} {v:.3g} mm" for t, v in rough_by_tool.items()))
    tool, ap = samples.tool, eng.ap_mm
    return _CutLoads(loads, rpm, engaged, spin, _per_tool(tool, ap, peak_by, np.inf), _per_tool(tool, ap, defl_by, 0.0),
                     defl_limit, chip_a, h_max, floor, chips.end, _per_tool(tool, ap, thrust_by, np.inf),
                     _per_tool(tool, ap, torque_by, np.inf), defaults)


@dataclass
class _Chips:
    """Per sample, the chip thickness per unit feed per tooth: `flank`, the flank's largest (chip thinning,
    a wrapped corner's full slot; times the edge's feed ratio), `end`, the end's axial chip
    (`end_chip_factor`), and `factor`, the chip-load limit's (the larger, the end's as `entry_chip_factor`
    sees it; a restart's descent as a plunge into solid material)."""

    flank: np.ndarray
    end: np.ndarray
    factor: np.ndarray


def _chunk_loads(job: Job, models: tuple, tool, samples: Samples, eng, at, rpm: np.ndarray, f_word: np.ndarray,
                 restart: np.ndarray | None, h_chip: float, loads: LinearLoads, chips: _Chips) -> None:
    """The loads (into `loads`) and chips (into `chips`) of the samples `at` (a slice or indices) of one
    tool from the force models (flank, and end: `EndCut` or None) at the programmed F words f_word
    (mm/min), the end's at the chip-load cap h_chip (mm) where that feed is lower."""
    model, end_model = models
    eng_p, rpm_p, f_word = eng.select(at), rpm[at], f_word[at]
    # the flank cuts at the edge's feed, the centre's times `edge` (larger on an inside arc).
    # Kienzle is concave in the feed: its tangent at the programmed feed bounds it from above
    edge = eng_p.edge
    ll = model.linear_loads(eng_p, tool, rpm_p, feed_ref_mm_min=f_word * edge)
    for key in ("peak", "power", "torque", "force"):
        a = getattr(ll, f"{key}_a")  # per mm/s of the edge → per mm/s of the centre
        getattr(loads, f"{key}_a")[at] = a * (edge[:, None] if a.ndim == 2 else edge)
        getattr(loads, f"{key}_b")[at] = getattr(ll, f"{key}_b")
    # a corner tighter than the tool (its centre's radius under R) wraps the tool: a full slot's
    # chip at the wall (sin φ = 1) whatever the stock model shows (a closing corner pre-cut by
    # the lead-in reads lighter than the cut a machinist programs it for)
    wraps = (edge > 1.0) & (np.abs(path_radius(samples.tangent[at], samples.curvature[at])) < tool.radius_mm)
    sin_flank = max_sin(eng_p)
    flank = chips.flank[at] = np.where(wraps & (sin_flank > 0), 1.0, sin_flank) * edge
    end = chips.end[at] = end_chip_factor(eng_p, tool)
    ratio = job.material.strategies.plunge_fz_ratio
    factor = np.maximum(flank, entry_chip_factor(eng_p, tool, ratio, end))
    if restart is not None:  # a descent into space cut before: its chip as a plunge into solid
        full = replace(eng_p, end_engaged=np.ones_like(eng_p.end_engaged))
        factor = np.where(restart[at], np.maximum(factor, entry_chip_factor(full, tool, ratio,
                                                                            end_chip_factor(full, tool))), factor)
    chips.factor[at] = factor
    if end_model is not None:  # the end's thrust and torque add to the axial force and spindle torque
        # tangent at the programmed feed, or at the chip-load cap where that is lower (no feed above
        # it is allowed: the bound is then exact where it can bind, not inflated by an absurd program)
        with np.errstate(divide="ignore"):
            fz_cap = np.where(factor > 0, h_chip / factor, np.inf)
        le = end_model.linear_loads(eng_p, tool, rpm_p, feed_ref_mm_min=np.minimum(f_word, fz_cap * tool.flutes * rpm_p))
        for key in ("power", "torque", "force"):
            getattr(loads, f"{key}_a")[at] += getattr(le, f"{key}_a")
            getattr(loads, f"{key}_b")[at] += getattr(le, f"{key}_b")


def _per_tool(tool: np.ndarray, ap_mm: np.ndarray, by_tool: dict[int, Callable[[np.ndarray], Any]],
              other: float) -> Derived:
    """Per sample, `by_tool[number](ap)` on the samples of each tool number in it (elementwise in the depth of
    cut ap_mm, or a constant), `other` on the others: computed on demand (`Derived`, memory)."""
    def f(t: np.ndarray, ap: np.ndarray) -> np.ndarray:
        out = np.full(len(t), other)
        for number, g in by_tool.items():
            if (mine := t == number).any():
                out[mine] = g(ap[mine])
        return out
    return Derived(f, (tool, ap_mm), (len(tool),))


@dataclass
class _Policy:
    """The feed policy over the limits being built: a load's bound is held at its load at keep_hard (a
    hard limit's) or keep_quality (a quality limit's) speed, mm/s, where it would need less
    (`_policed`); held and forced as in `JobLimits`, over the cutting samples."""

    limits: list[Limit]
    cutting: np.ndarray
    keep_hard: np.ndarray
    keep_quality: np.ndarray
    held: dict[str, np.ndarray] = field(default_factory=dict)
    forced: dict[str, np.ndarray] = field(default_factory=dict)

    def load_limit(self, name: str, kind: Kind, load: Load, effect: str, a, b, bound, signal,
                   default: str = "") -> np.ndarray:
        """The load a·v + b ≤ bound (v mm/s) as a limit of this kind on this load, its bound after the policy;
        `signal` is the same load in the forward model's signals of the samples `at`. Returns where the
        policy holds the limit's bound so far (over all its rows: a limit of several rows calls this once
        per row)."""
        held, forced, n = self.held, self.forced, len(self.cutting)
        bound = bound if isinstance(bound, Derived) else np.broadcast_to(bound, a.shape)
        bound_eff, h = _policed(a, b, bound, self.keep_hard if kind == HARD else self.keep_quality)
        held[name] = held.get(name, np.zeros(n, bool)) | (h & self.cutting)
        if kind == HARD:
            forced[name] = held[name]
        self.limits.append(Limit(SpeedLoad(a, b, bound_eff, name=name), kind, effect, default=default, signal=signal,
                                 bound=bound, load=load))
        return held[name]


def _cut_limits(policy: _Policy, job: Job, cut: _CutLoads) -> None:
    """The cut's loads under their bounds: the tool's breaking force, the spindle's power and torque, the
    deflection, the tool's buckling (thrust) and torsion, the chip load."""
    m, loads, n, spin, rpm = job.machine, cut.loads, len(cut.rpm), cut.spin, cut.rpm
    defl_per_N, chip_a, defaults = cut.defl_per_N, cut.chip_a, cut.defaults
    # each load is affine in the speed (the schedule's rows); arrays scaled from the loads or the spindle's
    # speed are `Derived` (memory: computed per window, the same numbers)
    power = Derived(lambda on, r: np.where(on, m.spindle.power_available_W(r), np.inf), (spin, rpm), (n,))
    torque = Derived(lambda on, r: np.where(on, m.spindle.torque_Nm(r), np.inf), (spin, rpm), (n,))
    policy.load_limit("cutting_force", HARD, Load.PEAK_FORCE, "cutting force", loads.peak_a, loads.peak_b,
                      cut.peak_limit, lambda s, at: s.peak_force_xy_N, defaults.get("cutting_force", ""))
    policy.load_limit("power", HARD, Load.POWER, "power", loads.power_a, loads.power_b, power,
                      lambda s, at: s.cutting_power_W)
    policy.load_limit("torque", HARD, Load.TORQUE, "power", loads.torque_a, loads.torque_b, torque,
                      lambda s, at: s.torque_Nm)
    policy.load_limit("deflection", QUALITY, Load.DEFLECTION, "deflection",
                      Derived(np.multiply, (loads.peak_a, defl_per_N), (n,)),
                      Derived(np.multiply, (loads.peak_b, defl_per_N), (n,)), cut.defl_limit,
                      lambda s, at: s.peak_force_xy_N * defl_per_N[at], defaults.get("deflection", ""))
    policy.load_limit("thrust", HARD, Load.THRUST, "thrust", loads.force_a[:, 2], loads.force_b[:, 2],
                      cut.thrust_limit, lambda s, at: s.force_tool_N[:, 2], defaults.get("thrust", ""))
    policy.load_limit("tool_torque", HARD, Load.TORQUE, "tool torque", loads.torque_a, loads.torque_b,
                      cut.tool_torque_limit, lambda s, at: s.torque_Nm, defaults.get("tool_torque", ""))
    policy.load_limit("chip_load_max", QUALITY, Load.CHIP, "chip load", chip_a, Derived(np.zeros_like, (chip_a,), (n,)),
                      cut.h_max,
                      lambda s, at: s.speed_mm_s * chip_a[at])  # a restart's descent has a chip where nothing cuts


def _plunge_limits(policy: _Policy, job: Job, cut: _CutLoads, restart: np.ndarray | None, v_prog: np.ndarray,
                   carried: np.ndarray) -> None:
    """The plunge feed cap where the end cuts (or a restart's descent would), from the user's
    plunge_feed_max_mm_min and plunge_raise_max × the programmed speed `v_prog` (mm/s; the speed the
    programmed blend arcs carry into it, `carried`, at least), and the chip floor (the minimum-chip feed)."""
    n, sin_end = len(v_prog), cut.sin_end
    plunging = (sin_end > 0) | (restart if restart is not None else False)
    user_cap = job.settings.plunge_feed_max_mm_s
    plunge_cap = np.full(n, np.inf if user_cap is None else user_cap)
    # the programmer chose the plunge feed (a tool that cuts poorly at its centre, a loose fixture): at
    # most plunge_raise_max times it; with the end's loads unknown, the programmed feed stays the cap
    raise_max = job.settings.plunge_raise_max if job.material.end_cutting is not None else 1.0
    # (the program itself runs a blended corner at the faster of its two feeds, into the plunge's end)
    raised = np.maximum(np.where(v_prog > 0, raise_max * v_prog, np.inf), carried)
    plunge_cap = np.minimum(plunge_cap, raised)
    policy.limits.append(Limit(FeedLimit(np.where(plunging, plunge_cap, np.inf), name="plunge_feed"), HARD, "feed",
                               baseline=False))
    policy.limits.append(Limit(MinSpeed(cut.floor, name="chip_load_min"), QUALITY, "chip-load floor"))


def _drive_limits(policy: _Policy, job: Job, samples: Samples, loads: LinearLoads, engaged: np.ndarray) -> np.ndarray:
    """The axis drives' current: the cut's share per axis under what the drive has left beside the
    controller's own acceleration (where the tool is `engaged`), the motor current with the cutting force
    at each sample's speed cap, and the current's slew. Returns that speed cap per sample (mm/s: the
    speed-only limits' `static_caps` before the motor current)."""
    limits, n = policy.limits, len(samples)
    ax = [job.machine.axes[a] for a in "xyz"]
    amax = tuple(a.amax_mm_s2 for a in ax)
    rho = np.array([a.rho_m_per_rad for a in ax])
    mass = tuple(a.moving_mass_kg + a.motor.rotor_inertia_kgm2 / r**2 for a, r in zip(ax, rho))
    kf = tuple(a.motor.kt_Nm_per_A * a.efficiency / r for a, r in zip(ax, rho))
    current = tuple(a.motor.current_limit_A for a in ax)
    friction = np.array([a.friction_coulomb_N for a in ax])
    viscous = np.array([a.friction_viscous_N_s_per_mm for a in ax])
    # Cutting force, friction and drag must leave the drive the current for the controller's own
    # acceleration (it ramps at a_max whatever the F words say): per axis
    # |F_b| + f_c + (|F_a| + c_v·|t|)·v ≤ k_f·I_max − m·a_max (N at the carriage), a conservative speed cap.
    capacity = np.asarray(kf) * np.asarray(current) - np.asarray(mass) * np.asarray(amax) * 1e-3
    for k in range(3):  # the drive force the cut and friction take at most, at the sample's speed (`Derived`)
        slope = Derived(lambda fa, t, c=viscous[k]: np.abs(fa) + c * np.abs(t),
                        (loads.force_a[:, k], samples.tangent[:, k]), (n,))
        static = Derived(lambda fb, c=friction[k]: np.abs(fb) + c, (loads.force_b[:, k],), (n,))
        stalled = policy.load_limit("cutting_current", HARD, Load.DRIVE_CURRENT, "current", slope, static,
                                    Derived(lambda e, c=capacity[k]: np.where(e, c, np.inf), (engaged,), (n,)),
                                    lambda s, at, slope=slope, static=static: slope[at] * s.speed_mm_s + static[at])
    # The cutting share of the current is taken at each sample's speed cap (the speed-only limits
    # above), the endpoint of larger magnitude of the force over [0, cap]: linear rows, no √b term.
    v_cap = static_caps(samples, limits)
    drive_force = Derived(_drive_force, (loads.force_a, loads.force_b, v_cap, stalled), (n, 3))
    limits.append(Limit(MotorCurrent(mass, kf, current, tuple(friction), tuple(viscous), cut_beta=drive_force),
                        HARD, "current"))
    limits.append(Limit(CurrentSlew(mass, kf, current, tuple(a.motor.resistance_ohm for a in ax),
                                    tuple(a.motor.inductance_H for a in ax), tuple(a.motor.ke_V_s_per_rad for a in ax),
                                    min(a.motor.bus_voltage_V for a in ax), tuple(1.0 / (r * 1000.0) for r in rho)),
                        HARD, "current"))
    return v_cap


def _drive_force(force_a: np.ndarray, force_b: np.ndarray, v_cap: np.ndarray, stalled: np.ndarray) -> np.ndarray:
    """The cutting force on the axes (N, (n, 3)) the motor current takes, at the speed cap v_cap (mm/s) or at
    standstill, whichever is larger; 0 where the policy held the cutting current (`stalled`: inertia only
    there, the cutting share is held at the kept feed, reported)."""
    at_cap = force_a * v_cap[:, None] + force_b
    drive_force = -np.where(np.abs(at_cap) > np.abs(force_b), at_cap, force_b)
    drive_force[stalled] = 0.0
    return drive_force


def _air_limits(policy: _Policy, job: Job, samples: Samples, eng, toolpath: Toolpath, engaged: np.ndarray,
                v_prog: np.ndarray, v_cap: np.ndarray, carried: np.ndarray) -> None:
    """Feed moves that cut nothing (not `engaged`): the air clearance near the stock as loaded
    (`_air_clearance`, from the programmed speed `v_prog` and the other limits' speed caps `v_cap`, mm/s;
    at least the speed the programmed blend arcs carry, `carried`), and the user's air_feed_max_mm_min in
    cut space below the stock's top."""
    limits, cutting = policy.limits, policy.cutting
    if eng.near_stock is not None:  # air beside or just above the stock; a retract straight up meets nothing new
        near = eng.near_stock & cutting & ~(samples.tangent[:, 2] > RETRACT_COS)
        # going down: an approach, the air part of a plunge (a canned cycle's block, which one F runs whole
        # from its R plane, keeps its cut's rule: R is where the program starts the cycle's feed)
        moves_of_block = np.bincount(toolpath.block)[toolpath.block]
        down = (samples.tangent[:, 2] < -DESCENDING) & (moves_of_block[samples.move] <= 1)
        known = near & eng.swept_air
        if not job.settings.trust_cut_space:  # a descent, whatever was swept: the tool enters what it meets
            known &= ~(samples.tangent[:, 2] < -DESCENDING)
        cap = np.maximum(_air_clearance(near, known, engaged, samples, v_prog, v_cap, down), carried)
        limits.append(Limit(FeedLimit(cap, name="air_clearance"), HARD, "air clearance", baseline=False))
    if job.settings.air_feed_max_mm_s is not None and eng.below_top is not None:  # the user's cap on air in cut space
        air = cutting & ~engaged & eng.below_top
        limits.append(Limit(FeedLimit(np.where(air, job.settings.air_feed_max_mm_s, np.inf),
                                      name="air_feed"), HARD, "feed", baseline=False))


def restart_descents(job: Job, samples: Samples, eng) -> np.ndarray | None:
    """Feed samples going down below the top of the stock as loaded (`Engagement.below_top`): the
    plunge rules hold there as if the material were still there (the chip of an end entering solid
    material, at most `plunge_raise_max` × the programmed feed), also where the program cut that space
    before: a restart from a later line, a skipped operation or a broken tool leaves it uncut. None
    with `[limits] trust_cut_space = true` (the program always runs whole) or without the stepping's
    record."""
    if job.settings.trust_cut_space or eng.below_top is None or eng.descent is None:
        return None
    return eng.below_top & (eng.descent > 0) & (samples.kind != RAPID)


def _air_clearance(near: np.ndarray, known: np.ndarray, engaged: np.ndarray, samples: Samples, v_prog: np.ndarray,
                   v_cap: np.ndarray, descending: np.ndarray) -> np.ndarray:
    """The air clearance's speed cap per sample (mm/s). near: feed samples that cut nothing within the
    clearance; known: those of them in space the tool swept before (`Engagement.swept_air`: not capped);
    engaged: samples that cut; blocks are source lines (one move, or a canned cycle's moves at one
    hole); v_prog: the programmed speed; v_cap: the other limits' speed caps. In a block that cuts
    nothing (an approach, a plunge or lead-in beside the stock, a link over it) the cap is the
    programmed feed; in the air part of a block that cuts, the programmed feed or, if higher, the lowest
    cap of its cut: the tool reaches material no faster than the cut it enters is allowed; but a sample
    going down (`descending`: an approach to the top, the air part of a plunge) keeps the programmed
    feed whatever the block cuts below it. The point
    where one move hands over to the next takes the higher of their caps (the programmed program passes
    it at the faster of the two feeds: a blending planner's blend); a known sample hands over its capped
    value (it is released after), so that nothing beside it that the tool has not swept is released
    with it."""
    line = samples.line
    v_cut = np.full(int(line.max(initial=0)) + 1, np.inf)
    np.minimum.at(v_cut, line[engaged], v_cap[engaged])
    entry = np.where(np.isinf(v_cut), 0.0, v_cut)[line]
    cap = np.where(near, np.where(descending, v_prog, np.maximum(v_prog, entry)), np.inf)
    handover = np.flatnonzero((samples.move[1:] != samples.move[:-1]) & ~np.asarray(samples.segment_start[1:], bool))
    both = np.maximum(cap[handover], cap[handover + 1])
    for k in (handover - 1, handover, handover + 1):  # within a step of it
        cap[k[k >= 0]] = np.maximum(cap[k[k >= 0]], both[k >= 0])
    cap[known] = np.inf
    return cap


def static_caps(samples: Samples, limits, kind: str | None = None, baseline: bool = False) -> np.ndarray:
    """Per sample the highest speed (mm/s) that the speed-only limits the controller does not hold
    by itself allow (loads, chip load, feed), of one kind or all, or (baseline) those the baseline's
    single F obeys (in chunks of LOAD_CHUNK samples: the rows of the whole program are never held at
    once)."""
    grid = PathGrid.from_samples(samples)
    mine = [lim for lim in limits if not lim.controller and kind in (None, lim.kind) and (lim.baseline or not baseline)]
    b_hi = np.empty(len(samples))
    for lo in range(0, len(samples), LOAD_CHUNK):
        hi = min(lo + LOAD_CHUNK, len(samples))
        b_hi[lo:hi] = merged_bounds(window_blocks(grid, mine, lo, hi, caps_only=True), hi - lo)[1]
    return np.sqrt(b_hi)
