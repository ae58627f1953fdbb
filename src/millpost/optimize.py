"""End to end: a job's program → engagement → limits → one convex feed schedule → the program with new
feeds → replay → summary. Only wiring: the limits and their policy are `millpost.limits`, the schedule
`millpost.schedule` (its solution v(s), mm/s), the F words and the written program `millpost.emit`,
the checks `millpost.replay` (through the forward model `millpost.signals`), the summary and the
trace `millpost.summary`, the spindle speeds (opt-in) `millpost.spindle_speed`.

Cycle times are always the controller model's (`millpost.controller`), before and after, and against
the honest baseline: per tool and per programmed feed (a CAM user's separate cutting, plunge, ramp and
lead-in feeds), the highest single constant feed that exceeds no limit anywhere those moves cut.
When the solver fails, the programmed feeds are kept and the summary says why; when the optimized
program is slower than the programmed one (a hard limit the program exceeds), the status says so.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from . import controller, safety
from ._kernels import set_threads
from .compensate.predicted import SurfaceError
from .emit import baseline_within, emission_limit, emit_programmed, emit_within, emitted_positions
from .engagement import engage
from .gcode import read_program
from .gcode.interpret import Program
from .job import Job
from .progress import Progress, reporting, resolve, silent, stage
from .limits import HARD, JobLimits, build_limits, static_caps
from .replay import baseline_feeds, replay
from .schedule import ScheduleOptions, schedule_samples
from .signals import controller_model
from .spindle_speed import choose_speeds
from .stability.check import Chatter, CutImmersion
from .summary import Run, f_words_over_caps, run_status, summarize, trace_columns
from .toolpath import Samples


@dataclass
class Result:
    """What `optimize` did: the emitted text, the summary (JSON-ready) and per-sample arrays (`trace`:
    empty unless asked for)."""

    text: str
    summary: dict
    samples: Samples
    trace: dict = field(default_factory=dict)


def optimize(job: Job, *, progress: Progress | bool | None = None, options: ScheduleOptions | None = None,
             trace: bool = False, surface_error: bool = False) -> Result:
    """Run the whole post step on a job and return the new program and its summary. progress: a
    `millpost.progress` callback, or True/False/None (bars on stderr: always, never, on a terminal).
    `options` default to the job's `[limits] solver` on all cores. trace: also build the per-sample
    trace (`Result.trace`: for `--trace` and `--report`; ~30 columns a sample, built only when asked).
    surface_error: also predict the surface error as programmed and as optimized (`SurfaceError`: about
    15 forward-model passes over the samples that finish a wall or floor, for each of the two feeds)."""
    t_start = time.perf_counter()
    options = options or ScheduleOptions.from_choices(solver=job.settings.solver)
    set_threads(options.processes)
    report = resolve(progress)
    with reporting(report):  # the schedule's windows and the first numba compile of a kernel report too
        with stage(report, "read program"):
            program = read_program(job.program, job.reader_options())
        t_read = time.perf_counter()
        with stage(report, "stock"):
            stock = job.stock()
        samples, eng, notes = engage(program, stock, dict(job.tools), job.settings.ds_mm, job.allow,
                                     progress=report, clearance_mm=job.settings.air_clearance_mm)
        samples = safety.check_spindle(program, samples, eng, job.spindle_rpm, job.allow, notes)
        cut = CutImmersion.of(job, samples, eng)  # chatter: the immersion, before the per-slice arcs go
        # memory: the stock grid is not needed after the engagement, nor its per-slice arcs and per-step
        # records (reported by `millpost simulate`, checked by the safety gates), nor (at the programmed
        # speeds, whose loads do not change) the per-slice engagement once the loads are computed
        del stock
        eng = replace(eng, arc_rad=None, step_mm=None, descending=None, move=None, line=None, depth_mm=None)
        t_engage = time.perf_counter()
        model = controller_model(job)
        limits, modes = None, controller.path_modes(program, model)
        zones = controller.blend_zones(program.toolpath, model, modes)  # the programmed corners' blend arcs
        if job.settings.rpm != "optimize":
            limits = build_limits(job, samples, eng, program.toolpath, report, release_slices=not surface_error,
                                  modes=modes, zones=zones)  # the surface error reads the slices
        t_limits = time.perf_counter()
        result = schedule_program(job, program, samples, eng, options, progress=report, limits=limits, modes=modes,
                                  zones=zones, trace=trace, cut=cut, surface_error=surface_error)
    result.summary["notes"] += notes
    result.summary["stage_s"] = {"read": round(t_read - t_start, 3), "engagement": round(t_engage - t_read, 3),
                                 **result.summary["stage_s"]}
    if limits is not None:  # built here
        result.summary["stage_s"]["limits"] = round(t_limits - t_engage, 3)
    result.summary["total_s"] = round(time.perf_counter() - t_start, 3)
    return result


def schedule_program(job: Job, program: Program, samples: Samples, eng, options: ScheduleOptions | None = None,
                     progress: Progress = silent, limits: JobLimits | None = None,
                     modes: controller.PathModes | None = None, zones: np.ndarray | None = None,
                     trace: bool = False, cut: CutImmersion | None = None, surface_error: bool = False) -> Result:
    """From the engagement on: (with `[limits] rpm = "optimize"` the spindle speeds,
    `millpost.spindle_speed`), limits (unless given: `build_limits` of these samples and engagement),
    schedule, emitted text, cycle times and the replay check. modes: the program's path modes
    (`controller.path_modes`), zones: its programmed corners' blend arcs (`controller.blend_zones`),
    both computed here unless given; trace: build the per-sample trace (`summary.trace_columns`);
    surface_error: predict it (`optimize`); cut: the
    samples' immersion for the chatter check (`stability.check.CutImmersion`), taken from `eng` unless
    given. (Split from `optimize` so that tests can give engagements of known geometry.) progress: stages
    "forces", "schedule", "emission" and "replay"."""
    options = options or ScheduleOptions.from_choices(solver=job.settings.solver)
    cut = cut if cut is not None else CutImmersion.of(job, samples, eng)
    model = controller_model(job)
    modes = modes if modes is not None else controller.path_modes(program, model)
    zones = zones if zones is not None else controller.blend_zones(program.toolpath, model, modes)
    spindle, t_spindle, as_given = {}, time.perf_counter(), (program, samples)
    if job.settings.rpm == "optimize":  # the S words change, the moves and their path modes do not
        program, samples, spindle = choose_speeds(job, program, samples, eng, options, modes, zones, progress, cut)
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
    base_feeds, baseline = baseline_within(program, samples, base_feeds, base_cap, zones, model, modes)
    del base_cap  # memory: the emission below is the run's peak
    progress("emission", 1, 4)
    failed = [s for _, _, s in sched.segments if not s.status.ok]
    if failed and spindle.get("changed"):  # never new speeds with the programmed feeds: the programmed S
        programmed = replace(job, settings=replace(job.settings, rpm="programmed"))
        result = schedule_program(programmed, *as_given, eng, options, progress, modes=modes, zones=zones, trace=trace,
                                  cut=cut, surface_error=surface_error)
        result.summary["notes"].append("note: the schedule failed at the chosen spindle speeds: S kept as programmed")
        return result
    if failed:
        emission = emit_programmed(job, program, model)
        progress("emission", 4, 4)
    else:
        # axis rates, ramps and corners stay the controller's: F words keep to the other limits
        limit_mm_s = emission_limit(samples, limits, sched, limits.names(f_word=False), limits.names(effect="current"),
                                    limits.names(clamp=True))
        # corners the controller blends at the faster feed carry it into the slower move: the bound at every
        # programmed corner here, the arcs of the program as emitted in `emit_within`
        hard_cap = np.full(len(tp), np.inf)  # per move, mm/s
        np.minimum.at(hard_cap, samples.move, static_caps(samples, limits, HARD))
        emission = emit_within(job, program, samples, limit_mm_s, zones, hard_cap, model, progress)
    t_emit = time.perf_counter()
    after = emission.execution
    status, message = run_status(failed, before, after)
    progress("replay", 0, 3)
    # the executed speed at each sample, at the same place of the emitted (split) moves
    executed = after.speed_at(*emitted_positions(tp, emission.program.toolpath, samples.move,
                                                 controller.Execution.sample_fractions(samples)))
    progress("replay", 1, 3)
    # the programmed run first: only its ratios are kept, so its signals are freed before the emitted run's;
    # a load against its bound before the policy (the policy's held bound is the programmed feed's own load,
    # against which the programmed feeds would read 1 however far over the limit they are)
    programmed_speed = before.speed_at_samples(samples)
    programmed_run = replay(job, samples, eng, limits, programmed_speed, columns=False)
    as_programmed = programmed_run.ratios | programmed_run.physical | f_words_over_caps(samples, limits)
    del programmed_run
    progress("replay", 2, 3)
    checked = replay(job, samples, eng, limits, executed, columns=trace)  # its columns: the trace's
    progress("replay", 3, 3)
    surface = (SurfaceError.predict(job, program, samples, eng, {"programmed": programmed_speed, "optimized": executed})
               if surface_error else None)
    run = Run(job, program, samples, eng, limits, sched, before, baseline, base_feeds, base_per_tool, emission,
              executed, checked, as_programmed, status, message, spindle, Chatter.check(job, cut, samples), surface)
    stage_s = {"limits": round(t0 - t_limits, 3), "schedule": round(solver_s, 3),
               "emit": round(t_emit - t0 - solver_s, 3), "replay": round(time.perf_counter() - t_emit, 3)}
    summary = summarize(run, solver_s, stage_s)
    return Result(emission.text, summary, samples, trace_columns(run) if trace else {})
