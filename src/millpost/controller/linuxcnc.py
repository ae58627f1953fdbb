"""LinuxCNC 2.9's trajectory planner (tp.c, blendmath.c), the model for look-ahead controllers that
blend corners within a tolerance (LinuxCNC, Mach3, Fanuc-like). Lines and arcs are segments of their
own (`segments`), except consecutive straight feeds whose points all lie within the naive-CAM tolerance
(G64 Q) of one line, on a controller that merges them: up to 101 of them run as that line
(`naive_cam_chains`). An arc's acceleration along the path is half of a (the other half is kept for the
turn). A corner between two segments is, in this order: a stop (rapid ↔ feed, a reversal, a command
between them); "tangent" when the velocity jump v·Δu in one servo period (1 ms) needs less than 10 %
of the axes' acceleration (both segments then lose that share of their acceleration); otherwise a
blend arc, or where none fits a parabolic blend (`blends`). The rest of a line before a blend arc that
would take less than 4 servo periods at the arc's speed is no segment of its own: it runs as the arc's
straight lead-in, at the arc's speed and acceleration. Speeds are planned backwards over
`lookahead_blocks` segments (LinuxCNC: 50), a segment lasts at least 1.02 servo periods (its speed is
at most its length over that), and one that ends at rest ends half a servo period late on average (the
period's rest is lost). A feed segment that takes less than 10 ms (1/ARC_BLEND_RAMP_FREQ) and flows
into the next changes speed linearly from end to end. The last segment before the motion queue runs
empty (a command, the end) keeps its parabolic end and half its acceleration."""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from .._kernels import compiling
from ..toolpath import Toolpath
from .blends import blend, kink_jump, parabolic_speed
from .model import EXACT_PATH, EXACT_STOP, ControllerModel, PathModes, Planner, Queue
from .pauses import stops
from .profile import peak_speed
from .segments import (GAP_CYCLES, KINK_RATIO, MIN_SEGMENT_CYCLES, RAMP_TIME_S, SHARP_CORNER_COS, SQUARE,
                       TANGENTIAL_SHARE, arc_maxvel, build_segments, dot, place)


PAUSE, STOP, TANGENT, BLEND, PARABOLIC = range(5)  # how the queue passes a junction (`_joint`)
FIRST = -1  # the "joint" before the first segment
BLOCK = np.dtype([("length", float), ("vnom", float), ("acc", float), ("vj2", float), ("move", np.int64),
                  ("u_end", float), ("may_ramp", np.bool_)], align=True)  # a row of the `Queue`


@numba.njit(cache=True)
def _kinked(segs, j: int, share: float) -> None:
    """Segments j − 1 and j give up `share` of their acceleration to a tangent kink (tcSetKinkProperties)."""
    segs[j - 1].kink_share = max(segs[j - 1].kink_share, share)
    segs[j].kink_share = max(segs[j].kink_share, share)


@numba.njit(cache=True)
def _joint(segs, j: int, paused: bool, exact_stop: bool, dt: float, accel, rates, two: float):
    """How the queue passes from segment j − 1 to j: (kind, speed cap (mm/s), blend arc). PAUSE (a
    command waits between them), STOP, TANGENT (at the cap), BLEND (on the arc: the trim of each
    segment, the arc's length, speed and acceleration, `blends.blend`; it trims both segments) or
    PARABOLIC (both segments at half acceleration). A tangent kink takes its share of both segments'
    acceleration. dt: the servo period (s); accel, rates: the axes' mm/s², mm/s; two: `SQUARE`."""
    prev, cur = segs[j - 1], segs[j]
    none = (0.0, 0.0, 0.0, 0.0)
    if paused:
        return PAUSE, 0.0, none
    if (exact_stop or prev.rapid != cur.rapid or prev.tolerance == EXACT_STOP
            or dot(prev.t1, cur.t0) < SHARP_CORNER_COS):
        return STOP, 0.0, none
    v_max = min(prev.maxvel, prev.req, cur.maxvel, cur.req)
    share = kink_jump(prev, cur, accel) * v_max / dt
    share /= TANGENTIAL_SHARE if prev.arc or cur.arc else 1.0
    if share < KINK_RATIO:
        _kinked(segs, j, share)
        return TANGENT, v_max, none
    if prev.tolerance == EXACT_PATH:  # G61: no blending, a stop at every corner, where the kink
        _kinked(segs, j, KINK_RATIO)  # check (tcSetKinkProperties) has taken its share of both
        return STOP, 0.0, none  # segments' acceleration all the same
    kink_vel = v_max * KINK_RATIO / share
    fits, d, s_arc, v, a = blend(segs, j, accel, rates, two)
    if fits and min(v, s_arc / dt) < kink_vel:
        _kinked(segs, j, KINK_RATIO)
        return TANGENT, kink_vel, none
    if fits:
        prev.trim_end = d
        prev.length -= d
        cur.length -= d
        cur.trim_start = d
        return BLEND, 0.0, (d, s_arc, v, a)
    prev.halved = True
    cur.halved = True
    return PARABOLIC, 0.0, none


