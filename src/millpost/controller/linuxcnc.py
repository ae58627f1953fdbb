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

from array import array
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..toolpath import Toolpath
from .blends import blend, parabolic_speed
from .model import EXACT_PATH, EXACT_STOP, ControllerModel, PathModes, Planner, Queue
from .pauses import stops
from .profile import peak_speed
from .segments import (GAP_CYCLES, KINK_RATIO, MIN_SEGMENT_CYCLES, RAMP_TIME_S, SHARP_CORNER_COS, TANGENTIAL_SHARE,
                       Segment, arc_maxvel, build_segments, dot, place)


class _Joint(NamedTuple):
    """How the queue passes from one segment to the next: kind "pause" (a command waits between them),
    "stop", "tangent" (at the speed cap `cap`, mm/s), "blend" (on the arc `arc`: the trim of each
    segment, the arc's length, speed and acceleration, `blends.blend`) or "parabolic"."""

    kind: str
    cap: float = 0.0
    arc: tuple | None = None


def _kinked(prev: Segment, cur: Segment, share: float) -> None:
    """Both segments give up `share` of their acceleration to a tangent kink (tcSetKinkProperties)."""
    prev.kink_share = max(prev.kink_share, share)
    cur.kink_share = max(cur.kink_share, share)


def _joint(prev: Segment, cur: Segment, paused: bool, model: ControllerModel) -> _Joint:
    """The junction between two queued segments; trims them for a blend arc, halves their acceleration
    for a parabolic blend and takes a tangent kink's share of it."""
    if paused:
        return _Joint("pause")
    if (model.exact_stop or prev.rapid != cur.rapid or prev.tolerance == EXACT_STOP
            or dot(prev.t1, cur.t0) < SHARP_CORNER_COS):
        return _Joint("stop")
    dt = model.servo_period_s
    amax = model.accel_mm_s2
    v_max = min(prev.maxvel, prev.req, cur.maxvel, cur.req)
    share = max(abs(cur.t0[i] - prev.t1[i]) / amax[i] for i in range(3)) * v_max / dt
    share /= TANGENTIAL_SHARE if prev.arc or cur.arc else 1.0
    if share < KINK_RATIO:
        _kinked(prev, cur, share)
        return _Joint("tangent", v_max)
    if prev.tolerance == EXACT_PATH:  # G61: no blending, a stop at every corner, where the kink
        _kinked(prev, cur, KINK_RATIO)  # check (tcSetKinkProperties) has taken its share of both
        return _Joint("stop")  # segments' acceleration all the same
    kink_vel = v_max * KINK_RATIO / share
    arc = blend(prev, cur, model)
    if arc is not None and min(arc[2], arc[1] / dt) < kink_vel:
        _kinked(prev, cur, KINK_RATIO)
        return _Joint("tangent", kink_vel)
    if arc is not None:
        prev.trim_end = arc[0]
        prev.length -= arc[0]
        cur.length -= arc[0]
        cur.trim_start = arc[0]
        return _Joint("blend", 0.0, arc)
    prev.halved = cur.halved = True
    return _Joint("parabolic")


def _joints(segs: list[Segment], stop: list[bool], model: ControllerModel) -> list[_Joint | None]:
    """Per segment the joint before it (None before the first); stop: per move, whether the motion
    stops before it (`pauses.stops`). The last queued segment before a pause (or the end) keeps its
    parabolic term in G64: half its acceleration."""
    joints: list[_Joint | None] = [None] * len(segs)
    for j in range(1, len(segs)):
        prev, cur = segs[j - 1], segs[j]
        joints[j] = _joint(prev, cur, any(stop[prev.move + 1:cur.first + 1]), model)
    for j, s in enumerate(segs):
        if ((j + 1 == len(segs) or joints[j + 1].kind == "pause") and not model.exact_stop
                and s.tolerance not in (EXACT_PATH, EXACT_STOP)):
            s.halved = True
    return joints


def _entry_cap2(joint: _Joint | None, prev: Segment, s: Segment) -> float:
    """The squared speed cap (mm²/s²) where segment s starts, after the joint from prev."""
    if joint is None or joint.kind in ("stop", "pause"):
        return 0.0
    if joint.kind == "blend":
        return np.inf
    if joint.kind == "tangent":
        return joint.cap ** 2
    return parabolic_speed(prev, s) ** 2


