"""Re-posting an interpreted program for another controller: same machine motion, the target's dialect.

The output is written from the interpreted moves and events, not by editing text: canned cycles
come out expanded (every controller runs lines), arcs as centre-format IJK relative to the start
(every dialect reads them; no R ambiguity), numbers in the target's format, units as programmed,
feeds in units per minute (G93/G95 converted to the equivalent G94 feed), and N numbers where the
dialect numbers its lines. A dialect of another language writes itself (`Dialect.write`: Heidenhain
Klartext from the moves, Sinumerik by rewriting this RS-274 text in its own words).

What depends on the machine rather than the program is re-posted as the source wrote it, so the
controller resolves it the same way: tool length compensation (G43 H / G43.1 / G43.2 / G49, where
the target runs it; else refused), G28/G30 (through the same intermediate point to the controller's
stored position) and G53 moves (the same machine coordinates). An axis is written only once the
source has named it: the reader's assumed start point and the positions it assumes after a home or
G53 retract are never posted as moves. Programs that set offsets (G10, G52, G92, G28.1, G30.1) are
refused: their frame depends on where the machine stands when they run.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..errors import ParseError
from ..toolpath import ARC_CW, PLANE_AXES, RAPID
from .dialects import Dialect
from .interpret import INCH, Program
from .lexer import Block, lex_line, source_lines

_WCS = {1: "G54", 2: "G55", 3: "G56", 4: "G57", 5: "G58", 6: "G59", 7: "G59.1", 8: "G59.2", 9: "G59.3"}


_FRAME_SETTING = re.compile(r"(?<![A-Z])G\s*0*(10|52|92(?:\.[0-3])?|28\.1|30\.1)(?![\d.])")
_COMMENT = re.compile(r"\([^)]*\)|;.*")
_FRAME_CODES = {10.0, 52.0, 92.0, 92.1, 92.2, 92.3, 28.1, 30.1}


class SourceBlocks:
    """The words of a program's source lines as written, lexed on demand and kept: `blocks[line]` is
    the `Block` of 1-based `line`, or None when the line needs the interpreter's parameters to be
    read (values of parameter words are not evaluated: check `Word.text`)."""

    def __init__(self, program: Program) -> None:
        self.lines, self.file = source_lines(program.text), program.path
        self._cache: dict[int, Block | None] = {}

    def __getitem__(self, line: int) -> Block | None:
        if line not in self._cache:
            try:
                text = self.lines[line - 1] if 0 < line <= len(self.lines) else ""
                self._cache[line] = lex_line(text, line, self.file, {})
            except ParseError:
                self._cache[line] = None
        return self._cache[line]


def _g_codes(block: Block | None) -> set[float]:
    return {round(w.value, 1) for w in block.words if w.letter == "G"} if block is not None else set()


def _refuse(program: Program, line: int, column: int, word: str, message: str, expected: str) -> ParseError:
    return ParseError(f"convert: {message}", file=program.path, line=line, column=column, word=word,
                      expected=expected)


def _frame_setting(program: Program, blocks: SourceBlocks) -> None:
    """Refuse offsets set in the program (G10, G52, G92..., G28.1, G30.1): re-posted coordinates would
    land elsewhere on the machine. (A text scan finds the candidate lines; the lexer confirms.)"""
    for n, text in enumerate(blocks.lines, 1):
        if "G" not in text.upper():
            continue
        clean = _COMMENT.sub(lambda m: " " * len(m.group()), text.upper())
        if not _FRAME_SETTING.search(clean):
            continue
        block = blocks[n]
        words = [w for w in block.words if w.letter == "G" and round(w.value, 1) in _FRAME_CODES] if block else []
        if block is None or words:
            column = words[0].column if words else _FRAME_SETTING.search(clean).start() + 1
            raise _refuse(program, n, column, words[0].text if words else "",
                          "offsets set in the program are not re-posted (the converted motion would differ)",
                          "a program without G10, G52, G92, G28.1 or G30.1 (set them on the controller)")


def convert(program: Program, dialect: Dialect) -> str:
    """The program as `dialect` writes it: the same machine motion, to the target's number precision."""
    tp = program.toolpath
    if program.compensated.any():  # the moves are tool-centre paths: re-posting would drop the machine's offset
        line = int(tp.line[np.flatnonzero(program.compensated)[0]])
        raise _refuse(program, line, 1, "", "cutter radius compensation (G41/G42) cannot be re-posted: convert "
                      "writes the interpreted tool-centre path, which would bypass the machine's tool diameter "
                      "and wear offsets", "a program without compensation")
    blocks = SourceBlocks(program)
    _frame_setting(program, blocks)
    if dialect.write is not None:  # a language other than RS-274 writes itself
        return dialect.write(program, blocks)
    return write_rs274(program, dialect, blocks)


