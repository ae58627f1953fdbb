"""`millpost inspect PROGRAM`: what a G-code program does (JSON), or its moves (CSV)."""

from __future__ import annotations

import argparse
import json
import sys

from ..gcode import ReaderOptions, read_program
from ..gcode.summary import moves_csv, summary
from ..progress import Bars, stage


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("inspect", help="summarise a G-code program (JSON) or list its moves (CSV)",
                       epilog="example:\n  millpost inspect sample_jobs/drill_and_mill/program.nc",
                       description="Read a program as a controller would and report what it does. Lengths in mm, "
                                   "times in s, feeds in mm/min; end points in the program's coordinate frame.")
    p.add_argument("program", help="G-code file")
    p.add_argument("--json", action="store_true", help="print the summary as JSON (the default)")
    p.add_argument("--moves", action="store_true", help="print CSV line,kind,x,y,z,feed_mm_min instead")
    p.add_argument("--dialect", help="controller dialect (default: detected from the text)")
    p.add_argument("--linuxcnc-frame", action="store_true",
                   help="assume LinuxCNC's frame: G28/G30 homes and G53 at machine zero (as `rs274` does)")
    p.add_argument("--tool-table", metavar="FILE",
                   help="LinuxCNC tool table (T P Z D): tool lengths for G43 and diameters for G41/G42")
    p.add_argument("--tool-table-units", choices=("mm", "inch"), default="mm", help="units of the tool table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    opts = ReaderOptions.linuxcnc() if args.linuxcnc_frame else ReaderOptions()
    if args.dialect:
        opts.dialect = args.dialect
    if args.tool_table:
        opts.use_tool_table(args.tool_table, args.tool_table_units)
    with Bars() as bars, stage(bars, "read program"):
        program = read_program(args.program, opts)
    if args.moves:
        sys.stdout.write(moves_csv(program))
    else:
        print(json.dumps(summary(program), indent=2))
    return 0
