"""LinuxCNC tool tables (`.tbl`): per tool number its length (Z) and diameter (D), in mm.

One tool a line, words in any order: ``T1 P1 Z0.5 D0.0625 ;comment`` (T tool number, P pocket, Z
length, D diameter, X/Y/... other offsets, I/J/Q lathe angles and orientation). A table has no units
of its own: they are the machine's (LinuxCNC's standalone `rs274` reads them as inches).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from ..errors import ParseError

_WORD = re.compile(r"\s*([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
INCH = 25.4


@dataclass
class ToolTable:
    """Tool lengths and diameters (mm) by tool number; `orientation` is the lathe tool orientation Q."""

    lengths_mm: dict[int, float]
    diameters_mm: dict[int, float]
    orientation: dict[int, int]


def read_tool_table(path: str | Path, units: str = "mm") -> ToolTable:
    """Read a LinuxCNC tool table whose lengths are in `units` ("mm" or "inch")."""
    if units not in ("mm", "inch"):
        raise ValueError(f"tool table units must be 'mm' or 'inch', not {units!r}")
    scale = INCH if units == "inch" else 1.0
    out = ToolTable({}, {}, {})
    for n, raw in enumerate(Path(path).read_text(errors="replace").splitlines(), start=1):
        body = raw.split(";", 1)[0]
        if not body.strip():
            continue
        words: dict[str, float] = {}
        pos = 0
        while pos < len(body.rstrip()):
            m = _WORD.match(body, pos)
            if m is None:
                raise ParseError("not a tool table word", file=str(path), line=n, column=pos + 1,
                                 word=body[pos:].strip()[:20], expected="letter-number words such as T1 P1 Z0.5 D6")
            words[m.group(1).upper()] = float(m.group(2))
            pos = m.end()
        if "T" not in words or words["T"] != int(words["T"]) or words["T"] < 0:
            raise ParseError("tool table line without a tool number", file=str(path), line=n, column=1,
                             word=body.strip()[:20], expected="T<tool number> first")
        tool = int(words["T"])
        out.lengths_mm[tool] = words.get("Z", 0.0) * scale
        out.diameters_mm[tool] = words.get("D", 0.0) * scale
        out.orientation[tool] = int(words.get("Q", 0))
    return out
