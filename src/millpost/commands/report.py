"""`millpost report TRACE`: the HTML job report from a saved optimize trace (and its summary)."""

from __future__ import annotations

import argparse
import json
import sys

from ..job import load_job


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "report", help="an HTML page of what optimize did, where and why",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Draw the job report (one HTML file that opens offline: cycle time per operation, feed "
                    "along the path coloured by the limit that holds it, loads against their limits, a top view "
                    "of the part, the final stock, the notes) from the files `optimize --trace/--json` wrote. "
                    "With --job also the operations' names, the limits per sample and the final stock.",
        epilog="example:\n  millpost optimize sample_jobs/slotting --trace t.csv --json s.json\n"
               "  millpost report t.csv --summary s.json --job sample_jobs/slotting -o slotting.html")
    p.add_argument("trace", help="trace CSV written by `optimize --trace`")
    p.add_argument("--summary", metavar="JSON", help="summary written by `optimize --json`")
    p.add_argument("--job", help="the job the trace came from (folder or job.toml)")
    p.add_argument("-o", "--output", required=True, metavar="HTML", help="the report to write")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..report import collect, read_trace, write_report
    summary = json.loads(open(args.summary).read()) if args.summary else {}
    job = load_job(args.job) if args.job else None
    write_report(args.output, collect(summary, read_trace(args.trace), job))
    print(f"millpost: wrote {args.output}", file=sys.stderr)
    return 0
