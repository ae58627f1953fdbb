"""`millpost optimize JOB`: the program with feeds scheduled by the physics (see `millpost.optimize`)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..files import write_atomic, write_csv
from ..job import load_job
from ..optimize import optimize


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("optimize", help="schedule the feeds of a job's program and write it back",
                       description="Read the job (a folder with job.toml, or the .toml; format in README), simulate "
                                   "engagement, predict loads, solve one convex feed schedule and write the same "
                                   "program with only F words changed (moves split where the feed must change).")
    p.add_argument("job", help="job folder or job.toml")
    p.add_argument("-o", "--output", help="output program (default: the job's output)")
    p.add_argument("--json", metavar="SUMMARY", help="write the summary JSON here ('-' for stdout)")
    p.add_argument("--trace", metavar="CSV", help="write per-sample engagement, loads and feeds as CSV")
    p.add_argument("--report", metavar="HTML", help="write the job report (one HTML page that opens offline)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    job = load_job(args.job)
    result = optimize(job, progress=sys.stderr.isatty())
    output = Path(args.output) if args.output else job.output
    write_atomic(output, result.text)
    result.summary["output"] = str(output)
    text = json.dumps(result.summary, indent=2)
    if args.json == "-":
        print(text)
    elif args.json:
        write_atomic(args.json, text + "\n")
    if args.trace:
        write_csv(args.trace, result.trace)
    if args.report:
        from ..report import collect, write_report
        write_report(args.report, collect(result.summary, result.trace, job))
    status = result.summary["status"]
    print(f"millpost: {status}; cycle time {result.summary['cycle_time_before_s']:.1f} s -> "
          f"{result.summary['cycle_time_after_s']:.1f} s (baseline {result.summary['cycle_time_baseline_s']:.1f} s); "
          f"wrote {output}", file=sys.stderr)
    return 0
