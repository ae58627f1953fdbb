"""What a run says: the summary (JSON-ready: status, cycle times before, after and against the honest
baseline, per-tool table, limits and their ratios, what the policy held, notes and warnings) and, when
asked for, the per-sample trace (`--trace`, `--report`). Feeds here are in mm/min, as a machinist reads
them; every stage before it works in mm/s.

The status is a `JobStatus`. The gates "slower" (much slower than programmed because the
programmed cuts exceed a hard load limit) and "overload" (a cut too heavy even at the lowest feed
written) refuse the run unless allowed (`safety.refuse_or_note`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from . import controller, safety
from .compensate.predicted import SurfaceError
from .emit import BLEND_PASSES, Emission, FeedPlan
from .engagement import Engagement
from .gcode.interpret import Program
from .job import Job
from .limits import HARD, QUALITY, JobLimits, static_caps
from .operations import restart_points
from .replay import Replay, binding_shares, feed_at_samples
from .schedule import FeedLimit, PathGrid, ProgramSchedule
from .signals import running_rpm
from .stability.check import Chatter
from .toolpath import RAPID, Samples



class JobStatus(StrEnum):
    """What became of a job, in the summary, the batch table, the CLI and the report: SOLVED; SLOWER, the
    optimized program runs longer than the programmed one (a hard limit the program exceeds);
    FALLBACK, the schedule failed and the programmed feeds were kept (the message says why); ERROR, the
    job did not run (batch: its row's message says why)."""

    SOLVED = "solved"
    SLOWER = "slower"
    FALLBACK = "fallback_programmed_feeds"
    ERROR = "error"


@dataclass
class Run:
    """What the stages of one run produced, for its summary and trace: the programmed run (`before`),
    the honest baseline's feeds (mm/min per move, `base_per_tool` per tool and programmed F) and run,
    the emission, the executed speed (mm/s per sample) of the emitted program, its replay (`checked`)
    and the programmed feeds' ratios (`as_programmed`), `spindle`: the chosen spindle speeds (opt-in),
    `chatter`: the chatter check (None: no tool has an FRF), `surface`: the predicted surface error as
    programmed and as optimized (with the trace; None: not asked for, or no wall or floor finished)."""

    job: Job
    program: Program
    samples: Samples
    eng: Engagement
    limits: JobLimits
    sched: ProgramSchedule
    before: controller.Execution
    baseline: controller.Execution
    base_feeds: np.ndarray
    base_per_tool: dict
    emission: Emission
    executed: np.ndarray
    checked: Replay
    as_programmed: dict[str, float]
    status: JobStatus
    message: str
    spindle: dict
    chatter: Chatter | None = None
    surface: SurfaceError | None = None


def run_status(failed: list, before: controller.Execution, after: controller.Execution | None
               ) -> tuple[JobStatus, str]:
    """The run's status and message: the schedule's failed segments (`failed`: their `Schedule`s) keep
    the programmed feeds; else SLOWER where the emitted program runs longer than the programmed one."""
    if failed:
        return JobStatus.FALLBACK, "; ".join(f"{s.status.value}: {s.message}" for s in failed[:3])
    if after is not None and after.time_s > before.time_s * (1 + 1e-3):
        return JobStatus.SLOWER, ""
    return JobStatus.SOLVED, ""


def summarize(run: Run, solver_s: float, stage_s: dict[str, float]) -> dict:
    """The summary of a run (JSON-ready), after the gates "slower" and "overload" (which raise unless
    allowed, else add their warning to the notes)."""
    job, program, samples, limits, sched = run.job, run.program, run.samples, run.limits, run.sched
    tp, emitted_tp = program.toolpath, run.emission.program.toolpath
    before, after, baseline = run.before, run.emission.execution, run.baseline
    checked, blends, spindle = run.checked, run.emission.blends, run.spindle
    by_effect, by_limit = binding_shares(samples, sched, limits, run.executed)
    cut = samples.kind != RAPID
    hard = sorted(set(limits.names(kind=HARD)))
    summary = {
        "program": str(job.program), "output": str(job.output), "status": run.status, "message": run.message,
        "samples": int(len(samples)), "cutting_samples": int(cut.sum()),
        "cycle_time_before_s": round(before.time_s, 3), "cycle_time_after_s": round(after.time_s, 3),
        "cycle_time_baseline_s": round(baseline.time_s, 3),
        "improvement_vs_baseline": round(1.0 - after.time_s / baseline.time_s, 4) if baseline.time_s else None,
        "improvement_vs_programmed": round(1.0 - after.time_s / before.time_s, 4) if before.time_s else None,
        "baseline_feed_mm_min": run.base_per_tool,
        "tools": _tool_table(tp, emitted_tp, before, after),
        "f_words": {"programmed": _f_words(program.text), "optimized": _f_words(run.emission.text)},
        "solver_s": round(solver_s, 3),
        # segments accepted with the certified O(N) profile ("reach") or solved by Clarabel ("socp", windows)
        "schedule_methods": {"reach": sum(s.method == "reach" for _, _, s in sched.segments),
                             "socp": sum(s.method == "socp" for _, _, s in sched.segments),
                             "windows": sum(s.windows for _, _, s in sched.segments)},
        # wall seconds per stage (read and engagement added by `optimize`); emit includes the programmed and
        # baseline controller runs, replay the emitted one and the limit ratios
        "stage_s": stage_s,
        "removed_volume_mm3": round(float(np.nansum(run.eng.volume_mm3)), 3),
        # emissions until no blend arc of the emitted program ran faster than the limits it covers (`emit_within`)
        "blend_passes": blends,
        "policy": limits.lower,
        "limits": {k: round(v, 4) for k, v in sorted(checked.ratios.items())},
        "limits_programmed": {k: round(v, 4) for k, v in sorted(run.as_programmed.items())},
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
        "below_min_chip": _below_min_chip(samples, limits, tp.feed_mm_min[samples.move],
                                          feed_at_samples(tp, emitted_tp, samples)),
        # the operations' starts: a restart there keeps every descent below the stock's top at its plunge feeds
        "restart_from": restart_points(program, samples),
        "notes": program.notes + _rpm_notes(job, samples) + _blend_notes(blends) + _flow_notes(run.emission.plan)
        + [f"note: {s.message}" for _, _, s in sched.segments if s.status.ok and s.message]
        + [f"note: line {row['line']}: {row['reason']}" for row in spindle.get("blocks", [])
           if row["changed"] or not row.get("chatter", {}).get("clears", True)],
    }
    if spindle:
        summary["spindle"] = spindle
    for check in (run.chatter, run.surface):
        if check is not None:
            summary[check.name] = check.summary()
            summary["notes"] += check.notes()
    _gates(run, summary)
    return summary


def _gates(run: Run, summary: dict) -> None:
    """The gates "slower" and "overload" on a run's summary (`safety.refuse_or_note`)."""
    job, limits = run.job, run.limits
    before, after = run.before.time_s, run.emission.execution.time_s
    slower_max = job.settings.slower_max
    slow = {t: row for t, row in summary["tools"].items() if row["optimized_s"] > slower_max * row["programmed_s"]}
    # the cuts exceed a physical hard limit (a load: power, torque, the tool's strength, the drives): not
    # quality limits lowered by `lower = "all"`, nor caps the user set (plunge_feed_max_mm_min)
    loads = {lim.name for lim in limits if lim.kind == HARD and lim.bound is not None}
    if (after > before * slower_max or slow) and any(run.as_programmed.get(k, 0.0) > 1.0 for k in loads):
        safety.refuse_or_note("slower", _too_heavy(job, run.samples, limits, before, after, slow), job.allow,
                              summary["notes"])
    if summary["hard_limits_exceeded"]:
        safety.refuse_or_note("overload", _overloaded(job, summary), job.allow, summary["notes"])


def trace_columns(run: Run) -> dict[str, np.ndarray]:
    """The per-sample trace (`--trace` CSV, the job report's plots): position, engagement, the feeds
    (mm/min) programmed, baseline, scheduled, executed, minimum-chip and hard cap, the loads and their
    bounds, which kind of limit binds, where the policy held a bound and (a tool with an FRF) the chatter
    check (`Chatter.trace_columns`) and the predicted surface error (`SurfaceError.trace_columns`)."""
    samples, eng, limits, sched = run.samples, run.eng, run.limits, run.sched
    cut = samples.kind != RAPID
    trace = {"s_mm": samples.s_mm, "x": samples.xyz_mm[:, 0], "y": samples.xyz_mm[:, 1], "z": samples.xyz_mm[:, 2],
             "line": samples.line, "tool": samples.tool, "ap_mm": eng.ap_mm, "ae_mm": eng.ae_mm,
             "area_mm2": eng.area_mm2, "feed_programmed_mm_min": run.program.toolpath.feed_mm_min[samples.move],
             "feed_baseline_mm_min": np.where(cut, run.base_feeds[samples.move], np.nan),
             "feed_schedule_mm_min": sched.feed_mm_s * 60.0, "feed_executed_mm_min": run.executed * 60.0,
             "feed_min_chip_mm_min": limits.floor_mm_s * 60.0,
             "feed_hard_cap_mm_min": static_caps(samples, limits, HARD) * 60.0,
             "deflection_limit_mm": limits.deflection_mm,
             "binding_hard": _binding_kind(samples, sched, limits, HARD), **run.checked.trace_columns()}
    # 1 where the policy held that limit's bound at the programmed or minimum-chip feed (reported)
    trace.update({f"held_{k}": v.astype(np.int8) for k, v in sorted(limits.held.items())})
    for check in (run.chatter, run.surface):
        if check is not None:
            trace.update(check.trace_columns())
    return trace


def _blend_notes(blends: dict) -> list[str]:
    """What the summary says when blend arcs needed more than their reach lowered (`emit.emit_within`)."""
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


def _below_min_chip(samples: Samples, limits: JobLimits, programmed_mm_min: np.ndarray, feed_mm_min: np.ndarray
                    ) -> dict:
    """Lines whose written F is under the minimum-chip feed (or the programmed one, if lower)
    somewhere: one F covers a stretch of samples, and a hard limit on a heavier part of it needs less
    than the chip floor of a lighter part."""
    cut = (samples.kind != RAPID) & (limits.floor_mm_s > 0)
    need = np.minimum(limits.floor_mm_s * 60.0, np.nan_to_num(programmed_mm_min, nan=np.inf))
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
    v_prog = np.nan_to_num(samples.feed_mm_s, nan=0.0)
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
            f"than slower_max {job.settings.slower_max:g}x); the cuts need to be lighter by those factors, "
            "or another tool or a stronger machine")


def f_words_over_caps(samples: Samples, limits: JobLimits) -> dict[str, float]:
    """The programmed F words against the speed caps F words hold (`JobLimits.f_word_caps`), per cap the
    largest programmed feed over it where a move is fed: the controller runs an F above the axis rates or
    the maximum feed at them, so the replay of the programmed run never shows it (F6000 on 3000 mm/min
    axes written at the rates is what makes such a program a little slower)."""
    v_prog = np.where(samples.kind != RAPID, np.nan_to_num(samples.feed_mm_s, nan=0.0), 0.0)
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
