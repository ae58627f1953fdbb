"""Cutter radius compensation (G40, G41/G42 with D, G41.1/G42.1) as LinuxCNC 2.9's interpreter does it.

The tool centre runs one tool radius r (mm) to the left (G41) or right (G42) of the programmed contour,
in the working plane (G17: X-Y, G18: Z-X); the third axis passes through. A negative diameter swaps
the side. Geometry, with n the unit normal of a move on the compensation side:

- entry (first move after G41/G42): from the current point, a line to its end point + r·n, n taken
  on the line from the start; an arc through the end point + r·n whose centre keeps the compensated
  arc tangent to the programmed one at the end (the start is not offset).
- later moves end at their programmed end + r·n; arcs keep their centre, radius R ± r (− inside).
  At the corner between two moves, by the turn β of the offset direction (0.05 rad tolerance):
  convex: an arc of radius r about the programmed corner joins the two offset moves (for G0, a
  straight rapid); straight on: joined directly; concave: the previous offset move is cut back to
  where the two offset paths meet — line-line by r/tan((β+π)/2), line-arc, arc-line, arc-arc by the
  intersection of the offset line and circles.
- a move is held until the next one fixes its end (one-move look-ahead); moves with no motion in the
  plane (Z only) are held with it and take the same end point in the plane.
- G40 (and M0/M1/M2/M30/M60): the held moves end at their own offset end point. The first move after
  G40 (a line: an arc is refused) runs from there to its programmed end, uncompensated.

Gouges and impossible corners are refused with LinuxCNC's own words, as `CompensationError`s that the
interpreter turns into file:line:column errors. So are the modal changes LinuxCNC refuses while
compensation is on (tool change, tool length, work offsets, G28/G30, G53, canned cycles, planes, ...).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import MillpostError
from ..toolpath import ARC_CCW, ARC_CW, FEED, PLANE_AXES, RAPID

LEFT, RIGHT = 1, -1  # the side as the sign of the turn from the direction of travel to the offset normal
CORNER_TOL_RAD = 0.05  # LinuxCNC's TOLERANCE_CONCAVE_CORNER: a turn within this is straight on
_EQUAL = 1e-4  # LinuxCNC's TOLERANCE_EQUAL (2.9)
# how much further (rad) a cut-back arc may sweep than programmed: rs274 2.9 allows 0.001 in inch programs
# and 25.4 times that in mm programs (measured: it scales the tolerance as a length)
_SWEEP_TOL_INCH, _SWEEP_TOL_MM = 0.001, 0.0254
_HALF_PI = math.pi / 2

# What LinuxCNC refuses while compensation is on, by (letter, code·10 for G / code for M): its message.
REFUSED_WHILE_ON: dict[tuple[str, int], str] = {
    **{("G", g): "Cannot change tool offset with cutter radius compensation on" for g in (430, 431, 432, 490)},
    **{("G", g): "Cannot change coordinate systems with cutter radius compensation on"
       for g in (540, 550, 560, 570, 580, 590, 591, 592, 593)},
    **{("G", g): "Cannot change control mode with cutter radius compensation on" for g in (610, 611, 640)},
    **{("G", g): "Cannot change retract mode with cutter radius compensation on" for g in (980, 990)},
    **{("G", g): "Cannot change axis offsets with cutter radius comp" for g in (920, 520)},
    **{("G", g): "Cannot use g28 or g30 with cutter radius comp" for g in (280, 300)},
    **{("G", g): "Cannot set reference point with cutter compensation in effect" for g in (281, 301)},
    **{("G", g): "Cannot use canned cycles with cutter compensation on"
       for g in (730, 740, 760, 810, 820, 830, 840, 850, 860, 870, 880, 890)},
    ("G", 530): "Cannot use g53 with cutter radius comp",
    ("M", 6): "Cannot change tools with cutter radius compensation on",
    ("M", 48): "Cannot enable overrides with cutter radius compensation on",
    **{("M", m): "Cannot disable overrides with cutter radius compensation on" for m in (49, 50, 51, 52, 53)},
}


class CompensationError(MillpostError):
    """A refusal of the compensation: LinuxCNC's message and the word (letter, value) it is about."""

    def __init__(self, message: str, expected: str, letter: str = "", code: float | None = None) -> None:
        self.message, self.expected, self.letter, self.code = message, expected, letter, code
        super().__init__(message)


