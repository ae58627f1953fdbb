"""End to end: a job's program → engagement → limits → one convex feed schedule → the program with new
feeds → replay. Only wiring: the limits and the feed policy are `millpost.limits`, the schedule
`millpost.schedule`, the written program `millpost.emit`, the checks `millpost.replay` (through the
forward model `millpost.signals`), the spindle speeds (opt-in) `millpost.spindle_speed`.

Cycle times are always the controller model's (`millpost.controller`), before and after, and against
the honest baseline: per tool and per programmed feed (a CAM user's separate cutting, plunge, ramp and
lead-in feeds), the highest single constant feed that exceeds no limit anywhere those moves cut.
When the solver fails, the programmed feeds are kept and the summary says why; when the optimized
program is slower than the programmed one (a hard limit the program exceeds), the status says so.
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass, field, replace

import numpy as np

from . import controller, safety
from ._kernels import set_threads
from .emit import SNAP_TO_PROGRAMMED, FeedPlan, emitted_positions, original_arc_length, whole_moves, write_feeds
from .engagement import engage
from .gcode import check_program, read_program, read_text
from .gcode.interpret import Program
from .job import Job, check_tools
from .progress import Progress, reporting, resolve, silent, stage
from .limits import HARD, QUALITY, JobLimits, build_limits, static_caps
from .operations import restart_points
from .replay import baseline_feeds, binding_shares, feed_at_samples, replay
from .schedule import FeedLimit, PathGrid, ScheduleOptions, schedule_samples
from .schedule.feeds import blend_excess, blend_limit, emission_limit, piecewise_feeds, run_limit
from .signals import controller_model, running_rpm
from .spindle_speed import choose_speeds
from .toolpath import RAPID, Samples


@dataclass
class Result:
    """What `optimize` did: the emitted text, the summary (JSON-ready) and per-sample arrays."""

    text: str
    summary: dict
    samples: Samples
    trace: dict = field(default_factory=dict)


def optimize(job: Job, *, progress: Progress | bool | None = None, options: ScheduleOptions | None = None) -> Result:
    """Run the whole post step on a job and return the new program and its summary. progress: a
    `millpost.progress` callback, or True/False/None (bars on stderr: always, never, on a terminal).
    `options` default to the job's `[limits] solver` on all cores."""
    t_start = time.perf_counter()
    options = options or ScheduleOptions.from_choices(solver=job.limits["solver"])
    set_threads(options.processes)
    report = resolve(progress)
    with reporting(report):  # the schedule's windows and the first numba compile of a kernel report too
        with stage(report, "read program"):
            program = read_program(job.program, job.reader_options())
        t_read = time.perf_counter()
        with stage(report, "stock"):
            stock = job.stock()
        check_program(program)
        check_tools(program, job.tools, float(stock.bounds()[1][2]))
        samples, eng, notes = engage(program, stock, dict(job.tools), float(job.limits["ds_mm"]), job.allow,
                                     progress=report, clearance_mm=float(job.limits["air_clearance_mm"]))
        samples = safety.check_spindle(program, samples, eng, job.spindle_rpm, job.allow, notes)
        # memory: the stock grid is not needed after the engagement, nor its per-slice arcs and per-step
        # records (reported by `millpost simulate`, checked by the safety gates), nor (at the programmed
        # speeds, whose loads do not change) the per-slice engagement once the loads are computed
        del stock
        eng = replace(eng, arc_rad=None, step_mm=None, descending=None, move=None, line=None, depth_mm=None)
        t_engage = time.perf_counter()
        model = controller_model(job)
        limits, modes = None, controller.path_modes(program, model)
        zones = controller.blend_zones(program.toolpath, model, modes)  # the programmed corners' blend arcs
        if job.limits["rpm"] != "optimize":
            limits = build_limits(job, samples, eng, program.toolpath, report, release_slices=True, modes=modes,
                                  zones=zones)
        t_limits = time.perf_counter()
        result = schedule_program(job, program, samples, eng, options, progress=report, limits=limits, modes=modes,
                                  zones=zones)
    result.summary["notes"] += notes
    result.summary["stage_s"] = {"read": round(t_read - t_start, 3), "engagement": round(t_engage - t_read, 3),
                                 **result.summary["stage_s"]}
    if limits is not None:  # built here
        result.summary["stage_s"]["limits"] = round(t_limits - t_engage, 3)
    result.summary["total_s"] = round(time.perf_counter() - t_start, 3)
    return result