def write_rs274(program: Program, dialect: Dialect, blocks: SourceBlocks) -> str:
    """The program's moves and events as RS-274 in `dialect`'s style (`convert`, after its refusals)."""
    return _RS274Writer(program, dialect, blocks).write()


class _RS274Writer:
    """Writes one program's moves and events in an RS-274 dialect, keeping the modal state it has written
    (units, plane, feed, the axes the source has named, the loaded tool) and the words to join to a
    line's next move (a G43 on the line of its move)."""

    def __init__(self, program: Program, dialect: Dialect, blocks: SourceBlocks) -> None:
        self.program, self.dialect, self.block = program, dialect, blocks.__getitem__
        self.out: list[str] = []
        self.seq = 0
        self.inch: bool | None = None
        self.plane: int | None = None
        self.feed: float | None = None
        self.known = [False, False, False]  # axes the source has named: only those are written
        self.tool = -1
        self.prefix: list[tuple[int, str]] = []  # (line, words) to put in front of that line's next move

    def g(self, code: int) -> str:
        return f"G{code:02d}" if self.dialect.trailing_point else f"G{code}"

    def emit(self, words: str) -> None:
        if self.dialect.line_numbers and words and not words.startswith(("(", ";", "%", "O")):
            self.seq += self.dialect.line_numbers
            words = f"N{self.seq} {words}"
        self.out.append(words)

    def comment(self, text: str) -> None:
        clean = text.replace("(", "[").replace(")", "]")
        self.emit(f"({clean})" if self.dialect.comment == "paren" else f"; {clean}")

    def write(self) -> str:
        program, dialect, tp = self.program, self.dialect, self.program.toolpath
        if dialect.percent:
            self.out += ["%", "O1000"]
        self.comment(f"converted by millpost from {program.path} ({program.dialect} to {dialect.name})")
        self.emit(f"{self.g(90)} {self.g(94)} {self.g(17)}")
        events = program.events  # in the order they ran (a line in a loop or subroutine runs again)
        ev, i = 0, 0
        while i < len(tp):
            move_inch = bool(program.move_inch[i])
            if move_inch != self.inch:  # units first: a block's G43 and dwell are read in its units
                self.emit(self.g(20) if move_inch else self.g(21))
                self.inch = move_inch
            ev = self._events_until(events, ev, i)
            line = int(tp.line[i])
            lead = " ".join(w for ln, w in self.prefix if ln == line)
            for ln, w in self.prefix:
                if ln != line:
                    self.emit(w)
            self.prefix.clear()
            i += self._move(i, line, lead)
        for ln, w in self.prefix:
            self.emit(w)
        for e in events[ev:]:
            self._event(e, -1, bool(self.inch))
        if not any(e.kind == "end" for e in program.events):
            self.emit(dialect.end_code)
        if dialect.percent:
            self.out.append("%")
        return "\n".join(self.out) + "\n"

    def _events_until(self, events: list, ev: int, i: int) -> int:
        """Write the events that run before move i (from index ev); returns the next event's index."""
        changed_at = -1  # source line of the tool change just written (its G43 joins that block)
        while ev < len(events) and events[ev].move <= i:
            e = events[ev]
            if e.kind == "tool_length" and int(self.program.toolpath.line[i]) == e.line:
                self.prefix.append((e.line, _tool_length(self.program, self.block(e.line), e.line, self.dialect,
                                                         self.tool, bool(self.program.move_inch[i]), self.g)))
            elif e.kind == "tool_length" and changed_at == e.line:
                self.out[-1] += " " + _tool_length(self.program, self.block(e.line), e.line, self.dialect, self.tool,
                                                   bool(self.program.move_inch[i]), self.g)  # G43 beside M6
            else:
                self._event(e, i, bool(self.program.move_inch[i]))
                if e.kind == "tool_change":
                    self.tool, changed_at = int(e.value), e.line
            ev += 1
        return ev

    def _event(self, e, i: int, inch: bool) -> None:
        """One event in its own block (a tool length change in the target's words)."""
        if e.kind == "tool_length":
            self.emit(_tool_length(self.program, self.block(e.line), e.line, self.dialect, self.tool, inch, self.g))
        else:
            _event(e, self.dialect, self.emit, self.comment, self.g)

    def _number(self, value_mm: float, inch: bool) -> str:
        dec = self.dialect.decimals_inch if inch else self.dialect.decimals_mm
        return self.dialect.number(value_mm / (INCH if inch else 1.0), inch, dec)

    def _move(self, i: int, line: int, lead: str) -> int:
        """Write move i (source line `line`, `lead`: words joined in front); returns the moves it took."""
        tp, src = self.program.toolpath, self.block(line)
        codes = _g_codes(src)
        if 28.0 in codes or 30.0 in codes:
            return self._stored_position(i, 28 if 28.0 in codes else 30, src, lead)
        if 53.0 in codes:
            self._machine_move(i, line, src, lead)
            return 1
        named = {w.letter for w in src.words} & set("XYZ") if src is not None else set()
        moved = np.abs(tp.end[i] - tp.start[i]) > 1e-12
        for a in range(3):
            touched = "XYZ"[a] in named or bool(moved[a])
            if touched and not self.known[a] and self.program.incremental[i]:
                raise _refuse(self.program, line, 1, "", f"an incremental (G91) move of {'XYZ'[a]}, whose position is "
                              "not known (program start, home or G53), has no absolute equivalent",
                              f"an absolute {'XYZ'[a]} move before it")
            self.known[a] = self.known[a] or touched
        inch, kind = bool(self.program.move_inch[i]), int(tp.kind[i])
        words = [f"{'XYZ'[a]}{self._number(tp.end[i, a], inch)}" for a in range(3) if self.known[a]]
        if kind == RAPID:
            self.emit(" ".join(w for w in (lead, self.g(0), *words) if w))
            return 1
        if kind >= ARC_CW and int(tp.plane[i]) != self.plane:
            self.plane = int(tp.plane[i])
            self.emit({0: self.g(17), 1: self.g(18), 2: self.g(19)}[self.plane])
        scale = INCH if inch else 1.0
        f, fw = tp.feed_mm_min[i] / scale, ""
        if self.feed is None or abs(f - self.feed) > 1e-9 * max(1.0, f):
            fw = f" F{self.dialect.number(f, inch, 1 if f >= 10 else 3)}"
            self.feed = f
        if kind >= ARC_CW:
            a1, a2, _ = PLANE_AXES[self.plane]
            start, dec = tp.start[i], self.dialect.decimals_inch if inch else self.dialect.decimals_mm
            # centre relative to the start as it was written, so rounding does not move the centre
            c = [tp.center[i, ax] - round(start[ax] / scale, dec) * scale for ax in (a1, a2)]
            words += [f"{'IJK'[a1]}{self._number(c[0], inch)}", f"{'IJK'[a2]}{self._number(c[1], inch)}"]
            if tp.turns[i]:
                words.append(f"P{int(tp.turns[i]) + 1}")
            self.emit(" ".join(w for w in (lead, self.g(2) if kind == ARC_CW else self.g(3), *words) if w) + fw)
        else:
            self.emit(" ".join(w for w in (lead, self.g(1), *words) if w) + fw)
        return 1

    def _stored_position(self, i: int, code: int, src: Block, lead: str) -> int:
        """G28/G30: to the stored position through the same intermediate point (the source's axes)."""
        inch = bool(self.program.move_inch[i])
        axes = [a for a in range(3) if "XYZ"[a] in {w.letter for w in src.words}]
        words = " ".join(f"{'XYZ'[a]}{self._number(self.program.toolpath.end[i, a], inch)}" for a in axes)
        self.emit(" ".join(w for w in (lead, self.g(code), words) if w))
        for a in axes or range(3):
            self.known[a] = False  # the stored position is the controller's, not the program's
        return 2 if axes else 1

    def _machine_move(self, i: int, line: int, src: Block, lead: str) -> None:
        """G53: the machine coordinates as the source wrote them."""
        tp, inch = self.program.toolpath, bool(self.program.move_inch[i])
        dec = self.dialect.decimals_inch if inch else self.dialect.decimals_mm
        words = []
        for w in src.words:
            if w.letter in "XYZ":
                if any(c in w.text for c in "#["):
                    raise _refuse(self.program, line, w.column, w.text, "G53 with a parameter word cannot be re-posted",
                                  "a number")
                words.append(f"{w.letter}{self.dialect.number(w.value, inch, dec)}")
                self.known["XYZ".index(w.letter)] = False
        motion, fw = (self.g(0), "") if int(tp.kind[i]) == RAPID else (self.g(1), "")
        if int(tp.kind[i]) != RAPID:
            self.feed = tp.feed_mm_min[i] / (INCH if inch else 1.0)
            fw = f" F{self.dialect.number(self.feed, inch, 3)}"
        self.emit(" ".join(w for w in (lead, "G53", motion, *words) if w) + fw)


