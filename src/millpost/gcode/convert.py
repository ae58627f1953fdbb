"""Re-posting an interpreted program for another controller: same toolpath, the target's dialect.

The output is written from the interpreted moves and events, not by editing text: canned cycles
come out expanded (every controller runs lines), arcs as centre-format IJK relative to the start
(every dialect reads them; no R ambiguity), numbers in the target's format, units as programmed,
feeds in units per minute (G93/G95 converted to the equivalent G94 feed), and N numbers where the
dialect numbers its lines. Offsets set by G92/G52/G10 are not re-posted: coordinates are written in
the program frame the original ran in, after selecting its work offset (G54...).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import MillpostError
from ..toolpath import ARC_CW, PLANE_AXES, RAPID
from .dialects import Dialect
from .interpret import INCH, Program

_WCS = {1: "G54", 2: "G55", 3: "G56", 4: "G57", 5: "G58", 6: "G59", 7: "G59.1", 8: "G59.2", 9: "G59.3"}


def convert(program: Program, dialect: Dialect) -> str:
    """The program as `dialect` writes it. Geometry is unchanged to the target's number precision."""
    tp = program.toolpath
    if program.compensated.any():  # the moves are tool-centre paths: re-posting would drop the machine's offset
        line = int(tp.line[np.flatnonzero(program.compensated)[0]])
        raise MillpostError(f"{program.path}:{line}: cutter radius compensation (G41/G42) cannot be re-posted: "
                            "convert writes the interpreted tool-centre path, which would bypass the machine's "
                            "tool diameter and wear offsets; convert the program without compensation")
    out: list[str] = []
    seq = [0]

    def emit(words: str) -> None:
        if dialect.line_numbers and words and not words.startswith(("(", ";", "%", "O")):
            seq[0] += dialect.line_numbers
            words = f"N{seq[0]} {words}"
        out.append(words)

    def comment(text: str) -> None:
        clean = text.replace("(", "[").replace(")", "]")
        emit(f"({clean})" if dialect.comment == "paren" else f"; {clean}")

    if dialect.percent:
        out.append("%")
        out.append("O1000")
    comment(f"converted by millpost from {program.path} ({program.dialect} to {dialect.name})")
    if any(k in n for n in program.notes for k in ("G92", "G52")):
        comment("note: G92/G52 offsets were not re-posted; coordinates are in the original program frame")
    inch = None
    plane = None
    feed = None
    g = lambda c: f"G{c:02d}" if dialect.trailing_point else f"G{c}"  # noqa: E731
    emit(f"{g(90)} {g(94)} {g(17)}")
    events = program.events  # in the order they ran (a line in a loop or subroutine runs again)
    ev = 0
    for i in range(len(tp)):
        while ev < len(events) and events[ev].move <= i:
            _event(events[ev], dialect, emit, comment, g)
            ev += 1
        move_inch = bool(program.move_inch[i])
        scale = INCH if move_inch else 1.0
        dec = dialect.decimals_inch if move_inch else dialect.decimals_mm
        if move_inch != inch:
            emit(g(20) if move_inch else g(21))
            inch = move_inch
        num = lambda v: dialect.number(v / scale, move_inch, dec)  # noqa: E731
        end = tp.end[i]
        words = [f"X{num(end[0])}", f"Y{num(end[1])}", f"Z{num(end[2])}"]
        kind = int(tp.kind[i])
        if kind == RAPID:
            emit(f"{g(0)} " + " ".join(words))
            continue
        if kind >= ARC_CW and int(tp.plane[i]) != plane:
            plane = int(tp.plane[i])
            emit({0: g(17), 1: g(18), 2: g(19)}[plane])
        f = tp.feed_mm_min[i] / scale
        fw = ""
        if feed is None or abs(f - feed) > 1e-9 * max(1.0, f):
            fw = f" F{dialect.number(f, move_inch, 1 if f >= 10 else 3)}"
            feed = f
        if kind >= ARC_CW:
            a1, a2, _ = PLANE_AXES[plane]
            start = tp.start[i]
            # centre relative to the start as it was written, so rounding does not move the centre
            c = [tp.center[i, ax] - round(start[ax] / scale, dec) * scale for ax in (a1, a2)]
            letters = "IJK"
            words += [f"{letters[a1]}{num(c[0])}", f"{letters[a2]}{num(c[1])}"]
            if tp.turns[i]:
                words.append(f"P{int(tp.turns[i]) + 1}")
            emit(f"{g(2) if kind == ARC_CW else g(3)} " + " ".join(words) + fw)
        else:
            emit(f"{g(1)} " + " ".join(words) + fw)
    for e in events[ev:]:
        _event(e, dialect, emit, comment, g)
    if not any(e.kind == "end" for e in program.events):
        emit(dialect.end_code)
    if dialect.percent:
        out.append("%")
    return "\n".join(out) + "\n"