def schedule_program(job: Job, program: Program, samples: Samples, eng, options: ScheduleOptions | None = None,
                     progress: Progress = silent, limits: JobLimits | None = None,
                     modes: controller.PathModes | None = None, zones: np.ndarray | None = None) -> Result:
    """From the engagement on: (with `[limits] rpm = "optimize"` the spindle speeds,
    `millpost.spindle_speed`), limits (unless given: `build_limits` of these samples and engagement),
    schedule, emitted text, cycle times and the replay check. modes: the program's path modes
    (`controller.path_modes`), zones: its programmed corners' blend arcs (`controller.blend_zones`),
    both computed here unless given. (Split from `optimize` so that tests can
    give engagements of known geometry.) progress: stages "forces", "schedule", "emission" and "replay"."""
    options = options or ScheduleOptions.from_choices(solver=job.limits["solver"])
    model = controller_model(job)
    modes = modes if modes is not None else controller.path_modes(program, model)
    zones = zones if zones is not None else controller.blend_zones(program.toolpath, model, modes)
    spindle, t_spindle, as_given = {}, time.perf_counter(), (program, samples)
    if job.limits["rpm"] == "optimize":  # the S words change, the moves and their path modes do not
        program, samples, spindle = choose_speeds(job, program, samples, eng, options, modes, zones, progress)
        spindle["seconds"] = round(time.perf_counter() - t_spindle, 3)
        limits = None  # the loads at the chosen speeds
    tp = program.toolpath
    t_limits = time.perf_counter()
    limits = limits if limits is not None else build_limits(job, samples, eng, tp, progress, modes=modes, zones=zones)
    t0 = time.perf_counter()
    sched = schedule_samples(samples, limits, options)
    solver_s = time.perf_counter() - t0
    progress("emission", 0, 4)
    before = controller.execute_program(program, model, modes=modes)
    base_feeds, base_per_tool, base_cap = baseline_feeds(program, samples, limits)
    base_feeds, baseline = _baseline_within(program, samples, base_feeds, base_cap, zones, model, modes)
    del base_cap  # memory: the emission below is the run's peak
    progress("emission", 1, 4)
    failed = [s for _, _, s in sched.segments if not s.status.ok]
    if failed and spindle.get("changed"):  # never new speeds with the programmed feeds: the programmed S
        result = schedule_program(replace(job, limits={**job.limits, "rpm": "programmed"}), *as_given, eng, options,
                                  progress, modes=modes, zones=zones)
        result.summary["notes"].append("note: the schedule failed at the chosen spindle speeds: S kept as programmed")
        return result
    if failed:
        plan = FeedPlan.programmed(program)
        status = "fallback_programmed_feeds"
        message = "; ".join(f"{s.status.value}: {s.message}" for s in failed[:3])
        text = write_feeds(program, plan)
        emitted = read_text(text, str(job.program), job.reader_options())  # what will run
        after = controller.execute_program(emitted, model)
        blends = {"passes": 1, "over": 0}
        progress("emission", 4, 4)
    else:
        # axis rates, ramps and corners stay the controller's: F words keep to the other limits
        limit_mm_s = emission_limit(samples, limits, sched, limits.names(f_word=False), limits.names(effect="current"),
                                    limits.names(clamp=True))
        # corners the controller blends at the faster feed carry it into the slower move: the bound at every
        # programmed corner here, the arcs of the program as emitted in `_emit_within`
        hard_cap = np.full(len(tp), np.inf)
        np.minimum.at(hard_cap, samples.move, static_caps(samples, limits, HARD) * 60.0)
        text, emitted, after, blends, plan = _emit_within(job, program, samples, limit_mm_s, zones, hard_cap, model,
                                                          progress)
        status, message = "solved", ""
    t_emit = time.perf_counter()
    emitted_tp = emitted.toolpath
    progress("replay", 0, 3)
    if status == "solved" and after.time_s > before.time_s * (1 + 1e-3):
        status = "slower"
    # the executed speed at each sample, at the same place of the emitted (split) moves
    executed = after.speed_at(*emitted_positions(tp, emitted_tp, samples.move,
                                                 controller.Execution.sample_fractions(samples)))
    progress("replay", 1, 3)
    # the programmed run first: only its ratios are kept, so its signals are freed before the emitted run's;
    # a load against its bound before the policy (the policy's held bound is the programmed feed's own load,
    # against which the programmed feeds would read 1 however far over the limit they are)
    programmed_run = replay(job, samples, eng, limits, before.speed_at_samples(samples))
    as_programmed = programmed_run.ratios | programmed_run.physical | _f_words_over_caps(samples, limits)
    del programmed_run
    progress("replay", 2, 3)
    checked = replay(job, samples, eng, limits, executed)
    progress("replay", 3, 3)
    by_effect, by_limit = binding_shares(samples, sched, limits, executed)
    cut = samples.kind != RAPID
    hard = sorted(set(limits.names(kind=HARD)))
    summary = {
        "program": str(job.program), "output": str(job.output), "status": status, "message": message,
        "samples": int(len(samples)), "cutting_samples": int(cut.sum()),
        "cycle_time_before_s": round(before.time_s, 3), "cycle_time_after_s": round(after.time_s, 3),
        "cycle_time_baseline_s": round(baseline.time_s, 3),
        "improvement_vs_baseline": round(1.0 - after.time_s / baseline.time_s, 4) if baseline.time_s else None,
        "improvement_vs_programmed": round(1.0 - after.time_s / before.time_s, 4) if before.time_s else None,
        "baseline_feed_mm_min": base_per_tool,
        "tools": _tool_table(tp, emitted_tp, before, after),
        "f_words": {"programmed": _f_words(program.text), "optimized": _f_words(text)},
        "solver_s": round(solver_s, 3),
        # segments accepted with the certified O(N) profile ("reach") or solved by Clarabel ("socp", windows)
        "schedule_methods": {"reach": sum(s.method == "reach" for _, _, s in sched.segments),
                             "socp": sum(s.method == "socp" for _, _, s in sched.segments),
                             "windows": sum(s.windows for _, _, s in sched.segments)},
        # wall seconds per stage (read and engagement added by `optimize`); emit includes the programmed and
        # baseline controller runs, replay the emitted one and the limit ratios
        "stage_s": {"limits": round(t0 - t_limits, 3), "schedule": round(solver_s, 3),
                    "emit": round(t_emit - t0 - solver_s, 3), "replay": round(time.perf_counter() - t_emit, 3)},
        "removed_volume_mm3": round(float(np.nansum(eng.volume_mm3)), 3),
        # emissions until no blend arc of the emitted program ran faster than the limits it covers (`_emit_within`)
        "blend_passes": blends,
        "policy": limits.lower,
        "limits": {k: round(v, 4) for k, v in sorted(checked.ratios.items())},
        "limits_programmed": {k: round(v, 4) for k, v in sorted(as_programmed.items())},
        "hard_limits": hard,
        # hard limits the optimized program still exceeds (value / bound before the policy): cuts too heavy
        # for the tool even at the lowest feed millpost writes (listed under `held`)
        "hard_limits_exceeded": {k: round(v, 4) for k, v in sorted(checked.physical.items())
                                 if v > 1.005 and k in hard},
        "f_word_caps": list(limits.f_word_cap_names(PathGrid.from_samples(samples))),
        "binding": by_effect,
        "binding_limits": by_limit,
        "defaults_binding": {k: v for k, v in limits.defaults.items() if by_limit.get(k, 0.0) > 0
                             or np.any(limits.held.get(k, False))},
        "chip_floor_unmet_samples": int(sum(int(np.sum(s.floor_unmet)) for _, _, s in sched.segments)),
        "held": _held_lines(samples, limits, checked.physical),
        "below_min_chip": _below_min_chip(samples, limits, feed_at_samples(tp, emitted_tp, samples)),
        # the operations' starts: a restart there keeps every descent below the stock's top at its plunge feeds
        "restart_from": restart_points(program, samples),
        "notes": program.notes + _rpm_notes(job, samples) + _blend_notes(blends) + _flow_notes(plan)
        + [f"note: {s.message}" for _, _, s in sched.segments if s.status.ok and s.message]
        + [f"note: line {row['line']}: {row['reason']}" for row in spindle.get("blocks", []) if row["changed"]],
    }
    if spindle:
        summary["spindle"] = spindle
    slower_max = float(job.limits["slower_max"])
    slow = {t: row for t, row in summary["tools"].items() if row["optimized_s"] > slower_max * row["programmed_s"]}
    # the cuts exceed a physical hard limit (a load: power, torque, the tool's strength, the drives): not
    # quality limits lowered by `lower = "all"`, nor caps the user set (plunge_feed_max_mm_min)
    loads = {lim.name for lim in limits if lim.kind == HARD and lim.bound is not None}
    if (after.time_s > before.time_s * slower_max or slow) and any(as_programmed.get(k, 0.0) > 1.0 for k in loads):
        safety.refuse_or_note("slower", _too_heavy(job, samples, limits, before.time_s, after.time_s, slow), job.allow,
                              summary["notes"])
    if summary["hard_limits_exceeded"]:
        safety.refuse_or_note("overload", _overloaded(job, summary), job.allow, summary["notes"])
    trace = {"s_mm": samples.s_mm, "x": samples.xyz_mm[:, 0], "y": samples.xyz_mm[:, 1], "z": samples.xyz_mm[:, 2],
             "line": samples.line, "tool": samples.tool, "ap_mm": eng.ap_mm, "ae_mm": eng.ae_mm,
             "area_mm2": eng.area_mm2, "feed_programmed_mm_min": samples.feed_mm_min,
             "feed_baseline_mm_min": np.where(cut, base_feeds[samples.move], np.nan),
             "feed_schedule_mm_min": sched.feed_mm_s * 60.0, "feed_executed_mm_min": executed * 60.0,
             "feed_min_chip_mm_min": limits.floor_mm_s * 60.0,
             "feed_hard_cap_mm_min": static_caps(samples, limits, HARD) * 60.0,
             "deflection_limit_mm": limits.deflection_mm,
             "binding_hard": _binding_kind(samples, sched, limits, HARD), **checked.trace_columns()}
    # 1 where the policy held that limit's bound at the programmed or minimum-chip feed (reported)
    trace.update({f"held_{k}": v.astype(np.int8) for k, v in sorted(limits.held.items())})
    return Result(text, summary, samples, trace)


