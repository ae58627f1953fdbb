"""`millpost convert IN --to DIALECT -o OUT`: re-post a program for another controller."""

from __future__ import annotations

import argparse

from ..files import write_atomic
from ..errors import MillpostError
from ..gcode import ReaderOptions, dialects, read_program, read_text
from ..gcode.convert import convert, same_path
from ..progress import Bars, stage


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("convert", help="re-post a program for another controller dialect",
                       epilog="example:\n  millpost convert sample_jobs/slotting/program.nc --to grbl -o slotting-grbl.nc",
                       description="Write the same toolpath for another controller: canned cycles expanded, "
                                   "arcs as IJK, the target's number format and line numbering. The result is "
                                   "read back and checked against the input path (1e-4 mm) before it is written.")
    p.add_argument("program", help="input G-code file")
    p.add_argument("--to", required=True, metavar="DIALECT", help=f"target dialect: {', '.join(dialects.names())}")
    p.add_argument("-o", "--output", required=True, help="output file (written atomically)")
    p.add_argument("--from", dest="source", metavar="DIALECT", help="input dialect (default: detected)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    target = dialects.get(args.to)
    with Bars() as bars:
        with stage(bars, "read program"):
            program = read_program(args.program, ReaderOptions(dialect=args.source))
        with stage(bars, "convert and read back"):
            text = convert(program, target)
            back = read_text(text, args.output, ReaderOptions(dialect=target.name))
            diff = same_path(program, back)
    if diff:
        raise MillpostError(f"conversion would change the toolpath: {'; '.join(diff)}")
    write_atomic(args.output, text)
    return 0
