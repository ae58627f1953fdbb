"""`millpost batch JOBS... --out DIR`: optimize many jobs on Dask (see `millpost.batch`)."""

from __future__ import annotations

import argparse
import sys


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "batch", help="optimize many jobs in parallel (Dask), with a results table",
        description="Optimize each job as one task on a dask.distributed cluster: a local one with --workers "
                    "processes (default 2), or the running scheduler at --scheduler. Each job gets a folder in "
                    "--out with its program, summary.json and report.html; a job that fails is reported in the "
                    "table and the others go on. The table is --out/results.csv and --out/results.html.",
        epilog="example:\n  millpost batch sample_jobs/slotting sample_jobs/drill_and_mill --out batch-results")
    p.add_argument("jobs", nargs="+", metavar="JOB", help="job folders or job.toml files")
    p.add_argument("--out", required=True, metavar="DIR", help="folder for the results")
    p.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. tcp://host:8786")
    p.add_argument("--workers", type=int, default=2, help="worker processes of the local cluster (default 2)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar and no summary line")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..batch import run_batch
    from ..progress import Bars
    from ..summary import JobStatus
    with Bars(enabled=False if args.quiet else None) as bars:
        rows = run_batch(args.jobs, args.out, scheduler=args.scheduler, workers=args.workers, progress=bars)
    failed = [r for r in rows if r["status"] == JobStatus.ERROR]
    if not args.quiet:
        print(f"millpost: {len(rows) - len(failed)} of {len(rows)} jobs done ({len(failed)} failed); "
              f"table in {args.out}/results.html", file=sys.stderr)
    return 1 if failed else 0
