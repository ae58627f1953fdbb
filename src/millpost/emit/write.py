"""Writing a program back with new feeds: every line byte-identical except the words that must change.

A `FeedPlan` gives, per move of the program's toolpath, the feed (mm/min) to run it at, and optionally
fragments: a move whose feed must change part-way is split at fractions of its length, lines as lines
and arcs as arcs (keeping the line's IJK or R style, its distance modes and its number format).
F is modal, so an F word is written wherever the wanted feed differs from the one in force; an F the
program already had and that still holds keeps its bytes; a line holding only an F word just before
the move (CAMotics' `F369.75` lines) takes the new value instead of the move getting a second F.
A move of zero length (a repeated point) takes no time: it gets no F of its own, the F in force holds.
Blocks that run several moves (canned cycles, G28) get the lowest feed any of their moves of nonzero
length wants: never faster than the plan. Moves under
cutter radius compensation (G41/G42) are never split: the controller offsets whatever coordinates are
written, so a split point (a point of the offset path) would be offset again; they take one F. Neither
are moves of canned cycles: a cycle block's X Y Z R are the hole's, not a move's end, nor moves of a
line that computes a word (a parameter or an expression, ``G1 Z#<depth>``): split pieces would replace
the expressions by numbers; the line keeps its words and only its F changes. Nor are the moves of a
program read through a translation (Sinumerik, Heidenhain): it is written back in its own language
with only F words changed (`in_source`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from ..errors import MillpostError
from ..gcode import dialects
from ..gcode.feed_mode import FeedMode
from ..gcode.flow import control_of
from ..gcode.interpret import BORING_CYCLES, INCH, TAPPING_CYCLES, Program
from ..gcode.lexer import Block, lex_line, source_lines
from ..toolpath import ARC_CW, PLANE_AXES, RAPID
from .policy import cluster

SPLIT_TOLERANCE_MM = 1e-4  # a split point lies this close to the original path at most
# relative: a planned feed this close under a value of the written grid is that value (float round-off of
# the unit conversion; the solver's tolerance on a cap is taken up by FeedPlan.from_fragments, which writes
# the cap itself); no larger, or a cap just under a grid value would be written above it
FEED_ROUNDOFF = 1e-9
SNAP_TO_PROGRAMMED = 1e-3  # relative: the solver's tolerance on a bound, far inside every limit's margin
_AXIS_LETTERS = "XYZ"
_ARC_LETTERS = "IJK"
_WORD_ORDER = "XYZIJKRF"  # where a word a line lacks goes among its words


def _slot(letter: str, line_letters: list[str]) -> tuple[int, int] | None:
    """Where a word the line lacks goes among the line's words (indices into line_letters): after the
    last one that comes before it in X Y Z I J K R F (+1), else before the first that comes after it
    (-1); None when the line has neither (a split arc's Y goes after X, not after I J)."""
    k = _WORD_ORDER.index(letter)
    before = [n for n, L in enumerate(line_letters) if L in _WORD_ORDER[:k]]
    if before:
        return max(before), 1
    after = [n for n, L in enumerate(line_letters) if L in _WORD_ORDER[k + 1:]]
    return (min(after), -1) if after else None


@dataclass
class FeedPlan:
    """Per move: `feed_mm_min` (nan for moves left as programmed, e.g. rapids) and, for moves split
    part-way, `fragments[move] = [(u_end, feed_mm_min), ...]` with u_end increasing to 1. `step`
    (relative): the least change of F worth a word, measured on the F words as written (`_stepped`)."""

    feed_mm_min: np.ndarray
    fragments: dict[int, list[tuple[float, float]]]
    step: float = 0.0
    # source lines that run several times (control flow): those that keep the program's F, and those
    # whose one F, the lowest any run allows, slows a run that could go faster (`from_fragments`)
    kept_lines: tuple[int, ...] = ()
    shared_lines: tuple[int, ...] = ()
    # the machine's axis rates (mm/min, X Y Z): a piece of a split line takes no F above what its axes run
    # in the direction its rounded split points give it (None: no such cap)
    axis_vmax_mm_min: tuple[float, float, float] | None = None

    @classmethod
    def programmed(cls, program: Program) -> "FeedPlan":
        return cls(program.toolpath.feed_mm_min.copy(), {})

    @classmethod
    def from_fragments(cls, program: Program, fragments, step: float, hard_cap_mm_s: np.ndarray,
                       axis_vmax_mm_min: tuple[float, float, float] | None = None) -> "FeedPlan":
        """The plan (mm/min, the F words' unit) from the policy's fragments (`emit.policy.Fragment`, mm/s).
        With control flow a line that runs several times gets
        one F (the lowest of its runs): those line feeds are clustered (`cluster`) so that two different
        ones differ by at least `step`. One F would slow the runs programmed faster than the slowest one
        (a subroutine's F[#5/1.5] called with several feeds): unless a run must go slower than programmed
        (a hard limit), a line with its own F word whose single F would be below a run's programmed feed
        keeps the program's F (each run at its programmed feed). axis_vmax_mm_min: the machine's axis rates
        (`_split_move`). hard_cap_mm_s: per move, the lowest speed
        cap of the hard limits over its samples (a run is forced slower where it is under the programmed feed)."""
        plan = replace(cls.programmed(program), step=step, axis_vmax_mm_min=axis_vmax_mm_min)
        hard_cap_mm_min = np.asarray(hard_cap_mm_s, float) * 60.0
        by_move: dict[int, list] = {}  # per move its fragments (u_start, u_end, feed in mm/min)
        for f in fragments:
            by_move.setdefault(f.move, []).append((f.u_start, f.u_end, f.feed_mm_s * 60.0))
        programmed_mm_min = program.toolpath.feed_mm_min

        def held(mv: int, f: float) -> float:
            """A bound held at the programmed feed or at the move's hard cap (machine maximum, plunge
            raise) is met to the solver's tolerance: a feed within SNAP_TO_PROGRAMMED under the programmed
            one (where no hard cap is under it), or under the hard cap, is that bound (no F400 → F399.9
            churn, no F24 → F23.99 for a plunge raised to twice its F12); nan where none is."""
            p, cap = programmed_mm_min[mv], hard_cap_mm_min[mv]
            for bound in ((p, cap) if p <= cap else (cap,)):
                if bound * (1 - SNAP_TO_PROGRAMMED) <= f < bound:
                    return float(bound)
            return math.nan

        # the schedule gives a run of moves one feed (its lowest member's): a feed held at a bound is
        # that bound on every move of its run whose hard cap allows it (not 10 and 9.9974 alternately)
        lifted: dict[float, float] = {}
        for mv, frs in by_move.items():
            for _, _, f in frs:
                bound = held(mv, f)
                if not math.isnan(bound):
                    lifted[f] = min(lifted.get(f, math.inf), bound)

        def snapped(mv: int, f: float) -> float:
            bound = lifted.get(f, math.nan)
            return bound if bound <= hard_cap_mm_min[mv] else f

        for mv, frs in by_move.items():
            frs.sort(key=lambda f: f[0])
            if len(frs) == 1:
                plan.feed_mm_min[mv] = snapped(mv, frs[0][2])
            else:
                plan.fragments[mv] = [(u_end, snapped(mv, f)) for _, u_end, f in frs]
                plan.feed_mm_min[mv] = min(f for _, f in plan.fragments[mv])
        plan.feed_mm_min, held = cycle_feeds(program, plan.feed_mm_min)
        for mv in held:
            plan.fragments.pop(int(mv), None)
        if program.control_flow:
            tp = program.toolpath
            fed = np.flatnonzero(np.isfinite(plan.feed_mm_min) & (tp.kind != RAPID))
            lines, inverse = np.unique(tp.line[fed], return_inverse=True)
            per_line, run_max = np.full(len(lines), np.inf), np.zeros(len(lines))
            prog_max, forced = np.zeros(len(lines)), np.zeros(len(lines), bool)
            np.minimum.at(per_line, inverse, plan.feed_mm_min[fed])
            np.maximum.at(run_max, inverse, plan.feed_mm_min[fed])
            np.maximum.at(prog_max, inverse, tp.feed_mm_min[fed])
            one_f = cluster(per_line, step)  # one F per line: the lowest of its runs, clustered
            np.logical_or.at(forced, inverse, hard_cap_mm_min[fed] < tp.feed_mm_min[fed] * (1 - step))
            text = source_lines(program.text)
            own_f = np.array([bool(re.search(r"[Ff]\s*[-+\d.#\[]", re.sub(r"\([^)]*\)|;.*", "", text[n - 1])))
                              for n in lines], bool)
            keep = own_f & ~forced & (one_f < prog_max * (1 - 1e-9))
            plan.feed_mm_min[fed] = np.where(keep[inverse], tp.feed_mm_min[fed], one_f[inverse])
            plan.fragments = {}
            runs = np.zeros(len(lines), int)  # moves of each line outside canned cycles: its runs
            np.add.at(runs, inverse, program.cycle[fed] == 0)
            again = runs > 1
            plan.kept_lines = tuple(int(n) for n in lines[keep & again])
            plan.shared_lines = tuple(int(n) for n in lines[~keep & again & (run_max > one_f * (1 + step))])
        return plan


def cycle_feeds(program: Program, feed_mm_min: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-move feeds (mm/min) as a canned cycle's block can carry them: one F for all the feed moves of
    a block (its pecks, its approach from R), the lowest any of them of nonzero length wants; a tapping
    cycle feeds at the tap's pitch times the spindle speed (synchronised), so its F is never changed; a
    boring cycle's feed sets the finish of the bore, so it is never raised (a hard limit may lower it).
    Returns the feeds and the indices of the tapping and boring cycles' moves."""
    tp = program.toolpath
    out = np.array(feed_mm_min, float, copy=True)
    cyc = np.flatnonzero((program.cycle != 0) & (tp.kind != RAPID) & (tp.lengths() > 0))
    if len(cyc):
        lines, inverse = np.unique(tp.line[cyc], return_inverse=True)
        lowest = np.full(len(lines), np.inf)
        np.fmin.at(lowest, inverse, out[cyc])
        out[cyc] = np.where(np.isfinite(lowest[inverse]), lowest[inverse], out[cyc])
    held = np.flatnonzero(np.isin(program.cycle, TAPPING_CYCLES + BORING_CYCLES))
    programmed = tp.feed_mm_min[held]
    out[held] = np.where(np.isin(program.cycle[held], TAPPING_CYCLES), programmed, np.fmin(out[held], programmed))
    return out, held


class UnknownParameters(dict):
    """Parameters whose values the text alone cannot give (0 for any missing one); an operation
    undefined on such values (a division by 0) gives 0 too: they only locate a line's words."""

    values_unknown = True

    def __missing__(self, key) -> float:
        return 0.0


def line_decimals(block: Block, default: int) -> int:
    found = [len(w.text.split(".")[1].rstrip()) for w in block.words if "." in w.text and "[" not in w.text]
    return max(found + [default])


def program_trailing_point(program: Program) -> bool:
    """Whether the program writes whole numbers as "10." (Fanuc style) or "10": from its own whole
    coordinates and feeds (comments aside), the more frequent; the dialect's style where it has none."""
    text = re.sub(r"\([^)\n]*\)|;[^\n]*", "", program.text)
    pointed = len(re.findall(r"[XYZIJKRF]\s*-?\d+\.(?![\d])", text, flags=re.IGNORECASE))
    bare = len(re.findall(r"[XYZIJKRF]\s*-?\d+(?![\d.])", text, flags=re.IGNORECASE))
    if pointed == bare:
        return dialects.get(program.dialect).trailing_point
    return pointed > bare


def _f_decimals(program: Program) -> int | None:
    """The program's own way of writing F (comments aside): a fixed count of decimals where every F word
    has that many and some end in a zero (FreeCAD's F400.000, a post's F5.0: padded), else None (as many
    as the value needs, 0.1 mm/min or 0.01 in/min; whole-number programs too: F2082.8 is not F2082)."""
    found = re.findall(r"[Ff]\s*[-+]?\d*(?:\.(\d*))?(?![\d#\[])", re.sub(r"\([^)\n]*\)|;[^\n]*", "", program.text))
    counts = {len(frac) for frac in found}
    if len(counts) != 1 or not any(frac.endswith("0") for frac in found):
        return None
    return counts.pop()


def line_trailing_point(block: Block, default: bool) -> bool:
    """Whether this line writes whole numbers as "10." (from its own numbers, else the dialect)."""
    nums = [w.text[1:].strip() for w in block.words if w.letter in "XYZIJKRF" and "[" not in w.text]
    if any(t.endswith(".") for t in nums):
        return True
    if any("." not in t for t in nums):
        return False
    return default


def format_number(value: float, decimals: int, trailing_point: bool) -> str:
    text = f"{value:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0")
        if text.endswith(".") and not trailing_point:
            text = text[:-1]
    if text in ("-0", "-0.", "-", "-."):
        text = "0." if trailing_point else "0"
    return text


_SPACED = re.compile(r"[A-Za-z0-9.\]>][ \t]+[A-Za-z]")  # a word, blanks, the next word
_UNSPACED = re.compile(r"[0-9.\]>][A-Za-z]")  # a word's value, the next word
_UNITS = re.compile(r"[Gg]\s*0*2[01](?![\d.])")  # G20 or G21 (a comment's text may match: the lexer decides)


def _units_of(block: Block, default: float | None) -> float | None:
    """mm per program unit a block's G20/G21 sets, else `default`."""
    for w in block.words:
        if w.letter == "G" and round(w.value * 10) in (200, 210):
            return INCH if round(w.value * 10) == 200 else 1.0
    return default


def program_spaced(program: Program) -> bool:
    """Whether the program usually puts blanks between its words (comments aside): the style of a line
    too short to show its own."""
    code = re.sub(r"\([^)\n]*\)|;[^\n]*", "", program.text)
    return len(_SPACED.findall(code)) >= len(_UNSPACED.findall(code))


class LineWriter:
    """Edits one source line: replace or add words, keeping every other byte."""

    def __init__(self, raw: str, block: Block, spaced: bool) -> None:
        self.raw, self.block = raw, block
        self.lower = bool(block.words) and all(w.text[0].islower() for w in block.words if w.text[0].isalpha())
        one_word = len(block.words) + (block.number is not None) < 2
        self.sep = " " if (spaced if one_word else _SPACED.search(raw)) else ""

    def replace(self, new: dict[str, str], drop: set[str] = frozenset()) -> str:
        """Words by letter set to new text (added where `_slot` puts them when absent, else after the
        last word); `drop` removed."""
        text = self.raw
        edits = []  # (start, end, replacement)
        placed = set()
        for w in self.block.words:
            if w.letter in new:
                edits.append((w.start, w.end, w.letter + new[w.letter] if w.text[0].isupper() or not w.text[0].isalpha()
                              else w.letter.lower() + new[w.letter]))
                placed.add(w.letter)
            elif w.letter in drop:
                s = w.start
                while s > 0 and text[s - 1] in " \t" and self.sep:
                    s -= 1
                edits.append((s, w.end, ""))
        missing = sorted((L for L in new if L not in placed), key=_WORD_ORDER.index)
        case = str.lower if self.lower else str.upper
        kept = [w for w in self.block.words if w.letter in _WORD_ORDER and w.letter not in drop]
        inserts: dict[tuple[int, int], str] = {}  # (position, side) -> text, in X Y Z I J K R F order
        for L in missing:
            slot = _slot(L, [w.letter for w in kept])
            if slot is None:
                anchor = [w.end for w in self.block.words if w.letter in "GXYZIJKR" and w.letter not in drop]
                slot_at, side = (max(anchor) if anchor else self.block.code_end), 1
            else:
                slot_at, side = (kept[slot[0]].end, 1) if slot[1] > 0 else (kept[slot[0]].start, -1)
            word = case(L) + new[L]
            before = inserts.get((slot_at, side), "")
            inserts[(slot_at, side)] = before + (self.sep + word if (side > 0 and (slot_at > 0 or before))
                                                 else word + self.sep)
        edits += [(at, at, text) for (at, _), text in inserts.items()]
        for s, e, rep in sorted(edits, key=lambda t: (t[0], t[1]), reverse=True):
            text = text[:s] + rep + text[e:]
        return text


def write_feeds(program: Program, plan: FeedPlan, *, trailing_point: bool | None = None) -> str:
    """The program's text with feeds as planned. Units, feed modes (G93/G94/G95) and distance modes
    are those the program had at each line; numbers take the line's own precision."""
    tp = program.toolpath
    if len(plan.feed_mm_min) != len(tp):
        raise MillpostError(f"feed plan has {len(plan.feed_mm_min)} moves, program has {len(tp)}")
    if program.control_flow and not plan.fragments and np.array_equal(plan.feed_mm_min, tp.feed_mm_min,
                                                                      equal_nan=True):
        return in_source(program, program.text)
    return in_source(program, _FeedWriter(program, plan, trailing_point).write())


class _FeedWriter:
    """Goes through a program's source lines once, writing each line that cuts with the F its moves
    want, and keeping what is modal as the lines run: the F in force in the output (`modal_f`) and in the
    program (`in_f`), both in F units of `f_units` mm; the length units (`units`, mm per program unit);
    parameters set so far; and a line holding only an F word just before (`f_line`).

    With O-word control flow (`flow`) a line may run several times, with other parameters and after other
    lines than the text shows: every line that feeds gets its own F (the lowest any run of it wants), no
    F is kept for its value, and parameters only locate the words."""

    def __init__(self, program: Program, plan: FeedPlan, trailing_point: bool | None) -> None:
        tp = program.toolpath
        self.program, self.plan = program, plan
        self.default_trailing = program_trailing_point(program) if trailing_point is None else trailing_point
        self.f_decimals = _f_decimals(program)
        # per move, as Python numbers (indexing numpy arrays one element at a time costs more than the work)
        self.lengths: list[float] = tp.lengths().tolist()
        self.planned: list[float] = plan.feed_mm_min.tolist()  # mm/min
        self.programmed: list[float] = tp.feed_mm_min.tolist()  # mm/min
        self.mode: list[int] = program.feed_mode.tolist()
        self.move_inch: list[bool] = program.move_inch.tolist()
        self.compensated: list[bool] = program.compensated.tolist()
        self.rpm: list[float] = tp.rpm.tolist()
        self.by_line: dict[int, list[int]] = {}
        for i in np.flatnonzero(tp.kind != RAPID):
            self.by_line.setdefault(int(tp.line[i]), []).append(int(i))
        self.spaced = program_spaced(program)
        self.modal_f: float | None = None
        self.in_f: float | None = None
        self.units, self.f_units = 1.0, 1.0
        self.before_units = dialects.get(program.dialect).feed_before_units  # F on a G20/G21 line: units before
        self.flow = program.control_flow
        self.params: dict = UnknownParameters() if self.flow else {}
        # a line holding only an F word (`F369.75` before `G1 X4`), followed by nothing but comments and
        # blank lines up to the next cutting line: (its index in out, its text, block, ending). Where that
        # line needs a new F, the F line's value is rewritten instead of a second F being added.
        self.f_line: tuple[int, str, Block, str] | None = None
        self.out: list[str] = []

    def write(self) -> str:
        for n, raw in enumerate(source_lines(self.program.text, keepends=True), start=1):
            body = raw.rstrip("\r\n")
            moves = self.by_line.get(n)
            if self.flow and control_of(body) is not None:
                self.out.append(raw)
            elif moves is None:
                self._other_line(n, raw, body)
            else:
                self._cutting_line(n, raw, body, raw[len(body):], moves)
        return "".join(self.out)

    def _other_line(self, n: int, raw: str, body: str) -> None:
        """A line without cutting moves, kept; read for parameters to carry, an F that sets the modal feed,
        or a change of length units."""
        if re.sub(r"\([^)]*\)|;.*", "", body).strip():
            self.f_line = None
        if "#" in body or "f" in body.lower() or _UNITS.search(body):
            try:
                block = lex_line(body, n, self.program.path, self.params)
            except MillpostError:  # a line the interpreter never ran (after M2, block delete, ...)
                self.out.append(raw)
                return
            self.params.update(block.assigns)
            f = next((w for w in block.words if w.letter == "F"), None)
            now = _units_of(block, self.units)
            if f is not None:
                self.modal_f = self.in_f = f.value
                self.f_units = self.units if self.before_units else now
                if not self.flow and len(block.words) == 1 and not block.assigns:
                    self.f_line = (len(self.out), body, block, raw[len(body):])
            self.units = now
        self.out.append(raw)

    def _cutting_line(self, n: int, raw: str, body: str, ending: str, moves: list[int]) -> None:
        """A line with cutting moves: its F (or, where the plan splits its one move, its pieces)."""
        program, plan, lengths, planned, mode = self.program, self.plan, self.lengths, self.planned, self.mode
        standalone_f, self.f_line = self.f_line, None
        block = lex_line(body, n, program.path, self.params)
        self.params.update(block.assigns)
        line_units = INCH if self.move_inch[moves[0]] else 1.0
        scale = self.units if self.before_units and _units_of(block, None) is not None else line_units  # its F's
        if self.modal_f is not None and self.f_units != scale:  # the F in force, in this line's F units
            self.modal_f = self.modal_f * self.f_units / scale
            self.in_f = None if self.in_f is None else self.in_f * self.f_units / scale
        self.f_units, self.units = scale, line_units
        line = _FeedLine(self, block, body, scale)
        in_before = self.in_f  # the program's F in force before this line
        if line.f_word is not None:
            self.in_f = line.f_word.value
        repeats = line.f_word is not None and in_before is not None and _same(line.f_word.value, in_before)
        one_feed = None  # a split move whose pieces all write one F: not split, that F
        i = moves[0]
        if len(moves) == 1 and len(plan.fragments.get(i, ())) > 1 and not self.compensated[i] and not computed(block):
            pieces = line.distinct(i, plan.fragments[i], self.modal_f)
            if len(pieces) > 1:
                new_lines, self.modal_f = _split_move(program, i, pieces, block, line.writer, ending,
                                                      line.trailing_point, line.feed_text, lengths[i], self.modal_f,
                                                      repeats, plan.axis_vmax_mm_min)
                self.out.extend(new_lines)
                return
            one_feed = pieces[0][1]
        if not self.flow and all(lengths[i] <= 0.0 and mode[i] != FeedMode.INVERSE_TIME for i in moves):
            # a move to where the tool is takes no time: no F of its own, the F in force holds (or the one it
            # has, which then holds after it as in the program)
            self.modal_f = line.f_word.value if line.f_word is not None else self.modal_f
            self.out.append(raw)
            return
        timed = [i for i in moves if lengths[i] > 0.0] or moves  # a block's moves that take time set its F
        k = min(timed, key=lambda i: planned[i] if not math.isnan(planned[i]) else math.inf)
        if math.isnan(planned[k]):  # none has a planned feed
            if line.f_word is not None:
                self.modal_f = line.f_word.value
            self.out.append(raw)
            return
        if mode[k] == FeedMode.INVERSE_TIME and len(moves) > 1 and not all(self.compensated[i] for i in moves):
            raise MillpostError(f"{program.path}:{n}: inverse-time feed on a block with several moves")
        self.modal_f = self._set_f(line, raw, ending, moves, k, planned[k] if one_feed is None else one_feed,
                                   repeats, standalone_f)

    def _set_f(self, line: "_FeedLine", raw: str, ending: str, moves: list[int], k: int, feed_k: float,
               repeats: bool, standalone_f) -> float:
        """Write the line with the F of its move k at feed_k (mm/min): its own F kept, dropped, replaced or
        added, or the F line before it rewritten. Returns the F in force after the line (program units)."""
        modal_f, f_word = self.modal_f, line.f_word
        value = line.f_value(k, feed_k, self.lengths[k])
        inverse = self.mode[k] == FeedMode.INVERSE_TIME
        if self.flow:  # its own F, evaluated as it runs, still right on every run: keep it; else write one
            if f_word is not None and all(self.planned[i] == self.programmed[i] for i in moves):
                self.out.append(raw)
            else:
                self.out.append(line.writer.replace({"F": line.f_text(value)}) + ending)
            return value
        if f_word is not None and _same(f_word.value, value):
            if modal_f is not None and _same(modal_f, value) and not repeats and not inverse:
                self.out.append(line.writer.replace({}, drop={"F"}) + ending)  # its own F is now the F in force
            else:
                self.out.append(raw)  # the program's own F still holds: keep its bytes
            return value
        modal_holds = f_word is None and modal_f is not None and not inverse  # no F of its own: the F in force may do
        if modal_holds and _same(modal_f, value):
            self.out.append(raw)
            return modal_f
        written = line.feed_value(k, value, self.lengths[k], modal_f)
        if modal_holds and _same(modal_f, written):
            self.out.append(raw)
            return modal_f  # the F in force stays the one written
        text = line.f_text(written)
        if standalone_f is not None and f_word is None and not inverse:
            at, f_body, f_block, f_ending = standalone_f  # the F line before this one sets the feed
            self.out[at] = LineWriter(f_body, f_block, self.spaced).replace({"F": text}) + f_ending
            self.out.append(raw)
        elif modal_f is not None and _same(written, modal_f) and not repeats and not inverse:
            self.out.append(line.writer.replace({}, drop={"F"}) + ending)  # the F in force holds: no repeat
        else:
            self.out.append(line.writer.replace({"F": text}) + ending)
        return written


class _FeedLine:
    """The F words of one cutting line: its feed values in the line's F units (`scale` mm each), their
    text in its number style, and the last F written on it (`written`: and whether that F is under its
    move's programmed F, which `_stepped` keeps). Its `LineWriter` and number style are found when
    first asked for: most lines keep their bytes."""

    def __init__(self, feeds: _FeedWriter, block: Block, body: str, scale: float) -> None:
        self.feeds, self.block, self.body, self.scale, self.inch = feeds, block, body, scale, scale == INCH
        self.f_word = next((w for w in block.words if w.letter == "F"), None)
        self.written = {"f": math.nan, "held": False}

    @cached_property
    def writer(self) -> LineWriter:
        return LineWriter(self.body, self.block, self.feeds.spaced)

    @cached_property
    def trailing_point(self) -> bool:
        return line_trailing_point(self.block, self.feeds.default_trailing)

    def f_value(self, i: int, feed_mm_min: float, length_mm: float) -> float:
        """Move i's F value at feed_mm_min in its feed mode and this line's units."""
        feeds = self.feeds
        mode = feeds.mode[i]
        if mode == FeedMode.INVERSE_TIME and (feeds.compensated[i] or length_mm <= 0.0):
            # timed by the programmed length; a move of no length takes 1/F minutes whatever its feed
            programmed = feeds.programmed[i]
            return self.f_word.value * feed_mm_min / programmed if programmed > 0.0 else self.f_word.value
        if mode == FeedMode.INVERSE_TIME:
            return feed_mm_min / length_mm  # inverse time: 1/min
        if mode == FeedMode.PER_REV:
            return feed_mm_min / self.scale / max(feeds.rpm[i], 1e-12)  # per revolution
        return feed_mm_min / self.scale

    def f_grid(self, value: float) -> tuple[float, int]:
        """F `value` rounded down (never faster) to 0.1 mm/min or 0.01 in/min (two more decimals under
        10, at least the program's own fixed decimals), and those decimals; a value within FEED_ROUNDOFF
        under a grid value is that value (a cap the solver held, not an excess). The number `f_text` writes."""
        d = max((2 if self.inch else 1) + (2 if value < 10 else 0), self.feeds.f_decimals or 0)
        return math.floor(value * 10**d * (1 + FEED_ROUNDOFF)) / 10**d, d

    def f_text(self, value: float) -> str:
        """F in the program's units on the grid of `f_grid`, padded with zeros to the program's own fixed
        decimals where it pads its F words (`_f_decimals`)."""
        rounded, d = self.f_grid(value)
        text = format_number(rounded, d, self.trailing_point)
        if self.feeds.f_decimals:
            whole, _, frac = text.partition(".")
            text = f"{whole}.{frac:0<{self.feeds.f_decimals}}"
        return text

    def feed_value(self, i: int, f_value: float, length_mm: float, modal: float | None) -> float:
        """The F (program units, on the grid of `f_grid`) for move i at F value `f_value` (this line's F
        units, as `_FeedLine.f_value` gives it) after the F in force `modal`, changes smaller than the
        plan's step made none or a full step, under the move's programmed F only where a limit asks for
        it (`_stepped`; not in inverse time)."""
        feeds = self.feeds
        value = self.f_grid(f_value)[0]
        if feeds.flow or modal is None or feeds.mode[i] == FeedMode.INVERSE_TIME:
            return value
        programmed = feeds.programmed[i]
        keep = self.f_grid(self.f_value(i, programmed, length_mm))[0] if math.isfinite(programmed) else 0.0
        # the F in force is one a limit held under the programmed F of the move it was written for
        held = self.written["held"] and _same(modal, self.written["f"])
        out = self.f_grid(_stepped(value, modal, feeds.plan.step, keep, held))[0]
        self.written.update(f=out, held=out < keep)
        return out

    def feed_text(self, i: int, feed_mm_min: float, length_mm: float, modal: float | None) -> str:
        """`feed_value` as written (`f_text`: a value on the grid is written as it is)."""
        return self.f_text(self.feed_value(i, self.f_value(i, feed_mm_min, length_mm), length_mm, modal))

    def distinct(self, i: int, fragments: list[tuple[float, float]], modal: float | None) -> list[tuple[float, float]]:
        """Move i's fragments with each one whose F as written would be the F before it (`modal` the F in
        force before the line) merged into that one: no split point where the feed does not change."""
        saved, pieces, u_prev = dict(self.written), [], 0.0
        for u_end, feed in fragments:
            text = self.feed_text(i, feed, self.feeds.lengths[i] * (u_end - u_prev), modal)
            if pieces and text == pieces[-1][2] and self.feeds.mode[i] != FeedMode.INVERSE_TIME:
                pieces[-1] = (u_end, pieces[-1][1], text)
            else:
                pieces.append((u_end, feed, text))
            u_prev, modal = u_end, float(text)
        self.written.update(saved)
        return [(u, f) for u, f, _ in pieces]


def in_source(program: Program, text: str) -> str:
    """`text` (the program's RS-274 text with feeds written, `write_feeds`) in the program's own
    language: for a program read through a translation (`Program.source`), the source with each line's
    F as the written translation has it (`Dialect.set_feed`), every other byte kept; else `text`."""
    if program.source is None:
        return text
    set_feed = dialects.get(program.dialect).set_feed
    before, after = source_lines(program.text), source_lines(text)
    if len(after) != len(before):
        raise MillpostError(f"{program.path}: the feeds written changed the translation's lines "
                            f"({len(before)} → {len(after)}); only F words may change in a {program.dialect} program")
    out = source_lines(program.source, keepends=True)
    for n, (old, new) in enumerate(zip(before, after)):
        if old != new and n < len(out):
            f_old, f_new = _f_text(old), _f_text(new)
            if f_old != f_new:
                body = out[n].rstrip("\r\n")
                out[n] = set_feed(body, f_new) + out[n][len(body):]
    return "".join(out)


# a plain F word of a translated line (the translation writes F<number>, never a parameter or expression),
# outside comments and not part of a parameter name (#<_f>)
_PLAIN_F = re.compile(r"(?<![#<_A-Za-z])[Ff][ \t]*([-+]?(?:\d+\.?\d*|\.\d+))")
_NGC_COMMENT = re.compile(r"\([^()]*\)|;.*")


def _f_text(line: str) -> str | None:
    """The number text of a translated line's F word (None without one). Read from the text, not by
    evaluating the line: a translation's expressions may need the run's parameters to be defined."""
    found = _PLAIN_F.findall(_NGC_COMMENT.sub(" ", line))
    return found[-1].strip() if found else None


def split_decimals(block: Block, inch: bool) -> int:
    """Decimals of a split point: the line's own precision plus one digit, and at least enough that
    rounding every axis by half a unit of the last digit moves the point less than SPLIT_TOLERANCE_MM
    (√3·½·10⁻ᵈ·scale: 4 decimals in mm, 0.87e-4 mm; 6 in inch, 0.22e-4 mm; 5 in inch would be 2.2e-4)."""
    scale = INCH if inch else 1.0
    needed = math.ceil(math.log10(math.sqrt(3) * 0.5 * scale / SPLIT_TOLERANCE_MM))
    return max(line_decimals(block, 0) + 1, needed)


def _axis_rate(delta_mm: np.ndarray, vmax_mm_min) -> float:
    """The highest feed (mm/min) at which no axis exceeds its rate on a straight move of `delta_mm`
    (min over the axes of vmax_i·L/|Δ_i|); inf without rates."""
    length = float(np.linalg.norm(delta_mm))
    if vmax_mm_min is None or length <= 0:
        return math.inf
    share = np.abs(delta_mm) / length
    return float(np.min(np.where(share > 1e-12, np.asarray(vmax_mm_min) / np.maximum(share, 1e-12), np.inf)))


def _split_move(program: Program, i: int, fragments, block: Block, writer: LineWriter, ending: str,
                trailing_point: bool, feed_text, length_mm: float, modal_f: float | None,
                repeats: bool = False, vmax_mm_min=None) -> tuple[list[str], float]:
    """Split move i at the fragment ends: the first piece is the original line with its axis, arc and F
    words changed; later pieces are new lines in the style of the original (its motion word as written
    or none when it had none, its word order, letter case and spacing; a word it lacks where `_slot`
    puts it) with the end point, arc centre and F; an axis word where the piece ends on the line's own end
    in that axis is the line's own text. A piece writes no F where the F in force (modal_f,
    program units, before the line) already holds, except in inverse time (G93: F on every block) and
    on the first piece of a line whose own F repeats the program's F in force (`repeats`: its style).
    Split points take `split_decimals`; a straight piece's F is at most the axis rate of its direction as
    written (`vmax_mm_min`: its rounded ends turn it by up to ~1e-4 rad). Returns the lines and the F in
    force after them."""
    tp = program.toolpath
    inch = bool(program.move_inch[i])
    scale = INCH if inch else 1.0
    decimals = split_decimals(block, inch)
    incremental = bool(program.incremental[i])
    arc = tp.kind[i] >= ARC_CW
    uses_r = any(w.letter == "R" for w in block.words)
    g_word = next((w for w in block.words if w.letter == "G" and int(round(w.value)) in (1, 2, 3)), None)
    order = [w.letter for w in block.words if w.letter in _WORD_ORDER or w is g_word]
    has_f = any(w.letter == "F" for w in block.words)
    us = np.array([0.0] + [u for u, _ in fragments])
    points = tp.points(np.full(len(us), i), us)
    a1, a2, an = PLANE_AXES[int(tp.plane[i])]
    written_axes = {w.letter for w in block.words if w.letter in _AXIS_LETTERS}
    # where a piece ends on the line's own end in an axis (the last piece; an axis that does not move), in
    # absolute distance mode: that axis word's own text ("Z-0.0500", "z-.1", not Z-0.05, z-0.1)
    as_written = {} if incremental else {w.letter: w.text[1:].strip() for w in block.words if w.letter in _AXIS_LETTERS}
    out = []
    modal = modal_f
    start_written = points[0]  # the piece's start as written (mm): the line's start, then each split point
    for k, (u_end, feed) in enumerate(fragments):
        start, end = points[k], points[k + 1]
        seg_len = length_mm * (u_end - us[k])
        words: dict[str, str] = {}
        for ax in range(3):
            value = (end[ax] - start[ax]) if incremental else end[ax]
            moves_here = abs(end[ax] - start[ax]) > 1e-9
            if _AXIS_LETTERS[ax] in written_axes or moves_here:
                if _AXIS_LETTERS[ax] in as_written and abs(end[ax] - tp.end[i, ax]) <= 1e-9:
                    words[_AXIS_LETTERS[ax]] = as_written[_AXIS_LETTERS[ax]]
                elif k == 0 or moves_here or not incremental:
                    words[_AXIS_LETTERS[ax]] = format_number(value / scale, decimals, trailing_point)
        if arc:
            if uses_r:
                r = math.hypot(start[a1] - tp.center[i, a1], start[a2] - tp.center[i, a2])
                sweep = _sweep(tp, i) * (u_end - us[k])
                words["R"] = format_number((r if abs(sweep) <= math.pi else -r) / scale, decimals, trailing_point)
            else:
                for ax in (a1, a2):  # relative to the start as written (rounded), so the centre stays exact
                    written = round(start[ax] / scale, decimals) * scale
                    c = tp.center[i, ax] if program.arc_absolute[i] else tp.center[i, ax] - written
                    words[_ARC_LETTERS[ax]] = format_number(c / scale, decimals, trailing_point)
        if not (arc or incremental):  # no faster than the axes run the piece as written (rounded)
            end_written = np.array([float(words[L]) * scale if L in words else end[ax]
                                    for ax, L in enumerate(_AXIS_LETTERS)])
            feed = min(feed, _axis_rate(end_written - start_written, vmax_mm_min))
            start_written = end_written
        f = feed_text(i, feed, seg_len, modal)
        if (modal is None or not _same(modal, float(f)) or int(program.feed_mode[i]) == FeedMode.INVERSE_TIME
                or (k == 0 and has_f and repeats)):
            words["F"] = f
        if k == 0:
            drop = set(_AXIS_LETTERS + _ARC_LETTERS + "RF") - set(words)
            out.append(writer.replace(words, drop=drop) + ending)
        else:
            def rank(L: str) -> tuple[int, int, int]:
                if L in order:
                    return order.index(L), 0, 0
                slot = _slot(L, order)
                return (len(order), 1, _WORD_ORDER.index(L)) if slot is None else (*slot, _WORD_ORDER.index(L))

            ranked = sorted(words, key=rank)
            texts = [(L.lower() if writer.lower else L) + words[L] for L in ranked]
            if g_word is not None:
                at = order.index("G") if "G" in order else 0
                texts.insert(min(at, len(texts)), g_word.text.strip())
            sep = writer.sep
            out.append(sep.join(texts) + ending)
        modal = float(f)
    return out, modal


def computed(block: Block) -> bool:
    """Whether a word other than F holds a parameter or an expression (``Z#<z_cut>``, ``Y[#1*2]``). Such
    a line is never split: split pieces would write the computed values as numbers. Only its F changes."""
    return any("#" in w.text or "[" in w.text for w in block.words if w.letter != "F")


def _computed_line(text: str, n: int, path: str) -> bool:
    try:
        return computed(lex_line(text, n, path, UnknownParameters()))
    except MillpostError:  # not a line the lexer reads alone (control flow): the interpreter ran it
        return True


def whole_moves(program: Program, fragments: list) -> list:
    """Fragments (`emit.policy.Fragment`) with those of each compensated move, of each move a canned
    cycle runs (its block's words are the cycle's, not a move's end point), and of each move whose line
    computes a word (`computed`), merged into one over the whole move at their lowest feed (such moves
    are written with one F, see the module docstring). A translated program's move whose source line
    cannot carry its feed (`Dialect.fixed_feed`: a Heidenhain cycle call, whose feed is its cycle's Q206),
    and one on a line past the source's end (a subroutine the translation appends, such as a Sinumerik
    subprogram read from its own file, which is not written), keeps its programmed feed."""
    out, whole = [], {}
    lines, move_line = source_lines(program.text), program.toolpath.line
    suspect = {int(move_line[f.move]) for f in fragments}
    computed_lines = {n for n in suspect if 0 < n <= len(lines) and (
        program.source is not None  # a translated program's moves: only F words may change
        or ("#" in lines[n - 1] or "[" in lines[n - 1]) and _computed_line(lines[n - 1], n, program.path))}
    fixed: set[int] = set()  # lines whose moves keep their programmed feed
    if program.source is not None:
        source, fixed_feed = source_lines(program.source), dialects.get(program.dialect).fixed_feed
        fixed = {n for n in suspect if n > len(source) or fixed_feed is not None and 0 < n and fixed_feed(source[n - 1])}
    programmed = program.toolpath.feed_mm_s
    for f in fragments:
        line = int(move_line[f.move])
        if not (program.compensated[f.move] or program.cycle[f.move] or line in computed_lines):
            out.append(f)
        elif line in fixed:
            whole[f.move] = replace(f, u_start=0.0, u_end=1.0, feed_mm_s=float(programmed[f.move]))
        elif f.move not in whole or f.feed_mm_s < whole[f.move].feed_mm_s:
            whole[f.move] = replace(f, u_start=0.0, u_end=1.0)
    return out + list(whole.values())


def _stepped(value: float, modal: float, step: float, keep: float = 0.0, held: bool = False) -> float:
    """The F to write (program units) for a wanted F `value` after the F in force `modal`, so that every
    change is at least `step` of the F it leaves: a rise by less keeps the F in force (slower, never
    faster than planned), a fall by less falls a full step to modal·(1 − step) (written rounded down).
    Where the wanted F is at least `keep` (the move's programmed F), only a limit may leave the written
    one under it: a rise by less keeps a modal under `keep` only if a limit `held` it there (one F for
    a run a limit slows in part), and a fall stops at `keep`; otherwise the change is smaller than the
    step. (The schedule's runs differ by `step` of the lower feed; a fall is measured from the higher
    one, and rounding to the written grid shrinks either.)"""
    if modal < value < modal * (1 + step):
        return modal if held or modal >= keep or value < keep else keep
    if modal * (1 - step) < value < modal:
        return modal * (1 - step) if value < keep else max(modal * (1 - step), keep)
    return value


def _same(a: float, b: float) -> bool:
    return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))


def _sweep(tp, i: int) -> float:
    sub = tp.subset(np.array([i]))
    return float(sub._arc_params()[3][0])


def replace_numbers(program: Program, words: dict[int, dict[str, float]]) -> str:
    """The program's text with the values of words on given lines replaced ({line: {letter: value}}),
    each written in its own style (decimals, trailing point, case); every other byte as it was. A
    letter the line does not have is an error (nothing is added)."""
    lines = source_lines(program.text, keepends=True)
    for n, new in sorted(words.items()):
        body = lines[n - 1].rstrip("\r\n")
        block = lex_line(body, n, program.path, UnknownParameters())
        have = {w.letter: w for w in block.words}
        missing = sorted(set(new) - set(have))
        if missing:
            raise MillpostError(f"{program.path}:{n}: no {', '.join(missing)} word to change")
        texts = {}
        for letter, value in new.items():
            old = have[letter].text[1:].strip()
            decimals = len(old.split(".")[1]) if "." in old else 0
            trailing = old.endswith(".")
            texts[letter] = format_number(value, max(decimals, 1) if trailing else decimals, trailing)
        lines[n - 1] = LineWriter(body, block, True).replace(texts) + lines[n - 1][len(body):]
    return "".join(lines)