BLEND_PASSES = 6  # emissions at most while blend arcs of the emitted program exceed the feed limit


def _emit_within(job: Job, program: Program, samples: Samples, limit_mm_s: np.ndarray, zones: np.ndarray,
                 hard_cap: np.ndarray, model: controller.ControllerModel, progress: Progress
                 ) -> tuple[str, Program, controller.Execution, dict, FeedPlan]:
    """The program with F words within the per-sample feed limit (mm/s; `piecewise_feeds`, hard_cap: per
    move, mm/min) where the controller's blend arcs carry them, what the reader makes of it and how the
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
    the run's lowest limit (`run_limit`), and the summary says so. Returns the text, the program, its
    execution, {"passes": emissions, "over": arcs over the limit in the returned program,
    "runs_lowered": arcs whose runs were lowered} and the feed plan written."""
    tp = program.toolpath
    step = float(job.limits["feed_step"])
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
    return text, emitted, after, {"passes": passes, "over": int(len(over)), "runs_lowered": stubborn}, plan


def _baseline_within(program: Program, samples: Samples, feeds: np.ndarray, cap_mm_s: np.ndarray,
                     zones: np.ndarray, model: controller.ControllerModel, modes: controller.PathModes
                     ) -> tuple[np.ndarray, controller.Execution]:
    """The baseline's feeds (per move, mm/min) and its run, with its blend arcs kept within the caps it
    was tuned under (mm/s per sample) as the optimized program's are (`_emit_within`): a blend arc runs
    the faster of its two feeds into the slower move, so every move an arc faster than the lowest cap
    it covers reaches runs at that cap (a CAM user's separate lead-in feed there). First the arcs of
    the programmed corners (`zones`, `controller.blend_zones`) at the faster of the two moves' feeds,
    then those of each run, their reach widened on later runs; after BLEND_PASSES runs, the whole run
    between stops at its lowest cap."""
    moving = program.toolpath.kind != RAPID

    def lowered_to(over: np.ndarray, limit: np.ndarray) -> np.ndarray:
        move_cap = np.full(len(feeds), np.inf)
        np.fmin.at(move_cap, samples.move, limit * 60.0)
        return np.where(moving, np.fmin(feeds, np.floor(move_cap * (1 + 1e-9))), feeds)

    ends = np.clip(np.searchsorted(samples.s_mm, zones[:, :2]), 0, len(samples) - 1)
    arcs = np.column_stack([zones[:, :2], np.minimum(zones[:, 2], np.fmax(*feeds[samples.move[ends]].T) / 60.0)])
    over = blend_excess(samples, cap_mm_s, arcs, SNAP_TO_PROGRAMMED)
    if len(over):
        feeds = lowered_to(over, blend_limit(samples, cap_mm_s, over))
    for passes in range(1, BLEND_PASSES + 2):
        run = controller.execute_program(program, model, feeds, modes=modes)
        over = blend_excess(samples, cap_mm_s, run.blends, SNAP_TO_PROGRAMMED)
        if not len(over) or passes > BLEND_PASSES:
            return feeds, run
        feeds = lowered_to(over, _arcs_kept(samples, cap_mm_s, over, cap_mm_s, passes))
    return feeds, run