def _event(e, dialect: Dialect, emit, comment, g) -> None:
    """Non-motion actions in the target's words (unknown to it: written as a comment)."""
    if e.kind == "tool_change":
        emit(f"T{e.value} M6" if e.value >= 0 else "M6")
    elif e.kind == "spindle":
        direction, rpm = e.value
        code = {"cw": "M3", "ccw": "M4", "off": "M5", "speed": ""}[direction]
        s = f"S{dialect.number(rpm, False, 0)}" if direction != "off" else ""
        emit(" ".join(w for w in (s, code) if w))
    elif e.kind == "coolant":
        emit({"mist": "M7", "flood": "M8", "off": "M9"}[e.value])
    elif e.kind == "dwell":
        secs = float(e.value)
        emit(f"{g(4)} P{int(round(secs * 1000))}" if dialect.dwell_ms else f"{g(4)} P{dialect.number(secs, False, 3)}")
    elif e.kind == "stop":
        if e.value in (0, 1):
            emit(f"M{e.value}")
        else:
            comment(f"stop: {e.value}")
    elif e.kind == "end":
        emit(dialect.end_code)
    elif e.kind == "work_offset":
        emit(_WCS[e.value])
    elif e.kind == "comment":
        comment(str(e.value))
    elif e.kind == "m_code":
        emit(f"M{e.value}")
    elif e.kind == "tool_length" and dialect.name != "grbl":
        if e.value == 0.0:
            emit(g(49))
    elif e.kind == "path_mode" and dialect.name != "grbl":
        name, p = e.value
        emit({"exact path": g(61), "exact stop": "G61.1", "blend": g(64) + (f" P{p:g}" if p else "")}[name])


def same_path(a: Program, b: Program, tol_mm: float = 1e-4) -> list[str]:
    """Differences between two programs' swept paths: moves of any length in order (zero-length moves
    ignored), end points within tol, arc centres where both are arcs, and cutting length and bbox."""
    def keep(p: Program) -> np.ndarray:
        L = p.toolpath.lengths()
        return np.flatnonzero(L > tol_mm)
    ia, ib = keep(a), keep(b)
    if len(ia) != len(ib):
        return [f"{len(ia)} moves vs {len(ib)}"]
    ta, tb = a.toolpath, b.toolpath
    out = []
    d = np.abs(ta.end[ia] - tb.end[ib]).max(axis=1) if len(ia) else np.zeros(0)
    bad = np.flatnonzero(d > tol_mm)
    if len(bad):
        k = bad[0]
        out.append(f"end point of move {ia[k]} (line {ta.line[ia[k]]}) differs by {d[k]:.2e} mm")
    kinds = (ta.kind[ia] == RAPID) != (tb.kind[ib] == RAPID)
    if kinds.any():
        out.append(f"rapid/cutting differs at line {ta.line[ia[np.flatnonzero(kinds)[0]]]}")
    la, lb = ta.lengths()[ia].sum(), tb.lengths()[ib].sum()
    if not math.isclose(la, lb, rel_tol=1e-6, abs_tol=tol_mm * max(1, len(ia))):
        out.append(f"path length {la:.6f} vs {lb:.6f} mm")
    return out
