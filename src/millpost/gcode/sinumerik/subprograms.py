"""Sinumerik subprograms (FB "Subprogram technique"): a call by name in a block of its own (``PART1``,
``PART1 P3``: three runs, ``L123``, ``L123 P2``, ``CALL "PART1"``) runs the subprogram file beside the
program (``PART1.SPF``, ``_N_PART1_SPF``, any letter case). It is translated by the same reader, in
the modal state of its first call, and appended after the program's lines as ``o<sin_part1> sub`` …
``endsub`` (``M17``, ``RET``, ``M2``, ``M30`` alone in a block: ``return``); a call with P runs a
wrapper sub that repeats it. Subprograms may call subprograms (`MAX_DEPTH` levels); recursion is
refused. A ``PROC NAME`` header is read; a PROC with parameters or attributes (SAVE) is refused.

Feeds: the moves of a subprogram keep their programmed feeds (they are written in the subprogram's file,
which millpost does not rewrite), so a subprogram must set its own feed: a feed move before any F word
of the subprogram is refused (its feed would be the caller's, which optimizing changes).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from .syntax import Line, Token

MAX_DEPTH = 16  # the main program and 15 subprogram levels (FB: "Nesting depth")
_CALL = re.compile(r'CALL[ \t]*"([A-Za-z_][A-Za-z0-9_]*)"[ \t]*$', re.IGNORECASE)
_PROC = re.compile(r"[ \t]*(?:[Nn][ \t]*\d+[ \t]*)?PROC[ \t]+([A-Za-z_][A-Za-z0-9_]*)[ \t]*([^;]*)", re.IGNORECASE)
END = re.compile(r"(M0*17|M0*2|M30|RET)", re.IGNORECASE)


def label(name: str) -> str:
    """The O-word label of a subprogram (``PART1`` → ``<sin_part1>``)."""
    return f"<sin_{re.sub(r'[^a-z0-9]', '_', name.lower())}>"


def quoted_call(code: str) -> str | None:
    """The name in ``CALL "NAME"`` (the whole block), None for another block."""
    m = _CALL.match(code)
    return m.group(1).upper() if m else None


def call_of(toks: list[Token]) -> tuple[str, Token | None] | None:
    """(subprogram name, its P word or None) when the block is a call by name: a name (or L<number>) and
    at most a P word; None otherwise."""
    first, rest = toks[0], toks[1:]
    if first.kind == "keyword":
        name = first.name
    elif first.kind == "word" and first.name == "L" and not first.eq and first.value.isdigit():
        name = f"L{first.value}"
    else:
        return None
    if len(rest) > 1 or rest and not (rest[0].kind == "word" and rest[0].name == "P"):
        return None
    return name, rest[0] if rest else None


def find(name: str, beside: str) -> Path | None:
    """The subprogram file NAME.SPF or _N_NAME_SPF (any letter case) in the folder of the file `beside`."""
    folder = Path(beside).parent
    wanted = {f"{name}.SPF".upper(), f"_N_{name}_SPF".upper()}
    try:
        return next((p for p in sorted(folder.iterdir()) if p.name.upper() in wanted and p.is_file()), None)
    except OSError:
        return None


def proc_header(src: Line) -> bool:
    """Whether the line is the subprogram's ``PROC NAME`` header (then its translation is a comment);
    parameters are refused."""
    m = _PROC.match(src.text)
    if not m:
        return False
    rest = m.group(2).rstrip()
    if rest:
        what = "parameters: subprogram parameters are" if rest.startswith("(") else "attributes (SAVE, ...) are"
        raise src.error(f"PROC with {what} not read", m.start(2), rest[:30], f"PROC {m.group(1)} alone")
    return True


@dataclass
class Registry:
    """The subprograms translated so far (shared by the main program's translator and its subprograms'):
    their appended NGC lines, the modal state each was translated in, and the call stack."""

    lines: list[str] = field(default_factory=list)
    origins: dict[int, tuple[str, int]] = field(default_factory=dict)  # index in lines → (file, line)
    state: dict[str, tuple] = field(default_factory=dict)  # name → (G90?, plane) of its translation
    wrappers: set[tuple[str, int]] = field(default_factory=set)
    stack: list[str] = field(default_factory=list)

    def add(self, name: str, file: str, body: list[str]) -> None:
        start = len(self.lines) + 1
        self.origins.update({start + k: (file, k + 1) for k in range(len(body))})
        self.lines += [f"o{label(name)} sub", *body, f"o{label(name)} endsub"]

    def repeated(self, name: str, runs: int) -> str:
        """The label of a sub that runs `name` `runs` times (added once per name and count)."""
        inner = label(name)
        outer = f"{inner[:-1]}_x{runs}>"
        if (name, runs) not in self.wrappers:
            self.wrappers.add((name, runs))
            loop = f"{inner[:-1]}_r{runs}>"
            self.lines += [f"o{outer} sub", f"o{loop} repeat [{runs}]", f"o{inner} call", f"o{loop} endrepeat",
                           f"o{outer} endsub"]
        return outer


class Translation(str):
    """A translation's NGC text, with `origins`: NGC line → (file, line) of the subprogram line it
    translates (`Dialect.translate`: an error the interpreter finds there names that file and line)."""

    origins: dict[int, tuple[str, int]]