def _arcs_kept(samples: Samples, limit_mm_s: np.ndarray, over: np.ndarray, within: np.ndarray, passes: int
               ) -> np.ndarray:
    """The feed limit (mm/s) lowered for the blend arcs `over` found on run `passes`: over each arc's
    reach widened (2^(passes−1) − 1)/2 times on either side (`blend_limit`), after BLEND_PASSES runs
    over the whole run between stops it lies on (`run_limit`); `within`: the limit the arcs must keep."""
    if passes < BLEND_PASSES:
        return blend_limit(samples, limit_mm_s, over, (2.0 ** (passes - 1) - 1.0) / 2.0, within)
    return run_limit(samples, limit_mm_s, over, within)


def _blend_notes(blends: dict) -> list[str]:
    """What the summary says when blend arcs needed more than their reach lowered (`_emit_within`)."""
    out = []
    if blends.get("runs_lowered"):
        out.append(f"note: {blends['runs_lowered']} blend arcs still ran above the feed limit after "
                   f"{BLEND_PASSES} emissions: the whole runs they lie on were lowered to their lowest limit")
    if blends.get("over"):
        out.append(f"warning: {blends['over']} blend arcs of the emitted program run above the feed limit "
                   "(the controller carries the faster F word into the slower move)")
    return out


