"""Sinumerik position patterns under a modal drilling cycle (MCALL CYCLE8x), Cycles manual "Drilling
pattern cycles": the modal cycle runs at each position of the pattern, in order.

- ``HOLES1(SPCA, SPCO, STA1, FDIS, DBH, NUM)`` ("HOLES1 - Row of holes"): NUM holes on the line through
  the reference point (SPCA, SPCO) at STA1 degrees to the abscissa, the first FDIS from it, DBH apart.
- ``HOLES2(CPA, CPO, RAD, STA1, INDA, NUM)`` ("HOLES2 - Circle of holes"): NUM holes on the circle of
  radius RAD about (CPA, CPO), the first at STA1 degrees, INDA apart (0: 360/NUM, a full circle).

Both are one parametrised pattern: hole k (0 ≤ k < NUM) at P + k·D + RAD·(cos, sin)(A + k·dA), written
as an O-sub (``o<sin_pattern_n>``, appended after the program like the subprograms) that the call's
line runs with the values at the call: #1, #2 = P, #3, #4 = D, #5 = RAD, #6 = A, #7 = dA, #8 = NUM.
"""

from __future__ import annotations

from collections.abc import Callable

from .cycles import arguments
from .syntax import Line, Token, skip

PATTERNS = {"HOLES1": ("SPCA", "SPCO", "STA1", "FDIS", "DBH", "NUM"),
            "HOLES2": ("CPA", "CPO", "RAD", "STA1", "INDA", "NUM")}
HOLE = ("[#1+#9*#3+#5*COS[#6+#9*#7]]", "[#2+#9*#4+#5*SIN[#6+#9*#7]]")  # hole #9's X, Y in the frame


def pattern_arguments(src: Line, t: Token, expr: Callable[[int], tuple[str, int]]) -> list[str]:
    """The sub's arguments [P1] [P2] [D1] [D2] [RAD] [A] [dA] [NUM] of a HOLES1/HOLES2 call (every
    parameter needed)."""
    names = PATTERNS[t.name]
    args = arguments(src, t)
    if len(args) != len(names) or not all(text for text, _ in args):
        raise src.error(f"{t.name} takes its {len(names)} parameters", t.start, t.name, ", ".join(names))
    v = {}
    for name, (text, at) in zip(names, args):
        value, end = expr(at)
        if skip(src.text, end) != at + len(text):
            raise src.error(f"unexpected text in {t.name} parameter {name}", end, src.text[end:at + len(text)],
                            "an expression")
        v[name] = f"[{value}]"
    if t.name == "HOLES1":
        a = v["STA1"]
        return [f"[{v['SPCA']}+{v['FDIS']}*COS[{a}]]", f"[{v['SPCO']}+{v['FDIS']}*SIN[{a}]]",
                f"[{v['DBH']}*COS[{a}]]", f"[{v['DBH']}*SIN[{a}]]", "0", "0", "0", v["NUM"]]
    step = f"[[{v['INDA']} EQ 0]*360/{v['NUM']}+{v['INDA']}]"
    return [v["CPA"], v["CPO"], "0", "0", v["RAD"], v["STA1"], step, v["NUM"]]


def pattern_sub(name: str, hole: list[str]) -> list[str]:
    """The O-sub `name` running the words `hole` (the position and the modal cycle, through #9) at
    each of the pattern's #8 holes."""
    loop = f"{name[:-1]}_loop>"
    return [f"o{name} sub", "#9=0", f"o{loop} while [#9 LT #8]", " ".join(hole), "#9=[#9+1]", f"o{loop} endwhile",
            f"o{name} endsub"]
