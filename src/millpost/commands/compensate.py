"""`millpost compensate JOB -o OUT`: the program with each cutting point moved against the tool's
predicted static deflection (tool beam plus the machine's compliance), and the predicted surface error
on the finished walls and floors before and after (docs/compensation.md)."""

from __future__ import annotations

import argparse


from ..errors import ConfigError
from ..files import json_text, write_atomic
from ..progress import Bars
from ..safety import check_outputs


def register(subparsers) -> None:
    p = subparsers.add_parser("compensate", help="move cutting points against the predicted deflection",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
                              epilog="example:\n  millpost compensate sample_jobs/thin_wall_finish -o thin_wall.nc")
    p.add_argument("job", metavar="JOB", help="job folder or job.toml")
    p.add_argument("-o", "--output", required=True, help="output program (written atomically)")
    p.add_argument("--json", metavar="SUMMARY", help="write the summary JSON here ('-' for stdout)")
    p.add_argument("--report", metavar="HTML", help="write a page with the surface error per operation and its map")
    p.add_argument("--tolerance", type=float, default=2.0, metavar="UM",
                   help="surface error and offset miss aimed at, µm (default 2)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars and no summary line")
    p.set_defaults(func=run)


def report_page(result) -> str:
    """The --report page: per sample its wall error, else its floor error (µm), before and after."""
    from ..compensate.surface import map_errors_um
    from ..report.figures import surface_error_map
    from ..report.page import compensation_page

    p = result.samples.xyz_mm
    errors = {}
    for name, run in (("as programmed", result.before), ("compensated", result.after)):
        errors[name] = map_errors_um(*result.surfaces.errors_mm(run.actual_mm - p))
    return compensation_page(result.summary, surface_error_map(p[:, 0], p[:, 1], errors))


def run(args: argparse.Namespace) -> int:
    from ..compensate import compensate
    from ..job import load_job

    if not 0.1 <= args.tolerance <= 1000.0:
        raise ConfigError("tolerance", args.tolerance, "must be in [0.1, 1000] µm")
    job = load_job(args.job)
    check_outputs({"-o": args.output, "--json": args.json if args.json != "-" else None, "--report": args.report},
                  job.inputs)
    with Bars(enabled=False if args.quiet else None) as bars:
        result = compensate(job, tolerance_mm=args.tolerance / 1000.0, progress=bars)
    text = json_text(result.summary)
    write_atomic(args.output, result.text)
    if args.report:
        write_atomic(args.report, report_page(result))
    if args.json == "-":
        print(text)
    elif args.json:
        write_atomic(args.json, text + "\n")
    if not args.quiet and args.json != "-":
        s = result.summary
        print(f"surface error (RMS over walls and floors) {s['surface_error_before_um']:.1f} → "
              f"{s['surface_error_after_um']:.1f} µm ({100 * s['reduction']:.0f} % less; largest "
              f"{s['largest_error_before_um']:.1f} → {s['largest_error_after_um']:.1f} µm); {s['moves_moved']} moves "
              f"moved, {s['points_added']} points added, none closer than F·DT; {args.output}")
        for op in s["operations"]:
            for surf in ("wall", "floor"):
                if surf in op["before"]:
                    print(f"  {op['operation']}: {surf} {op['before'][surf]['rms_um']:.1f} → "
                          f"{op['after'][surf]['rms_um']:.1f} µm RMS, largest {op['before'][surf]['max_um']:.1f} → "
                          f"{op['after'][surf]['max_um']:.1f} µm")
    return 0