def _tool_length(program: Program, src: Block | None, line: int, dialect: Dialect, tool: int, inch: bool, g) -> str:
    """The tool length words of source line `line` in the target's form; refused where the target
    has no such code or the words need parameters to be read."""
    if src is None:
        raise _refuse(program, line, 1, "", "tool length compensation with parameter words cannot be re-posted",
                      "G43 H<number>, G43.1 Z<number>, G43.2 H<number> or G49")
    word = next(w for w in src.words if w.letter == "G" and round(w.value, 1) in (43.0, 43.1, 43.2, 49.0))
    code = {43.0: "G43", 43.1: "G43.1", 43.2: "G43.2", 49.0: "G49"}[round(word.value, 1)]
    if code not in dialect.tool_length_codes:
        raise _refuse(program, line, word.column, word.text,
                      f"{dialect.name} has no {code}: tool length compensation would be lost",
                      f"a target that runs it ({code}), or a program without it")
    if code == "G49":
        return g(49)
    args = {w.letter: w for w in src.words if w.letter in "HZK"}
    for w in args.values():
        if any(c in w.text for c in "#["):
            raise _refuse(program, line, w.column, w.text, f"{code} with a parameter word cannot be re-posted",
                          "a number")
    if code == "G43.1":
        w = args.get("Z") or args.get("K")
        return f"G43.1 Z{dialect.number(w.value, inch)}"
    h = int(args["H"].value) if "H" in args else tool
    if h < 0:
        if not dialect.g43_without_h:
            raise _refuse(program, line, word.column, word.text, f"{code} without H and no tool loaded",
                          f"{code} H<tool number>")
        return code
    return f"{g(43)} H{h}" if code == "G43" else f"{code} H{h}"


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
    elif e.kind == "path_mode" and dialect.path_modes:
        name, p, q = e.value
        blend = g(64) + (f" P{p:g}" if p else "") + (f" Q{q:g}" if q is not None else "")
        emit({"exact path": g(61), "exact stop": "G61.1", "blend": blend}[name])


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
