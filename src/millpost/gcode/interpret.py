"""The modal state machine: lexed blocks → `Program` (moves as a `Toolpath` in mm, plus events).

Semantics follow LinuxCNC 2.9's interpreter (the project's oracle, `rs274 -g`), with the
controller-specific differences that matter to a CAM post taken from the dialect (Fanuc/Haas G76
fine boring and G87 back boring, dwell P in milliseconds, ...). Positions are program coordinates
(after G5x, G92 and G52 offsets), as LinuxCNC's canonical trace reports them. Everything a CAM post
may write and that moves the machine is either interpreted or refused with file:line:column.
"""

from __future__ import annotations

import math
import re
from array import array
from dataclasses import dataclass, field

import numpy as np

from ..errors import ParseError
from ..toolpath import ARC_CCW, ARC_CW, FEED, PLANE_AXES, RAPID, Toolpath
from .cutter_comp import LEFT, RIGHT, CompensationError, CutterComp
from .dialects import Dialect
from .feed_mode import FeedMode
from .flow import MAX_REPEATED_LINES, Flow, Source, control_of
from .lexer import LENGTH_LIMIT, NUMBER_LIMIT, Block, Word, lex_line
from .tool_table import read_tool_table

INCH = 25.4
# G codes as integers: round(value * 10)
_MOTION = {0, 10, 20, 30, 730, 740, 760, 810, 820, 830, 840, 850, 860, 870, 880, 890}
_CYCLES = {730, 740, 760, 810, 820, 830, 840, 850, 860, 870, 880, 890}
TAPPING_CYCLES = (740, 840)  # the feed is the tap's pitch times the spindle speed (synchronised)
BORING_CYCLES = (760, 850, 860, 870, 880, 890)  # the feed sets the finish of the bore
_MODAL_GROUPS = {
    **{g: "motion" for g in _MOTION | {800}},
    170: "plane", 180: "plane", 190: "plane", 200: "units", 210: "units", 900: "distance", 910: "distance",
    901: "arc distance", 911: "arc distance", **dict.fromkeys(map(int, FeedMode), "feed mode"),
    **{g: "cutter comp" for g in (400, 410, 420, 411, 421)}, 430: "tool length", 431: "tool length",
    432: "tool length", 490: "tool length", 980: "retract", 990: "retract",
    **{g: "coordinate system" for g in (540, 550, 560, 570, 580, 590, 591, 592, 593)},
    610: "path", 611: "path", 640: "path", 40: "non-modal", 100: "non-modal", 280: "non-modal",
    281: "non-modal", 300: "non-modal", 301: "non-modal", 520: "non-modal", 530: "non-modal",
    920: "non-modal", 921: "non-modal", 922: "non-modal", 923: "non-modal",
}
_UNSUPPORTED_G = {
    50: "spline (G5)", 51: "spline (G5.1)", 52: "NURBS (G5.2)", 53: "NURBS (G5.3)", 70: "lathe diameter mode (G7)",
    80: "lathe radius mode (G8)", 120: "circular pocket (G12)", 130: "circular pocket (G13)",
    150: "polar coordinates (G15)", 160: "polar coordinates (G16)", 310: "skip function (G31)",
    330: "spindle-synchronised motion (G33)", 331: "rigid tapping (G33.1)", 382: "probing (G38.2)",
    383: "probing (G38.3)", 384: "probing (G38.4)", 385: "probing (G38.5)", 434: "5-axis tool centre point (G43.4)",
    435: "5-axis tool centre point (G43.5)", 500: "scaling (G50)", 510: "scaling (G51)", 501: "mirroring (G50.1)",
    511: "mirroring (G51.1)", 650: "macro call (G65)", 680: "coordinate rotation (G68)",
    682: "5-axis tilted work plane (G68.2)", 700: "lathe cycle (G70; inch units on some older controls: write G20)",
    710: "lathe cycle (G71; millimetre units on some older controls: write G21)", 720: "lathe cycle (G72)",
    960: "constant surface speed (G96)", 1000: "user G code",
}
MAX_CYCLE_MOVES = 100_000  # one canned-cycle block (repeats x pecks)
MAX_CYCLE_MOVES_TOTAL = 1_000_000  # all canned cycles of a program
_TAKE_AXES = {100, 280, 300, 520, 920}  # non-modal codes whose axis words are not a move
# M-code modal groups (LinuxCNC): two codes of one group in a block are an error
_M_GROUPS = {**dict.fromkeys((0, 1, 2, 30, 60), "stopping"), 6: "tool change", 61: "tool change",
             **dict.fromkeys((3, 4, 5, 19), "spindle"), **dict.fromkeys((7, 8, 9), "coolant"),
             **dict.fromkeys((48, 49, 50, 51, 52, 53), "override")}
# M codes this reader knows (stops, tool change, spindle, coolant, overrides, I/O, modal state, ...): an
# M code outside them and outside M100-M199 (user commands) is passed through with a note
_M_KNOWN = frozenset((0, 1, 2, 30, 3, 4, 5, 6, 7, 8, 9, 29, 19, 48, 49, 50, 51, 52, 53, 60, 61, 62, 63, 64, 65, 66, 67,
                      68, 70, 71, 72, 73))
_CHECKED = frozenset("DEHIJKLPQR")  # words a block may only carry when one of its codes reads them
_WORD_USERS = {
    "D": "D only with G41/G42 (cutter radius compensation)", "E": "E only with M66/M67/M68",
    "H": "H only with G43 or G43.2", "I": "I only with G2/G3, G87 or G10", "J": "J only with G2/G3, G87 or G10",
    "K": "K only with G2/G3 or G87", "L": "L only with a canned cycle, G10, G41/G42 or M98",
    "P": "P only with G2/G3 (turns), G4, G10, G64, G82/G84/G86/G88/G89 (dwell), M98 or M19/M50-M66",
    "Q": "Q only with G73/G83 (peck), G10, G64 or M19/M66-M68", "R": "R only with G2/G3, a canned cycle or G10",
}
_LATHE_G76 = "threading cycle G76 (LinuxCNC's G76 is a lathe threading cycle)"
_AXES = "XYZ"
_NO_CENTRE = (math.nan, math.nan, math.nan)
_FAST = re.compile(r"[ \t]*(?:[Gg]0?([01])(?![0-9.])[ \t]*)?((?:[XYZFxyzf][ \t]*[-+]?(?:\d+\.?\d*|\.\d+)[ \t]*)+)")
_FAST_WORD = re.compile(r"([XYZFxyzf])[ \t]*([-+]?(?:\d+\.?\d*|\.\d+))")
_ROTARY = "ABCUVW"
_FEED_MODES = tuple(FeedMode)
_PER_MINUTE = FeedMode.PER_MINUTE  # the fast path's test, once a line: no enum attribute lookup


@dataclass
class ReaderOptions:
    """What the program alone cannot say: the machine frame and how to treat unknowns.

    home_g28_mm / home_g30_mm: G28/G30 home in machine coordinates (mm); None = unknown.
    work_offsets_mm: G54..G59.3 offsets by index 1..9 (machine mm); unknown ones are zero.
    machine_frame_known: whether machine coordinates (G53) are meaningful. When False (the usual case
    for a post step), a Z-only move to home or to a machine coordinate (Fusion's ``G28 G91 Z0.``,
    Haas's ``G53 G0 Z0.``) goes to `safe_z_mm` in the program frame — by default the highest Z the
    program reaches — and the assumption is reported in `Program.notes`.
    tool_lengths_mm: tool lengths by H number for G43 (unknown: 0, so Z is the tool tip).
    tool_diameters_mm: tool diameters by tool number for cutter compensation (G41/G42 D); a program that
    compensates with a tool whose diameter is not given is refused.
    dialect: name of the controller dialect (None: detect from the text).
    loaded_tool: the tool in the spindle when the program starts (a job that describes one tool): the
    moves made before any T word selects a tool run with it (said in `Program.notes`); None: no tool
    is loaded, those moves have tool -1.
    block_delete: when True, lines starting with '/' are skipped (switch on); default off, as LinuxCNC.
    """

    home_g28_mm: tuple[float, float, float] | None = None
    home_g30_mm: tuple[float, float, float] | None = None
    work_offsets_mm: dict[int, tuple[float, float, float]] = field(default_factory=dict)
    machine_frame_known: bool = False
    tool_lengths_mm: dict[int, float] = field(default_factory=dict)
    tool_diameters_mm: dict[int, float] = field(default_factory=dict)
    safe_z_mm: float | None = None
    dialect: str | None = None
    block_delete: bool = False
    loaded_tool: int | None = None

    def use_tool_table(self, path, units: str = "mm") -> "ReaderOptions":
        """Tool lengths (G43) and diameters (G41/G42) from a LinuxCNC tool table file in `units`. Lathe
        tools (a nose orientation 1..8) are left out of the diameters: compensating with one is refused."""
        table = read_tool_table(path, units)
        self.tool_lengths_mm = table.lengths_mm
        self.tool_diameters_mm = {n: d for n, d in table.diameters_mm.items() if table.orientation[n] in (0, 9)}
        return self

    @classmethod
    def for_tools(cls, diameters_mm: dict[int, float], dialect: str | None = None) -> "ReaderOptions":
        """Options for a job's tools (diameters in mm by tool number, for cutter compensation): when it
        describes exactly one tool, that tool is the one loaded before any T word."""
        only = next(iter(diameters_mm)) if len(diameters_mm) == 1 else None
        return cls(dialect=dialect, tool_diameters_mm=dict(diameters_mm), loaded_tool=only)

    @classmethod
    def linuxcnc(cls) -> "ReaderOptions":
        """The frame LinuxCNC's standalone interpreter assumes: homes and offsets at machine zero."""
        return cls(home_g28_mm=(0.0, 0.0, 0.0), home_g30_mm=(0.0, 0.0, 0.0), machine_frame_known=True,
                   dialect="linuxcnc")