@dataclass
class _Held:
    """A compensated move waiting for the next one to fix its end. Plane coordinates (u, v) are the
    plane's first and second axes; `direction` is what LinuxCNC checks a moved end point against."""

    kind: int
    end: np.ndarray  # (3,) mm, program frame
    direction: tuple[float, float]
    line: int
    feed_mm_min: float
    modal: tuple
    center: tuple[float, float] = (math.nan, math.nan)
    turn: int = 0  # LinuxCNC's turn: +P counter-clockwise, -P clockwise
    sweep: float = 0.0  # the sweep (rad) a moved end point may not exceed; 0: not checked


def find_turn(u1: float, v1: float, cu: float, cv: float, turn: int, u2: float, v2: float) -> float:
    """Signed sweep (rad, + counter-clockwise) of an arc about (cu, cv) from (u1, v1) to (u2, v2) making
    `turn` partial or full turns (LinuxCNC's find_turn)."""
    if turn == 0:
        return 0.0
    a = math.atan2(v1 - cv, u1 - cu)
    b = math.atan2(v2 - cv, u2 - cu)
    if turn > 0:
        if b <= a:
            b += 2 * math.pi
        return b - a + (turn - 1) * 2 * math.pi
    if a <= b:
        a += 2 * math.pi
    return b - a + (turn + 1) * 2 * math.pi


def _inside(side: int, turn: int) -> bool:
    """Whether the tool runs inside an arc of this turn direction (LinuxCNC's TOOL_INSIDE_ARC)."""
    return (side == LEFT and turn > 0) or (side == RIGHT and turn < 0)


def _tool_too_large(radius_mm: float) -> CompensationError:
    return CompensationError("Tool radius not less than arc radius with comp",
                             f"an arc radius larger than the tool radius ({radius_mm:g} mm)")


Record = Callable[[int, object, object, object, int, float, int, tuple], None]


