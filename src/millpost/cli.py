"""The `millpost` command: a thin shell over the Python API. Each subcommand lives in
`millpost.commands.<name>`; errors millpost raises on purpose print one line and exit 2; Ctrl-C
prints "interrupted" and exits 130 (outputs are written atomically: no partial file is left)."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from . import __version__, commands
from .errors import MillpostError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="millpost", description=__doc__)
    parser.add_argument("--version", action="version", version=f"millpost {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        importlib.import_module(f"{commands.__name__}.{info.name}").register(sub)
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


if __name__ == "__main__":
    sys.exit(main())