@numba.njit(cache=True)
def _joints(segs, stop, exact_stop: bool, dt: float, accel, rates, two: float):
    """Per segment the joint before it (`_joint`; kind FIRST before the first): kinds, speed caps (mm/s)
    and blend arcs (n, 4). stop: per move, whether the motion stops before it (`pauses.stops`). The
    last queued segment before a pause (or the end) keeps its parabolic term in G64: half its
    acceleration."""
    n = len(segs)
    kind, cap, arc = np.full(n, FIRST, np.int64), np.zeros(n), np.zeros((n, 4))
    for j in range(1, n):
        paused = False
        for m in range(segs[j - 1].move + 1, segs[j].first + 1):
            paused = paused or stop[m]
        kind[j], cap[j], (arc[j, 0], arc[j, 1], arc[j, 2], arc[j, 3]) = _joint(segs, j, paused, exact_stop, dt,
                                                                              accel, rates, two)
    for j in range(n):
        s = segs[j]
        if ((j + 1 == n or kind[j + 1] == PAUSE) and not exact_stop
                and s.tolerance != EXACT_PATH and s.tolerance != EXACT_STOP):
            s.halved = True
    return kind, cap, arc


@numba.njit(cache=True)
def _entry_cap2(kind: int, cap: float, segs, j: int, two: float) -> float:
    """The squared speed cap (mm²/s²) where segment j starts, after the joint before it."""
    if kind == BLEND:
        return np.inf
    if kind == TANGENT:
        return cap ** two
    if kind == PARABOLIC:
        return parabolic_speed(segs, j) ** two
    return 0.0


@numba.njit(cache=True)
def _add(blocks, k: int, length: float, vnom: float, acc: float, vj2: float, s, ends, x: float) -> None:
    """Block k: of segment s (`place` by the moves' `ends`), ending x mm along it."""
    b = blocks[k]
    b.length, b.vnom, b.acc, b.vj2 = length, vnom, acc, vj2
    b.move, b.u_end = place(s, ends, x)
    b.may_ramp = not s.rapid


@numba.njit(cache=True)
def _arc_length(at, s, ends, x: float) -> float:
    """The program's arc length (mm) x mm along segment s; at: the program's arc length at each move's start."""
    m, u = place(s, ends, x)
    return at[m] + u * (at[m + 1] - at[m])


@numba.njit(cache=True)
def _segment_block(blocks, k: int, cuts, c: int, s, ends, vj2: float, dt: float, block_rate: float) -> int:
    """Block k: segment s at its own limits (halved, kinked, an arc's tangential share, the block rate, at
    least 1.02 servo periods long); a merged chain cut where each of its moves ends (rows of `cuts` from
    c on). Returns the next free row of `cuts`."""
    a = s.acc * (0.5 if s.halved else 1.0) * (1.0 - s.kink_share)
    vmax = min(s.req, arc_maxvel(s, s.halved) if s.arc else s.maxvel, s.nominal * block_rate)
    if s.length > 0:
        vmax = min(vmax, s.length / (MIN_SEGMENT_CYCLES * dt))
    if s.arc:
        a *= TANGENTIAL_SHARE
    _add(blocks, k, max(s.length, 0.0), vmax, a, vj2, s, ends, s.nominal - s.trim_end)
    span = s.nominal - s.trim_end - s.trim_start
    for i in range(s.move - s.first):
        x = ends[s.first + i]
        if s.trim_start < x < s.nominal - s.trim_end and span > 0:
            cuts[c, 0], cuts[c, 1], cuts[c, 2], cuts[c, 3] = k, (x - s.trim_start) / span, s.first + i, 1.0
            c += 1
    return c


