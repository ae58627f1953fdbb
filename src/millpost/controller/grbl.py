"""grbl's planner (planner.c, motion_control.c): arcs are cut into chords within `arc_tolerance_mm`
(mc_arc); each block runs a trapezoidal velocity profile (constant acceleration, no jerk limit) at the
smallest axis acceleration along its direction, at most the programmed feed (rapids: the axis rates)
and at most its length times the block rate. Junction speeds follow grbl's junction deviation δ: a
virtual arc of deviation δ run at the centripetal acceleration the axes allow along the direction
change. The planner sees `lookahead_blocks` blocks (16 on an AVR) and must be able to stop at the end
of the last one."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..toolpath import ARC_CW, RAPID, Toolpath
from .model import ControllerModel, PathModes, Planner, Queue
from .pauses import stops
from .profile import axis_limited


@dataclass
class Blocks:
    """Planner blocks: chord end points, owning move, fraction of the move at the block end."""

    start: np.ndarray
    end: np.ndarray
    move: np.ndarray
    u_end: np.ndarray
    feed_mm_s: np.ndarray  # programmed (nan for rapids)


def to_blocks(tp: Toolpath, model: ControllerModel, feed_mm_s: np.ndarray | None = None) -> Blocks:
    """grbl: lines as one block each, arcs as chords with sagitta ≤ arc_tolerance (grbl's mc_arc)."""
    feed = tp.feed_mm_s if feed_mm_s is None else np.asarray(feed_mm_s, float)
    L = tp.lengths()
    nseg = np.ones(len(tp), np.int64)
    arc = tp.kind >= ARC_CW
    if arc.any():
        r0, r1, _, sweep, _, _ = tp.subset(arc)._arc_params()
        r = np.maximum(0.5 * (r0 + r1), 1e-9)
        tol = np.minimum(model.arc_tolerance_mm, r)
        seg_len = 2 * np.sqrt(tol * (2 * r - tol))  # chord whose sagitta is tol
        nseg[arc] = np.maximum(np.floor(np.abs(sweep) * r / seg_len), 1).astype(np.int64)
    keep = L > 1e-9
    nseg[~keep] = 0
    move = np.repeat(np.arange(len(tp)), nseg)
    first = np.repeat(np.cumsum(nseg) - nseg, nseg)
    j = np.arange(len(move)) - first + 1
    u = j / np.repeat(nseg, nseg)
    end = tp.points(move, u)
    start = tp.points(move, u - 1.0 / np.repeat(nseg, nseg))
    return Blocks(start, end, move, u, feed[move])


def _junction_speeds2(tp: Toolpath, blk: Blocks, u: np.ndarray, model: ControllerModel,
                      pauses: np.ndarray | None) -> np.ndarray:
    """Squared junction speed caps (n+1) by grbl's junction deviation: v² = a·δ·sin(θ/2)/(1 − sin(θ/2)),
    a the acceleration the axes allow along the direction change, θ the angle between the reversed
    incoming and the outgoing direction (inf where collinear, 0 at a reversal); 0 at the ends, at a
    jump in position, before a paused move and everywhere in exact stop. u: the blocks' directions."""
    n = len(u)
    vj = np.zeros(n + 1)
    if n > 1 and not model.exact_stop:
        u0, u1 = u[:-1], u[1:]
        cos_t = np.clip(-(u0 * u1).sum(1), -1, 1)  # grbl: cos of the angle between reversed in and out
        jv = u1 - u0
        jv /= np.maximum(np.linalg.norm(jv, axis=1), 1e-300)[:, None]
        aj = axis_limited(jv, np.asarray(model.accel_mm_s2))
        sin_half = np.sqrt(np.maximum(0.5 * (1 - cos_t), 0))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            v2 = np.where(cos_t < -0.999999, np.inf,  # grbl: collinear
                          np.where(cos_t > 0.999999, 0.0,  # grbl: reversal
                                   aj * model.junction_deviation_mm * sin_half / (1 - sin_half)))
        # a jump between blocks or a pause before the next move is a stop
        cont = np.linalg.norm(blk.start[1:] - blk.end[:-1], axis=1) < 1e-6
        first_of_move = np.r_[True, blk.move[1:] != blk.move[:-1]][1:]
        paused = stops(tp, pauses)[blk.move[1:]] & first_of_move
        vj[1:-1] = np.where(cont & ~paused, v2, 0.0)
    return vj


@dataclass(frozen=True)
class GrblPlanner(Planner):
    """grbl's planner: arcs as chords (their F word carries the centripetal cap), junction deviation at
    corners, 16-block look-ahead; grbl merges no feeds and has no path modes."""

    lookahead_blocks = 16
    runs_arcs_whole = False
    blends_corners = False

    def queue(self, tp: Toolpath, model: ControllerModel, feed_mm_s: np.ndarray | None,
              pauses: np.ndarray | None, modes: PathModes | None) -> Queue:
        """Chord blocks (`to_blocks`) with grbl's junction-deviation corner speeds; modes play no part."""
        blk = to_blocks(tp, model, feed_mm_s)
        d = blk.end - blk.start
        L = np.linalg.norm(d, axis=1)
        u = d / np.maximum(L, 1e-300)[:, None]
        axis_rate = axis_limited(u, model.max_rate_mm_s)
        acc = axis_limited(u, np.asarray(model.accel_mm_s2))
        rapid = tp.kind[blk.move] == RAPID
        vnom = np.where(rapid | ~np.isfinite(blk.feed_mm_s), axis_rate, np.minimum(blk.feed_mm_s, axis_rate))
        vnom = np.minimum(vnom, L * model.block_rate_hz)
        return Queue(L, vnom, acc, _junction_speeds2(tp, blk, u, model, pauses), blk.move, blk.u_end,
                     np.zeros(len(L), bool))


Planner.register("grbl", GrblPlanner())