def _flow_notes(plan: FeedPlan) -> list[str]:
    """What the summary says of source lines that run several times (a subroutine or loop): one F word
    serves all their runs (`FeedPlan.from_fragments`)."""
    def some(lines: tuple[int, ...]) -> str:
        if len(lines) == 1:
            return f"line {lines[0]} runs"
        more = f" and {len(lines) - 10} more" if len(lines) > 10 else ""
        return "lines " + ", ".join(map(str, lines[:10])) + more + " run"

    out = []
    if plan.kept_lines:
        keeps = "keeps" if len(plan.kept_lines) == 1 else "keep"
        out.append(f"note: {some(plan.kept_lines)} several times (a subroutine or loop) at different programmed "
                   f"feeds and {keeps} the program's F: one F for every run would slow the faster runs")
    if plan.shared_lines:
        out.append(f"note: {some(plan.shared_lines)} several times (a subroutine or loop): one F serves every "
                   "run, the lowest any run allows, so the others run slower than they could")
    return out


def _binding_kind(samples: Samples, sched, limits: JobLimits, kind: str) -> np.ndarray:
    """1 where the limit that binds in the schedule is of this kind (hard: the schedule's speed there is
    forced, e.g. by the drives' current, which has no speed cap of its own), else 0."""
    owner = limits.by_block(PathGrid.from_samples(samples))
    out = np.zeros(len(samples), np.int8)
    for lo, hi, s in sched.segments:
        names, which = np.unique(s.binding.astype(str), return_inverse=True)
        out[lo:hi] = np.array([name in owner and owner[name].kind == kind for name in names], bool)[which.reshape(-1)]
    return out


