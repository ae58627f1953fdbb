"""`millpost optimize JOB`: the program with feeds scheduled by the physics (see `millpost.optimize`)."""

from __future__ import annotations

import argparse
from dataclasses import replace
import sys
from pathlib import Path

from ..files import json_text, write_atomic, write_csv
from ..job import load_job
from ..optimize import optimize
from ..progress import Bars, stage
from ..report.page import headline
from ..safety import check_outputs
from ..schedule import ScheduleOptions
from ..summary import JobStatus
from . import add_allow_argument


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("optimize", help="rewrite a job's feeds as fast as the machine, tool and material allow",
                       epilog="example:\n  millpost optimize sample_jobs/adaptive_pocket --report pocket.html",
                       description="Read the job (a folder with job.toml, or the .toml; format in docs/job-files.md), simulate "
                                   "engagement, predict loads, solve one convex feed schedule and write the same "
                                   "program with only F words changed (moves split where the feed must change).")
    p.add_argument("job", help="job folder or job.toml")
    p.add_argument("-o", "--output", help="output program (default: the job's output)")
    p.add_argument("--json", metavar="SUMMARY", help="write the summary JSON here ('-' for stdout)")
    p.add_argument("--trace", metavar="CSV", help="write per-sample engagement, loads and feeds as CSV")
    p.add_argument("--report", metavar="HTML", help="write the job report (one HTML page that opens offline)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars and no summary line")
    p.add_argument("--solver", choices=ScheduleOptions.SOLVERS,
                   help="auto: the certified O(N) profile where its proven gap is within 0.1 %%, Clarabel "
                        "elsewhere; clarabel: Clarabel everywhere, for comparison (default: the job's "
                        "[limits] solver, else auto)")
    p.add_argument("--jobs", type=_positive_int, metavar="N", help="worker processes (default: all cores)")
    add_allow_argument(p)
    p.set_defaults(func=run)


def _positive_int(text: str) -> int:
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a whole number >= 1")
    return int(text)


def run(args: argparse.Namespace) -> int:
    job = load_job(args.job)
    job = replace(job, allow=job.allow | set(args.allow))
    output = Path(args.output) if args.output else job.output
    check_outputs({"output": output, "--json": args.json, "--trace": args.trace, "--report": args.report},
                  job.inputs)
    options = ScheduleOptions.from_choices(solver=args.solver or job.settings.solver, jobs=args.jobs)
    with Bars(enabled=False if args.quiet else None) as bars:
        asked = bool(args.trace or args.report)  # the trace and the surface error: for --trace and --report
        result = optimize(job, progress=bars, options=options, trace=asked, surface_error=asked)
        result.summary["output"] = str(output)
        text = json_text(result.summary)  # before anything is written: no NaN/inf reaches a report
        write_atomic(output, result.text)
        if args.json == "-":
            print(text)
        elif args.json:
            write_atomic(args.json, text + "\n")
        if args.trace:
            write_csv(args.trace, result.trace)
        if args.report:
            from ..report import collect, write_report
            with stage(bars, "report"):
                write_report(args.report, collect(result.summary, result.trace, job))
    if not args.quiet:
        for note in result.summary["notes"]:
            if note.startswith(("warning", "note:")):
                print(f"millpost: {note}", file=sys.stderr)
        print(report(result.summary, output), file=sys.stderr)
    return 0


def report(s: dict, output: Path) -> str:
    """What a machinist reads after a run: the outcome, why (the limits that bound the feeds and for
    which share of the cutting time, limits the program already exceeds, defaults that bound), the
    feeds held by the policy, and per tool the programmed and optimized time and feed range."""
    out = [f"millpost: {headline(s)}; F words {s['f_words']['programmed']} -> {s['f_words']['optimized']}; "
           f"wrote {output}"]
    if s["message"]:
        out.append(f"  {s['message']}")
    hard = set(s.get("hard_limits", ()))
    if s.get("binding_limits"):
        out.append("  limits that set the feed (share of cutting time): " + ", ".join(
            f"{k} {v:.0%}{' (hard)' if k in hard else ''}" for k, v in
            sorted(s["binding_limits"].items(), key=lambda kv: -kv[1]) if v >= 0.005))
    over = {k: v for k, v in s.get("limits_programmed", {}).items() if v > 1.005 and k in hard}
    if over:
        out.append("  the programmed feeds exceed hard limits (x bound): " +
                   ", ".join(f"{k} {v:.2f}" for k, v in sorted(over.items())) +
                   ("; feeds lowered there, hence slower" if s["status"] == JobStatus.SLOWER else ""))
    if s.get("hard_limits_exceeded"):
        out.append("  warning: the optimized program still exceeds hard limits (x bound) where the cut is too "
                   "heavy at the lowest feed written (see held): " +
                   ", ".join(f"{k} {v:.2f}" for k, v in s["hard_limits_exceeded"].items()) +
                   "; check the tool and the depths of cut before running it")
    for name, why in s.get("defaults_binding", {}).items():
        out.append(f"  default {name}: {why}")
    for name, h in s.get("held", {}).items():
        lines = ", ".join(map(str, h["lines"])) + (" ..." if h["line_count"] > len(h["lines"]) else "")
        out.append(f"  {name} ({h['kind']}) held on {h['line_count']} lines [{lines}]: {h['reason']}; "
                   f"up to {h['over_bound']:g} x its bound in the optimized program")
    if s.get("restart_from"):
        starts = s["restart_from"]
        shown = ", ".join(f"{r['line']} ({r['operation']})" for r in starts[:6]) + (" ..." if len(starts) > 6 else "")
        out.append(f"  restart from an operation's start: line {shown}; descents below the stock's top keep "
                   "their plunge feeds there")
    out.append("  tool  programmed s  optimized s  programmed F  optimized F (mm/min)")
    for number, row in s.get("tools", {}).items():
        out.append(f"  T{number:<4} {row['programmed_s']:12.1f} {row['optimized_s']:12.1f}  "
                   f"{row['programmed_feed_mm_min'][0]:g}-{row['programmed_feed_mm_min'][1]:g}  "
                   f"{row['optimized_feed_mm_min'][0]:g}-{row['optimized_feed_mm_min'][1]:g}")
    return "\n".join(out)
