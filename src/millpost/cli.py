"""millpost: a post step for CNC milling programs that knows the physics. It reads the G-code your CAM
wrote, simulates the cutter through the stock, predicts the cutting forces and rewrites only the feeds,
as fast as your machine, tool and material allow and never faster.

start with:  millpost optimize sample_jobs/adaptive_pocket --report pocket.html
then see:    millpost COMMAND --help (each has an example)"""

# A thin shell over the Python API: each subcommand lives in `millpost.commands.<name>`; errors
# millpost raises on purpose print one line and exit 2; Ctrl-C prints "interrupted" and exits 130
# (outputs are written atomically: no partial file is left).

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import signal
import sys

from . import __version__, commands
from .errors import MillpostError
from .files import remove_pending


class HelpFormatter(argparse.HelpFormatter):
    """Wraps one-line paragraphs to the terminal; keeps paragraphs written on several lines (tables,
    examples) as they are."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        return "\n\n".join(p if "\n" in p.strip("\n") else super(HelpFormatter, self)._fill_text(p, width, indent)
                             for p in text.split("\n\n"))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="millpost", description=__doc__,
                                     formatter_class=HelpFormatter)
    parser.add_argument("--version", action="version", version=f"millpost {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        importlib.import_module(f"{commands.__name__}.{info.name}").register(sub)
    for p in sub.choices.values():
        p.formatter_class = HelpFormatter
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
        return int(args.func(args) or 0)
    except MillpostError as exc:
        print(f"millpost: error: {exc}", file=sys.stderr)
        return 2
    except (OSError, UnicodeDecodeError) as exc:
        print(f"millpost: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("millpost: interrupted", file=sys.stderr)
        return 130
    except SystemError as exc:  # Ctrl-C while numba's dispatcher returned from a compiled kernel
        cause = exc
        while isinstance(cause, SystemError):  # numba chains one SystemError per C-level frame
            cause = cause.__cause__ or cause.__context__
        if not isinstance(cause, KeyboardInterrupt):
            raise
        print("millpost: interrupted", file=sys.stderr)
        return 130


def _interrupted(signum, frame) -> None:
    """Ctrl-C in the `millpost` command: the temporary files of unfinished outputs removed, one line, and
    the process ends at once (os._exit 130), before an exception could unwind through a compiled
    kernel's worker threads (that crashed the process, exit -11, about once in ten interrupts)."""
    remove_pending()
    os.write(2, b"\nmillpost: interrupted\n" if os.isatty(2) else b"millpost: interrupted\n")
    os._exit(130)


def run() -> None:
    """The `millpost` command: `main`, then the process ends. Ctrl-C ends it at once (`_interrupted`:
    outputs are written whole or not at all); `main` alone, in process, turns it into exit code 130."""
    signal.signal(signal.SIGINT, _interrupted)
    sys.exit(main())


if __name__ == "__main__":
    run()
