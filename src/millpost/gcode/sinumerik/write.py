"""Writing Sinumerik: a feed back into a source line (`set_feed`), and a program from another dialect
(`write`: `convert`'s RS-274 text in Sinumerik's words, `from_ngc`)."""

from __future__ import annotations

import re

from ...errors import MillpostError
from ..convert import SourceBlocks, write_rs274
from ..interpret import Program
from .cycles import CYCLES
from .syntax import Line, skip, tokens
from .read import _BLOCK_NUMBER, _LABEL, split_comment


def _tokens(line: str):
    """The line's tokens after block delete, N number and label, up to its comment."""
    src = Line(line, 0, "<line>")
    end, _ = split_comment(src)
    i = skip(line, 0)
    if line[i:i + 1] == "/":
        i = skip(line, i + 1)
    for pattern in (_BLOCK_NUMBER, _LABEL):
        m = pattern.match(line, i)
        if m:
            i = skip(line, m.end())
    return tokens(src, i, end)


def fixed_feed(line: str) -> bool:
    """A drilling cycle called on this line (CYCLE81...): the call takes a block of its own (FB
    "Subprogram call"), so its feed is the F in force, written elsewhere; its moves keep it."""
    return any(t.kind == "call" and t.name in CYCLES for t in _tokens(line))


def feed_span(line: str) -> tuple[int, int] | None:
    """[start, end) of the line's F word (``F300``, ``F=R1*2``), None without one; a dwell's F
    (G4 F<seconds>) is not a feed. A cycle call's line takes no feed (`fixed_feed`: MillpostError)."""
    if fixed_feed(line):
        raise MillpostError(f"{line.strip()!r}: a drilling cycle's call takes a block of its own: a new feed for "
                            "its drilling cannot be written into it (its moves keep the programmed feed)")
    toks = _tokens(line)
    if any(t.kind == "word" and t.name == "G" and t.value.lstrip("0") == "4" for t in toks):
        return None
    found = [t for t in toks if t.kind == "word" and t.name == "F"]
    return (found[-1].start, found[-1].end) if found else None


def set_feed(line: str, f: str | None) -> str:
    """The line with its F word's value `f` (mm/min or inch/min as the line's units; None: the F
    removed), F added before a ';' comment where the line has none; every other character kept."""
    span = feed_span(line)
    if span is not None:
        start, end = span
        if f is not None:
            return line[:start] + f"F{f}" + line[end:]
        cut = line[:start].rstrip(" \t")
        return cut + (" " if cut and line[end:].strip() and not line[end:].startswith((" ", "\t")) else "") + line[end:]
    if f is None:
        return line
    end, comment = split_comment(Line(line, 0, "<line>"))
    code = line[:end].rstrip(" \t")
    gap = line[len(code):end]
    return f"{code} F{f}" + (gap or (" " if comment else "")) + comment


_NGC_WORD = re.compile(r"([A-Z])(-?(?:\d+\.?\d*|\.\d+))")
# RS-274 codes → Sinumerik (FB "Inch/metric dimensions", "Settable zero offset", "Exact stop",
# "Dwell time"); the reader maps them back (`read`)
_G = {"20": "G700", "21": "G710", "49": "D0", "58": "G505", "59": "G506", "59.1": "G507", "59.2": "G508",
      "59.3": "G500", "61": "G60", "61.1": "G60"}


def write(program: Program, blocks: SourceBlocks) -> str:
    """The program (and its lexed source blocks) as Sinumerik writes it: `convert`'s RS-274 text in this
    dialect's style (N numbers, ';' comments), in Sinumerik's words."""
    from . import SINUMERIK  # the dialect this module's functions make up
    return from_ngc(write_rs274(program, SINUMERIK, blocks))


def from_ngc(text: str) -> str:
    """`convert`'s RS-274 program (N numbers, ';' comments) in Sinumerik words, line for line: G710/G700
    units, D1/D0 for G43/G49 (the loaded tool's edge), G4 F<s>, G641 ADIS=<P> for G64 P, TURN= for
    an arc's P, G505-G508/G500 for G58-G59.3."""
    out = []
    for line in text.split("\n"):
        code, sep, comment = line.partition(";")
        words = _NGC_WORD.findall(code)
        out.append(" ".join(_block(words, line)) + (" " if words and sep else "") + sep + comment)
    return "\n".join(out)


def _block(words: list[tuple[str, str]], line: str) -> list[str]:
    codes = {v for L, v in words if L == "G"}
    if codes & {"28", "30"}:
        raise MillpostError(f"convert: {line.strip()!r}: a return to G28/G30's stored position has no Sinumerik "
                            "equivalent (G74/G75 go to machine data, not to the position the program stored)")
    out = []
    for letter, value in words:
        if letter == "G" and value in _G:
            out.append(_G[value])
        elif letter == "G" and value == "43":
            out.append("D1")
        elif letter == "G" and value == "64" and any(L == "P" for L, _ in words):
            out.append("G641")
        elif letter == "H" and "43" in codes:
            continue
        elif letter == "P" and "4" in codes:
            out.append(f"F{value}")
        elif letter == "P" and "64" in codes:
            out.append(f"ADIS={value}")
        elif letter == "Q" and "64" in codes:
            continue  # the naive-CAM tolerance: Sinumerik compresses with COMPCAD, which millpost does not model
        elif letter == "P" and codes & {"2", "3"}:
            out.append(f"TURN={int(float(value)) - 1}")
        else:
            out.append(f"{letter}{value}")
    return out
