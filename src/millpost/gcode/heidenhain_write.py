"""Writing an interpreted program as HEIDENHAIN Klartext (`millpost convert --to heidenhain`).

The output is written from the interpreted moves and events (as `convert` does for RS-274
targets): ``BEGIN PGM``, numbered blocks, ``TOOL CALL n Z S..``, ``L`` with signed coordinates and
``FMAX`` for rapids (FMAX holds for its block only; F is modal), arcs as ``CC`` (centre, by the
two coordinates of the arc's plane: ``CC X.. Y..``, ``CC X.. Z..`` for G18, ``CC Y.. Z..`` for G19)
and ``C`` (end point, ``DR+`` counter-clockwise, as G3, ``DR-`` clockwise), helices of more than
one turn in XY as ``CP IPA.. IZ..`` about the pole, dwells as ``CYCL DEF 9`` (seconds), G53 moves
as ``L .. FMAX M91``, ``END PGM``. A Klartext program has one unit: it is written in mm (inch
programs converted, feeds in mm/min), so the motion is the same to 1e-4 mm. Tool length
compensation is the control's on TOOL CALL (G43/G49 are not written).

Refused (file:line:column): helices of more than one turn outside the XY plane, G28/G30 returns, work offsets other than G54,
and actions Klartext has no word for (mist coolant M7, unknown M codes).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import ParseError
from ..toolpath import ARC_CCW, ARC_CW, PLANE_AXES, RAPID
from .convert import SourceBlocks
from .interpret import Event, Program

_PASSED_M = {0, 1, 3, 4, 5, 8, 9}


class _Out:
    """Numbered Klartext blocks."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def __call__(self, block: str) -> None:
        self.lines.append(f"{len(self.lines)} {block}")

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


def _num(value: float, decimals: int = 4) -> str:
    """A signed Klartext number (``+10``, ``-2.5``, ``+0``)."""
    text = f"{value:.{decimals}f}".rstrip("0").rstrip(".")
    if text in ("-0", ""):
        text = "0"
    return text if text.startswith("-") else "+" + text


def _feed(value: float) -> str:
    text = f"{value:.{1 if value >= 10 else 3}f}".rstrip("0").rstrip(".")
    return f"F{text}"


def _refuse(program: Program, line: int, message: str, expected: str) -> ParseError:
    return ParseError(f"convert to heidenhain: {message}", file=program.path, line=line, column=1,
                      expected=expected)