def _f_words(text: str) -> int:
    """F words in a program's text (outside comments)."""
    return len(re.findall(r"[Ff]\s*[-+]?[\d.#\[]", re.sub(r"\([^)\n]*\)|;[^\n]*", "", text)))


def _tool_table(tp, emitted_tp, before: controller.Execution, after: controller.Execution) -> dict:
    """Per tool: programmed and optimized time (s) and the range of cutting feeds (mm/min)."""
    out = {}
    for number in np.unique(tp.tool[tp.kind != RAPID]):
        row = {}
        for key, path, run in (("programmed", tp, before), ("optimized", emitted_tp, after)):
            mine = path.tool[run.move] == number
            feeds = path.feed_mm_min[(path.tool == number) & (path.kind != RAPID)]
            row[f"{key}_s"] = round(float(run.block_time_s[mine].sum()), 3)
            row[f"{key}_feed_mm_min"] = [round(float(np.nanmin(feeds)), 1), round(float(np.nanmax(feeds)), 1)]
        out[int(number)] = row
    return out


def _below_min_chip(samples: Samples, limits: JobLimits, feed_mm_min: np.ndarray) -> dict:
    """Lines whose written F is under the minimum-chip feed (or the programmed one, if lower)
    somewhere: one F covers a stretch of samples, and a hard limit on a heavier part of it needs less
    than the chip floor of a lighter part."""
    cut = (samples.kind != RAPID) & (limits.floor_mm_s > 0)
    need = np.minimum(limits.floor_mm_s * 60.0, np.nan_to_num(samples.feed_mm_min, nan=np.inf))
    low = cut & (feed_mm_min < need * (1 - 1e-3) - 0.1)  # F words are rounded down to 0.1 mm/min
    lines = np.unique(samples.line[low])
    return {"samples": int(low.sum()), "lines": [int(x) for x in lines[:20]], "line_count": int(len(lines)),
            "reason": "a hard limit on a heavier part of the same F needs a feed below the chip floor here"}


def _held_lines(samples: Samples, limits: JobLimits, physical: dict[str, float]) -> dict:
    """Per limit whose bound the policy held (see `millpost.limits`): its kind, the sample count, the
    first source lines and `over_bound`, the largest value / its bound before the policy over the
    optimized program (`replay.Replay.physical`). A hard limit held means the cut needs a feed below
    the minimum-chip feed; a quality limit held does not lower the feed (other limits may)."""
    out = {}
    for name, mask in sorted(limits.held.items()):
        if not mask.any():
            continue
        kind = HARD if name in limits.forced else QUALITY
        lines = np.unique(samples.line[mask])
        out[name] = {"kind": kind, "samples": int(mask.sum()), "lines": [int(x) for x in lines[:20]],
                     "line_count": int(len(lines)), "over_bound": round(float(physical.get(name, 0.0)), 3),
                     "reason": ("the cut needs a feed below the minimum-chip feed (or the programmed one): held "
                                "there; the cut itself is too heavy for this tool on this machine" if kind == HARD else
                                "the programmed feed already exceeds it: it does not lower the feed there (hard "
                                "limits may), reported")}
    return out


