"""Sinumerik jumps (Job planning, "Program jumps to jump markers": GOTOF forward, GOTOB backward,
GOTO/GOTOC either way; ``IF <condition> GOTOF <label>``) as O-word structure, decided before the
translation: a forward jump skips to its label (``o<jN> if [NOT cond]`` … ``o<jN> endif`` on the label's
line), a backward jump repeats from its label (``o<jN> do`` on the label's line … ``o<jN> while [cond]``).

Labels are ``NAME:`` at the start of a block (two letters or an underscore first) or block numbers
(``GOTOF N100``). The label's line must hold nothing else (its block would have to run on both sides of
the structure), one jump per label; jumps that cross other loops or branches are refused by the
interpreter's O-word checks."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from .syntax import Line

_HEAD = re.compile(r"[ \t]*(?:/[ \t]*)?(?:(?:[Nn][ \t]*(\d+)|:[ \t]*(\d+))(?![\d.])[ \t]*)?"
                   r"(?:([A-Za-z_][A-Za-z_][A-Za-z0-9_]*)[ \t]*:(?!=))?")
_JUMP = re.compile(r"\b(GOTOF|GOTOB|GOTOC|GOTO)[ \t]+([A-Za-z_][A-Za-z0-9_]*)", re.IGNORECASE)


@dataclass
class Jumps:
    """at_label: line → its O-word statement; at_jump: line → ("if"/"while", O label)."""

    at_label: dict[int, str] = field(default_factory=dict)
    at_jump: dict[int, tuple[str, str]] = field(default_factory=dict)


def plan(lines: list[str], file: str, prefix: str = "jump") -> Jumps:
    """Where each jump and its label go in the translation (O labels <prefix1>, <prefix2>, ...: a
    subprogram's differ from its caller's)."""
    labels: dict[str, list[int]] = {}
    found = []
    for n, raw in enumerate(lines, 1):
        code = raw.split(";", 1)[0]
        head = _HEAD.match(code)
        for name in (head.group(3), f"N{head.group(1) or head.group(2)}" if head.group(1) or head.group(2) else None):
            if name:
                labels.setdefault(name.upper(), []).append(n)
        jump = _JUMP.search(code)
        if jump and re.match(r"(IF|GOTO)", code[head.end():].lstrip(), re.IGNORECASE):
            found.append((n, jump))
    out = Jumps()
    for k, (n, jump) in enumerate(found, 1):
        kind, target = jump.group(1).upper(), jump.group(2).upper()
        src = Line(lines[n - 1], n, file)
        ahead = [m for m in labels.get(target, []) if m > n]
        behind = [m for m in labels.get(target, []) if m <= n]
        where = {"GOTOF": ahead[:1], "GOTOB": behind[-1:]}.get(kind, ahead[:1] or behind[-1:])
        if not where:
            side = {"GOTOF": "ahead", "GOTOB": "behind"}.get(kind, "in the program")
            raise src.error(f"jump to {target}, which is not {side}", jump.start(2), jump.group(2),
                            "a label NAME: or block number of this program")
        to = where[0]
        if to in out.at_label or to in out.at_jump or n in out.at_label:
            raise src.error("a second jump to the same place (or a jump from a label's own line)", jump.start(),
                            jump.group(0), "one jump per label")
        label = f"<{prefix}{k}>"
        out.at_label[to] = f"o{label} endif" if to > n else f"o{label} do"
        out.at_jump[n] = ("if" if to > n else "while", label)
        code = lines[to - 1].split(";", 1)[0]
        after = code[_HEAD.match(code).end():]
        if after.strip():
            at = len(code) - len(after.lstrip())
            raise Line(lines[to - 1], to, file).error(f"the jump target {target} has a block on its line", at,
                                                      after.strip()[:40], "the label alone on its line (then the "
                                                      "block on the next)")
    return out
