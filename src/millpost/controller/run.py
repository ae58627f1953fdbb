"""Running a program through the controller model: the planner's queue (`Planner.queue`), its speeds
planned over the look-ahead (`profile.plan_speeds`), each block's time, and the pauses between moves."""

from __future__ import annotations

import numpy as np

from .._kernels import compiling
from ..toolpath import Toolpath
from .execution import Execution
from .model import ControllerModel, PathModes
from .paths import path_modes
from .pauses import paused_s, pauses_s
from .profile import plan_speeds, trapezoid_time


def execute_program(program, model: ControllerModel, feed_mm_s: np.ndarray | None = None,
                    modes: PathModes | None = None) -> Execution:
    """`execute` on an interpreted program: its pauses (dwells, tool changes, commands) stop the
    motion and take their time, its path modes (G61/G64 P Q; `path_modes`, computed here unless
    given) set the corners and the merging of straight feeds; feed_mm_s overrides the programmed
    feed per move (mm/s)."""
    return execute(program.toolpath, model, feed_mm_s, pauses=pauses_s(program, model),
                   modes=path_modes(program, model) if modes is None else modes)


def program_time(program, model: ControllerModel) -> float:
    """Cycle time of an interpreted program (s): motion and the pauses between its first and last
    move, in the path modes (G61/G64) the program sets."""
    return execute_program(program, model).time_s


def execute(tp: Toolpath, model: ControllerModel, feed_mm_s: np.ndarray | None = None,
            pauses: np.ndarray | None = None, modes: PathModes | None = None) -> Execution:
    """Plan and time the whole program (rapids at the axis rates) on the model's planner. feed_mm_s
    overrides the programmed feed per move (mm/s); pauses (see `pauses_s`, len(tp)+1) stop the motion between
    moves; modes (see `path_modes`; default: the controller's own) set the path modes. A junction is
    never faster than the slower of its two blocks; a controller that processes at most `block_rate_hz`
    blocks per second runs a block of length L at most at L·rate."""
    q = model.planner.queue(tp, model, feed_mm_s, pauses, modes)
    L, vnom, acc = q.length, q.vnom, q.acc
    vj2 = q.vj2.copy()
    vj2[1:-1] = np.minimum(vj2[1:-1], np.minimum(vnom[:-1], vnom[1:]) ** 2)
    n = len(L)
    with compiling(plan_speeds):
        v2 = plan_speeds(L, vnom, acc, vj2, int(model.lookahead_blocks)) if n else np.zeros(1)
    ve = np.sqrt(np.maximum(v2, 0))
    t = trapezoid_time(L, ve[:-1], ve[1:], vnom, acc) if n else np.zeros(0)
    t, ramp, blends = model.planner.timed(q, ve, t, model)
    pause = paused_s(pauses, q.move[0], q.move[-1]) if n else 0.0
    move, u_end = q.move, q.u_end
    if len(q.cuts):
        t, L, vnom, acc, ve, move, u_end, ramp = cut_blocks(q.cuts, t, L, vnom, acc, ve, ramp, move, u_end)
    return Execution(float(t.sum()) + pause, t, move, u_end, L, vnom, acc, ve, ramp,
                     np.r_[0.0, np.cumsum(tp.lengths())], pause, blends)


def cut_blocks(cuts, t, L, vnom, acc, ve, ramp, move, u_end):
    """Blocks cut where they pass from one program move onto the next (a blend arc's two halves, a
    merged chain's moves), so that every piece lies on one move. cuts: (block, fraction of it at the
    cut, the move and the fraction of it where the piece before the cut ends: rows of an (m, 4) array);
    the piece after the last cut keeps the block's own place. A piece runs the block's speed profile between the cut points
    (constant acceleration on a linear ramp, the trapezoid elsewhere); the pieces' times share the
    block's time in proportion to those runs. Returns the pieces' t, L, vnom, acc, entry speeds (n+1),
    move, u_end and ramp."""
    n = len(L)
    blk = np.r_[cuts[:, 0].astype(np.int64), np.arange(n)]
    f_end = np.r_[np.clip(cuts[:, 1], 0.0, 1.0), np.ones(n)]
    mv = np.r_[cuts[:, 2].astype(np.int64), move]
    uu = np.r_[cuts[:, 3], u_end]
    order = np.lexsort((f_end, blk))
    blk, f_end, mv, uu = blk[order], f_end[order], mv[order], uu[order]
    f_start = np.r_[0.0, np.where(blk[1:] == blk[:-1], f_end[:-1], 0.0)]
    v0, v1, Lb, a, vm = ve[blk], ve[blk + 1], L[blk], acc[blk], vnom[blk]

    def speed(f):
        linear = np.sqrt(np.maximum(v0**2 + (v1**2 - v0**2) * f, 0.0))
        trapezoid = np.minimum.reduce([np.sqrt(v0**2 + 2 * a * f * Lb), vm, np.sqrt(v1**2 + 2 * a * (1 - f) * Lb)])
        return np.where(f <= 0.0, v0, np.where(f >= 1.0, v1, np.where(ramp[blk], linear, trapezoid)))

    vs, vf = speed(f_start), speed(f_end)
    Lp = (f_end - f_start) * Lb
    with np.errstate(divide="ignore", invalid="ignore"):
        run = np.where(ramp[blk], np.where(vs + vf > 0, 2.0 * Lp / (vs + vf), 0.0), trapezoid_time(Lp, vs, vf, vm, a))
        total = np.bincount(blk, run, minlength=n)
        share = np.where(total[blk] > 0, run / total[blk], f_end - f_start)
    return t[blk] * share, Lp, vm, a, np.r_[vs, ve[-1]], mv, uu, ramp[blk]