def _too_heavy(job: Job, samples: Samples, limits: JobLimits, before_s: float, after_s: float,
               slow: dict[int, dict]) -> str:
    """Why the optimized program, or the work of some tools (`slow`: their rows of the summary's tool
    table), is much slower than programmed: per tool, each hard load limit the programmed feeds
    exceed, its first lines and how far over its bound the load is at the programmed feed (the factor
    the cut must lose)."""
    v_prog = np.nan_to_num(samples.feed_mm_min, nan=0.0) / 60.0
    over: dict[tuple[int, str], tuple[float, np.ndarray]] = {}  # (tool, limit) → (largest ratio, its samples)
    for lim in limits:
        if lim.bound is None or lim.kind != HARD:
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.nan_to_num((lim.constraint.alpha * v_prog + lim.constraint.beta) / lim.bound)
        for tool in np.unique(samples.tool[ratio > 1.0]):
            mine = (ratio > 1.0) & (samples.tool == tool)
            was_ratio, was = over.get((int(tool), lim.name), (0.0, mine))
            over[(int(tool), lim.name)] = (max(was_ratio, float(ratio[mine].max())), was | mine)
    parts = []
    for (tool, name), (ratio, mine) in sorted(over.items()):
        lines = np.unique(samples.line[mine])
        more = f" and {len(lines) - 8} more" if len(lines) > 8 else ""
        parts.append(f"T{tool} {name} up to {ratio:.2f}x its bound on lines {', '.join(map(str, lines[:8]))}{more}")
    tools = "; ".join(f"T{t} {row['optimized_s']:.1f} s against {row['programmed_s']:.1f} s" for t, row in slow.items())
    return (f"{job.program}: the programmed cuts exceed hard limits of this machine and tool "
            f"({'; '.join(parts) or 'see limits_programmed'}): within them the program takes {after_s:.1f} s "
            f"against {before_s:.1f} s programmed ({after_s / before_s:.2f}x{'; ' + tools if tools else ''}: more "
            f"than slower_max {float(job.limits['slower_max']):g}x); the cuts need to be lighter by those factors, "
            "or another tool or a stronger machine")


def _f_words_over_caps(samples: Samples, limits: JobLimits) -> dict[str, float]:
    """The programmed F words against the speed caps F words hold (`JobLimits.f_word_caps`), per cap the
    largest programmed feed over it where a move is fed: the controller runs an F above the axis rates or
    the maximum feed at them, so the replay of the programmed run never shows it (F6000 on 3000 mm/min
    axes written at the rates is what makes such a program a little slower)."""
    v_prog = np.where(samples.kind != RAPID, np.nan_to_num(samples.feed_mm_min, nan=0.0) / 60.0, 0.0)
    out = {}
    for lim in limits.f_word_caps():
        if isinstance(lim.constraint, FeedLimit):
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.nan_to_num(v_prog / lim.constraint.max_feed_mm_s, nan=0.0, posinf=0.0)
            out[lim.name] = float(np.max(ratio, initial=0.0))
    return {k: v for k, v in out.items() if v > 1.0}


def _overloaded(job: Job, summary: dict) -> str:
    """Which cuts exceed a hard load limit even at the lowest feed written: per limit, how far over its
    bound and the lines (`held`)."""
    parts = []
    for name, over in summary["hard_limits_exceeded"].items():
        held = summary["held"].get(name, {"lines": [], "line_count": 0})
        more = f" and {held['line_count'] - len(held['lines'])} more" if held["line_count"] > len(held["lines"]) else ""
        parts.append(f"{name} {over:.2f}x its bound on lines {', '.join(map(str, held['lines']))}{more}")
    return (f"{job.program}: cuts too heavy for this tool on this machine even at the lowest feed millpost writes "
            f"(the minimum-chip feed): {'; '.join(parts)}; they need a lighter cut, another tool or a stronger "
            "machine")


def _rpm_notes(job: Job, samples: Samples) -> list[str]:
    """The speeds the feed moves ask for (S words, or a hand-switched spindle's) outside the spindle's range."""
    on = (samples.rpm > 0) & (samples.kind != RAPID)
    out = []
    for rpm in np.unique(samples.rpm[on]):
        used = float(running_rpm(job, rpm))
        if used != rpm:
            line = int(samples.line[np.flatnonzero(on & (samples.rpm == rpm))[0]])
            out.append(f"{job.program}:{line}: S{rpm:g} is outside the spindle's range "
                       f"{job.machine.spindle.rpm_min:g}–{job.machine.spindle.rpm_max:g} rpm; "
                       f"the controller runs it at {used:g} rpm and the loads are computed there")
    return out
