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
from typing import TYPE_CHECKING

import numpy as np

from ..toolpath import Toolpath
from .blends import blend, parabolic_speed
from .paths import EXACT_PATH, EXACT_STOP
from .pauses import stops
from .segments import (GAP_CYCLES, KINK_RATIO, MIN_SEGMENT_CYCLES, SHARP_CORNER_COS, TANGENTIAL_SHARE, Segment,
                       arc_maxvel, build_segments, dot, place)

if TYPE_CHECKING:
    from .model import ControllerModel


def linuxcnc_blocks(tp: Toolpath, model: ControllerModel, feed_mm_min, pauses, modes):
    """LinuxCNC 2.9's queue: segments, blend arcs and the speed caps at their junctions; and the blend
    arcs' spans and top speeds (`Execution.blends`)."""
    segs = build_segments(tp, model, feed_mm_min, modes, merge=True)
    at = np.r_[0.0, np.cumsum(tp.lengths())]

    def arc_length(s: Segment, x: float) -> float:  # the program's arc length x mm along segment s
        m, u = place(s, x)
        return float(at[m] + u * (at[m + 1] - at[m]))

    stop = stops(tp, pauses).tolist()
    dt = model.servo_period_s
    amax = model.accel_mm_s2
    exact = model.exact_stop
    # per junction between segments j-1 and j: ("stop"|"tangent"|"blend"|"parabolic", cap, arc)
    joints: list = [None] * len(segs)
    for j in range(1, len(segs)):
        prev, cur = segs[j - 1], segs[j]
        if any(stop[prev.move + 1:cur.first + 1]):
            joints[j] = ("pause", 0.0, None)
            continue
        if exact or prev.rapid != cur.rapid or prev.tolerance == EXACT_STOP:
            joints[j] = ("stop", 0.0, None)
            continue
        if dot(prev.t1, cur.t0) < SHARP_CORNER_COS:
            joints[j] = ("stop", 0.0, None)
            continue
        v_max = min(prev.maxvel, prev.req, cur.maxvel, cur.req)
        share = max(abs(cur.t0[i] - prev.t1[i]) / amax[i] for i in range(3)) * v_max / dt
        share /= TANGENTIAL_SHARE if prev.arc or cur.arc else 1.0
        if share < KINK_RATIO:
            joints[j] = ("tangent", v_max, None)
            prev.kink_share = max(prev.kink_share, share)
            cur.kink_share = max(cur.kink_share, share)
            continue
        if prev.tolerance == EXACT_PATH:  # G61: no blending, a stop at every corner, where the kink
            joints[j] = ("stop", 0.0, None)  # check (tcSetKinkProperties) has taken its share of both
            prev.kink_share = max(prev.kink_share, KINK_RATIO)  # segments' acceleration all the same
            cur.kink_share = max(cur.kink_share, KINK_RATIO)
            continue
        kink_vel = v_max * KINK_RATIO / share
        arc = blend(prev, cur, model)
        if arc is not None and min(arc[2], arc[1] / dt) < kink_vel:
            joints[j] = ("tangent", kink_vel, None)
            prev.kink_share = max(prev.kink_share, KINK_RATIO)
            cur.kink_share = max(cur.kink_share, KINK_RATIO)
        elif arc is not None:
            joints[j] = ("blend", 0.0, arc)
            prev.trim_end = arc[0]
            prev.length -= arc[0]
            cur.length -= arc[0]
            cur.trim_start = arc[0]
        else:
            joints[j] = ("parabolic", 0.0, None)
            prev.halved = cur.halved = True
    for j, s in enumerate(segs):  # the last queued segment before a pause keeps its parabolic term (G64)
        if (j + 1 == len(segs) or joints[j + 1][0] == "pause") and not exact and s.tolerance not in (EXACT_PATH,
                                                                                                    EXACT_STOP):
            s.halved = True
    # blendCheckConsume: a line whose rest before a blend arc would take less than GAP_CYCLES periods at
    # the arc's speed is dropped from the queue and its rest becomes the straight lead-in of that arc
    consumed = [j + 1 < len(segs) and joints[j + 1][0] == "blend" and not s.arc
                and s.length < GAP_CYCLES * dt * joints[j + 1][2][2] for j, s in enumerate(segs)]
    L, vnom, acc, vj2, move, u_end, ramps, cuts = [], [], [], [], [], [], [], []
    blends = array("d")  # start, end (mm of arc length), queue index per blend arc: flat, 24 B an arc
    lead, lead_vj2 = 0.0, np.inf  # a consumed rest waiting for its arc, and the speed cap at its start
    for j, s in enumerate(segs):
        joint = joints[j]
        if joint is not None and joint[0] == "blend":  # the arc; its second half lies on the next move
            d, s_arc, v, a = joint[2]
            length = lead + s_arc
            vj2.append(lead_vj2)
            L.append(length)
            vnom.append(min(v, length / (MIN_SEGMENT_CYCLES * dt)))
            acc.append(a)
            m, u = place(s, d)
            move.append(m)
            u_end.append(u)
            ramps.append(not s.rapid)
            cuts.append((len(L) - 1, (lead + 0.5 * s_arc) / length, segs[j - 1].move, 1.0))
            prev = segs[j - 1]
            blends.extend((arc_length(prev, prev.nominal - prev.trim_end - lead), arc_length(s, d), len(L) - 1))
            lead, lead_vj2 = 0.0, np.inf
        if joint is None or joint[0] in ("stop", "pause"):
            start_vj2 = 0.0
        elif joint[0] == "blend":
            start_vj2 = np.inf
        elif joint[0] == "tangent":
            start_vj2 = joint[1] ** 2
        else:
            start_vj2 = parabolic_speed(segs[j - 1], s) ** 2
        if consumed[j]:
            lead, lead_vj2 = max(s.length, 0.0), start_vj2
            continue
        vj2.append(start_vj2)
        a = s.acc * (0.5 if s.halved else 1.0) * (1.0 - s.kink_share)
        vmax = min(s.req, arc_maxvel(s, s.halved) if s.arc else s.maxvel, s.nominal * model.block_rate_hz)
        if s.length > 0:
            vmax = min(vmax, s.length / (MIN_SEGMENT_CYCLES * dt))
        if s.arc:
            a *= TANGENTIAL_SHARE
        L.append(max(s.length, 0.0))
        vnom.append(vmax)
        acc.append(a)
        m, u = place(s, s.nominal - s.trim_end)
        move.append(m)
        u_end.append(u)
        ramps.append(not s.rapid)
        span = s.nominal - s.trim_end - s.trim_start
        for k, x in enumerate(s.ends[:-1]):  # a merged chain: a cut where each of its moves ends
            if s.trim_start < x < s.nominal - s.trim_end and span > 0:
                cuts.append((len(L) - 1, (x - s.trim_start) / span, s.first + k, 1.0))
    vj2.append(0.0)
    return (np.asarray(L, float), np.asarray(vnom, float), np.asarray(acc, float), np.asarray(vj2, float),
            np.asarray(move, np.int64), np.asarray(u_end, float), np.asarray(ramps, bool), cuts,
            np.frombuffer(blends, float).reshape(-1, 3).copy())