class _Rows:
    """The queue's blocks as they are appended (`Queue`), the blend arcs flat (24 B an arc)."""

    def __init__(self, tp: Toolpath, model: ControllerModel):
        self.L, self.vnom, self.acc, self.vj2, self.move, self.u_end, self.ramps, self.cuts = ([] for _ in range(8))
        self.blends = array("d")
        self.at = np.r_[0.0, np.cumsum(tp.lengths())]
        self.model = model

    def arc_length(self, s: Segment, x: float) -> float:
        """The program's arc length (mm) x mm along segment s."""
        m, u = place(s, x)
        return float(self.at[m] + u * (self.at[m + 1] - self.at[m]))

    def add(self, length: float, vnom: float, acc: float, vj2: float, s: Segment, x: float) -> int:
        """A block of segment s ending x mm along it; returns its index."""
        self.vj2.append(vj2)
        self.L.append(length)
        self.vnom.append(vnom)
        self.acc.append(acc)
        m, u = place(s, x)
        self.move.append(m)
        self.u_end.append(u)
        self.ramps.append(not s.rapid)
        return len(self.L) - 1

    def add_arc(self, prev: Segment, s: Segment, arc: tuple, lead: float, lead_vj2: float) -> None:
        """The blend arc between prev and s with the straight lead-in `lead` (mm) it absorbed; its
        second half lies on s's first move."""
        d, s_arc, v, a = arc
        length = lead + s_arc
        k = self.add(length, min(v, length / (MIN_SEGMENT_CYCLES * self.model.servo_period_s)), a, lead_vj2, s, d)
        self.cuts.append((k, (lead + 0.5 * s_arc) / length, prev.move, 1.0))
        self.blends.extend((self.arc_length(prev, prev.nominal - prev.trim_end - lead), self.arc_length(s, d), k))

    def add_segment(self, s: Segment, vj2: float) -> None:
        """Segment s as one block at its own limits (halved, kinked, an arc's tangential share, the
        block rate, at least 1.02 servo periods long); a merged chain cut where each of its moves ends."""
        dt = self.model.servo_period_s
        a = s.acc * (0.5 if s.halved else 1.0) * (1.0 - s.kink_share)
        vmax = min(s.req, arc_maxvel(s, s.halved) if s.arc else s.maxvel, s.nominal * self.model.block_rate_hz)
        if s.length > 0:
            vmax = min(vmax, s.length / (MIN_SEGMENT_CYCLES * dt))
        if s.arc:
            a *= TANGENTIAL_SHARE
        k = self.add(max(s.length, 0.0), vmax, a, vj2, s, s.nominal - s.trim_end)
        span = s.nominal - s.trim_end - s.trim_start
        for i, x in enumerate(s.ends[:-1]):
            if s.trim_start < x < s.nominal - s.trim_end and span > 0:
                self.cuts.append((k, (x - s.trim_start) / span, s.first + i, 1.0))

    def queue(self) -> Queue:
        return Queue(np.asarray(self.L, float), np.asarray(self.vnom, float), np.asarray(self.acc, float),
                     np.asarray(self.vj2 + [0.0], float), np.asarray(self.move, np.int64),
                     np.asarray(self.u_end, float), np.asarray(self.ramps, bool), self.cuts,
                     np.frombuffer(self.blends, float).reshape(-1, 3).copy())


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
        segs = build_segments(tp, model, feed_mm_s, modes, merge=True)
        joints = _joints(segs, stops(tp, pauses).tolist(), model)
        dt = model.servo_period_s
        consumed = [j + 1 < len(segs) and joints[j + 1].kind == "blend" and not s.arc
                    and s.length < GAP_CYCLES * dt * joints[j + 1].arc[2] for j, s in enumerate(segs)]
        rows = _Rows(tp, model)
        lead, lead_vj2 = 0.0, np.inf  # a consumed rest waiting for its arc, and the speed cap at its start
        for j, s in enumerate(segs):
            joint = joints[j]
            if joint is not None and joint.kind == "blend":
                rows.add_arc(segs[j - 1], s, joint.arc, lead, lead_vj2)
                lead, lead_vj2 = 0.0, np.inf
            start_vj2 = _entry_cap2(joint, segs[j - 1], s)
            if consumed[j]:
                lead, lead_vj2 = max(s.length, 0.0), start_vj2
                continue
            rows.add_segment(s, start_vj2)
        return rows.queue()

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