class CutterComp:
    """The compensation state machine of one program run. `record(kind, start, end, center, turns,
    feed_mm_min, line, modal)` appends a move to the toolpath; `count()` is how many it holds.
    Positions in mm in the program frame; `plane` indexes PLANE_AXES."""

    def __init__(self, record: Record, count: Callable[[], int]) -> None:
        self.record, self.count = record, count
        self.side = 0
        self.radius = 0.0
        self.first = True
        self.plane = 0
        self.programmed = np.zeros(3)  # programmed end of the last move
        self.current = np.zeros(3)  # its offset end (where the tool would stop with no next move)
        self.held: list[_Held] = []
        self.endpoint: tuple[float, float] | None = None  # start of the held moves in the plane, when known
        self.last_end: np.ndarray | None = None  # end of the last recorded compensated move
        self.exit_from: np.ndarray | None = None  # after G40: where the tool is, for the exit move
        self.moves: list[int] = []  # indices of the moves recorded here

    # --- state ------------------------------------------------------------------------------------
    @property
    def active(self) -> bool:
        """Whether moves must go through `move` (offsetting, or the exit move after G40)."""
        return (self.side != 0 and self.radius > 0) or self.exit_from is not None

    @property
    def pending(self) -> int:
        """Moves held back: they run before anything the interpreter records now."""
        return len(self.held)

    def check(self, letter: str, codes) -> None:
        """Refuse a G or M code LinuxCNC refuses while compensation is on."""
        if not self.side:
            return
        for code in codes:
            msg = REFUSED_WHILE_ON.get((letter, code))
            if msg is not None:
                if letter == "G" and code == 530 and self.radius <= 0:
                    continue
                value = code / 10 if letter == "G" else code
                raise CompensationError(msg, "G40 (compensation off) before this line", letter, value)

    def check_plane(self, plane: int) -> None:
        if self.side and plane != self.plane:
            raise CompensationError("Cannot change planes with cutter radius compensation on",
                                    "G40 (compensation off) before this line", "G", (17, 18, 19)[plane])

    def check_offsets(self, index: int, active: int) -> None:
        """G10 L2/L20 may not change the work offset in use."""
        if self.side and index == active:
            raise CompensationError("Cannot change the active coordinate system with cutter radius compensation on",
                                    "G40 before changing the active work offset", "G", 10)

    def on(self, side: int, radius_mm: float, plane: int) -> None:
        """G41 (LEFT) / G42 (RIGHT) with the tool radius (negative: the other side)."""
        if self.side:
            raise CompensationError("Cannot turn cutter radius comp on when on", "G40 before turning it on again",
                                    "G", 41 if side == LEFT else 42)
        if plane == 2:
            raise CompensationError("Cutter radius compensation allowed only in XY, XZ planes", "G17 or G18", "G", 19)
        if radius_mm < 0:
            side, radius_mm = -side, -radius_mm
        self.side, self.radius, self.plane, self.first = side, radius_mm, plane, True

    def off(self) -> None:
        """G40: the held moves end at their own offset end; the next move is the exit move."""
        if self.side and self.radius > 0 and not self.first:
            self.flush_at(self.current)
            self.exit_from = self.last_end.copy()
        self.side, self.first, self.endpoint = 0, True, None

    def stop(self, end_program: bool) -> None:
        """M0/M1/M60 flush the held moves; M2/M30 also switch compensation off."""
        if self.held:
            self.flush_at(self.current)
        self.endpoint = None
        if end_program:
            self.side, self.first, self.exit_from = 0, True, None

    # --- moves ------------------------------------------------------------------------------------
    def move(self, kind: int, start, end, center, turns: int, feed_mm_min: float, line: int, modal: tuple) -> None:
        """A programmed move (start, end, centre: program frame, mm) while `active`."""
        end = np.asarray(end, float)
        if self.side == 0 or self.radius <= 0:  # the exit move after G40
            if kind >= ARC_CW:
                raise CompensationError("The move just after exiting cutter compensation mode must be straight, "
                                        "not an arc", "a G0 or G1 move after G40", "G", 2 if kind == ARC_CW else 3)
            self._record(kind, self.exit_from, end, (math.nan,) * 3, 0, feed_mm_min, line, modal)
            self.exit_from = None
            return
        if self.first:  # the entry move starts where the tool is (after G40 and no exit move: still offset)
            self.last_end = self.exit_from if self.exit_from is not None else np.array(start, float)
            self.exit_from = None
            self.programmed = np.array(start, float)
        a1, a2, _ = PLANE_AXES[self.plane]
        if kind >= ARC_CW:
            turn = (turns + 1) * (1 if kind == ARC_CCW else -1)
            c = (float(center[a1]), float(center[a2]))
            (self._arc_entry if self.first else self._arc)(kind, end, c, turn, feed_mm_min, line, modal)
        else:
            (self._line_entry if self.first else self._line)(kind, end, feed_mm_min, line, modal)

    def _uv(self, p) -> tuple[float, float]:
        a1, a2, _ = PLANE_AXES[self.plane]
        return float(p[a1]), float(p[a2])

    def _point(self, u: float, v: float, normal: float) -> np.ndarray:
        a1, a2, an = PLANE_AXES[self.plane]
        p = np.empty(3)
        p[a1], p[a2], p[an] = u, v, normal
        return p

    def _normal(self, p) -> float:
        return float(p[PLANE_AXES[self.plane][2]])

    def _line_entry(self, kind: int, end: np.ndarray, feed: float, line: int, modal: tuple) -> None:
        cu, cv = self._uv(self.programmed)
        pu, pv = self._uv(end)
        r = self.radius
        if math.hypot(pu - cu, pv - cv) <= r:
            raise CompensationError("Length of cutter compensation entry move is not greater than the tool radius",
                                    f"an entry move longer than the tool radius ({r:g} mm)")
        alpha = math.atan2(pv - cv, pu - cu) + self.side * _HALF_PI
        target = self._point(pu + r * math.cos(alpha), pv + r * math.sin(alpha), self._normal(end))
        self.endpoint = (cu, cv)
        self.held.append(_Held(kind, target, (math.cos(alpha), math.sin(alpha)), line, feed, modal))
        self.first = False
        self.current, self.programmed = target, end.copy()

    def _arc_entry(self, kind: int, end: np.ndarray, center: tuple[float, float], turn: int, feed: float,
                   line: int, modal: tuple) -> None:
        cu, cv = self._uv(self.programmed)
        pu, pv = self._uv(end)
        r = self.radius
        if math.hypot(pu - cu, pv - cv) <= r:
            raise CompensationError("Radius of cutter compensation entry arc is not greater than the tool radius",
                                    f"an entry arc longer than the tool radius ({r:g} mm)")
        inside = _inside(self.side, turn)
        if inside and math.hypot(center[0] - cu, center[1] - cv) <= r:
            raise _tool_too_large(r)
        gamma = (math.atan2(center[1] - pv, center[0] - pu) if inside else math.atan2(pv - center[1], pu - center[0]))
        eu, ev = pu + r * math.cos(gamma), pv + r * math.sin(gamma)
        # the compensated arc: through the start and the offset end, centre on the line end->programmed centre
        half = math.hypot(cv - ev, cu - eu) / 2
        to_centre = math.atan2(center[1] - ev, center[0] - eu)
        a = math.atan2(cv - ev, cu - eu) - to_centre
        if abs(math.cos(a)) < _EQUAL:
            raise _tool_too_large(r)
        dist = half / math.cos(a)
        c2 = (eu + dist * math.cos(to_centre), ev + dist * math.sin(to_centre))
        target = self._point(eu, ev, self._normal(end))
        sweep = find_turn(cu, cv, c2[0], c2[1], turn, eu, ev)
        self.held.append(_Held(kind, target, (0.0, 0.0), line, feed, modal, c2, turn, sweep))
        self.first = False
        self.current, self.programmed = target, end.copy()

    def _line(self, kind: int, end: np.ndarray, feed: float, line: int, modal: tuple) -> None:
        cu, cv = self._uv(self.current)
        ou, ov = self._uv(self.programmed)
        pu, pv = self._uv(end)
        cz = self._normal(self.current)
        if pu == ou and pv == ov:  # no motion in the plane: held with the move before, same end in the plane
            self.held.append(_Held(kind, self._point(cu, cv, self._normal(end)), (0.0, 0.0), line, feed, modal))
            self.current = self._point(cu, cv, self._normal(end))
            self.programmed = end.copy()
            return
        r, side = self.radius, self.side
        theta = math.atan2(cv - ov, cu - ou)
        alpha = math.atan2(pv - ov, pu - ou)
        if side == LEFT:
            if theta < alpha:
                theta += 2 * math.pi
            beta = theta - alpha - _HALF_PI
        else:
            if alpha < theta:
                alpha += 2 * math.pi
            beta = alpha - theta - _HALF_PI
        gamma = side * _HALF_PI
        nu, nv = r * math.cos(alpha + gamma), r * math.sin(alpha + gamma)
        target = self._point(pu + nu, pv + nv, self._normal(end))
        front = self.held[0] if self.held else None
        concave = beta < -CORNER_TOL_RAD or beta > math.pi + CORNER_TOL_RAD or (
            beta > math.pi - CORNER_TOL_RAD and front is not None and front.kind >= ARC_CW
            and _inside(-side, front.turn))  # over the round top of an "h": stay on this side
        if not concave and beta > CORNER_TOL_RAD:  # convex: around the corner first
            self.flush_at((cu, cv))
            mid = self._point(ou + nu, ov + nv, cz)
            if kind == FEED:
                self._record(ARC_CW if side == LEFT else ARC_CCW, self.last_end, mid,
                             self._point(ou, ov, cz), 0, feed, line, modal)
            else:  # no arc at rapid: a rapid to the corner's far side
                self._record(RAPID, self.last_end, mid, (math.nan,) * 3, 0, math.nan, line, modal)
            self.endpoint = (ou + nu, ov + nv)
        elif concave:
            if front is None or front.kind < ARC_CW:  # line -> line
                half = (beta + math.pi) / 2
                if half == 0.0:
                    raise CompensationError("Zero degree inside corner is invalid for cutter compensation",
                                            "a corner the tool can enter")
                back = r / math.tan(half)
                self.flush_at((cu + back * math.cos(theta + gamma), cv + back * math.sin(theta + gamma)))
            else:  # arc -> line: where the offset line meets the offset arc
                self.flush_at(self._arc_line_corner(front, ou, ov, math.atan2(pv - ov, pu - ou)))
        else:  # straight on
            self.flush_at(None)
            self.endpoint = (cu, cv)
        self.held.append(_Held(kind, target, (pu - ou, pv - ov), line, feed, modal))
        self.current, self.programmed = target, end.copy()

    def _arc_line_corner(self, prev: _Held, ou: float, ov: float, base: float) -> tuple[float, float]:
        r, side = self.radius, self.side
        eu, ev = self._uv(prev.end)
        old = math.hypot(prev.center[1] - ev, prev.center[0] - eu)
        theta = base + _HALF_PI if prev.turn > 0 else base - _HALF_PI
        phi = math.atan2(prev.center[1] - ov, prev.center[0] - ou)
        inside = _inside(side, prev.turn)
        d = (old + r if inside else old - r) * math.cos(theta - phi)
        ratio = (d - r if inside else d + r) / old
        if abs(ratio) > 1.0:
            raise CompensationError("Arc to straight motion makes a corner the compensated tool can't fit in "
                                    "without gouging", f"a corner wider than the tool (radius {r:g} mm)")
        flip = (prev.turn > 0) == inside
        angle = theta + math.pi + (-math.acos(ratio) if flip else math.acos(ratio))
        return prev.center[0] + old * math.cos(angle), prev.center[1] + old * math.sin(angle)

    def _arc(self, kind: int, end: np.ndarray, center: tuple[float, float], turn: int, feed: float, line: int,
             modal: tuple) -> None:
        cu, cv = self._uv(self.current)
        ou, ov = self._uv(self.programmed)
        pu, pv = self._uv(end)
        cz = self._normal(self.current)
        r, side = self.radius, self.side
        R = math.hypot(center[0] - pu, center[1] - pv)
        theta = math.atan2(cv - ov, cu - ou) - side * _HALF_PI  # direction of travel at the end of the last move
        delta = math.atan2(center[1] - ov, center[0] - ou)
        alpha = delta - _HALF_PI if turn > 0 else delta + _HALF_PI  # direction of travel at the arc's start
        beta = theta - alpha if side == LEFT else alpha - theta
        beta = beta - 2 * math.pi if beta > 1.5 * math.pi else beta + 2 * math.pi if beta < -_HALF_PI else beta
        inside = _inside(side, turn)
        if inside:
            gamma = math.atan2(center[1] - pv, center[0] - pu)
            if R <= r:
                raise _tool_too_large(r)
        else:
            gamma = math.atan2(pv - center[1], pu - center[0])
            delta += math.pi
        target = self._point(pu + r * math.cos(gamma), pv + r * math.sin(gamma), self._normal(end))
        front = self.held[0] if self.held else None
        if (beta < -CORNER_TOL_RAD or beta > math.pi + CORNER_TOL_RAD
                or (abs(beta - math.pi) < CORNER_TOL_RAD and not inside)):  # concave
            if front is None or front.kind < ARC_CW:
                self.flush_at(self._line_arc_corner(center, R, theta, beta, turn))
            else:
                self.flush_at(self._arc_arc_corner(front, center, R, turn))
        elif beta > CORNER_TOL_RAD:  # convex: around the corner first
            self.flush_at(None)
            mu, mv = ou + r * math.cos(delta), ov + r * math.sin(delta)
            self._record(ARC_CW if side == LEFT else ARC_CCW, self.last_end, self._point(mu, mv, cz),
                         self._point(ou, ov, cz), 0, feed, line, modal)
            self.endpoint = (mu, mv)
        else:
            self.flush_at(None)
            self.endpoint = (cu, cv)
        sweep = find_turn(ou, ov, center[0], center[1], turn, pu, pv)
        self.held.append(_Held(kind, target, (0.0, 0.0), line, feed, modal, center, turn, sweep))
        self.current, self.programmed = target, end.copy()

    def _line_arc_corner(self, center, R: float, theta: float, beta: float, turn: int) -> tuple[float, float]:
        r = self.radius
        cy = R * math.sin(beta - _HALF_PI)
        if _inside(self.side, turn):
            dist = R - r
            ratio = (cy + r) / dist
            self._reachable(ratio)
            angle = theta + math.asin(ratio) if turn > 0 else theta - math.asin(ratio)
        else:
            dist = R + r
            ratio = (cy - r) / dist
            self._reachable(ratio)
            angle = theta + math.pi - math.asin(ratio) if turn > 0 else theta + math.pi + math.asin(ratio)
        return center[0] + dist * math.cos(angle), center[1] + dist * math.sin(angle)

    def _arc_arc_corner(self, prev: _Held, center, R: float, turn: int) -> tuple[float, float]:
        eu, ev = self._uv(prev.end)
        old = math.hypot(prev.center[1] - ev, prev.center[0] - eu)
        new = R - self.radius if _inside(self.side, turn) else R + self.radius
        cc = math.hypot(prev.center[1] - center[1], prev.center[0] - center[0])
        if old == 0 or cc == 0:
            raise CompensationError("Arc to arc motion is invalid because the arcs have the same center",
                                    "arcs about different centres")
        a = (old * old + cc * cc - new * new) / (2 * old * cc)
        if abs(a) > 1.0:
            raise CompensationError("Arc to arc motion makes a corner the compensated tool can't fit in without "
                                    "gouging", f"a corner wider than the tool (radius {self.radius:g} mm)")
        pull = math.acos(a)
        direction = math.atan2(center[1] - prev.center[1], center[0] - prev.center[0])
        plus = (turn > 0) == _inside(self.side, prev.turn)
        direction += pull if plus else -pull
        return prev.center[0] + old * math.cos(direction), prev.center[1] + old * math.sin(direction)

    @staticmethod
    def _reachable(ratio: float) -> None:
        if abs(ratio) > 1.0:
            raise CompensationError("Arc move in concave corner cannot be reached by the tool without gouging",
                                    "a corner wider than the tool")

    # --- the held moves -------------------------------------------------------------------------------
    def flush_at(self, at) -> None:
        """Record the held moves, their end in the plane moved to `at` (u, v) or a 3-point (None: as
        they are), refusing a move that would run backwards or an arc that would sweep further."""
        if not self.held:
            return
        if at is not None:
            u, v = self._uv(at) if len(at) == 3 else (float(at[0]), float(at[1]))
            for q in self.held:
                if q.kind >= ARC_CW:
                    if q.sweep and self.endpoint is not None:
                        new = find_turn(*self.endpoint, q.center[0], q.center[1], q.turn, u, v)
                        if abs(new) > abs(q.sweep) + (_SWEEP_TOL_INCH if q.modal[4] else _SWEEP_TOL_MM):
                            raise CompensationError(
                                "Arc move in concave corner cannot be reached by the tool without gouging",
                                f"a corner the tool fits in (arc of line {q.line})")
                elif self.endpoint is not None:
                    du, dv = u - self.endpoint[0], v - self.endpoint[1]
                    if q.direction[0] * du + q.direction[1] * dv < 0:
                        what = "Straight traverse" if q.kind == RAPID else "Straight feed"
                        raise CompensationError(f"{what} in concave corner cannot be reached by the tool without "
                                                f"gouging", f"a corner the tool fits in (move of line {q.line})")
                q.end = self._point(u, v, self._normal(q.end))
            self.endpoint = (u, v)
        else:
            self.endpoint = None
        for q in self.held:
            if q.kind >= ARC_CW:
                centre = self._point(q.center[0], q.center[1], 0.0)
                self._record(q.kind, self.last_end, q.end, centre, abs(q.turn) - 1, q.feed_mm_min, q.line, q.modal)
            else:
                self._record(q.kind, self.last_end, q.end, (math.nan,) * 3, 0, q.feed_mm_min, q.line, q.modal)
        self.held.clear()
        if at is None:
            self.endpoint = None

    def _record(self, kind: int, start, end, center, turns: int, feed: float, line: int, modal: tuple) -> None:
        start = np.array(start, float)
        end = np.array(end, float)
        if kind >= ARC_CW:  # an arc's centre lies in its start's plane
            center = np.array(center, float)
            center[PLANE_AXES[self.plane][2]] = start[PLANE_AXES[self.plane][2]]
        self.moves.append(self.count())
        self.record(kind, start, end, center, turns, feed, line, modal)
        self.last_end = end
