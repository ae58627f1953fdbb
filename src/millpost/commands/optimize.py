"""`millpost optimize JOB`: the program with feeds scheduled by the physics (see `millpost.optimize`)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..files import write_atomic, write_csv
from ..job import load_job
from ..optimize import optimize
from ..progress import Bars, stage
from ..report.page import headline


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("optimize", help="rewrite a job's feeds as fast as the machine, tool and material allow",
                       epilog="example:\n  millpost optimize sample_jobs/adaptive_pocket --report pocket.html",
                       description="Read the job (a folder with job.toml, or the .toml; format in README), simulate "
                                   "engagement, predict loads, solve one convex feed schedule and write the same "
                                   "program with only F words changed (moves split where the feed must change).")
    p.add_argument("job", help="job folder or job.toml")
    p.add_argument("-o", "--output", help="output program (default: the job's output)")
    p.add_argument("--json", metavar="SUMMARY", help="write the summary JSON here ('-' for stdout)")
    p.add_argument("--trace", metavar="CSV", help="write per-sample engagement, loads and feeds as CSV")
    p.add_argument("--report", metavar="HTML", help="write the job report (one HTML page that opens offline)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars and no summary line")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    job = load_job(args.job)
    with Bars(enabled=False if args.quiet else None) as bars:
        result = optimize(job, progress=bars)
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
            with stage(bars, "report"):
                write_report(args.report, collect(result.summary, result.trace, job))
    if not args.quiet:
        print(f"millpost: {headline(result.summary)}; wrote {output}", file=sys.stderr)
    return 0