@dataclass
class Event:
    """A non-motion action at a block: tool change, spindle, coolant, dwell, stop, comment, ...
    ("s_word": an S word's speed in rpm, whether or not the spindle runs)."""

    line: int
    kind: str
    value: object = None
    move: int = 0  # moves run before it: its place in the order of execution


@dataclass
class Program:
    """An interpreted program. Moves in mm in the program frame; `text` is the source, untouched, or
    for a dialect read through a translation (`Dialect.translate`) its RS-274 translation, line for
    line, with the source in `source`.

    units: units as programmed, in order of first appearance ("mm", "inch"). Per move, as modal state
    when it ran (for writing it back): move_inch (G20), feed_mode (a `FeedMode` value, 930/940/950 for
    G93/G94/G95), incremental (G91), arc_absolute (G90.1), compensated (G41/G42: the toolpath is the tool
    centre, not the programmed path), cycle (the canned cycle that ran it, its G code × 10: 810 for G81,
    840 for G84; 0 for other moves).
    notes: assumptions made (unknown home, rotary axes at zero, ...), each naming its line.
    """

    path: str
    text: str
    toolpath: Toolpath
    dialect: str
    blocks: int
    units: list[str]
    move_inch: np.ndarray
    feed_mode: np.ndarray
    incremental: np.ndarray
    arc_absolute: np.ndarray
    events: list[Event]
    notes: list[str]
    dwell_s: float
    compensated: np.ndarray  # per move: offset by cutter compensation (its end is not the programmed point)
    cycle: np.ndarray  # per move: the canned cycle's G code × 10, 0 outside cycles
    control_flow: bool = False  # O-word subroutines or loops: a line may run several times
    source: str | None = None  # the text as written, when `text` is its translation

    @property
    def tools(self) -> list[int]:
        """Tools that cut or moved, in order of first use."""
        seen: list[int] = []
        for t in self.toolpath.tool.tolist():
            if t >= 0 and t not in seen:
                seen.append(t)
        return seen

    @property
    def spindle_rpm(self) -> list[float]:
        seen: list[float] = []
        for e in self.events:
            if e.kind == "spindle" and e.value[1] > 0 and e.value[1] not in seen:
                seen.append(e.value[1])
        return seen


def _arc_length(start, end, center, axes, ccw: bool, turns: int) -> float:
    """Helix length (mm), the same closed form as `Toolpath.lengths` for one arc."""
    a1, a2, an = axes
    r0 = math.hypot(start[a1] - center[a1], start[a2] - center[a2])
    r1 = math.hypot(end[a1] - center[a1], end[a2] - center[a2])
    t0 = math.atan2(start[a2] - center[a2], start[a1] - center[a1])
    t1 = math.atan2(end[a2] - center[a2], end[a1] - center[a1])
    sweep = (t1 - t0) % (2 * math.pi) if ccw else (t0 - t1) % (2 * math.pi)
    if abs(sweep) <= 1e-12:
        sweep = 2 * math.pi
    sweep += 2 * math.pi * turns
    return math.hypot(0.5 * (r0 + r1) * sweep, end[an] - start[an])


class _Moves:
    """Growable compact columns for the toolpath: per move 11 floats (start, end, centre, feed, rpm)
    and 10 ints (kind, plane, turns, tool, line, block, inch, feed mode, G91, G90.1) in two
    array.arrays — 124 bytes a move, no Python objects, two appends."""

    def __init__(self) -> None:
        self.f = array("d")
        self.i = array("i")

    def __len__(self) -> int:
        return len(self.i) // 10

    def to_arrays(self) -> tuple[Toolpath, np.ndarray]:
        """The toolpath (views over the float buffer, no copy) and the (n, 10) int columns."""
        f = (np.frombuffer(self.f, float) if len(self.f) else np.zeros(0)).reshape(-1, 11)
        i = (np.frombuffer(self.i, np.int32) if len(self.i) else np.zeros(0, np.int32)).reshape(-1, 10)
        tp = Toolpath(kind=i[:, 0].astype(np.int8), start=f[:, 0:3], end=f[:, 3:6], center=f[:, 6:9],
                      plane=i[:, 1].astype(np.int8), turns=i[:, 2], feed_mm_min=f[:, 9], rpm=f[:, 10], tool=i[:, 3],
                      line=i[:, 4], block=i[:, 5])
        return tp, i


class _Codes:
    """One block's codes and words as its steps read them (`Interpreter.execute`): the G codes (code × 10,
    word) and their set, the M codes and their set, the other words by letter, the G word of each modal
    group; then the axis words (after polar coordinates), whether a non-modal code used them, and the
    block's motion code (G80 included), set by the steps that find them."""

    __slots__ = ("block", "g", "gset", "mcodes", "mset", "val", "groups", "axis_words", "consumed_axes",
                 "motion_code")

    def __init__(self, block: Block) -> None:
        self.block = block
        self.g: list[tuple[int, Word]] = []
        self.gset: set[int] = set()
        self.mcodes: list[tuple[int, Word]] = []
        self.mset: set[int] = set()
        self.val: dict[str, Word] = {}
        self.groups: dict[str, Word] = {}
        self.axis_words: dict[str, Word] = {}
        self.consumed_axes = False
        self.motion_code: int | None = None


class _StepTable:
    """The steps of a block in order, each with what wakes it: G codes ("G93", "G59.1"), M codes ("M6"),
    word letters ("S"), any G or any M code ("G*", "M*") or every block ("*"). A block runs the steps its
    codes and words wake, in table order (`woken_by`); the others would do nothing. Iterating the table
    gives all its steps."""

    def __init__(self, *entries: tuple) -> None:
        self.steps = tuple(step for step, _ in entries)
        self.wakes = {step.__name__: wake.split() for step, wake in entries}
        self.g: dict[int, int] = {}  # G code (× 10) -> bit mask of the steps it wakes
        self.m: dict[int, int] = {}  # M code -> bit mask
        self.words: dict[str, int] = {}  # word letter -> bit mask
        self.every = self.any_g = self.any_m = 0
        for i, (_, wake) in enumerate(entries):
            bit = 1 << i
            for token in wake.split():
                if token == "*":
                    self.every |= bit
                elif token == "G*":
                    self.any_g |= bit
                elif token == "M*":
                    self.any_m |= bit
                elif token[0] == "G":
                    code = round(float(token[1:]) * 10)
                    self.g[code] = self.g.get(code, 0) | bit
                elif token[0] == "M":
                    self.m[int(token[1:])] = self.m.get(int(token[1:]), 0) | bit
                else:
                    self.words[token] = self.words.get(token, 0) | bit
        self.plans: dict[int, tuple] = {}  # bit mask -> its steps, in order

    def __iter__(self):
        return iter(self.steps)

    def woken_by(self, k: _Codes) -> tuple:
        """The steps the block's codes and words wake, in table order."""
        mask = self.every
        if k.gset:
            mask |= self.any_g
            for code in k.gset:
                mask |= self.g.get(code, 0)
        if k.mset:
            mask |= self.any_m
            for code in k.mset:
                mask |= self.m.get(code, 0)
        for L in k.val:
            mask |= self.words.get(L, 0)
        plan = self.plans.get(mask)
        if plan is None:
            plan = self.plans[mask] = tuple(step for i, step in enumerate(self.steps) if mask >> i & 1)
        return plan


