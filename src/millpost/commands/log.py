"""`millpost log`: log spindle load from a VFD over Modbus into the measurement log format."""

from __future__ import annotations

import argparse
import json
import signal
import sys

from ..config import builtin_names
from ..measure.modbus import RegisterMap, SpindleLogger, make_client, progress_line

HELP = """\
TARGET: tcp:HOST[:PORT] (Modbus TCP, default port 502), rtu-tcp:HOST:PORT (RTU frames over TCP, e.g. a
serial device server) or rtu:DEVICE (RS-485 adapter, e.g. rtu:/dev/ttyUSB0 with --baud/--parity).
MAP: a built-in register map ({maps}) or your own TOML (see generic-example; the Huanyang HY series
speaks a non-standard protocol and is refused). Rows are taken at a fixed rate; every lost interval
(timeout, exception response, lost connection, overrun) is a gap record in the log and a count in the
summary, and the logger reconnects. Ctrl-C ends the log cleanly: the file is complete up to the last row.

example:
  millpost log tcp:192.168.1.50 --map delta-ms300 -o spindle.csv --rate 50"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("log", help="log spindle load from a VFD over Modbus (RTU or TCP)",
                       description=__doc__, epilog=HELP.format(maps=", ".join(builtin_names("vfd_maps"))),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("target", metavar="TARGET", help="tcp:HOST[:PORT], rtu-tcp:HOST:PORT or rtu:DEVICE")
    p.add_argument("--map", required=True, metavar="MAP", help="register map: built-in name or .toml")
    p.add_argument("-o", "--output", required=True, metavar="LOG.csv", help="log file to write (CSV)")
    p.add_argument("--rate", type=float, default=50.0, metavar="HZ", help="samples per second (default 50)")
    p.add_argument("--duration", type=float, metavar="S", help="stop after this many seconds (default: Ctrl-C)")
    p.add_argument("--timeout", type=float, metavar="S", help="per request (default: 2 sample periods, ≥ 20 ms)")
    p.add_argument("--device-id", type=int, help="Modbus device (slave) id (default: the map's)")
    p.add_argument("--baud", type=int, default=9600, help="serial baud rate (rtu:, default 9600)")
    p.add_argument("--parity", choices=("N", "E", "O"), default="N", help="serial parity (default N)")
    p.add_argument("--stopbits", type=int, choices=(1, 2), default=1)
    p.add_argument("--json", metavar="SUMMARY", help="write the summary as JSON here ('-' for stdout)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    regmap = RegisterMap.load(args.map)
    if args.device_id is not None:
        from dataclasses import replace
        regmap = replace(regmap, device_id=args.device_id)
    timeout = args.timeout or max(2.0 / args.rate, 0.02)
    def client():
        return make_client(args.target, timeout_s=timeout, baudrate=args.baud, parity=args.parity,
                           stopbits=args.stopbits)

    probe = client()  # a bad target is refused before the log is opened; an absent drive is said
    if not probe.connect():
        print(f"millpost: no answer from {args.target} yet: logging gaps until it answers (Ctrl-C ends)",
              file=sys.stderr)
    probe.close()
    logger = SpindleLogger(client, regmap, args.output, rate_hz=args.rate,
                           progress=progress_line(regmap.columns) if sys.stderr.isatty() else None)
    # Ctrl-C is how a log ends (the logger finishes its file on KeyboardInterrupt), not the command's
    # immediate exit (`millpost.cli.run`): the default handler while it runs
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        summary = logger.run(args.duration)
    finally:
        signal.signal(signal.SIGINT, previous)
    if sys.stderr.isatty():
        sys.stderr.write("\n")
    text = json.dumps(summary.as_dict(), indent=2)
    if args.json == "-":
        print(text)
    elif args.json:
        from ..files import write_atomic
        write_atomic(args.json, text + "\n")
    lost = sum(summary.lost_ticks.values())
    print(f"millpost: {summary.rows} rows in {summary.duration_s:.1f} s, {summary.gaps} gaps ({lost} lost samples"
          + (": " + ", ".join(f"{n} {r}" for r, n in summary.lost_ticks.items()) if lost else "")
          + f"), {summary.reconnects} reconnects{'; interrupted' if summary.interrupted else ''}; wrote {args.output}",
          file=sys.stderr)
    return 0