@numba.njit(cache=True)
def _blocks(segs, ends, at, kind, cap, arc, dt: float, block_rate: float, two: float):
    """The queue's blocks (`BLOCK`) after the joints (`_joints`), its cuts (`Queue.cuts`) and blend arcs
    (`Queue.blends`). A line's rest shorter than GAP_CYCLES periods at the next blend arc's speed is
    no block: it runs as that arc's lead-in (blendCheckConsume), from the speed cap at its start; the
    arc's second half lies on the next segment's first move."""
    n = len(segs)
    blocks, cuts, blends = np.zeros(2 * n, BLOCK), np.zeros((n + len(ends), 4)), np.zeros((n, 3))
    k = c = b = 0
    lead, lead_vj2 = 0.0, np.inf  # a consumed rest waiting for its arc, and the speed cap at its start
    for j in range(n):
        s = segs[j]
        if kind[j] == BLEND:
            prev, (d, s_arc, v, a) = segs[j - 1], (arc[j, 0], arc[j, 1], arc[j, 2], arc[j, 3])
            length = lead + s_arc
            _add(blocks, k, length, min(v, length / (MIN_SEGMENT_CYCLES * dt)), a, lead_vj2, s, ends, d)
            cuts[c, 0], cuts[c, 1], cuts[c, 2], cuts[c, 3] = k, (lead + 0.5 * s_arc) / length, prev.move, 1.0
            blends[b, 0] = _arc_length(at, prev, ends, prev.nominal - prev.trim_end - lead)
            blends[b, 1], blends[b, 2] = _arc_length(at, s, ends, d), k
            k, c, b = k + 1, c + 1, b + 1
            lead, lead_vj2 = 0.0, np.inf
        start_vj2 = _entry_cap2(kind[j], cap[j], segs, j, two)
        if j + 1 < n and kind[j + 1] == BLEND and not s.arc and s.length < GAP_CYCLES * dt * arc[j + 1, 2]:
            lead, lead_vj2 = max(s.length, 0.0), start_vj2
            continue
        c = _segment_block(blocks, k, cuts, c, s, ends, start_vj2, dt, block_rate)
        k += 1
    return blocks[:k], cuts[:c], blends[:b]


@dataclass(frozen=True)
class LinuxCNCPlanner(Planner):
    """LinuxCNC 2.9's planner: arcs run whole (it clamps each at √(a_n·r) itself), blend arcs at corners
    at up to the faster move's feed, 50-segment look-ahead. merges_naive_cam: its canon layer merges
    straight feeds within G64 Q into one line (LinuxCNC's does; Mach3's and Fanuc's look-ahead, modelled
    by the same planner, blend the programmed moves as they are)."""

    lookahead_blocks = 50
    runs_arcs_whole = True
    blends_corners = True
    merges_naive_cam: bool = True

    def queue(self, tp: Toolpath, model: ControllerModel, feed_mm_s: np.ndarray | None,
              pauses: np.ndarray | None, modes: PathModes | None) -> Queue:
        """LinuxCNC's queue: segments, blend arcs and the speed caps at their junctions; and the blend
        arcs' spans (`Execution.blends`). A line's rest shorter than GAP_CYCLES periods at the next
        blend arc's speed is dropped from the queue and runs as that arc's lead-in (blendCheckConsume)."""
        segs, ends = build_segments(tp, model, feed_mm_s, modes, merge=True)
        accel, rates = np.asarray(model.accel_mm_s2, float), np.asarray(model.max_rate_mm_s, float)
        dt = model.servo_period_s
        with compiling(_joints, _blocks):
            kind, cap, arc = _joints(segs, stops(tp, pauses), model.exact_stop, dt, accel, rates, SQUARE)
            blocks, cuts, blends = _blocks(segs, ends, np.r_[0.0, np.cumsum(tp.lengths())], kind, cap, arc, dt,
                                           model.block_rate_hz, SQUARE)
        return Queue(blocks["length"].copy(), blocks["vnom"].copy(), blocks["acc"].copy(), np.r_[blocks["vj2"], 0.0],
                     blocks["move"].copy(), blocks["u_end"].copy(), blocks["may_ramp"].copy(), cuts, blends)

    def timed(self, q: Queue, ve: np.ndarray, t: np.ndarray, model: ControllerModel
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A feed segment run in less than RAMP_TIME_S that flows into the next changes speed linearly
        from end to end (no cruise above both ends); one ending at rest ends half a servo period late.
        The blend arcs get their top speed: a linear ramp's faster end, else the trapezoid's peak."""
        L, vnom, acc = q.length, q.vnom, q.acc
        with np.errstate(divide="ignore", invalid="ignore"):
            t_ramp = np.where(ve[:-1] + ve[1:] > 0, 2.0 * L / (ve[:-1] + ve[1:]), np.inf)
            v_end = ve[:-1] + np.minimum(ve[1:], vnom)
            t_est = np.where(v_end > 0, 2.0 * L / v_end, np.inf)
        ramp = q.may_ramp & (ve[1:] > 0) & (t_est < RAMP_TIME_S)
        t = np.where(ramp, t_ramp, t) + np.where(ve[1:] == 0.0, 0.5 * model.servo_period_s, 0.0)
        blends = q.blends
        if len(blends):
            k = blends[:, 2].astype(np.int64)
            v0, v1 = ve[k], ve[k + 1]
            blends = np.column_stack([blends[:, :2], np.where(ramp[k], np.maximum(v0, v1),
                                                              peak_speed(L[k], v0, v1, vnom[k], acc[k]))])
        return t, ramp, blends


# only LinuxCNC's canon layer merges naive-CAM feeds; the other look-ahead controllers run its planner as is
Planner.register("linuxcnc", LinuxCNCPlanner(merges_naive_cam=True))
for _kind in ("fanuc", "mach3", "generic"):
    Planner.register(_kind, LinuxCNCPlanner(merges_naive_cam=False))
