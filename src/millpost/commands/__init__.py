"""CLI subcommands, one module each. A module defines ``register(subparsers)`` which adds its parser
and sets ``func`` (taking the parsed args, returning an exit code). The CLI discovers modules here,
so adding a command touches no shared file."""

from __future__ import annotations

import argparse


def add_allow_argument(p: argparse.ArgumentParser) -> None:
    """`--allow NAME` (repeatable): override a safety gate by name (see `millpost.safety`)."""
    from ..safety import GATES

    names = [g.name for g in GATES.values() if g.overridable]
    p.add_argument("--allow", action="append", default=[], choices=names, metavar="GATE",
                   help="run although this safety gate fires (its message becomes a warning); one of "
                        + ", ".join(names) + "; repeatable")