class _Writer:
    """The state of one conversion: the blocks written, the axes known, the feed and tool in force."""

    def __init__(self, program: Program, blocks: SourceBlocks) -> None:
        self.program, self.out = program, _Out()
        self.blocks = blocks
        self.known = [False, False, False]
        self.last: list[str | None] = [None, None, None]  # the coordinate text last written per axis
        self.feed: float | None = None
        self.tool = -1
        self.rpm = 0.0
        self.tool_call_at = -1  # index of the TOOL CALL block an S may still join

    def event(self, e: Event) -> None:
        """A non-motion action as Klartext blocks."""
        out = self.out
        if e.kind == "tool_change":
            if e.value < 0:
                raise _refuse(self.program, e.line, "a tool change with no tool number", "T<n> M6")
            self.tool = int(e.value)
            out(f"TOOL CALL {self.tool} Z")
            self.tool_call_at = len(out.lines) - 1
        elif e.kind == "spindle":
            self._spindle(*e.value)
        elif e.kind == "coolant":
            if e.value == "mist":
                raise _refuse(self.program, e.line, "mist coolant (M7) has no Klartext M function", "M8 or M9")
            out("M8" if e.value == "flood" else "M9")
        elif e.kind == "dwell":
            out("CYCL DEF 9.0 DWELL TIME")
            out(f"CYCL DEF 9.1 DWELL {float(e.value):.3f}".rstrip("0").rstrip("."))
        elif e.kind == "stop":
            if e.value not in (0, 1):
                raise _refuse(self.program, e.line, f"stop {e.value!r} has no Klartext block", "M0 or M1")
            out("STOP" if e.value == 0 else "M1")
        elif e.kind == "end":
            out("M30")
        elif e.kind == "work_offset" and e.value != 1:
            raise _refuse(self.program, e.line, f"work offset {e.value} (G55..G59.3): a Klartext program runs in "
                          "the preset the operator activates", "G54 or none")
        elif e.kind == "comment":
            out(f"; {str(e.value).replace(';', ',')}")
        elif e.kind == "m_code":
            if e.value not in _PASSED_M:
                raise _refuse(self.program, e.line, f"M{e.value} has no known Klartext meaning", "M0-M9")
            out(f"M{e.value}")
        elif e.kind == "path_mode" and e.value[0] == "blend" and e.value[1]:
            out("CYCL DEF 32.0 TOLERANCE")
            out(f"CYCL DEF 32.1 T{e.value[1]:g}")
        # tool_length (the control's on TOOL CALL), s_word, canned_cycle (expanded), work offset 1: nothing

    def _spindle(self, direction: str, rpm: float) -> None:
        if direction != "off" and rpm and rpm != self.rpm:
            if self.tool_call_at == len(self.out.lines) - 1:
                self.out.lines[-1] += f" S{rpm:g}"
            else:
                self.out(f"TOOL CALL {max(self.tool, 0)} Z S{rpm:g}" if self.tool >= 0 else f"TOOL CALL Z S{rpm:g}")
            self.rpm = rpm
        if direction != "speed":
            self.out({"cw": "M3", "ccw": "M4", "off": "M5"}[direction])

    def move(self, i: int) -> None:
        """Move i as L (FMAX for rapids), CC + C, or CC + CP for helices of more than one turn."""
        tp, program = self.program.toolpath, self.program
        line = int(tp.line[i])
        src = self.blocks[line]
        codes = {round(w.value, 1) for w in src.words if w.letter == "G"} if src is not None else set()
        if 28.0 in codes or 30.0 in codes:
            raise _refuse(program, line, "G28/G30 (a return to a stored position) has no Klartext equivalent",
                          "the position as a move, or L Z.. FMAX M91 (machine coordinates)")
        if 53.0 in codes:
            self._machine_move(i, src, line)
            return
        named = {w.letter for w in src.words} & set("XYZ") if src is not None else set()
        moved = np.abs(tp.end[i] - tp.start[i]) > 1e-12
        for a in range(3):
            self.known[a] = self.known[a] or "XYZ"[a] in named or bool(moved[a])
        kind = int(tp.kind[i])
        if kind in (ARC_CW, ARC_CCW):
            self._arc(i, line)
            return
        coords = " ".join(self._coords(tp.end[i], range(3)))
        if kind == RAPID:
            self.out(f"L {coords} FMAX".replace("  ", " "))
        else:
            self.out(f"L {coords}{self._f(i)}".replace("  ", " "))

    def _coords(self, point: np.ndarray, axes) -> list[str]:
        """The words of the known axes among `axes` whose text changes (Klartext coordinates are modal);
        all of them for a move that goes nowhere, so that it stays a move."""
        words = []
        for a in axes:
            text = _num(point[a])
            if self.known[a] and text != self.last[a]:
                words.append(f"{'XYZ'[a]}{text}")
                self.last[a] = text
        if not words:  # a move to where the tool is: still a move (every axis known written again)
            words = [f"{'XYZ'[a]}{self.last[a]}" for a in axes if self.known[a] and self.last[a] is not None]
        return words

    def _f(self, i: int) -> str:
        f = float(self.program.toolpath.feed_mm_min[i])
        if self.feed is not None and abs(f - self.feed) <= 1e-9 * max(1.0, f):
            return ""
        self.feed = f
        return f" {_feed(f)}"

    def _machine_move(self, i: int, src, line: int) -> None:
        """G53 G0/G1: the same machine coordinates with M91 (the position is the machine's, so the axes
        it names are no longer known in the program's frame)."""
        words = []
        for w in src.words:
            if w.letter in "XYZ":
                if any(c in w.text for c in "#["):
                    raise _refuse(self.program, line, "G53 with a parameter word", "a number")
                words.append(f"{w.letter}{_num(w.value * (25.4 if self.program.move_inch[i] else 1.0))}")
                self.known["XYZ".index(w.letter)] = False
                self.last["XYZ".index(w.letter)] = None
        rapid = int(self.program.toolpath.kind[i]) == RAPID
        self.out(f"L {' '.join(words)} {'FMAX' if rapid else self._f(i).strip()} M91".replace("  ", " "))

    def _arc(self, i: int, line: int) -> None:
        """An arc as CC (the centre, by the two coordinates of its plane: X Y, X Z for G18, Y Z for G19)
        and C (DR+ for G3 in every plane: the reader's `heidenhain._PLANES`); a helix of more than one
        turn in XY as CP IPA.. IZ.. about the pole (refused in the other planes, whose poles Klartext's
        polar blocks do not take)."""
        tp = self.program.toolpath
        plane = int(tp.plane[i])
        first, second, _ = PLANE_AXES[plane]
        centre, start, end = tp.center[i], tp.start[i], tp.end[i]
        sign = "+" if int(tp.kind[i]) == ARC_CCW else "-"
        if plane and tp.turns[i]:
            raise _refuse(self.program, line, "a helix of more than one turn outside the XY plane (G18/G19)",
                          "one turn at most per arc")
        self.out("CC " + " ".join(f"{'XYZ'[a]}{_num(centre[a])}" for a in sorted((first, second))))
        if tp.turns[i]:
            a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
            a1 = math.atan2(end[1] - centre[1], end[0] - centre[0])
            base = (a1 - a0) % (2 * math.pi) if sign == "+" else (a0 - a1) % (2 * math.pi)
            base = base if base > 1e-12 else 2 * math.pi  # the end on the start: a whole circle
            sweep = math.degrees(base if sign == "+" else -base)
            sweep += (360.0 if sign == "+" else -360.0) * int(tp.turns[i])
            self.out(f"CP IPA{_num(sweep, 6)} IZ{_num(end[2] - start[2])} DR{sign}{self._f(i)}")
            self.last = [_num(end[0]), _num(end[1]), _num(end[2]) if self.known[2] else None]
            return
        self.last[first] = self.last[second] = None  # C takes its end point whole
        words = " ".join(self._coords(end, range(3)))
        self.out(f"C {words} DR{sign}{self._f(i)}")


def write(program: Program, blocks: SourceBlocks) -> str:
    """The program (and its lexed source blocks) as Klartext (see the module docstring), in mm."""
    w = _Writer(program, blocks)
    name = "".join(c for c in Path(program.path).stem.upper() if c.isalnum() or c in "_-") or "MILLPOST"
    w.out(f"BEGIN PGM {name} MM")
    w.out(f"; converted by millpost from {program.path} [{program.dialect} to heidenhain]")  # as `convert` words it
    events, ev = program.events, 0
    for i in range(len(program.toolpath)):
        while ev < len(events) and events[ev].move <= i:
            w.event(events[ev])
            ev += 1
        w.move(i)
    for e in events[ev:]:
        w.event(e)
    if not any(e.kind == "end" for e in events):
        w.out("M30")
    w.out(f"END PGM {name} MM")
    return w.out.text()
