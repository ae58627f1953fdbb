"""Writing Sinumerik: a feed back into a source line (`set_feed`)."""

from __future__ import annotations

import re

from .syntax import Line, skip, tokens, value_end
from .read import _BLOCK_NUMBER, _LABEL, _split_comment


def feed_span(line: str) -> tuple[int, int] | None:
    """[start, end) of the line's F word (``F300``, ``F=R1*2``), None without one; a dwell's F
    (G4 F<seconds>) is not a feed."""
    src = Line(line, 0, "<line>")
    end, _ = _split_comment(src)
    i = skip(line, 0)
    if line[i:i + 1] == "/":
        i = skip(line, i + 1)
    for pattern in (_BLOCK_NUMBER, _LABEL):
        m = pattern.match(line, i)
        if m:
            i = skip(line, m.end())
    toks = tokens(src, i, end, lambda s, k: value_end(s, k))
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
    end, comment = _split_comment(Line(line, 0, "<line>"))
    code = line[:end].rstrip(" \t")
    gap = line[len(code):end]
    return f"{code} F{f}" + (gap or (" " if comment else "")) + comment
