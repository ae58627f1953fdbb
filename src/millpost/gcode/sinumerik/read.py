"""Sinumerik 840D sl / 828D part programs → RS-274/NGC, line for line (`Dialect.translate`).

Section references are to the SINUMERIK 840D sl / 828D "Fundamentals" programming manual (FB) and
"Job planning" manual (AV). What a line means, and its NGC:

- ``;`` comments stay ``;`` comments; ``N10`` / ``:10`` block numbers stay N numbers; ``/`` block skip.
- Units (FB "Inch/metric dimensions"): G710 → G21, G700 → G20 (geometry and feeds). G70/G71 set the
  geometry only, F staying in the machine's basic system, which the program cannot tell: it is taken
  to be the programmed one (as CAM posts intend: Fusion writes G70 with feeds in inch/min), said in a
  note; G70 → G20, G71 → G21.
- G90/G91 modal; per word ``X=AC(..)`` / ``X=IC(..)`` (FB "Absolute/incremental dimensions") through
  the current position (#5420..#5422, program units). G94/G95/G93, G17/G18/G19, G40-G42, G0-G3.
- Arcs (FB "Circular interpolation"): I/J/K incremental from the start (``I=AC(..)``: absolute), or
  ``CR=`` (radius; negative: the arc over 180°) → R; ``TURN=n`` → P(n+1); ``AR=`` and ``CIP`` through
  the start point (`geometry`, `Translator.circle_through`). ``CT`` (FB "Circular interpolation with
  tangential transition", modal): in a program with CT every path move in the plane sets its end
  direction in #<_sin_tx>/#<_sin_ty>/#<_sin_tz>, from which the CT line computes its centre
  (`geometry.tangent_arc`); in G17, G18 and G19.
- Frames (FB "Programmable zero offset", "Programmable rotation", "Programmable scale factor",
  "Programmable mirroring"): TRANS/ATRANS offsets, ROT/AROT about Z in G17, SCALE/ASCALE and
  MIRROR/AMIRROR in X/Y (`geometry`): in a program with these, X/Y, I/J and CR go through
  `Translator.transform`.
- Work offsets (FB "Settable zero offset"): G54-G57 → G54-G57, G505-G508 → G58, G59, G59.1, G59.2,
  G500 (settable offsets off) → G59.3; G53 / SUPA → G53 (that block in machine coordinates).
- Tools (FB "Tool change"): ``T1`` / ``T=1`` / ``T="name"`` (names numbered by first appearance unless
  all digits), M6; D<n> (the edge's length and radius: on) → G43 at the tool change, D0 → G49.
- Path modes (FB "Exact stop", "Continuous-path mode"): G60 → G61, G64/G642-G645 → G64, G641 ADIS=d →
  G64 P<d>, CYCLE832(tol, ...) → G64 P<tol>; G9, G601-G603, SOFT, BRISK, FFWON/FFWOF, CFC/CFTCP/CFIN,
  STOPRE, WORKPIECE(...) are kept as notes (no effect on the path).
- Dwell (FB "Dwell time"): G4 F<s> → G4 P<s>; G4 S<revolutions> → seconds at the last programmed S.
- G74/G75 (reference / fixed point) → a G0 in machine coordinates of the named axes.
- M30, M2, M17 (end) → M30/M2; M0 M1 M3-M9 as written; ``MSG("text")`` → ``(MSG,text)``.
- R parameters and DEF variables, expressions in any value (`syntax`); IF/ELSE/ENDIF, WHILE/ENDWHILE,
  LOOP/ENDLOOP, REPEAT/UNTIL (AV "Program jumps and branches", "Program section repetitions")
  → O-word if/while/do.

The translation keeps what it needs of the modal state (G90/G91 for AC/IC, the plane, G0-G3/CIP, MCALL,
the last S) in the order of the text: a loop or backward jump whose body changes one of them before
a line that depends on it reads that line with the state the text shows there.

- Drilling cycles CYCLE81-86 (`cycles`), immediate or modal with MCALL at each position that follows,
  or at each hole of a HOLES1/HOLES2 pattern (`patterns`, an appended O-sub).
- Subprogram calls (FB "Subprogram technique"): ``NAME [P n]``, ``L<n> [P n]``, ``CALL "NAME"`` in a
  block of their own run NAME.SPF beside the program, appended as an O-sub (`subprograms`).

Anything else is refused with its file:line:column (5-axis transformations, swivel CYCLE800, shop-floor
and pocket cycles, SPOS, subprogram parameters, PCALL/EXTCALL, polar coordinates, system variables, ...).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from ..lexer import source_lines
from ..tool_names import tool_number
from .cycles import CYCLES, FEED_PARAMETER, cycle_words
from .geometry import (DET, FRAME_BASE, FRAMES, PLANES, arc_by_angle, end_tangent, frame_words, framed_centre,
                       framed_point, matrix_words, rotation, tangent_arc)
from .jumps import Jumps, plan
from .patterns import HOLE, PATTERNS, pattern_arguments, pattern_sub
from .subprograms import END, MAX_DEPTH, Registry, Translation, call_of, find, label, proc_header, quoted_call
from .syntax import R_BASE, R_COUNT, Expr, Line, Token, skip, tokens

_WORK_OFFSETS = {54: "G54", 55: "G55", 56: "G56", 57: "G57", 505: "G58", 506: "G59", 507: "G59.1", 508: "G59.2",
                 500: "G59.3"}
_SAME_G = {0, 1, 2, 3, 17, 18, 19, 40, 41, 42, 53, 90, 91, 93, 94, 95}
_PATH_G = {60: "G61", 64: "G64", 642: "G64", 643: "G64", 644: "G64", 645: "G64"}
_NOTE_G = {9: "exact stop in this block", 450: "compensated corners: arcs", 451: "compensated corners: intersection",
           601: "exact stop fine", 602: "exact stop coarse",
           603: "exact stop at interpolator end"}
_NOTE_KEYWORDS = {"SOFT", "BRISK", "DRIVE", "FFWON", "FFWOF", "CFC", "CFTCP", "CFIN", "STOPRE", "TRAFOOF", "G9",
                  "UPATH", "SPATH", "DYNNORM", "DYNPOS", "DYNROUGH", "DYNSEMIFIN", "DYNFINISH", "COMPOF", "COMPON",
                  "COMPCAD", "COMPCURV", "FNORM", "ORIWKS", "ORIMKS", "ORIAXES", "ORIVECT"}
_NOTE_CALLS = {"WORKPIECE"}
_REFUSED = {
    "TRAORI": "5-axis transformation", "TRACYL": "cylinder surface transformation", "TRANSMIT": "end face "
    "transformation", "CYCLE800": "swivel plane", "SPOS": "spindle positioning", "SPOSA": "spindle positioning",
    "PROC": "subprogram definition", "G33": "thread cutting",
    "BSPLINE": "spline interpolation",
    "POLY": "polynomial interpolation", "OFFN": "contour offset",
    "REPEATB": "program section repetition",
    "GOTO": "a jump inside a block (write it alone or after IF)", "GOTOF": "a jump inside a block (write it alone or "
    "after IF)", "GOTOB": "a jump inside a block (write it alone or after IF)", "GOTOC": "a jump inside a block", "FOR": "FOR loop", "CASE": "CASE jump",
    "CALL": "a subprogram call other than CALL \"NAME\" alone", "PCALL": "subprogram call with its path",
    "EXTCALL": "external subprogram call", "RET": "a subprogram return outside a subprogram, or with other words"
}
_FLOW_KEYWORDS = ("IF", "ELSE", "ENDIF", "WHILE", "ENDWHILE", "LOOP", "ENDLOOP", "REPEAT", "UNTIL", "DEF", "GOTOF",
                  "GOTOB", "GOTO", "GOTOC")
# keywords that are commands, never a subprogram's name
_NOT_CALLS = _NOTE_KEYWORDS | set(FRAMES) | set(_REFUSED) | {"MCALL", "SUPA", "CIP", "CT"}
_LABEL = re.compile(r"([A-Za-z_][A-Za-z_][A-Za-z0-9_]*)[ \t]*:(?!=)")
_BLOCK_NUMBER = re.compile(r"(?:[Nn][ \t]*(\d+)|:[ \t]*(\d+))(?![\d.])")
_SIMPLE = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)")


@dataclass
class _Block:
    """The NGC words of one source block, and what its words need from each other."""

    src: Line
    toks: list[Token]
    g: dict[int, Token] = field(default_factory=dict)
    words: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    assigned: dict[str, str] = field(default_factory=dict)  # parameter → its new value's expression

    def word(self, name: str) -> Token | None:
        return next((t for t in self.toks if t.kind == "word" and t.name == name), None)


class Translator:
    """The modal state the translation needs (G90/G91, motion, S, tools, control structures)."""

    def __init__(self, file: str, registry: Registry | None = None, sub: str | None = None) -> None:
        self.file = file
        self.subs = registry or Registry()  # the subprograms called, shared with theirs
        self.sub_name = sub  # the subprogram this translator reads (None: the main program)
        self.fed = sub is None  # an F word has been read (a subprogram's feed moves need their own F)
        self.absolute = True
        self.spindle: str | None = None  # the last S value (NGC text), for G4 S
        self.tools: dict[str, int] = {}
        self.tool_pending = False  # a T selected and no M6 since
        self.length_at_change = False  # a D given before the M6: G43 goes with the M6
        self.names: dict[str, str] = {}
        self.motion = 0  # the modal G0-G3
        self.plane = 17
        self.cip = False  # CIP is the modal motion
        self.ct = False  # CT is the modal motion
        self.tangent: set[str] = set()  # the axes whose tangent parameter (#<_sin_tx>..) a move has set
        self.tracks_tangent = False  # the program has CT: path moves set the tangent parameters
        self.mcall: list[str] | None = None  # the modal drilling cycle's words (MCALL CYCLE8x), None: off
        self.restore_motion = False  # a G74/G75 block wrote G0: the next move names the modal motion again
        self.flow: list[tuple[str, int, Line, int]] = []  # open IF/WHILE/LOOP/REPEAT: (keyword, label, line, col)
        self.labels = 0
        self.jumps = Jumps()
        self.keeps_feed = False  # the program has CYCLE84/85 (their own feed): F values kept in FEED_PARAMETER
        self.feed_restore = False  # a cycle's own feed is in force: the next block restores the programmed F
        self.framed = False  # the program sets a programmable offset: absolute values get #2000.. added
        self.linear = False  # the program rotates, scales or mirrors: X/Y/I/J/CR through the matrix #2003..
        self.mirrored = False  # the program mirrors: G2/G3 and G41/G42 written as swapped when DET < 0
        self.arcs = False  # the program has arcs: a scale must be uniform in X/Y

    def text(self, text: str) -> str:
        """The program's NGC, line for line, and after it the subprograms it calls (`subprograms`)."""
        out = self.lines(text)
        if self.subs.lines:
            ngc = Translation("\n".join(out + self.subs.lines) + "\n")
            ngc.origins = {len(out) + k + 1: where for k, where in self.subs.origins.items()}
            return ngc
        return "\n".join(out) + ("\n" if text.endswith("\n") else "")

    def lines(self, text: str) -> list[str]:
        """The NGC of each line of a program or subprogram."""
        lines = source_lines(text)
        self.jumps = plan(lines, self.file, label(self.sub_name)[1:-1] + "_jump" if self.sub_name else "jump")
        self.linear = self.linear or _has(r"\bA?(?:ROT|SCALE|MIRROR)\b[ \t]*[^\s;]", text)
        self.mirrored = self.mirrored or _has(r"\bAMIRROR\b|\bMIRROR\b[ \t]*[^\s;]", text)
        self.arcs = self.arcs or _has(r"(?<![A-Z0-9_$])(?:G0*[23](?![\d.])|CIP\b|CT\b)", text)
        self.keeps_feed = self.keeps_feed or _has(r"\bCYCLE8[45]\b", text)
        self.framed = self.framed or self.linear or _has(r"\bA?TRANS\b", text)
        self.tracks_tangent = self.tracks_tangent or re.search(r"^[^;\n]*\bCT\b", text, re.I | re.M) is not None
        out = [self.line(Line(raw, n, self.file)) for n, raw in enumerate(lines, 1)]
        if self.flow:
            kw, _, src, col = self.flow[-1]
            raise src.error(f"{kw} without its end", col, kw, {"IF": "ENDIF", "WHILE": "ENDWHILE", "LOOP": "ENDLOOP",
                                                              "REPEAT": "UNTIL"}[kw])
        return out

    def line(self, src: Line) -> str:
        """The NGC of one source line."""
        code_end, comment = split_comment(src)
        text = src.text
        i = skip(text, 0)
        if text[i:i + 1] == "%":
            return f";{text}"
        head = []
        if text[i:i + 1] == "/":
            head.append("/")
            i = skip(text, i + 1)
        m = _BLOCK_NUMBER.match(text, i)
        if m:
            head.append(f"N{m.group(1) or m.group(2)}")
            i = skip(text, m.end())
        m = _LABEL.match(text, i)
        if m and i < code_end:
            i = skip(text, m.end())
        if src.line in self.jumps.at_label:
            head = [h for h in head if h == "/"]
            head.append(self.jumps.at_label[src.line])
        first = re.match(r"[A-Za-z_]+", text[i:code_end])
        code = text[i:code_end].strip()
        if self.sub_name and proc_header(src):
            return f";{text}"
        if first and first.group(0).upper() in _FLOW_KEYWORDS:
            body = self.flow_statement(src, first.group(0).upper(), i, code_end)
        elif quoted_call(code):
            body = self.subprogram(src, quoted_call(code), None, i)
        elif self.sub_name and END.fullmatch(code):
            body = f"o{label(self.sub_name)} return"
        else:
            toks = tokens(src, i, code_end)
            called = call_of(toks) if toks and toks[0].name not in _NOT_CALLS else None
            body = (self.subprogram(src, called[0], called[1], i) if called else
                    self.block(_Block(src, toks)) if toks else "")
        if body.startswith("o") and head:
            head = [h for h in head if h == "/"]  # an O-word line takes no N number
        return " ".join(w for w in (*head, body) if w) + (f" {comment}" if comment and (head or body) else comment)

    # --- blocks -------------------------------------------------------------------------------
    def block(self, b: _Block) -> str:
        for t in b.toks:
            if t.kind == "word" and t.name == "G":
                code = _g_number(b.src, t)
                b.g[code] = t
        if b.toks[0].kind == "keyword" and b.toks[0].name in FRAMES:
            return self.frame(b)
        if b.toks[0].kind == "call" and b.toks[0].name in PATTERNS:
            return self.pattern(b, b.toks[0])
        self.modes(b)
        taken = self.special_arc(b)
        if self.linear and not self.machine_block(b):
            taken |= self.transform(b)
        for t in b.toks:
            if t.name in taken:
                continue
            if t.kind == "word":
                self.address(b, t)
            elif t.kind == "call":
                self.call(b, t)
            else:
                self.keyword(b, t)
        moves = any(t.kind == "word" and t.name in "XYZ" for t in b.toks)
        if self.mcall and moves and not any(t.kind == "keyword" and t.name == "MCALL" for t in b.toks):
            self.at_hole(b)
        elif self.restore_motion and moves and not {0, 1, 2, 3, 74, 75} & set(b.g):
            b.words.insert(0, f"G{self.motion}")
        self.restore_feed(b)
        self.track_tangent(b)
        self.own_feed(b)
        if moves or {74, 75} & set(b.g):
            self.restore_motion = bool({74, 75} & set(b.g))
        for note in b.notes:
            b.words.append("(" + note.replace("(", "[").replace(")", "]") + ")")
        return " ".join(b.words)

    def modes(self, b: _Block) -> None:
        """The block's G codes: modal state first (G90/G91 apply to the block's own words)."""
        for code, t in b.g.items():
            if code == 90:
                self.absolute = True
            elif code == 91:
                self.absolute = False
            if code in (0, 1, 2, 3):
                self.motion = code
            if code in (17, 18, 19):
                self.plane = code
            if code in _SAME_G:
                b.words.append(f"G{code}")
            elif code in _WORK_OFFSETS:
                b.words.append(_WORK_OFFSETS[code])
            elif code in (70, 71, 700, 710):
                b.words.append("G20" if code in (70, 700) else "G21")
                if code in (70, 71):
                    b.notes.append(f"G{code}: feeds taken in {'inch' if code == 70 else 'mm'}/min, the basic system "
                                   "assumed to be the programmed one")
            elif code in _PATH_G:
                b.words.append(_PATH_G[code])
            elif code == 641:
                adis = b.word("ADIS")
                b.words.append(f"G64 P{self.value(b, adis)}" if adis else "G64")
            elif code in _NOTE_G:
                b.notes.append(f"G{code}: {_NOTE_G[code]}")
            elif code in (25, 26):
                b.notes.append(f"G{code}: spindle speed limit")
            elif code in (74, 75):
                b.words.append("G53 G0")
            elif code == 4:
                b.words.append("G4")
            else:
                raise b.src.error(f"G{code} is not read by millpost's Sinumerik reader", t.start, b.src.text[t.start:t.end],
                                  "G0-G4, G9, G17-G19, G25/G26, G40-G42, G53-G57, G60, G64, G641-G645, G70/G71, "
                                  "G74/G75, G90/G91, G93-G95, G500, G505-G508, G601-G603, G700/G710")

    def address(self, b: _Block, t: Token) -> None:
        name, src = t.name, b.src
        if name == "G":
            return
        if name in "XYZ":
            b.words.append(name + self.coordinate(b, t, "XYZ".index(name)))
        elif name in "IJK":
            b.words.append(name + self.centre(b, t, "IJK".index(name)))
        elif name in "ABC":
            b.words.append(name + self.value(b, t))
        elif name == "CR":
            b.words.append("R" + self.value(b, t))
        elif name == "TURN":
            b.words.append(f"P[{self.value(b, t)}+1]")
        elif name == "F":
            self.feed(b, t)
        elif name in ("S", "S1"):
            self.speed(b, t)
        elif name in ("M", "M1") and t.eq or name == "M":
            self.m_code(b, t)
        elif name == "T":
            self.tool(b, t)
        elif name == "D":
            self.edge(b, t)
        elif name in ("ADIS", "ADISPOS", "FP", "DISC"):
            if name in ("ADISPOS", "DISC") or (name == "ADIS" and 641 not in b.g):
                b.notes.append(f"{name}={t.value}")
        elif name == "H":
            b.notes.append(f"H{t.value}: auxiliary function")
        elif t.eq and re.fullmatch(r"R\d+", name) or name in self.names:
            self.assign(b, t)
        else:
            raise src.error(f"address {name} is not read by millpost's Sinumerik reader"
                            + (f" ({_REFUSED[name]})" if _REFUSED.get(name) else ""), t.start,
                            src.text[t.start:t.end], "X Y Z A B C I J K CR TURN F S M T D G H, R parameters, DEF "
                            "variables, ADIS/ADISPOS")

    def expr(self, b: _Block, text_start: int) -> tuple[str, int]:
        out, end = Expr(b.src, self.names).read(text_start)
        for key, new in b.assigned.items():  # values assigned earlier in this block are already set
            out = re.sub(re.escape(key) + r"(?![\d>])", f"[{new}]", out)
        return out, end

    def value(self, b: _Block, t: Token) -> str:
        """A word's value as an NGC word value: the number as written, or [expression]."""
        if _SIMPLE.fullmatch(t.value.strip()):
            return t.value.strip()
        start = t.end - len(t.value)
        if t.value.startswith('"'):
            raise b.src.error(f"{t.name} takes a number, not a string", start, t.value, f"{t.name}=<number>")
        out, end = self.expr(b, start)
        if end != t.end:
            raise b.src.error(f"unexpected text in the value of {t.name}", end, b.src.text[end:t.end], "an expression")
        return f"[{out}]"

    def coordinate(self, b: _Block, t: Token, axis: int) -> str:
        """An axis value in the workpiece frame: the programmable offset (TRANS/ATRANS, #2000..) added to
        an absolute value; AC()/IC() written in the other distance mode go through the current position."""
        mode = re.match(r"(AC|IC)[ \t]*\(", t.value, re.IGNORECASE) if t.eq else None
        absolute = self.absolute if not mode else mode.group(1).upper() == "AC"
        value = self.inner(b, t, mode) if mode else self.value(b, t)
        if absolute and self.framed and not self.machine_block(b):
            value = f"[{value}+#{FRAME_BASE + axis}]"
        if absolute == self.absolute:
            return value if not mode or value.startswith("[") else f"[{value}]"
        pos = f"#{5420 + axis}"
        return f"[{value}-{pos}]" if absolute else f"[{pos}+[{value}]]"

    def centre(self, b: _Block, t: Token, axis: int) -> str:
        """An arc centre offset, incremental from the start (I=AC(..): the absolute centre)."""
        mode = re.match(r"(AC|IC)[ \t]*\(", t.value, re.IGNORECASE) if t.eq else None
        if not mode:
            return self.value(b, t)
        inner = self.inner(b, t, mode)
        if mode.group(1).upper() == "IC":
            return f"[{inner}]"
        frame = f"+#{FRAME_BASE + axis}" if self.framed else ""
        return f"[[{inner}]{frame}-#{5420 + axis}]"

    def machine_block(self, b: _Block) -> bool:
        """G53/SUPA/G74/G75: machine coordinates, no frame."""
        return bool({53, 74, 75} & set(b.g)) or any(t.kind == "keyword" and t.name == "SUPA" for t in b.toks)

    def inner(self, b: _Block, t: Token, mode: re.Match) -> str:
        start = t.end - len(t.value) + mode.end()
        out, end = self.expr(b, start)
        if b.src.text[skip(b.src.text, end):skip(b.src.text, end) + 1] != ")" or skip(b.src.text, end) + 1 != t.end:
            raise b.src.error(f"unexpected text in {mode.group(1)}(...)", end, b.src.text[end:t.end],
                              f"{mode.group(1)}(<expression>)")
        return out

    def feed(self, b: _Block, t: Token) -> None:
        """F: the feed (kept as written), or with G4 the dwell in seconds."""
        if 4 in b.g:
            b.words.append(f"P{self.value(b, t)}")
        else:
            b.words.append(f"F{self.value(b, t)}")
            if self.keeps_feed:
                b.words.append(f"{FEED_PARAMETER}={self.value(b, t)}")

    def speed(self, b: _Block, t: Token) -> None:
        if 25 in b.g or 26 in b.g:
            return
        if 4 in b.g:
            if self.spindle is None:
                raise b.src.error("dwell in spindle revolutions before any spindle speed", t.start, t.value,
                                  "G4 F<seconds>, or an S word before this G4 S")
            b.words.append(f"P[60*[{self.value(b, t)}]/[{self.spindle}]]")
            return
        self.spindle = self.value(b, t)
        b.words.append(f"S{self.spindle}")

    def m_code(self, b: _Block, t: Token) -> None:
        value = self.value(b, t)
        if not value.isdigit():
            raise b.src.error("M function with a computed value", t.start, t.value, "M<integer>")
        code = int(value)
        if self.sub_name and code in (2, 17, 30):
            raise b.src.error(f"M{code} ends the subprogram: in a block of its own", t.start, b.src.text[t.start:t.end],
                              f"M{code} alone on its line")
        if code == 17:
            b.words.append("M2")
            b.notes.append("M17: end")
            return
        b.words.append(f"M{code}")
        if code == 6:
            self.tool_pending = False
            if self.length_at_change:
                b.words.append("G43")
                self.length_at_change = False

    def tool(self, b: _Block, t: Token) -> None:
        if t.value.startswith('"'):
            name = t.value[1:-1]
            number = tool_number(name, self.tools)
            b.words.append(f"T{number}")
            b.notes.append(f"tool {name} = T{number}")
        else:
            b.words.append(f"T{self.value(b, t)}")
        self.tool_pending = True

    def edge(self, b: _Block, t: Token) -> None:
        """D<n>: the tool's edge offsets on (length: G43), D0: off (G49)."""
        value = self.value(b, t)
        if value in ("0", "00"):
            b.words.append("G49")
        elif self.tool_pending and not any(x.kind == "word" and x.name == "M" and x.value == "6" for x in b.toks):
            self.length_at_change = True
        elif "G43" not in b.words:
            b.words.append("G43")

    def assign(self, b: _Block, t: Token) -> None:
        r = re.fullmatch(r"R(\d+)", t.name)
        if r and int(r.group(1)) >= R_COUNT:
            raise b.src.error(f"R parameter {t.name} out of range", t.start, t.name, f"R0 ... R{R_COUNT - 1}")
        key = f"#{R_BASE + int(r.group(1))}" if r else self.names[t.name]
        value = self.value(b, t)
        b.words.append(f"{key}={value}")
        b.assigned[key] = value

    def frame(self, b: _Block) -> str:
        """TRANS/ATRANS X Y Z (alone in their block), ROT/AROT (`rotation`), SCALE/ASCALE/MIRROR/AMIRROR
        (`scaling`), or a frame cleared (`geometry.frame_words`)."""
        kind, rest = b.toks[0], b.toks[1:]
        if kind.name in ("ROT", "AROT") and rest:
            return self.rotation(b, kind, rest)
        if kind.name not in ("TRANS", "ATRANS", "ROT", "AROT") and rest:
            return self.scaling(b, kind, rest)
        if kind.name not in ("TRANS", "ATRANS") and rest:
            raise b.src.error(f"{kind.name} with values: rotation, scaling and mirroring frames are not modelled",
                              kind.start, b.src.text[kind.start:rest[-1].end],
                              "TRANS/ATRANS offsets, ROT/AROT RPL=.., or ROT/SCALE/MIRROR alone (frame cleared)")
        for t in rest:
            if not (t.kind == "word" and t.name in "XYZ"):
                raise b.src.error(f"{kind.name} takes axis offsets only, in a block of its own", t.start,
                                  b.src.text[t.start:t.end], f"{kind.name} X.. Y.. Z..")
        words = frame_words(kind.name, {t.name: self.value(b, t) for t in rest}, self.linear)
        if words is None:
            raise b.src.error(f"{kind.name} alone does not say which frame", kind.start, kind.name,
                              "TRANS/ATRANS X.. Y.. Z.., or TRANS/ROT/SCALE/MIRROR alone (frame cleared)")
        return " ".join(words)

    def rotation(self, b: _Block, kind: Token, rest: list[Token]) -> str:
        """ROT/AROT RPL=a in G17, or ROT/AROT Z a (FB "Programmable rotation (ROT, AROT)"): a rotation about
        Z by a degrees (counter-clockwise seen from +Z). ROT replaces the programmable frame (its offsets
        cleared), AROT is composed after it (about its origin). Other axes, and other planes, are refused."""
        t = rest[0]
        if len(rest) > 1 or t.kind != "word" or t.name not in ("RPL", "Z") or self.plane != 17:
            t = rest[1] if len(rest) > 1 and t.kind == "word" and t.name in ("RPL", "Z") else t
            raise b.src.error(f"{kind.name}: only a rotation about Z in G17 is modelled", t.start,
                              b.src.text[t.start:t.end], f"G17 and {kind.name} RPL=<degrees> or {kind.name} Z<degrees>"
                              " alone in the block")
        return " ".join(matrix_words(kind.name, rotation(self.value(b, t))))

    def scaling(self, b: _Block, kind: Token, rest: list[Token]) -> str:
        """SCALE/ASCALE X.. Y.. (FB "Programmable scale factor (SCALE, ASCALE)": factors along the frame's
        X/Y, 1 where not given; uniform when the program has arcs) and MIRROR/AMIRROR X0 Y0 (FB
        "Programmable mirroring (MIRROR, AMIRROR)": the named axes flipped, their values ignored) as a
        matrix (`geometry.matrix_words`). Z factors and Z mirroring are refused."""
        factors = {}
        for t in rest:
            if t.kind != "word" or t.name not in "XY":
                raise b.src.error(f"{kind.name} {t.name}: only X and Y are modelled", t.start,
                                  b.src.text[t.start:t.end], f"{kind.name} X.. Y.. alone in the block")
            factors[t.name] = "-1" if kind.name.endswith("MIRROR") else self.value(b, t)
        if kind.name.endswith("SCALE") and self.arcs and factors.get("X") != factors.get("Y"):
            raise b.src.error(f"{kind.name} with different X and Y factors in a program with arcs: not modelled",
                              kind.start, b.src.text[kind.start:rest[-1].end], f"{kind.name} X<f> Y<f> (equal)")
        if any(f in ("0", "0.", "0.0") for f in factors.values()):
            raise b.src.error(f"{kind.name} with a factor 0", kind.start, kind.name, "factors other than 0")
        return " ".join(matrix_words(kind.name, (factors.get("X", "1"), "0", "0", factors.get("Y", "1"))))

    def programmed(self, b: _Block, t: Token, absolute: bool) -> tuple[str, bool]:
        """A word's value as written (AC(..)/IC(..) unwrapped) and whether it is absolute (`absolute`:
        the mode without AC/IC)."""
        mode = re.match(r"(AC|IC)[ \t]*\(", t.value, re.IGNORECASE) if t.eq else None
        if mode:
            return self.inner(b, t, mode), mode.group(1).upper() == "AC"
        return self.value(b, t), absolute

    def transform(self, b: _Block) -> set[str]:
        """In a program with rotation, scaling or mirroring: the block's X/Y end point, I/J centre and CR
        from the frame into the workpiece frame (`geometry.framed_point`, `framed_centre`; CR times the
        scale); G2/G3 and G41/G42 swapped while the frame mirrors (`swap`); the tokens taken."""
        xy = {t.name: self.programmed(b, t, self.absolute) for t in b.toks if t.kind == "word" and t.name in "XY"}
        ij = {t.name: self.programmed(b, t, False) for t in b.toks if t.kind == "word" and t.name in "IJ"}
        arc = self.motion in (2, 3) and not self.mcall and not any(t.kind == "call" for t in b.toks)
        if arc and self.plane != 17 and (xy or ij or b.word("Z") or b.word("K")):
            t = next(t for t in b.toks if t.kind == "word" and t.name in "XYZIJK")
            raise b.src.error(f"an arc in G{self.plane} in a program with ROT/SCALE/MIRROR: not modelled", t.start,
                              b.src.text[t.start:t.end], "arcs in G17")
        cr = b.word("CR")
        self.swap(b, arc and bool(xy or ij or cr))
        if xy:
            b.words.extend(framed_point(xy, self.absolute))
        if ij:
            b.words.extend(framed_centre(ij))
        if cr is not None:
            b.words.append(f"R[{self.value(b, cr)}*SQRT[ABS[{DET}]]]")
        return set(xy) | set(ij) | ({"CR"} if cr is not None else set())

    def swap(self, b: _Block, arc: bool) -> None:
        """In a program with mirroring: G2/G3 (written in every arc block, the frame may change between
        them) and G41/G42 as computed G words that swap while the frame's determinant is negative."""
        if not self.mirrored:
            return
        b.words = [w for w in b.words if w not in ("G2", "G3")]
        if arc:
            b.words.insert(0, f"G[{self.motion}{'+' if self.motion == 2 else '-'}[{DET} LT 0]]")
        b.words = [f"G[{w[1:]}{'+' if w == 'G41' else '-'}[{DET} LT 0]]" if w in ("G41", "G42") else w
                   for w in b.words]

    def special_arc(self, b: _Block) -> set[str]:
        """An arc by opening angle (AR=) or through an intermediate point (CIP, modal until G0-G3): its
        words written; the names of the tokens it took."""
        (p1, p2), (c1, c2) = PLANES[self.plane]
        if {0, 1, 2, 3} & set(b.g):
            self.cip = self.ct = False
        ct = next((t for t in b.toks if t.kind == "keyword" and t.name == "CT"), None)
        if ct is not None or self.ct and not any(t.kind == "keyword" and t.name == "CIP" for t in b.toks) and any(
                t.kind == "word" and t.name in "XYZ" for t in b.toks):
            self.not_linear(b, "CT")
            self.tangential(b, ct)
            self.ct, self.cip = True, False
            return {p1, p2, "CT"}
        if b.word("AR") is not None:
            self.not_linear(b, "AR")
            self.opening_angle(b)
            return {p1, p2, c1, c2, "AR"}
        if any(t.kind == "keyword" and t.name == "CIP" for t in b.toks) or self.cip and any(
                t.kind == "word" and t.name in "XYZ" for t in b.toks):
            self.not_linear(b, "CIP")
            self.circle_through(b)
            self.cip, self.ct = True, False
            return {p1, p2, f"{c1}1", f"{c2}1", "CIP"}
        return set()

    def not_linear(self, b: _Block, what: str) -> None:
        """CT, AR= and CIP are refused in a program with rotation, scaling or mirroring (not modelled)."""
        if self.linear:
            t = next((t for t in b.toks if t.name == what), b.toks[0])
            raise b.src.error(f"{what} in a program with ROT/SCALE/MIRROR: not modelled", t.start, b.src.text[t.start:t.end],
                              "G2/G3 with I/J or CR= under a rotation, scale or mirror")

    def circle_through(self, b: _Block) -> None:
        """CIP (FB "Circular interpolation with intermediate and end points (CIP)"): the circle through the
        start, the intermediate point (I1=, J1=, K1=: absolute in G90, from the start in G91) and the end,
        in the active plane; clockwise (G2) when the three points turn clockwise. The centre, relative to
        the start P0 with B = P1 - P0 and C = P2 - P0: ((Cy|B|² - By|C|²), (Bx|C|² - Cx|B|²)) / 2(BxCy - ByCx)."""
        (p1, p2), (c1, c2) = PLANES[self.plane]
        normal = next(a for a in "XYZ" if a not in (p1, p2))
        off_plane = [t for t in b.toks if t.kind == "word" and t.name in (normal, "IJK"["XYZ".index(normal)] + "1")]
        if off_plane:
            t = off_plane[0]
            raise b.src.error("CIP out of the active plane: a circle in space is not modelled", t.start,
                              b.src.text[t.start:t.end], f"{p1}, {p2} and {c1}1=, {c2}1= only (G{self.plane})")
        rel = {}
        for name, axis in ((p1, p1), (p2, p2), (f"{c1}1", p1), (f"{c2}1", p2)):
            t = b.word(name)
            k = "XYZ".index(axis)
            v = self.coordinate(b, t, k) if t is not None else None
            rel[name] = "0" if v is None else f"[{v}-#{5420 + k}]" if self.absolute else v
        if b.word(f"{c1}1") is None and b.word(f"{c2}1") is None:
            raise b.src.error("CIP without its intermediate point", 0, b.src.text.strip()[:40],
                              f"{c1}1= and {c2}1= (the intermediate point)")
        bx, by, cx, cy = rel[f"{c1}1"], rel[f"{c2}1"], rel[p1], rel[p2]
        cross = f"[{bx}*{cy}-{by}*{cx}]"
        bb, cc = f"[{bx}*{bx}+{by}*{by}]", f"[{cx}*{cx}+{cy}*{cy}]"
        b.words.append(f"G[2+[{cross} GT 0]]")
        b.words.extend(f"{a}{self.coordinate(b, b.word(a), 'XYZ'.index(a))}" for a in (p1, p2) if b.word(a))
        b.words.append(f"{c1}[[{cy}*{bb}-{by}*{cc}]/[2*{cross}]]")
        b.words.append(f"{c2}[[{bx}*{cc}-{cx}*{bb}]/[2*{cross}]]")

    def tangential(self, b: _Block, ct: Token | None) -> None:
        """CT (FB "Circular interpolation with tangential transition (CT)", modal like G2/G3/CIP): the arc
        from the current point to the end point, tangent at its start to the previous path element, whose
        end direction the tangent parameters hold (`track_tangent`); `geometry.tangent_arc`."""
        (p1, p2), (c1, c2) = PLANES[self.plane]
        at = ct or next(t for t in b.toks if t.kind == "word" and t.name in "XYZ")
        if not {p1, p2} <= self.tangent:
            raise b.src.error(f"CT with no path element in the {p1}/{p2} plane before it to be tangent to", at.start,
                              at.name, f"a G1/G2/G3/CIP/CT move along {p1}/{p2} before the CT")
        extra = [t for t in b.toks if t.kind == "word" and t.name in (c1, c2, "CR", "AR", "TURN", "I1", "J1", "K1")]
        if extra:
            t = extra[0]
            raise b.src.error(f"{t.name} in a CT block: the tangent alone sets the arc", t.start,
                              b.src.text[t.start:t.end], f"CT {p1}.. {p2}.. (the end point only)")
        ends = {a: self.coordinate(b, b.word(a), "XYZ".index(a)) for a in (p1, p2) if b.word(a)}
        b.words.extend(tangent_arc(self.plane, ends, self.absolute))

    def track_tangent(self, b: _Block) -> None:
        """After a path move in the active plane (G0-G3, CIP, CT), its end direction in the plane's axes,
        set in #<_sin_tx>/#<_sin_ty>/#<_sin_tz> for a CT that follows (`geometry.end_tangent`). Moves
        along the plane's normal alone, cycles and machine-coordinate moves leave it as it was."""
        (p1, p2), _ = PLANES[self.plane]
        in_plane = any(t.kind == "word" and t.name in (p1, p2) for t in b.toks)
        cycle = any(w.startswith("G8") for w in b.words) or any(t.kind == "call" and t.name in CYCLES for t in b.toks)
        if not self.tracks_tangent or not in_plane or cycle or self.machine_block(b):
            return
        b.words.extend(end_tangent(self.plane, b.words, self.absolute, self.motion if not (self.cip or self.ct)
                                   else None))
        self.tangent |= {p1, p2}

    def opening_angle(self, b: _Block) -> None:
        """G2/G3 with AR=: from its end point or from its centre, not both (`geometry.arc_by_angle`)."""
        ar = b.word("AR")
        (p1, p2), (c1, c2) = PLANES[self.plane]
        if self.motion not in (2, 3):
            raise b.src.error("AR= outside a G2/G3 arc", ar.start, b.src.text[ar.start:ar.end], "G2 or G3 with AR=")
        ends = {t.name: self.coordinate(b, t, "XYZ".index(t.name)) for t in b.toks
                if t.kind == "word" and t.name in (p1, p2)}
        centre = {t.name: self.centre(b, t, "IJK".index(t.name)) for t in b.toks
                  if t.kind == "word" and t.name in (c1, c2)}
        if bool(ends) == bool(centre):
            raise b.src.error("AR= needs the end point or the centre, and not both", ar.start,
                              b.src.text[ar.start:ar.end], f"G{self.motion} {p1}.. {p2}.. AR=.. or G{self.motion} "
                              f"{c1}.. {c2}.. AR=..")
        b.words.extend(arc_by_angle(self.plane, self.value(b, ar), self.motion == 3, self.absolute, ends, centre))

    def restore_feed(self, b: _Block) -> None:
        """A block that runs CYCLE84/85 (their own feed, immediate or at a MCALL position) leaves that
        feed in force: the next block without an F of its own sets the programmed F again
        (FEED_PARAMETER); in the order of the text."""
        programmed = b.word("F") is not None and 4 not in b.g
        if any(w.startswith("F") for w in b.words) and not programmed:
            self.feed_restore = True
        elif programmed:
            self.feed_restore = False
        elif self.feed_restore:
            b.words.append(f"F[{FEED_PARAMETER}]")
            self.feed_restore = False

    def at_hole(self, b: _Block) -> None:
        """A position block under MCALL: the move to the hole and the modal cycle (the hole's Z is the
        cycle's, so a Z word is refused; the positioning is at rapid, as the canned cycle's)."""
        z = b.word("Z")
        if z is not None:
            raise b.src.error("Z in a position block of a modal drilling cycle", z.start, b.src.text[z.start:z.end],
                              "X and Y only (the cycle's planes set Z)")
        b.words = [w for w in b.words if w not in ("G0", "G1")] + self.mcall
        self.restore_motion = True

    def pattern(self, b: _Block, t: Token) -> str:
        """HOLES1/HOLES2 (`patterns`), alone in their block under MCALL in G90: the modal cycle at each
        hole, the holes through the frame (TRANS, ROT, ...) as any position; an O-sub appended and called."""
        if len(b.toks) > 1 or self.mcall is None or not self.absolute:
            raise b.src.error(f"{t.name} outside a modal drilling cycle, in G91 or with other words", t.start,
                              t.name, f"MCALL CYCLE8x(..), then {t.name}(..) alone in its block in G90")
        values = pattern_arguments(b.src, t, lambda at: self.expr(b, at))
        x, y = HOLE
        if self.linear:
            hole = framed_point({"X": (x, True), "Y": (y, True)}, True)
        else:
            hole = [f"X[{x}+#{FRAME_BASE}]", f"Y[{y}+#{FRAME_BASE + 1}]"] if self.framed else [f"X{x}", f"Y{y}"]
        self.labels += 1
        name = f"<sin_pattern_{self.labels}>"
        self.subs.lines += pattern_sub(name, hole + self.mcall)
        self.subs.origins.update({len(self.subs.lines) - k: (self.file, b.src.line) for k in range(7)})
        self.restore_motion = True
        self.feed_restore = self.feed_restore or any(w.startswith("F") for w in self.mcall)
        return f"o{name} call " + " ".join(f"[{v}]" if not v.startswith("[") else v for v in values)

    def drill(self, b: _Block, t: Token) -> None:
        """CYCLE81-86: modal after MCALL (run at each following position), else at the current point."""
        if self.plane != 17:
            raise b.src.error(f"{t.name} outside G17", t.start, t.name, "drilling along Z (G17)")
        words = cycle_words(b.src, t, lambda at: self.expr(b, at), f"#{FRAME_BASE + 2}" if self.framed else None,
                            self.spindle)
        modal = any(x.kind == "keyword" and x.name == "MCALL" for x in b.toks)
        if modal:
            self.mcall = words
            b.notes.append(f"MCALL {t.name}: at each position that follows")
        else:
            b.words.extend(words)
            self.restore_motion = True
        b.notes.append(f"{t.name}: retract to the start level [RTP when positioned there]")

    def call(self, b: _Block, t: Token) -> None:
        if t.name in CYCLES:
            self.drill(b, t)
        elif t.name == "MSG":
            text = t.value.strip()
            text = text[1:-1] if len(text) >= 2 and text[0] == text[-1] == '"' else text
            b.notes.append("MSG," + text)
        elif t.name == "CYCLE832":
            tol = t.value.split(",")[0].strip()
            b.words.append(f"G64 P{tol}" if _SIMPLE.fullmatch(tol) and float(tol) > 0 else "G64")
            b.notes.append(f"CYCLE832({t.value})")
        elif t.name in _NOTE_CALLS or t.name == "CYCLE800" and not t.value.strip():
            b.notes.append(f"{t.name}: noted" if t.name in _NOTE_CALLS else "CYCLE800: swivel reset")
        else:
            self.refuse(b, t)

    def keyword(self, b: _Block, t: Token) -> None:
        if t.name == "MCALL":
            if not any(x.kind == "call" for x in b.toks):
                if self.mcall is not None:
                    b.words.append("G80")
                    self.restore_motion = True
                self.mcall = None
        elif t.name in _NOTE_KEYWORDS:
            b.notes.append(t.name)
        elif t.name in FRAMES:
            raise b.src.error(f"{t.name} must be in a block of its own", t.start, t.name, f"{t.name} X.. Y.. Z.. alone "
                              "on its line (FB: frame instructions take a block of their own)")
        elif t.name == "SUPA":
            if "G53" not in b.words:
                b.words.append("G53")
        else:
            self.refuse(b, t)

    def refuse(self, b: _Block, t: Token) -> None:
        why = _REFUSED.get(t.name) or ("a cycle or subprogram call" if t.kind == "call" else "an unknown command or "
                                       "a subprogram call")
        raise b.src.error(f"{t.name}: {why}, which millpost does not read", t.start,
                          b.src.text[t.start:t.end][:40], "moves, arcs, tool and spindle words, R parameters, "
                          "IF/WHILE/LOOP/REPEAT, CYCLE832, MSG")

    # --- subprograms ---------------------------------------------------------------------------
    def subprogram(self, src: Line, name: str, runs: Token | None, at: int) -> str:
        """A call by name (`subprograms`): the subprogram translated at its first call, in this call's
        modal state, which its end state then replaces; the NGC call (through a repeating sub with P)."""
        if runs is not None and not (runs.value.isdigit() and 1 <= int(runs.value) <= 9999):
            raise src.error("P of a subprogram call is its number of runs", runs.start, src.text[runs.start:runs.end],
                            "P1 ... P9999")
        if name in self.subs.stack or name == self.sub_name:
            raise src.error(f"subprogram {name} calls itself (recursion is not read)", at, name, "calls that end")
        if len(self.subs.stack) + 1 >= MAX_DEPTH:
            raise src.error(f"subprograms nested more than {MAX_DEPTH - 1} deep", at, name, "fewer levels")
        state = (self.absolute, self.plane)
        if name not in self.subs.state:
            path = find(name, self.file)
            if path is None:
                raise src.error(f"subprogram {name} not found: no {name}.SPF nor _N_{name}_SPF beside the program "
                                f"(in {path_folder(self.file)})", at, name, f"the file {name}.SPF beside the program")
            self.subs.state[name] = (state, self.run_subprogram(name, path))
        first, end = self.subs.state[name]
        if end[7][2] and not self.keeps_feed:
            raise src.error(f"subprogram {name} has CYCLE84/85 (their own feed) and this program has none: the "
                            "programmed F to restore after them is not known", at, name,
                            "CYCLE84/85 in the main program too, or none")
        if end[7][0] and not self.linear or end[7][1] and not self.mirrored:
            raise src.error(f"subprogram {name} rotates, scales or mirrors and this program does not: not modelled",
                            at, name, "ROT/SCALE/MIRROR in the main program too, or none")
        if end[6] and not self.framed:
            raise src.error(f"subprogram {name} sets a frame (TRANS/ATRANS) and this program has none: not modelled",
                            at, name, "TRANS/ATRANS in the main program too, or none")
        if first != state:
            raise src.error(f"subprogram {name} called in another mode than at its first call ({_mode(state)}, "
                            f"first {_mode(first)}): its translation is the first call's", at, name, _mode(first))
        self.absolute, self.plane, self.motion, self.cip, self.ct = end[:5]
        self.tangent |= end[5]
        self.feed_restore = end[7][3]  # the subprogram ends with a cycle's own feed in force
        n = int(runs.value) if runs is not None else 1
        return f"o{label(name) if n == 1 else self.subs.repeated(name, n)} call"

    def run_subprogram(self, name: str, path: Path) -> tuple:
        """Translate the subprogram file (its errors name it) and append it; its modal state at the end."""
        data = path.read_bytes()
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError:
            text = data.decode("latin-1")
        child = Translator(str(path), self.subs, name)
        child.absolute, child.plane, child.motion, child.cip, child.ct = (self.absolute, self.plane, self.motion,
                                                                         self.cip, self.ct)
        child.tangent, child.framed, child.tracks_tangent = set(self.tangent), self.framed, self.tracks_tangent
        child.linear, child.mirrored, child.arcs = self.linear, self.mirrored, self.arcs
        child.keeps_feed, child.feed_restore = self.keeps_feed, self.feed_restore
        child.spindle, child.tools, child.names, child.labels, child.mcall = (self.spindle, self.tools, self.names,
                                                                              self.labels, self.mcall)
        self.subs.stack.append(name)
        body = child.lines(text)
        self.subs.stack.pop()
        self.subs.add(name, str(path), body)
        self.labels, self.mcall = child.labels, child.mcall
        return (child.absolute, child.plane, child.motion, child.cip, child.ct, child.tangent, child.framed,
                (child.linear, child.mirrored, child.keeps_feed, child.feed_restore))

    def own_feed(self, b: _Block) -> None:
        """In a subprogram, a feed move before any F word of it is refused (`subprograms`: its moves keep
        their programmed feeds, which the caller's F, changed by optimizing, would not be)."""
        if self.fed:
            return
        if b.word("F") is not None and 4 not in b.g:
            self.fed = True
            return
        moves = any(t.kind == "word" and t.name in "XYZ" for t in b.toks)
        feeding = moves and (self.motion in (1, 2, 3) or self.cip or self.ct or self.mcall) and not (
            0 in b.g) or any(t.kind == "call" and t.name in CYCLES for t in b.toks)
        if feeding:
            t = b.toks[0]
            raise b.src.error("a feed move of a subprogram before any F of its own: its feed would be the caller's",
                              t.start, b.src.text[t.start:t.end], "an F word in the subprogram before its first "
                              "feed move (its moves keep the feeds its file programs)")

    # --- control flow -------------------------------------------------------------------------
    def flow_statement(self, src: Line, kw: str, i: int, end: int) -> str:
        """IF/ELSE/ENDIF, WHILE/ENDWHILE, LOOP/ENDLOOP, REPEAT/UNTIL as O words; DEF as assignments."""
        rest = skip(src.text, i + len(kw))
        if kw == "DEF":
            return self.define(src, rest, end)
        if kw.startswith("GOTO"):
            return self.jump(src, "1", i)
        if kw in ("IF", "WHILE", "UNTIL"):
            cond, j = Expr(src, self.names).read(rest)
            j = skip(src.text, j)
            if kw == "IF" and src.text[j:j + 4].upper() == "GOTO":
                return self.jump(src, cond, j)
            if j != end:
                raise src.error("unexpected text after the condition", j, src.text[j:end][:40], "a condition alone, "
                                "or IF <condition> GOTOF/GOTOB <label>")
        elif rest != end:
            raise src.error(f"unexpected text after {kw}", rest, src.text[rest:end][:40], f"{kw} alone on its line")
        if kw in ("IF", "WHILE", "LOOP", "REPEAT"):
            self.labels += 1
            self.flow.append((kw, self.labels, src, i))
            if kw == "LOOP":
                return f"o{self.labels} while [1]"
            return f"o{self.labels} do" if kw == "REPEAT" else f"o{self.labels} {kw.lower()} [{cond}]"
        opener = {"ELSE": "IF", "ENDIF": "IF", "ENDWHILE": "WHILE", "ENDLOOP": "LOOP", "UNTIL": "REPEAT"}[kw]
        if not self.flow or self.flow[-1][0] != opener:
            raise src.error(f"{kw} without {opener}", i, kw, f"{kw} closing the innermost open {opener}"
                            if not self.flow else f"the end of {self.flow[-1][0]} first")
        label = self.flow[-1][1]
        if kw == "ELSE":
            return f"o{label} else"
        self.flow.pop()
        if kw == "UNTIL":
            return f"o{label} while [[{cond}] EQ 0]"
        return f"o{label} endif" if kw == "ENDIF" else f"o{label} endwhile"

    def jump(self, src: Line, cond: str, at: int) -> str:
        """[IF cond] GOTOx label: the structure `jumps.plan` laid out (forward: skip while not cond)."""
        if src.line not in self.jumps.at_jump:
            raise src.error("a jump without its label", at, src.text[at:at + 20].strip(), "GOTOF/GOTOB/GOTO <label>, "
                            "the only text after IF <condition>")
        kind, label = self.jumps.at_jump[src.line]
        return f"o{label} if [[{cond}] EQ 0]" if kind == "if" else f"o{label} while [{cond}]"

    def define(self, src: Line, i: int, end: int) -> str:
        """DEF REAL/INT/BOOL name[=value], ...: each variable set (0 when no value is given)."""
        m = re.match(r"(REAL|INT|BOOL)\b", src.text[i:end], re.IGNORECASE)
        if not m:
            raise src.error("DEF of a type millpost does not model", i, src.text[i:end][:20], "DEF REAL, DEF INT or "
                            "DEF BOOL")
        out, k = [], skip(src.text, i + m.end())
        while k < end:
            name = re.match(r"[A-Za-z_][A-Za-z0-9_]*", src.text[k:end])
            if not name:
                raise src.error("expected a variable name", k, src.text[k:end][:20], "DEF REAL NAME[=value], ...")
            var, k = name.group(0).upper(), skip(src.text, k + name.end())
            if re.fullmatch(r"R\d+", var) or src.text[k:k + 1] == "[":
                raise src.error("a DEF name must not be an R parameter nor an array", k, var, "a plain name")
            value = "0"
            if src.text[k:k + 1] == "=":
                value, k = Expr(src, self.names).read(k + 1)
                k = skip(src.text, k)
            self.names[var] = f"#<_v_{var.lower()}>"
            out.append(f"{self.names[var]}={value if _SIMPLE.fullmatch(value) else f'[{value}]'}")
            if src.text[k:k + 1] == ",":
                k = skip(src.text, k + 1)
            elif k < end:
                raise src.error("unexpected text in DEF", k, src.text[k:end][:20], "',' or the end of the line")
        return " ".join(out)