class Interpreter:
    """Runs blocks through the modal state. Use `read_program` / `read_text` rather than this directly."""

    def __init__(self, options: ReaderOptions, file: str, dialect: Dialect) -> None:
        self.opt, self.file, self.dialect = options, file, dialect
        self.m = _Moves()
        self.cycle_runs: list[tuple[int, int, int]] = []  # (first move, end, G code × 10)
        self.events: list[Event] = []
        self.notes: list[str] = []
        self.params: dict = {"_value": 0.0, "_value_returned": 0.0}  # LinuxCNC's predefined return value
        self.units_seen: list[str] = []
        # modal state
        self.scale = 1.0  # mm per program unit
        self.absolute = True
        self.arc_absolute = False
        self.plane = 0
        self.motion: int | None = None
        self.basic_motion: int | None = None  # last G0-G3 (Fanuc returns to it after G80)
        self.feed_mode = FeedMode.PER_MINUTE
        self.f = 0.0  # mm per minute (G94) or per rev (G95), as set; G93 uses the block's own F
        self.s = 0.0
        self.spindle_on = False
        self.tool = -1
        self.selected = -1
        self.assumed_tool = False  # the tool is `ReaderOptions.loaded_tool`, not one the program chose
        self.assumed_from = 0  # the first move made with it
        self.retract_old_z = dialect.starts_g98
        self.cs = 1
        self.g5x = {i: np.array(v, float) for i, v in options.work_offsets_mm.items()}
        self.g92 = np.zeros(3)
        self.tlo = 0.0  # tool length offset, mm
        self.g92_saved = np.zeros(3)
        self._pos: np.ndarray | None = np.zeros(3)  # program frame, mm (see `pos`)
        self._xyz: tuple[float, float, float] | None = None
        self.rotary = {a: 0.0 for a in _ROTARY}
        self.cycle: dict = {}
        self.polar_step: tuple[float, float] | None = None
        self.cycle_il = None
        self.cycle_moves = 0.0  # moves made by canned cycles so far (bounded by MAX_CYCLE_MOVES_TOTAL)
        self.blocks = 0
        self.dwell_s = 0.0
        self.block_index = 0
        self.ended = False
        self.safe_z_pending = False
        self.control_flow = False  # O-word control flow ran: lines may run more than once
        self.subprogram: tuple[str, str, int] | None = None  # M98/M99 of the block being executed
        self.comp = CutterComp(self.record, self.m.__len__)

    # --- helpers ----------------------------------------------------------------------------
    def err(self, msg: str, block: Block, word: Word | None, expected: str) -> ParseError:
        col = word.column if word is not None else 1
        return ParseError(msg, file=self.file, line=block.line, column=col,
                          word=word.text if word is not None else "", expected=expected)

    def event(self, line: int, kind: str, value: object = None) -> None:
        self.events.append(Event(line, kind, value, len(self.m) + self.comp.pending))

    def pending_scale(self, b: Block) -> float:
        """mm per unit for words of this block: a G20/G21 in the same block applies first."""
        for w in b.words:
            if w.letter == "G" and round(w.value * 10) in (200, 210):
                return INCH if round(w.value * 10) == 200 else 1.0
        return self.scale

    def offset(self) -> np.ndarray:
        """Program frame origin in machine coordinates: G5x + G92/G52 + tool length (on Z)."""
        return self.g5x.get(self.cs, np.zeros(3)) + self.g92 + np.array([0.0, 0.0, self.tlo])

    def emit(self, kind: int, end, block: Block, center=(math.nan,) * 3, turns: int = 0,
             feed_mm_min: float = math.nan) -> None:
        if self.tool < 0:
            self.take_loaded(block.line)
        if self.comp.active:
            self.comp.move(kind, self.pos, end, center, turns, feed_mm_min, block.line, self.modal())
        else:
            self.record(kind, self.pos.tolist(), end, center, turns, feed_mm_min, block.line)
        self.pos = np.array(end, float)

    def take_loaded(self, line: int) -> None:
        """A move with no tool changed in: the selected tool (T without M6) is the one in the spindle,
        else the job's only tool (`ReaderOptions.loaded_tool`) when no T word came before."""
        if self.selected >= 0:
            self.tool = self.selected
            self.notes.append(f"line {line}: T{self.selected} selected without M6: taken as loaded")
        elif self.opt.loaded_tool is not None:
            self.tool, self.assumed_tool, self.assumed_from = self.opt.loaded_tool, True, len(self.m)
            self.notes.append(f"line {line}: the program moves before any T word selects a tool: "
                              f"T{self.tool}, the job's only tool, taken as loaded")

    def drop_assumed_tool(self) -> None:
        """A T word after moves made with the assumed tool: if none of them fed (rapids to a safe
        height before the first tool change, Fusion's G28), they had no tool after all (tool -1, as
        without the assumption) and the note goes; moves that cut keep the job's tool."""
        moves = range(self.assumed_from, len(self.m))
        if all(self.m.i[10 * k] == RAPID for k in moves):
            for k in moves:
                self.m.i[10 * k + 3] = -1
            self.notes.pop(next(j for j in range(len(self.notes) - 1, -1, -1)
                                if "the job's only tool, taken as loaded" in self.notes[j]))
        self.tool, self.assumed_tool = -1, False

    def feed_rate(self, block: Block, length_mm: float) -> float:
        """Programmed feed of a move in mm/min from the modal F and feed mode."""
        if self.feed_mode == FeedMode.INVERSE_TIME:
            if self._f_this_block is None:
                raise self.err("inverse-time feed mode (G93) needs an F word on every feed move", block, None,
                               "an F word on this line")
            return length_mm * self._f_this_block
        if self.f <= 0:
            raise self.err("feed move with no feed rate set", block, None, "an F word before or on this line")
        if self.feed_mode == FeedMode.PER_REV:
            if self.s <= 0:
                raise self.err("feed per revolution (G95) with no spindle speed", block, None, "an S word")
            return self.f * self.s
        return self.f

    # --- blocks -----------------------------------------------------------------------------
    def run(self, text: str) -> None:
        percent_seen = 0
        pos, size, line_no = 0, len(text), 0  # one line at a time: no list of lines, no copy of the text
        source: Source | None = None  # lines by number, from the first control statement (or M98) on
        flow: Flow | None = None

        def start_flow() -> Flow:
            nonlocal source, flow
            if flow is None:
                source = Source(text, line_no, pos)
                flow = Flow(source, self.file, self.params)
            return flow

        while True:
            if source is None:  # straight-line reading, no bookkeeping per line
                if pos >= size:
                    break
                end = text.find("\n", pos)
                end = size if end < 0 else end
                raw = text[pos:end].rstrip("\r")
                pos = end + 1
                line_no += 1
            else:
                raw = source.next()
                if raw is None:
                    break
                line_no = source.line
            if self.ended:
                if raw.strip() and raw.strip() != "%":
                    if (control_of(raw) or ("", ""))[1] != "sub":  # subroutines after the end run when called
                        self.notes.append(f"line {line_no}: after program end (M2/M30): not executed")
                    break
                continue
            if source is not None and source.repeats > MAX_REPEATED_LINES:
                raise ParseError(f"loops and calls read more than {MAX_REPEATED_LINES:,} lines again", file=self.file,
                                 line=line_no, column=1, word=raw.strip()[:40],
                                 expected=f"loops that end within {MAX_REPEATED_LINES:,} repeated lines")
            if self.fast_line(raw, line_no):
                continue
            control = control_of(raw)
            if control is not None:
                if not (raw.lstrip().startswith("/") and self.opt.block_delete):
                    start_flow().statement(raw, *control)
                    self.control_flow = True
                continue
            if "#542" in raw:
                self.position_parameters()
            block = lex_line(raw, line_no, self.file, self.params)
            if block.percent:
                percent_seen += 1
                if percent_seen == 2:
                    break
                continue
            if block.block_delete and self.opt.block_delete:
                continue
            if block.words or block.assigns:
                self.blocks += 1
                try:
                    self.execute(block)
                except CompensationError as e:
                    raise self.comp_error(e, block) from None
                self.block_index += 1
                if self.subprogram is not None:  # M98 / M99, after the rest of the block
                    kind, label, repeats = self.subprogram
                    self.subprogram = None
                    self.control_flow = True
                    if kind == "call":
                        start_flow().call_subprogram(label, repeats, raw)
                    elif not start_flow().return_subprogram():  # M99 in the main program ends it
                        self.event(line_no, "end", 2)
                        self.notes.append(f"line {line_no}: M99 in the main program: taken as its end")
                        self.ended = True
            for c in block.comments:
                if c:
                    self.event(line_no, "comment", c)
            for key, value in block.assigns:
                self.params[key] = value

    def position_parameters(self) -> None:
        """#5420-#5422 (LinuxCNC): the current point in program coordinates and units, set before a
        line that reads them."""
        for axis, value in enumerate(self.pos):
            self.params[5420 + axis] = float(value) / self.scale

    def modal(self) -> tuple:
        """The modal state a move records: rpm, plane, tool, block, inch, feed mode, G91, G90.1."""
        return (self.s if self.spindle_on else 0.0, self.plane, self.tool, self.block_index, self.scale != 1.0,
                self.feed_mode, not self.absolute, self.arc_absolute)

    def record(self, kind: int, start, end, center, turns: int, feed_mm_min: float, line: int,
               modal: tuple | None = None) -> None:
        """Append one move with the modal state it ran in (now, or `modal` when it was held back)."""
        rpm, plane, tool, block, inch, feed_mode, incremental, arc_absolute = modal or self.modal()
        self.m.f.extend((start[0], start[1], start[2], end[0], end[1], end[2], center[0], center[1], center[2],
                         feed_mm_min, rpm))
        self.m.i.extend((kind, plane, turns, tool, line, block, inch, feed_mode, incremental, arc_absolute))

    def fast_line(self, raw: str, line_no: int) -> bool:
        """The common block of CAM output — an optional G0/G1 then X/Y/Z/F words — without building
        words or touching numpy. Returns False (the general path runs) for anything else."""
        m = _FAST.fullmatch(raw)
        if m is None or self.feed_mode != _PER_MINUTE or self.comp.active:
            return False
        g, body = m.groups()
        motion = self.motion if g is None else (0 if g == "0" else 10)
        if motion != 0 and motion != 10:
            return False
        words = _FAST_WORD.findall(body.upper())
        value_of = dict(words)
        if len(value_of) != len(words):  # a letter twice: the general path says why
            return False
        x, y, z = start = self._xyz if self._xyz is not None else tuple(self._pos.tolist())
        f = self.f
        sc = self.scale
        for L, text in words:
            value = float(text)
            if L == "F":
                if not 0.0 <= value <= NUMBER_LIMIT:
                    return False
                f = value * sc
            elif not -LENGTH_LIMIT <= value <= LENGTH_LIMIT:  # the general path says why
                return False
            elif self.absolute:
                if L == "X":
                    x = value * sc
                elif L == "Y":
                    y = value * sc
                else:
                    z = value * sc
            elif L == "X":
                x += value * sc
            elif L == "Y":
                y += value * sc
            else:
                z += value * sc
        if motion == 10 and f <= 0:
            return False
        self.f = f
        if g is not None:
            self.motion = self.basic_motion = motion
            self.cycle_il = None
        self.blocks += 1
        if len(words) > ("F" in value_of) or g is not None:
            self.emit_xyz(RAPID if motion == 0 else FEED, start, x, y, z, line_no, math.nan if motion == 0 else f)
        self.block_index += 1
        return True

    def emit_xyz(self, kind: int, start: tuple, x: float, y: float, z: float, line: int, feed_mm_min: float) -> None:
        """Append a straight move from the current point `start` (floats, mm) — the fast path's `emit`.
        The position stays a tuple until the general path reads it (`pos`): no numpy per line."""
        if self.tool < 0:
            self.take_loaded(line)
        self.record(kind, start, (x, y, z), _NO_CENTRE, 0, feed_mm_min, line)
        self._xyz, self._pos = (x, y, z), None

    @property
    def pos(self) -> np.ndarray:
        """The current point (program frame, mm)."""
        if self._pos is None:
            self._pos = np.array(self._xyz)
        return self._pos

    @pos.setter
    def pos(self, value: np.ndarray) -> None:
        self._pos, self._xyz = value, None

    def execute(self, b: Block) -> None:
        """Run one block as LinuxCNC does: its words sorted and checked (`block_codes`, `check_words`),
        then the steps of `STEPS` in turn, in the order of execution of the LinuxCNC G-code overview
        ("G-code overview: order of execution"; O words and comments are `run`'s). A step the block's
        codes and words do not wake would do nothing and is not called (`_StepTable.woken_by`)."""
        k = self.block_codes(b)
        self.check_words(b, k.val, k.gset, k.mcodes)
        for step in self.STEPS.woken_by(k):
            step(self, k)

    def block_codes(self, b: Block) -> _Codes:
        """The block's words sorted: G codes, M codes and the other words by letter, each refused where
        LinuxCNC refuses it (an unknown or unsupported G code, two codes of one modal group, a letter twice)."""
        k = _Codes(b)
        for w in b.words:
            L = w.letter
            if L == "G":
                self.add_g_code(k, w)
            elif L == "M":
                self.add_m_code(k, w)
            else:
                if L in k.val:
                    raise self.err(f"word {L} appears twice in one block", b, w, f"one {L} word per block")
                k.val[L] = w
        k.gset = {c for c, _ in k.g}
        k.mset = {c for c, _ in k.mcodes}
        return k

    def add_g_code(self, k: _Codes, w: Word) -> None:
        """A G word of the block: its code (× 10) checked and added to `k.g`, with its modal group's word."""
        b, g, groups = k.block, k.g, k.groups
        code = int(round(w.value * 10))
        if abs(w.value * 10 - code) > 1e-6:
            raise self.err(f"G{w.value:g} is not a G code", b, w, "a G code such as G1 or G90.1")
        grp = _MODAL_GROUPS.get(code)
        if code == 760 and self.dialect.g76_lathe:
            raise self.err(f"{_LATHE_G76} is not supported", b, w, "milling canned cycles (G73, G81-G89)")
        if grp is None:
            if code in _UNSUPPORTED_G:
                what = _UNSUPPORTED_G[code]
                raise self.err(f"{what} is not supported", b, w,
                               "3-axis milling motion (G0-G3, canned cycles); this feature is out of scope")
            if code == 690:  # cancel rotation / tilted plane: nothing to cancel
                return
            if code == 970:  # rpm mode (the only one supported)
                return
            raise self.err(f"unknown G code G{w.value:g}", b, w, "a G code of RS-274 milling")
        if grp == "motion" and "motion" in groups and 800 in (code, int(round(groups[grp].value * 10))):
            # LinuxCNC accepts G80 beside another motion code (as in "G00 G17 G40 G80"): the other wins
            if code == 800:
                return
            g[:] = [(c, x) for c, x in g if c != 800]
        elif grp in groups and grp != "non-modal":
            raise self.err(f"two G codes from the {grp} group in one block", b, w,
                           f"at most one of the {grp} group (first was {groups[grp].text})")
        if grp == "non-modal" and "non-modal" in groups and code not in (530,):
            if groups["non-modal"].value * 10 != 530:
                raise self.err("two non-modal G codes in one block", b, w, "one of G4, G10, G28, G30, G52, G92")
        groups[grp if code != 530 else "g53"] = w
        g.append((code, w))

    def add_m_code(self, k: _Codes, w: Word) -> None:
        """An M word of the block: a non-negative integer, at most one of each M group."""
        if w.value < 0 or w.value != int(w.value):
            raise self.err("M code must be a non-negative integer", k.block, w, "M0 ... M199")
        code = int(w.value)
        grp = _M_GROUPS.get(code)
        for other, x in k.mcodes:
            if grp is not None and _M_GROUPS.get(other) == grp:
                raise self.err(f"two M codes from the {grp} group in one block", k.block, w,
                               f"at most one of the {grp} group (first was {x.text.strip()})")
        k.mcodes.append((code, w))

    # --- the steps of a block (`STEPS`), in LinuxCNC's order of execution ----------------------
    def set_feed_mode(self, k: _Codes) -> None:
        """G93, G94, G95. LinuxCNC sets the feed rate to 0 on every one of them (rs274: SET_FEED_RATE(0)
        after SET_FEED_MODE, then "Cannot do g1 with zero feed rate" until an F): an F in force in one mode
        is not a feed in another (F100 in mm/min read per revolution at S1000 is 100 m/min). Other
        dialects reset it where the mode changes."""
        for mode in _FEED_MODES:
            if mode in k.gset:
                if self.dialect.feed_mode_resets_f or mode != self.feed_mode:
                    self.f = 0.0
                self.feed_mode = mode

    def set_feed_rate(self, k: _Codes) -> None:
        """F, held in mm (per minute or per revolution) as set: a later G20/G21 does not change the
        machine's feed. F on a line with G20/G21 is in the units before them where the dialect says so
        (`Dialect.feed_before_units`: LinuxCNC sets F before the block's G20/G21, its order of execution),
        else in the block's units."""
        b, val = k.block, k.val
        self._f_this_block = val["F"].value if "F" in val else None
        if "F" not in val:
            return
        if val["F"].value < 0:
            raise self.err("negative feed rate", b, val["F"], "F >= 0")
        scale = self.scale if self.dialect.feed_before_units else self.pending_scale(b)
        if scale != self.pending_scale(b) and self.feed_mode != FeedMode.INVERSE_TIME:
            was, new = ("mm", "inch") if scale == 1.0 else ("inch", "mm")
            self.notes.append(f"warning: line {b.line}: F{val['F'].value:g} shares its line with the change to {new}: read "
                              f"in {was} per minute, the units before it, as {self.dialect.name} does; write F on a "
                              f"line after the G{20 if new == 'inch' else 21} if {new} per minute was meant")
        self.f = val["F"].value * (1.0 if self.feed_mode == FeedMode.INVERSE_TIME else scale)

    def set_spindle_speed(self, k: _Codes) -> None:
        """S: the speed set, spindle on or off (an event: a hand-switched spindle takes it too)."""
        if "S" in k.val:
            s = k.val["S"]
            if s.value < 0:
                raise self.err("negative spindle speed", k.block, s, "S >= 0")
            self.s = s.value
            self.event(k.block.line, "s_word", self.s)

    def select_tool(self, k: _Codes) -> None:
        """T: the tool selected (M6 changes it in); it replaces a tool that was only assumed loaded."""
        if "T" in k.val:
            t = k.val["T"]
            if t.value < 0 or t.value != int(t.value):
                raise self.err("tool number must be a non-negative integer", k.block, t, "T followed by an integer")
            self.selected = int(t.value)
            if self.assumed_tool:  # the job's tool was only assumed: the program's own choice replaces it
                self.drop_assumed_tool()

    def other_m_codes(self, k: _Codes) -> None:
        """The block's M codes checked against cutter compensation; M98 (a Fanuc-style subprogram call)
        and M99 held to run after the rest of the block (`run`); M codes that move nothing and millpost
        does not model passed through (an event and a note)."""
        b, val = k.block, k.val
        self.comp.check("M", k.mset)
        for code, w in k.mcodes:
            if code == 98:
                p = val.get("P")
                if p is None or p.value < 0 or p.value != int(p.value):
                    raise self.err("M98 needs the subprogram number", b, w, "M98 P<number> [L<repeats>]")
                reps = val.get("L")
                if reps is not None and (reps.value < 0 or reps.value != int(reps.value)):
                    raise self.err("repeat count L must be a non-negative integer", b, reps, "L0, L1, L2, ...")
                self.subprogram = ("call", str(int(p.value)), 1 if reps is None else int(reps.value))
            elif code == 99:
                self.subprogram = ("return", "", 0)
            elif code not in _M_KNOWN and not 100 <= code <= 199:
                self.event(b.line, "m_code", code)
                self.notes.append(f"line {b.line}: M{code} passed through (no motion)")

    def change_tool(self, k: _Codes) -> None:
        """M6: the selected tool (or the block's T) goes into the spindle."""
        if 6 in k.mset:
            tool = self.selected if self.selected >= 0 else (int(k.val["T"].value) if "T" in k.val else -1)
            self.tool, self.assumed_tool = tool, False
            self.event(k.block.line, "tool_change", tool)

    def switch_spindle(self, k: _Codes) -> None:
        """M3, M4, M5; an S word alone changes the speed of a running spindle."""
        mset = k.mset
        for code in (3, 4, 5):
            if code in mset:
                self.spindle_on = code != 5
                self.event(k.block.line, "spindle", ("cw" if code == 3 else "ccw" if code == 4 else "off",
                                                     self.s if code != 5 else 0.0))
        if "S" in k.val and self.spindle_on and not mset & {3, 4, 5}:
            self.event(k.block.line, "spindle", ("speed", self.s))

    def switch_coolant(self, k: _Codes) -> None:
        """M7, M8, M9."""
        for code in (7, 8, 9):
            if code in k.mset:
                self.event(k.block.line, "coolant", {7: "mist", 8: "flood", 9: "off"}[code])

    def dwell(self, k: _Codes) -> None:
        """G4 P (seconds, or milliseconds in a Fanuc dialect; X or U on some controls)."""
        if 40 in k.gset:
            b, val = k.block, k.val
            p = val.get("P") or val.get("X") or val.get("U")
            if p is None or p.value < 0:
                raise self.err("dwell G4 needs a non-negative P (seconds; Fanuc: milliseconds)", b,
                               k.groups.get("non-modal"), "G4 P<time>")
            secs = self.dialect.dwell_s(p.value, decimal_point="." in p.text) if p.letter == "P" else p.value
            self.dwell_s += secs
            self.event(b.line, "dwell", secs)

    def set_plane(self, k: _Codes) -> None:
        """G17, G18, G19."""
        for code, plane in ((170, 0), (180, 1), (190, 2)):
            if code in k.gset:
                self.comp.check_plane(plane)
                self.plane = plane

    def set_units(self, k: _Codes) -> None:
        """G20, G21."""
        for code, scale, name in ((200, INCH, "inch"), (210, 1.0, "mm")):
            if code in k.gset:
                self.scale = scale
                if name not in self.units_seen:
                    self.units_seen.append(name)

    def radius_compensation(self, k: _Codes) -> None:
        """G40, G41, G42 (and .1); then the block's G codes checked against the compensation in effect."""
        if k.gset & {400, 410, 420, 411, 421}:
            self.cutter_comp(k.gset, k.block, k.val)
        self.comp.check("G", k.gset)

    def length_compensation(self, k: _Codes) -> None:
        """G43, G43.1, G43.2, G49."""
        if k.gset & {430, 431, 432, 490}:
            self.tool_length(k.gset, k.block, k.val)

    def select_coordinate_system(self, k: _Codes) -> None:
        """G54 ... G59.3."""
        for code, idx in ((540, 1), (550, 2), (560, 3), (570, 4), (580, 5), (590, 6), (591, 7), (592, 8), (593, 9)):
            if code in k.gset:
                self.set_offsets(lambda: setattr(self, "cs", idx))
                self.event(k.block.line, "work_offset", idx)

    def set_path_mode(self, k: _Codes) -> None:
        """G61, G61.1, G64 (P and Q, its tolerances): an event for the controller model."""
        for code, name in ((610, "exact path"), (611, "exact stop"), (640, "blend")):
            if code in k.gset:
                p, q = ((k.val[L].value if L in k.val and code == 640 else None) for L in "PQ")
                self.event(k.block.line, "path_mode", (name, p, q))

    def set_distance_modes(self, k: _Codes) -> None:
        """G90, G91 (axes) and G90.1, G91.1 (arc centres)."""
        for code in (900, 910):
            if code in k.gset:
                self.absolute = code == 900
        for code in (901, 911):
            if code in k.gset:
                self.arc_absolute = code == 901

    def set_retract_mode(self, k: _Codes) -> None:
        """G98, G99 (canned cycles)."""
        for code in (980, 990):
            if code in k.gset:
                self.retract_old_z = code == 980

    def read_axis_words(self, k: _Codes) -> None:
        """The block's X/Y/Z words, polar coordinates (@ ^) first turned into X/Y; rotary and extra axis
        words checked (kept at zero)."""
        b, val = k.block, k.val
        if "@" in val or "^" in val:
            block_motion = next((c for c in k.gset if c in _MOTION), self.motion)
            self.polar_words(b, val, block_motion in _CYCLES)
        k.axis_words = {L: val[L] for L in _AXES if L in val}
        self.check_rotary(b, val)

    def offsets_and_homes(self, k: _Codes) -> None:
        """G10, G28/G30 (and .1), G52, G92 (and .1-.3): the block's non-modal codes but G4 and G53, noting
        whether one used the axis words (then they are not a move)."""
        nonmodal = [c for c in k.gset if _MODAL_GROUPS.get(c) == "non-modal" and c not in (40, 530)]
        for code in nonmodal:
            k.consumed_axes = self.non_modal(code, k.block, k.val, k.axis_words) or k.consumed_axes

    def set_motion_mode(self, k: _Codes) -> None:
        """G80 (cancel), G0-G3, canned cycles: the motion mode the block's axis words run in."""
        k.motion_code = motion_code = next((c for c in k.gset if c in _MOTION or c == 800), None)
        if motion_code == 800:
            if k.axis_words and not k.consumed_axes:
                raise self.err("axis words with G80", k.block, next(iter(k.axis_words.values())),
                               "no axis words on a G80 line, or a G0/G1 word to move")
            self.motion = self.basic_motion if self.dialect.g80_keeps_motion else None
            self.cycle_il = None
        elif motion_code is not None:
            if motion_code in _CYCLES and self.motion != motion_code:  # another cycle: its words anew, the
                self.cycle.clear()  # level where the sequence began kept (LinuxCNC)
            if motion_code not in _CYCLES:
                self.cycle_il = None
                self.basic_motion = motion_code
            self.motion = motion_code

    def move(self, k: _Codes) -> None:
        """The motion of the block, as modified by G53: a straight move, an arc or a canned cycle. LinuxCNC
        moves (zero length) on a bare G0/G1 too, so the trace has a move for every motion word."""
        motion_code = k.motion_code
        if k.consumed_axes or not (k.axis_words or motion_code in (0, 10, 20, 30) or motion_code in _CYCLES):
            return
        b, val, axis_words = k.block, k.val, k.axis_words
        if self.motion is None:
            raise self.err("axis words with no motion mode in effect", b, next(iter(axis_words.values())),
                           "a G0, G1, G2 or G3 word (after G80, the motion mode must be given again)")
        if self.motion in _CYCLES:
            first = len(self.m)
            self.canned_cycle(b, val, axis_words)
            self.cycle_runs.append((first, len(self.m), self.motion))
        elif self.motion in (20, 30):
            self.arc(b, val, axis_words)
        else:
            self.straight(b, val, axis_words, 530 in k.gset)

    def stop(self, k: _Codes) -> None:
        """M0, M1, M60 (pause) and M2, M30 (end): cutter compensation ends its held move first."""
        for code, _ in k.mcodes:
            if code in (0, 1, 60):
                self.comp.stop(end_program=False)
                self.event(k.block.line, "stop", code)
            elif code in (2, 30):
                self.comp.stop(end_program=True)
                self.event(k.block.line, "end", code)
                self.ended = True

    # LinuxCNC G-code overview, "order of execution": a block's steps in that order (items 1 and 2, O words
    # and comments, are `run`'s; M codes that move nothing stand at item 7, HAL pin I/O), each with the
    # codes and words that wake it ("*": every block; "G*", "M*": any G or M code)
    STEPS = _StepTable(
        (set_feed_mode, "G93 G94 G95"),
        (set_feed_rate, "*"),  # also forgets the last block's F (inverse time needs one on every move)
        (set_spindle_speed, "S"),
        (select_tool, "T"),
        (other_m_codes, "M*"),
        (change_tool, "M6"),
        (switch_spindle, "M3 M4 M5 S"),
        (switch_coolant, "M7 M8 M9"),
        (dwell, "G4"),
        (set_plane, "G17 G18 G19"),
        (set_units, "G20 G21"),
        (radius_compensation, "G*"),  # G40-G42, then every G code checked against compensation on
        (length_compensation, "G43 G43.1 G43.2 G49"),
        (select_coordinate_system, "G54 G55 G56 G57 G58 G59 G59.1 G59.2 G59.3"),
        (set_path_mode, "G61 G61.1 G64"),
        (set_distance_modes, "G90 G91 G90.1 G91.1"),
        (set_retract_mode, "G98 G99"),
        (read_axis_words, "*"),
        (offsets_and_homes, "G10 G28 G28.1 G30 G30.1 G52 G92 G92.1 G92.2 G92.3"),
        (set_motion_mode, "G0 G1 G2 G3 G73 G74 G76 G80 G81 G82 G83 G84 G85 G86 G87 G88 G89"),
        (move, "*"),  # the motion mode in effect moves on axis words
        (stop, "M0 M1 M2 M30 M60"),
    )

    def check_words(self, b: Block, val: dict, gset: set, mcodes: list) -> None:
        """Refuse a word that nothing in its block uses, as LinuxCNC 2.9 does (its check_other_codes):
        D, E, H, I, J, K, L, P, Q, R each need a G or M code of the block, or the motion mode the block
        runs in, that reads them (``G1 X1 Q3`` is an error, not a move). A dialect may add P (dwell) and
        K (repeats) on every canned cycle, Q (shift) on G76/G87, Q (peck) on G74/G84 and H on G49 (`Dialect`)."""
        if 40 in gset or 530 in gset or not val.keys().isdisjoint(_CHECKED):
            motion = next((c for c in gset if c in _MOTION or c == 800), None)
            if motion is None and not gset & _TAKE_AXES and not val.keys().isdisjoint("XYZABCUVW@^"):
                motion = self.motion
            mset = {c for c, _ in mcodes}
            for L, w in val.items():
                if L in _CHECKED and not self.word_used(L, motion, gset, mset):
                    raise self.err(f"{L} word with nothing in the block to use it", b, w, _WORD_USERS[L])
            if motion in _CYCLES:
                for L in "ABCUVW":
                    if L in val:
                        raise self.err(f"{L} word in a canned cycle", b, val[L], "only the plane's axes, R, Q, P, L")
            if 40 in gset and motion in (20, 30):
                raise self.err("G4 with G2/G3 (both use P)", b, val.get("P"), "the dwell and the arc on separate lines")
            if 530 in gset and (910 in gset or (not self.absolute and 900 not in gset)):
                raise self.err("G53 in incremental mode (G91)", b, None, "G90 with G53")
        if "N" in val:
            raise self.err("N (line number) word not at the start of the block", b, val["N"], "N first, or no N")

    def word_used(self, L: str, motion: int | None, gset: set, mset: set) -> bool:
        """Whether a code of the block (or the motion it runs in) reads the word `L` (LinuxCNC's rules)."""
        if motion in (20, 30) and L in "IJKRP":  # arcs: the common case first
            return True
        cycle = motion in _CYCLES
        d = self.dialect
        comp = not gset.isdisjoint((410, 420, 411, 421))
        if L in "IJ":
            return motion == 870 or 100 in gset
        if L == "K":
            return motion == 870 or (d.cycle_k_repeats and cycle)
        if L == "R":
            return cycle or not gset.isdisjoint((100, 411, 421)) or 19 in mset
        if L == "P":
            return (not gset.isdisjoint((40, 100, 640)) or motion in (20, 30, 740, 820, 840, 860, 880, 890)
                    or (d.cycle_dwell_any and cycle) or not mset.isdisjoint((19, 50, 51, 52, 53, 62, 63, 64, 65, 66, 98))
                    or any(100 <= c <= 199 for c in mset))
        if L == "Q":
            return (motion in (730, 830) or (d.boring_shift_q and motion in (760, 870)) or (d.tap_peck_q and motion in (740, 840)) or not gset.isdisjoint((100, 640))
                    or not mset.isdisjoint((19, 66, 67, 68)) or any(100 <= c <= 199 for c in mset))
        if L == "L":
            return cycle or comp or 100 in gset or not mset.isdisjoint((98, 66))
        if L == "H":
            return not gset.isdisjoint((430, 432)) or (d.g49_takes_h and 490 in gset)
        if L == "D":
            return comp
        return not mset.isdisjoint((66, 67, 68))  # E

    def cutter_comp(self, gset: set, b: Block, val: dict) -> None:
        """G40 off. G41/G42 (left/right) D<tool number>, no D or D0: the tool in the spindle, its diameter
        from `ReaderOptions.tool_diameters_mm`; G41.1/G42.1 D<diameter in program units>."""
        if 400 in gset:
            self.comp.off()
            return
        code = next(c for c in (410, 420, 411, 421) if c in gset)
        name, d = f"G{code / 10:g}", val.pop("D", None)
        if code in (411, 421):
            if d is None:
                g = next(w for w in b.words if w.letter == "G" and round(w.value * 10) == code)
                raise self.err(f"{name} with no D word", b, g, f"{name} D<tool diameter>")
            if "L" in val:
                raise self.err(f"{name} L (lathe tool orientation) is not supported", b, val["L"], f"{name} D alone")
            diameter = d.value * self.scale
        else:
            if d is not None and (d.value < 0 or abs(d.value - round(d.value)) >= 1e-4):
                raise self.err(f"{name} requires D word to be a whole number", b, d, "D<tool number>")
            tool = int(round(d.value)) if d is not None else 0
            tool = tool or (self.tool if self.tool >= 0 else self.selected)  # D0 or none: the spindle's
            if tool < 0:  # LinuxCNC: an empty spindle has diameter 0
                diameter = 0.0
                self.notes.append(f"line {b.line}: {name} with no tool loaded: radius 0, no offset (as LinuxCNC)")
            elif tool in self.opt.tool_diameters_mm:
                diameter = self.opt.tool_diameters_mm[tool]
            else:
                raise self.err(f"{name} needs the diameter of tool {tool}, which is not given", b, d,
                               f"tool {tool} in the job's tools or the tool table (its diameter)")
        self.comp.on(LEFT if code in (410, 411) else RIGHT, diameter / 2, self.plane)

    def comp_error(self, e: CompensationError, b: Block) -> ParseError:
        """A compensation refusal at the word it is about (else the block's first axis or motion word)."""
        def about(w: Word) -> bool:
            return w.letter == e.letter and (e.code is None or abs(w.value - e.code) < 1e-6)
        word = (next((w for w in b.words if about(w)), None) or next((w for w in b.words if w.letter in _AXES), None)
                or next((w for w in b.words if w.letter == "G"), None))
        return self.err(e.message, b, word, e.expected)

    def tool_length(self, gset: set, b: Block, val: dict) -> None:
        """G43 (H or current tool), G43.1 (dynamic Z/K), G43.2 (additional), G49 (cancel). Lengths come
        from `ReaderOptions.tool_lengths_mm`; an unknown length is 0, so Z stays the tool tip."""
        if 490 in gset:
            new = 0.0
        elif 431 in gset:
            w = val.get("Z") or val.get("K")
            new = w.value * self.scale if w is not None else 0.0
            val.pop("Z", None)
        else:
            h = int(val["H"].value) if "H" in val else self.tool
            length = self.opt.tool_lengths_mm.get(h)
            if length is None and h >= 0 and "tool length" not in self.params:
                self.params["tool length"] = 1.0
                self.notes.append(f"line {b.line}: tool length of H{h} unknown: Z is programmed tool-tip Z")
            new = (self.tlo if 432 in gset else 0.0) + (length or 0.0)
        self.set_offsets(lambda: setattr(self, "tlo", new))
        self.event(b.line, "tool_length", new)

    def polar_words(self, b: Block, val: dict, cycle: bool) -> None:
        """LinuxCNC polar coordinates in G17: @ radius and ^ angle (degrees) about the origin, absolute
        or (G91) incremental to the current point's radius and angle. Replaced by X/Y words."""
        w = val.get("@") or val.get("^")
        if self.plane != 0 or "X" in val or "Y" in val:
            raise self.err("polar coordinates (@ ^) need G17 and no X/Y words", b, w, "@radius ^angle in G17 alone")
        if cycle and not self.absolute and "L" in val:
            self.polar_step = (val["@"].value if "@" in val else 0.0, val["^"].value if "^" in val else 0.0)
            val.pop("@", None), val.pop("^", None)
            return
        x, y = self.polar_point(val.pop("@", None), val.pop("^", None))
        for L, v in (("X", x), ("Y", y)):
            val[L] = Word(L, v / self.scale, w.column, w.start, w.end, w.text)
        if not self.absolute:  # the words above are absolute: express them as increments
            for i, L in enumerate("XY"):
                val[L].value = (val[L].value * self.scale - self.pos[i]) / self.scale

    def polar_point(self, radius: Word | None, angle: Word | None, step=None) -> tuple[float, float]:
        r0 = math.hypot(self.pos[0], self.pos[1])
        a0 = math.degrees(math.atan2(self.pos[1], self.pos[0]))
        if step is not None:
            r, a = r0 + step[0] * self.scale, a0 + step[1]
        elif self.absolute:
            r = radius.value * self.scale if radius else r0
            a = angle.value if angle else a0
        else:
            r = r0 + (radius.value * self.scale if radius else 0.0)
            a = a0 + (angle.value if angle else 0.0)
        return r * math.cos(math.radians(a)), r * math.sin(math.radians(a))

    def check_rotary(self, b: Block, val: dict) -> None:
        """Rotary and extra linear axes: accepted only where they stay at zero (no motion)."""
        for L in _ROTARY:
            if L in val:
                w = val[L]
                target = w.value if self.absolute else self.rotary[L] + w.value
                if abs(target) > 1e-9:
                    raise self.err(f"{L} axis motion is not supported (3-axis milling only)", b, w,
                                   f"no {L} word, or {L}0 (an axis kept at zero)")
                if abs(self.rotary[L]) < 1e-12 and f"{L}-zero" not in self.params:
                    self.params[f"{L}-zero"] = 1.0
                    self.notes.append(f"line {b.line}: {L} axis assumed at 0 at program start; {L}0 words accepted")

    def set_offsets(self, change) -> None:
        """Apply a change of offsets keeping the machine position fixed (program position moves)."""
        before = self.offset()
        change()
        self.pos = self.pos + before - self.offset()

    def target(self, axis_words: dict, absolute: bool | None = None) -> np.ndarray:
        absolute = self.absolute if absolute is None else absolute
        t = self.pos.copy()
        for L, w in axis_words.items():
            i = _AXES.index(L)
            t[i] = w.value * self.scale if absolute else t[i] + w.value * self.scale
        return t

    def non_modal(self, code: int, b: Block, val: dict, axis_words: dict) -> bool:
        """G10, G28/G28.1, G30/G30.1, G52, G92 family (`NON_MODAL`). Returns True if the axis words were used."""
        return self.NON_MODAL[code](self, code, b, val, axis_words)

    def set_data(self, code: int, b: Block, val: dict, axis_words: dict) -> bool:
        """G10: L1/L10/L11 (tool table: an event) or L2/L20 (a coordinate system's offsets)."""
        L = val.get("L")
        if L is None:
            raise self.err("G10 without an L word", b, None, "G10 L1/L10/L11 (tool table) or L2/L20 (offsets)")
        lv = int(L.value)
        if lv in (1, 10, 11):
            self.event(b.line, "tool_table", lv)
            return True
        if lv in (2, 20):
            p = int(val["P"].value) if "P" in val else 0
            idx = self.cs if p == 0 else p
            if not 1 <= idx <= 9:
                raise self.err("G10 P must select a coordinate system 0..9", b, val.get("P"), "P0..P9")
            self.comp.check_offsets(idx, self.cs)
            if "R" in val and val["R"].value != 0:
                raise self.err("coordinate system rotation (G10 R) is not supported", b, val["R"], "R0 or no R")

            def change() -> None:
                cur = self.g5x.get(idx, np.zeros(3)).copy()
                for Lt, w in axis_words.items():
                    i = _AXES.index(Lt)
                    if lv == 2:
                        cur[i] = w.value * self.scale
                    else:  # L20: set so the current point has the given coordinate
                        machine = self.pos[i] + self.offset()[i]
                        cur[i] = machine - self.g92[i] - w.value * self.scale
                self.g5x[idx] = cur
            self.set_offsets(change)
            return True
        raise self.err(f"G10 L{lv} is not supported", b, L, "G10 L1, L2, L10, L11 or L20")

    def go_home(self, code: int, b: Block, val: dict, axis_words: dict) -> bool:
        """G28, G30: a rapid through the axis words' point (if any) to the home of those axes (all without
        axis words); an unknown home retracts Z to the safe height and leaves X/Y (noted)."""
        home_opt = self.opt.home_g28_mm if code == 280 else self.opt.home_g30_mm
        if axis_words:
            mid = self.target(axis_words)
            self.emit(RAPID, mid, b)
        axes = [_AXES.index(L) for L in axis_words] or [0, 1, 2]
        end = self.pos.copy()
        if home_opt is not None:
            home = np.array(home_opt, float) - self.offset()
            end[axes] = home[axes]
        else:
            if 2 in axes:
                end[2] = math.nan
                self.safe_z_pending = True
            self.notes.append(f"line {b.line}: G{code // 10} home position unknown: Z retracts to the safe "
                              "height (highest Z of the program), X/Y stay (assumed)")
        self.emit(RAPID, end, b)
        return True

    def set_home(self, code: int, b: Block, val: dict, axis_words: dict) -> bool:
        """G28.1, G30.1: store the current point as home (the machine's business: nothing to model)."""
        return False

    def set_axis_offsets(self, code: int, b: Block, val: dict, axis_words: dict) -> bool:
        """G92 (the current point gets the given coordinates), G52 (a local offset of the given values)."""
        if not axis_words:
            if code == 520:
                return True
            raise self.err("G92 without axis words", b, None, "G92 with at least one of X, Y, Z")

        def change() -> None:
            for L, w in axis_words.items():
                i = _AXES.index(L)
                if code == 920:  # current point gets the given coordinate
                    machine = self.pos[i] + self.offset()[i]
                    self.g92[i] = machine - self.g5x.get(self.cs, np.zeros(3))[i] - w.value * self.scale
                else:  # G52: local offset = the value
                    self.g92[i] = w.value * self.scale
        self.set_offsets(change)
        return True

    def clear_axis_offsets(self, code: int, b: Block, val: dict, axis_words: dict) -> bool:
        """G92.1, G92.2: the G92/G52 offsets to zero (G92.2 keeps them for G92.3)."""
        def clear() -> None:
            if code == 922:
                self.g92_saved = self.g92.copy()
            self.g92 = np.zeros(3)
        self.set_offsets(clear)
        return False

    def restore_axis_offsets(self, code: int, b: Block, val: dict, axis_words: dict) -> bool:
        """G92.3: the offsets G92.2 kept."""
        self.set_offsets(lambda: setattr(self, "g92", self.g92_saved.copy()))
        return False

    # the non-modal codes of LinuxCNC's order of execution item 23 (G4 and G53 are steps of their own)
    NON_MODAL = {100: set_data, 280: go_home, 300: go_home, 281: set_home, 301: set_home, 920: set_axis_offsets,
                 520: set_axis_offsets, 921: clear_axis_offsets, 922: clear_axis_offsets, 923: restore_axis_offsets}

    def straight(self, b: Block, val: dict, axis_words: dict, g53: bool) -> None:
        if g53:
            if self.motion not in (0, 10):
                raise self.err("G53 needs G0 or G1 motion", b, None, "G53 G0 or G53 G1")
            if self.opt.machine_frame_known:
                t = self.pos.copy()
                off = self.offset()
                for L, w in axis_words.items():
                    i = _AXES.index(L)
                    t[i] = w.value * self.scale - off[i]
            elif set(axis_words) == {"Z"}:
                t = self.pos.copy()
                t[2] = math.nan
                self.safe_z_pending = True
                self.notes.append(f"line {b.line}: G53 Z move with the machine frame unknown: goes to the safe height "
                                  "(highest Z of the program) (assumed)")
            else:
                t = self.target(axis_words, absolute=True)
                self.notes.append(f"line {b.line}: G53 move with the machine frame unknown: machine coordinates taken "
                                  "as program coordinates (assumed)")
        else:
            t = self.target(axis_words)
        if self.motion == 0:
            self.emit(RAPID, t, b)
        else:
            L = float(np.linalg.norm(t - self.pos)) if not np.isnan(t).any() else 0.0
            self.emit(FEED, t, b, feed_mm_min=self.feed_rate(b, L))

    def arc(self, b: Block, val: dict, axis_words: dict) -> None:
        a1, a2, an = PLANE_AXES[self.plane]
        offs = ("I", "J", "K")
        o1, o2 = offs[a1], offs[a2]
        if self.dialect.off_plane_arc_offset_refused and offs[an] in val:
            raise self.err(f"{offs[an]} word given for an arc in the {('XY', 'XZ', 'YZ')[self.plane]} plane (LinuxCNC "
                           "refuses it)", b, val[offs[an]], f"only {o1} and {o2} on a G{17 + self.plane} arc, or the "
                           "job's dialect of a controller that ignores it (dialect = \"fanuc\" or \"grbl\")")
        end = self.target(axis_words)
        start = self.pos
        cw = self.motion == 20
        turns = 0
        if "P" in val:
            p = val["P"].value
            if p != int(p) or p < 1:
                raise self.err("arc turns P must be a positive integer", b, val["P"], "P1, P2, ...")
            turns = int(p) - 1
        center = start.copy()
        if "R" in val:
            if o1 in val or o2 in val:
                raise self.err("arc with both R and I/J/K", b, val["R"], "either R or centre offsets")
            r = val["R"].value * self.scale
            d1, d2 = end[a1] - start[a1], end[a2] - start[a2]
            chord = math.hypot(d1, d2)
            if chord < 1e-9:
                raise self.err("full circle with R format (start equals end)", b, val["R"],
                               "I/J/K centre offsets for a full circle")
            half = chord / 2
            if abs(r) < half:
                if half - abs(r) > (0.0005 * INCH if self.scale != 1.0 else 0.005):  # LinuxCNC's tolerance
                    raise self.err(f"arc radius {abs(r) / self.scale:g} too small to reach the end point "
                                   f"(half chord {half / self.scale:g})", b, val["R"], "|R| >= half the chord")
                r = math.copysign(half, r)
            h = math.sqrt(max(r * r - half * half, 0.0))
            # centre on the left of the chord for a CCW arc < 180 (R > 0), on the right for CW
            left = (not cw) == (r > 0)
            m1, m2 = start[a1] + d1 / 2, start[a2] + d2 / 2
            n1, n2 = -d2 / chord, d1 / chord
            sgn = 1.0 if left else -1.0
            center[a1], center[a2] = m1 + sgn * h * n1, m2 + sgn * h * n2
        else:
            if o1 not in val and o2 not in val:
                raise self.err("arc with neither R nor centre offsets", b, None,
                               f"{o1} and/or {o2} (centre) or R (radius) for this plane")
            if self.arc_absolute:
                c1 = val[o1].value * self.scale if o1 in val else start[a1]
                c2 = val[o2].value * self.scale if o2 in val else start[a2]
                center[a1], center[a2] = c1, c2
            else:
                center[a1] = start[a1] + (val[o1].value * self.scale if o1 in val else 0.0)
                center[a2] = start[a2] + (val[o2].value * self.scale if o2 in val else 0.0)
            r0 = math.hypot(start[a1] - center[a1], start[a2] - center[a2])
            r1 = math.hypot(end[a1] - center[a1], end[a2] - center[a2])
            if r0 < 1e-9:
                raise self.err("arc of zero radius", b, val.get(o1) or val.get(o2), "a centre away from the start point")
            # LinuxCNC 2.9's rule: absolute threshold 2·0.001 in·√2 (2·0.01 mm·√2), relative 0.1 %;
            # refused beyond 100× the absolute threshold, or beyond both thresholds.
            t_abs = 2 * (0.001 * INCH if self.scale != 1.0 else 0.01) * math.sqrt(2)
            err = abs(r1 - r0)
            if err > 100 * t_abs or (err > t_abs and err / max(r0, r1) > 0.001):
                raise self.err(f"radius to end of arc ({r1 / self.scale:g}) differs from radius to start "
                               f"({r0 / self.scale:g})", b, val.get(o1) or val.get(o2),
                               "a centre equidistant from start and end")
        center[an] = start[an]
        kind = ARC_CW if cw else ARC_CCW
        L = _arc_length(start, end, center, (a1, a2, an), kind == ARC_CCW, turns)
        self.emit(kind, end, b, center=center, turns=turns, feed_mm_min=self.feed_rate(b, L))

    # --- canned cycles ------------------------------------------------------------------------
    def canned_cycle(self, b: Block, val: dict, axis_words: dict) -> None:
        """Expand a drilling/boring/tapping cycle into moves the way LinuxCNC does."""
        code = self.motion
        self.comp.check("G", (code,))
        a1, a2, an = PLANE_AXES[self.plane]
        an_letter = _AXES[an]
        cyc = self.cycle
        if self.cycle_il is None:  # first block of a cycle sequence
            self.cycle_il = self.pos[an]
            cyc.clear()
        for L in ("R", "Q", "P", an_letter, "I", "J", "K"):
            if L in val:
                cyc[L] = val[L].value
        for need in ("R", an_letter):
            if need not in cyc:
                raise self.err(f"canned cycle G{code / 10:g} without {need}", b, None, f"an {need} word")
        if code in (730, 830) and cyc.get("Q", 0) <= 0:
            raise self.err(f"peck cycle G{code / 10:g} needs Q > 0", b, val.get("Q"), "Q (peck depth) > 0")
        repeats = 1
        count = val.get("L") or (val.get("K") if self.dialect.cycle_k_repeats and code != 870 else None)
        if count is not None:
            if count.value < 0 or count.value != int(count.value) or (count.value == 0 and self.dialect.zero_repeats_refused):
                raise self.err("repeat count must be a positive integer", b, count, f"{count.letter}1, {count.letter}2, ...")
            repeats = int(count.value)
        sc = self.scale
        old = self.cycle_il  # LinuxCNC: the level where the cycle sequence began, not the current one
        if self.absolute:
            r = cyc["R"] * sc
            bottom = cyc[an_letter] * sc
        else:
            r = cyc["R"] * sc + self.cycle_il  # LinuxCNC: from the level where the cycle sequence began
            bottom = r + cyc[an_letter] * sc
        if bottom > r and code != 870:  # back boring cuts upwards from an R below the part
            raise self.err(f"canned cycle bottom {an_letter} above the R plane", b, val.get(an_letter),
                           f"{an_letter} below R")
        self.check_cycle_size(b, code, repeats, r, bottom, cyc)
        feed = self.feed_rate(b, 1.0)
        if old < r:  # (a move of no length when the cycle sequence is already at R: LinuxCNC makes it too)
            p = self.pos.copy()
            p[an] = r
            self.emit(RAPID, p, b)
            old = r
        clear = r if not self.retract_old_z else old
        current = self.pos[an]
        # LinuxCNC runs a cycle's moves after the climb to R in exact path (G61), then restores the mode
        first = len(self.m) + self.comp.pending
        d1 = axis_words.get(_AXES[a1])
        d2 = axis_words.get(_AXES[a2])
        if self.polar_step is not None and self.plane != 0:
            raise self.err("polar coordinates need G17", b, None, "G17")
        for rep in range(repeats):
            p = self.pos.copy()
            if self.polar_step is not None:
                p[0], p[1] = self.polar_point(None, None, self.polar_step)
            elif self.absolute:
                if d1 is not None:
                    p[a1] = d1.value * sc
                if d2 is not None:
                    p[a2] = d2.value * sc
            else:
                p[a1] += d1.value * sc if d1 is not None else 0.0
                p[a2] += d2.value * sc if d2 is not None else 0.0
            # LinuxCNC 2.9: the first hole is reached at the current level, if above R; any other at the
            # clear level; then down to R (back boring goes down to R beside the bore itself)
            p[an] = current if rep == 0 and current > r else clear
            self.emit(RAPID, p, b)
            if p[an] > r and code != 870:
                self.to_depth(RAPID, r, b)
            self.cycle_body(code, b, r, bottom, clear, feed, cyc)
        self.event(b.line, "canned_cycle", first)
        self.polar_step = None

    def check_cycle_size(self, b: Block, code: int, repeats: int, r: float, bottom: float, cyc: dict) -> None:
        """Refuse a cycle block that would expand to more than `MAX_CYCLE_MOVES` moves, or take the
        program's canned cycles past `MAX_CYCLE_MOVES_TOTAL` (peck count = depth / Q, times L)."""
        per_hole = 6.0
        if code in (730, 830) or (code in (740, 840) and cyc.get("Q", 0) > 0):
            per_hole += 3.0 * (r - bottom) / (cyc["Q"] * self.scale)
        moves = repeats * per_hole
        if moves > MAX_CYCLE_MOVES or self.cycle_moves + moves > MAX_CYCLE_MOVES_TOTAL:
            limit = MAX_CYCLE_MOVES if moves > MAX_CYCLE_MOVES else MAX_CYCLE_MOVES_TOTAL - self.cycle_moves
            raise self.err(f"canned cycle G{code / 10:g} would make about {moves:.3g} moves (repeats x pecks), "
                           f"more than the {limit:,} millpost reads", b, b.words[0] if b.words else None,
                           f"at most {MAX_CYCLE_MOVES:,} moves per cycle block and {MAX_CYCLE_MOVES_TOTAL:,} "
                           "per program (fewer repeats L, a larger peck Q)")
        self.cycle_moves += moves

    def to_depth(self, kind: int, depth: float, b: Block, feed: float = math.nan) -> None:
        an = PLANE_AXES[self.plane][2]
        p = self.pos.copy()
        p[an] = depth
        self.emit(kind, p, b, feed_mm_min=feed if kind == FEED else math.nan)

    def tap_pecks(self, b: Block, r: float, bottom: float, delta: float, feed: float) -> None:
        """The pecks of a peck tapping cycle before its last one (G84/G74 with Q). The tap feeds down Q
        deeper each time and reverses out at the same synchronised feed. Fanuc's deep-hole form
        retracts to R; the high-speed form backs off by a control parameter only. Both are modelled as
        the deep-hole form (the longer one) and noted; a tapping feed is never changed."""
        for depth in _peck_depths(r, bottom, delta):
            self.to_depth(FEED, depth, b, feed)
            self.to_depth(FEED, r, b, feed)
        self.notes.append(f"line {b.line}: peck tapping modelled as Fanuc's deep-hole form (the tap reverses "
                          "out to R after each peck; the high-speed form backs off by a control parameter)")

    def cycle_body(self, code: int, b: Block, r: float, bottom: float, clear: float, feed: float, cyc: dict) -> None:
        sc = self.scale
        delta = cyc.get("Q", 0.0) * sc
        rapid_delta = 0.010 * INCH if sc != 1.0 else 0.254  # LinuxCNC's G73/G83 clearance
        dwell = cyc.get("P", 0.0)
        dwell = self.dialect.dwell_s(dwell, cycle=True)
        if code == 810:
            self.to_depth(FEED, bottom, b, feed)
            self.to_depth(RAPID, clear, b)
        elif code == 820:
            self.to_depth(FEED, bottom, b, feed)
            self.add_dwell(b, dwell)
            self.to_depth(RAPID, clear, b)
        elif code in (730, 830):
            for depth in _peck_depths(r, bottom, delta):
                self.to_depth(FEED, depth, b, feed)
                if code == 830:
                    self.to_depth(RAPID, r, b)
                self.to_depth(RAPID, depth + rapid_delta, b)
            self.to_depth(FEED, bottom, b, feed)
            self.to_depth(RAPID, clear, b)
        elif code in (840, 740):  # tapping: in, reverse, feed out to the clear plane
            if delta > 0:  # peck tapping (tap_peck_q dialects): each peck reverses out to R and back in
                self.tap_pecks(b, r, bottom, delta, feed)
            self.to_depth(FEED, bottom, b, feed)
            self.add_dwell(b, dwell)
            self.to_depth(FEED, clear, b, feed)
        elif code == 860:
            self.to_depth(FEED, bottom, b, feed)
            self.add_dwell(b, dwell)
            self.event(b.line, "spindle", ("off", 0.0))
            self.to_depth(RAPID, clear, b)
            self.event(b.line, "spindle", ("cw", self.s))
        elif code in (850, 890):  # boring: feed in, (G89: dwell), feed out to R
            self.to_depth(FEED, bottom, b, feed)
            if code == 890:
                self.add_dwell(b, dwell)
            self.to_depth(FEED, r, b, feed)
            if clear != r:
                self.to_depth(RAPID, clear, b)
        elif code == 880:
            self.to_depth(FEED, bottom, b, feed)
            self.add_dwell(b, dwell)
            self.event(b.line, "stop", "G88 manual retract")
            self.notes.append(f"line {b.line}: G88 stops for a manual retract; modelled as a rapid to the clear plane")
            self.to_depth(RAPID, clear, b)
        elif code == 760:  # Fanuc/Haas fine boring: feed in, orient, shift by Q, rapid out, shift back
            self.to_depth(FEED, bottom, b, feed)
            self.add_dwell(b, dwell)
            self.shift(b, delta)  # the shift direction depends on the orientation; +first axis assumed
            self.to_depth(RAPID, clear, b)
            self.shift(b, -delta)
            self.notes.append(f"line {b.line}: G76 shift direction taken along +{_AXES[PLANE_AXES[self.plane][0]]} "
                              "(assumed)")
        elif code == 870:
            self.back_bore(b, r, bottom, clear, feed, cyc)

    def shift(self, b: Block, delta: float) -> None:
        """Rapid sideways along the plane's first axis (the boring bar's oriented-stop shift)."""
        p = self.pos.copy()
        p[PLANE_AXES[self.plane][0]] += delta
        self.emit(RAPID, p, b)

    def back_bore(self, b: Block, r: float, bottom: float, clear: float, feed: float, cyc: dict) -> None:
        """G87 back boring (Fanuc form: shift by Q, rapid to R below the part, shift back, feed up to Z)."""
        delta = cyc.get("Q", 0.0) * self.scale
        start = self.pos[PLANE_AXES[self.plane][2]]
        self.shift(b, delta)
        self.to_depth(RAPID, r, b)
        self.shift(b, -delta)
        self.to_depth(FEED, bottom, b, feed)
        self.shift(b, delta)
        self.to_depth(RAPID, start, b)
        self.shift(b, -delta)
        self.notes.append(f"line {b.line}: G87 back boring with the Fanuc sequence; shift along "
                          f"+{_AXES[PLANE_AXES[self.plane][0]]} (assumed)")

    def add_dwell(self, b: Block, secs: float) -> None:
        if secs > 0:
            self.dwell_s += secs
            self.event(b.line, "dwell", secs)

    # --- result -----------------------------------------------------------------------------
    def finish(self, path: str, text: str) -> Program:
        if self.comp.held or self.comp.side:
            self.notes.append("program ends with cutter compensation on (no G40, M2 or M30): the last move ends at "
                              "its offset end point (assumed)")
            try:
                self.comp.stop(end_program=True)
            except CompensationError as e:
                raise ParseError(e.message, file=self.file, line=max(self.comp.held[0].line, 1), column=1,
                                 expected=e.expected) from None
        tp, ints = self.m.to_arrays()
        compensated = np.zeros(len(tp), bool)
        compensated[self.comp.moves] = True
        cycle = np.zeros(len(tp), np.int16)
        for first, end, code in self.cycle_runs:
            cycle[first:end] = code
        if self.safe_z_pending:
            z = np.concatenate([tp.start[:, 2], tp.end[:, 2]])
            finite = z[np.isfinite(z)]
            safe = self.opt.safe_z_mm if self.opt.safe_z_mm is not None else (finite.max() if len(finite) else 0.0)
            for arr in (tp.start, tp.end):
                arr[np.isnan(arr[:, 2]), 2] = safe
            arc = (tp.kind >= ARC_CW) & np.isnan(tp.center[:, 2])
            tp.center[arc, 2] = safe
            self.notes.append(f"safe height for unknown-home retracts: Z {safe:g} mm")
        return Program(
            path=path, text=text, toolpath=tp, dialect=self.dialect.name, blocks=self.blocks,
            units=self.units_seen or ["mm"], move_inch=ints[:, 6].astype(bool), feed_mode=ints[:, 7].astype(np.int16),
            incremental=ints[:, 8].astype(bool), arc_absolute=ints[:, 9].astype(bool), events=self.events, notes=self.notes,
            dwell_s=self.dwell_s, compensated=compensated, control_flow=self.control_flow,
            cycle=cycle)


def _peck_depths(r: float, bottom: float, delta: float):
    """The depths of a peck cycle's pecks above its bottom (mm): R − Q, R − 2Q, ...; they stop where a
    peck falls below the float resolution at that depth (no progress)."""
    depth = r - delta
    while depth > bottom:
        yield depth
        if depth - delta >= depth:
            return
        depth -= delta
