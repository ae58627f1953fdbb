"""Writing the compensated program: only the X/Y/Z words of the moved moves change, and a split line's
later points are new lines in its style (its motion word as written, its letter case and spacing); every
other byte is the program's. Numbers take the line's own decimals, at least 3 in mm (1 µm) and 4 in inch
(2.5 µm), and its way of writing whole numbers.

Refused, naming the line: a program read through a translation (Sinumerik, Heidenhain) or with O-word
control flow (a line may run several times at other positions); coordinate offsets set in the program
(G92, G52, G10) or rotated and scaled frames (G68, G51), where a word's value is not the point; and on a
moved line: several moves (a canned cycle, G28), cutter radius compensation (the controller offsets the
words again), incremental distance mode, a computed word (a parameter or an expression), an arc with an
absolute centre (G90.1: its I J K would have to move).
"""

from __future__ import annotations

import re

import numpy as np

from ..emit.write import (LineWriter, UnknownParameters, computed, format_number, line_decimals, line_trailing_point,
                          program_spaced, program_trailing_point)
from ..errors import MillpostError
from ..gcode.interpret import INCH, Program
from ..gcode.lexer import lex_line, source_lines
from ..toolpath import ARC_CW
from .path import MoveOffsets

_FRAME = re.compile(r"(?<![A-Za-z])[Gg]\s*0*(92|52|10|68|51)(?![\d])")
_AXES = "XYZ"


def _code(text: str) -> str:
    return re.sub(r"\([^)\n]*\)|;[^\n]*", "", text)


def check_writable(program: Program) -> None:
    """Refuse a program whose words compensate cannot move as points (see the module docstring)."""
    if program.source is not None:
        raise MillpostError(f"{program.path}: compensate writes RS-274 programs; a {program.dialect} program "
                            "(read through a translation) is not supported: convert it first (millpost convert)")
    if program.control_flow:
        raise MillpostError(f"{program.path}: O-word control flow (a line may run several times at other "
                            "positions) is not supported by compensate")
    for n, body in enumerate(source_lines(program.text), start=1):
        m = _FRAME.search(_code(body))
        if m:
            raise MillpostError(f"{program.path}:{n}:{m.start() + 1}: {m.group(0).strip()} sets a coordinate "
                                "offset or frame; compensate needs the words to be the points (program frame)")


def _check_line(program: Program, n: int, moves: list[int], block) -> None:
    tp = program.toolpath
    i = moves[0]
    why = ("it runs several moves (a canned cycle or G28)" if len(moves) > 1 else
           "it runs under cutter radius compensation (G41/G42)" if program.compensated[i] else
           "it is in incremental distance mode (G91)" if program.incremental[i] else
           "a word is computed (a parameter or an expression)" if computed(block) else
           "the arc's centre is absolute (G90.1)" if tp.kind[i] >= ARC_CW and program.arc_absolute[i] else None)
    if why:
        raise MillpostError(f"{program.path}:{n}: compensate cannot move this line's points: {why}")


def write_offsets(program: Program, plan: dict[int, MoveOffsets]) -> str:
    """The program's text with each planned move written at its programmed points plus the offsets."""
    check_writable(program)
    tp = program.toolpath
    lines = source_lines(program.text, keepends=True)
    on_line: dict[int, list[int]] = {}
    for i in np.flatnonzero(np.isin(tp.line, [int(tp.line[m]) for m in plan])):
        on_line.setdefault(int(tp.line[i]), []).append(int(i))
    default_trailing = program_trailing_point(program)
    spaced = program_spaced(program)
    end_off = {i: mo.offset_mm[-1] for i, mo in plan.items()}
    for n, moves in sorted(on_line.items()):
        raw = lines[n - 1]
        body = raw.rstrip("\r\n")
        block = lex_line(body, n, program.path, UnknownParameters())  # a computed word: refused by name below
        _check_line(program, n, moves, block)
        i = moves[0]
        mo = plan[i]
        inch = bool(program.move_inch[i])
        scale = INCH if inch else 1.0
        decimals = max(line_decimals(block, 0), 4 if inch else 3)
        trailing = line_trailing_point(block, default_trailing)
        writer = LineWriter(body, block, spaced)
        named = {w.letter for w in block.words if w.letter in _AXES}
        points = tp.points(np.full(len(mo.u), i), mo.u) + mo.offset_mm
        in_force = tp.start[i] + end_off.get(i - 1, np.zeros(3))
        texts = []
        for k, point in enumerate(points):
            words = {}
            for ax, letter in enumerate(_AXES):
                text = format_number(point[ax] / scale, decimals, trailing)
                if (k == 0 and letter in named) or abs(float(text) * scale - in_force[ax]) > 0.5 * 10**-decimals * scale:
                    words[letter] = text
            in_force = np.array([float(words[L]) * scale if L in words else in_force[ax] for ax, L in enumerate(_AXES)])
            texts.append(words)
        out = [writer.replace(texts[0])]
        g_word = next((w.text.strip() for w in block.words if w.letter == "G" and round(w.value) == 1), None)
        for words in texts[1:]:
            parts = ([g_word] if g_word else []) + [(L.lower() if writer.lower else L) + t for L, t in words.items()]
            out.append(writer.sep.join(parts))
        ending = raw[len(body):] or "\n"
        lines[n - 1] = ending.join(out) + raw[len(body):]
    return "".join(lines)