def split_comment(src: Line) -> tuple[int, str]:
    """(end of the code, the ';' comment as written or '') — a ';' in a string is not a comment."""
    i, text = 0, src.text
    if '"' not in text:
        i = text.find(";")
        return (len(text), "") if i < 0 else (i, text[i:])
    while i < len(text):
        if text[i] == '"':
            end = text.find('"', i + 1)
            i = len(text) if end < 0 else end + 1
            continue
        if text[i] == ";":
            return i, text[i:]
        i += 1
    return len(text), ""


def path_folder(file: str) -> str:
    return str(Path(file).parent)


def _mode(state: tuple) -> str:
    return f"G{90 if state[0] else 91} G{state[1]}"


def _has(pattern: str, text: str) -> bool:
    """Whether the program's code (outside ';' comments) matches `pattern` on some line."""
    return re.search(r"^[^;\n]*" + pattern, text, re.I | re.M) is not None


def _g_number(src: Line, t: Token) -> int:
    if not re.fullmatch(r"\d+", t.value):
        raise src.error("G code with a computed or fractional value", t.start, src.text[t.start:t.end], "G<integer>")
    return int(t.value)


def translate(text: str, file: str) -> str:
    """A Sinumerik program as RS-274/NGC, line for line (`Dialect.translate`)."""
    return Translator(file).text(text)
