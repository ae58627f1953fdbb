"""What a real motion planner does with a program: a grbl/LinuxCNC-like model for cycle times.

Moves become blocks (arcs are cut into chords within `arc_tolerance_mm`, as grbl does); each block
runs a trapezoidal velocity profile (constant acceleration, no jerk limit) at the smallest axis
acceleration along its direction, at most the programmed feed (rapids: the axis rates) and the axis
rate limits. Junction speeds follow grbl's junction deviation δ (a virtual blend arc of deviation δ
run at the centripetal acceleration the axes allow along the direction change); a G64 P<tol>
blend (LinuxCNC) is the same geometry with δ = tol; with `exact_stop` (G61) every junction stops.
The planner only sees `lookahead_blocks` blocks ahead and must be able
to stop at the end of the last one; a controller that processes at most `block_rate_hz` blocks per
second cannot finish a block of length L faster than 1/rate, so its speed is at most L·rate.
Returns the executed time and the actual speed at any sample of the path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from millpost.errors import ConfigError
from millpost.toolpath import ARC_CW, RAPID, Samples, Toolpath


@dataclass(frozen=True)
class ControllerModel:
    """Planner settings. Rates mm/s, accelerations mm/s², lengths mm (grbl: $110-$112 in mm/min,
    $120-$122, $11 junction deviation, $12 arc tolerance; buffer of 16 blocks on an AVR)."""

    max_rate_mm_s: tuple[float, float, float]
    accel_mm_s2: tuple[float, float, float]
    junction_deviation_mm: float = 0.01
    lookahead_blocks: int = 16
    block_rate_hz: float = float("inf")
    arc_tolerance_mm: float = 0.002
    exact_stop: bool = False

    def __post_init__(self) -> None:
        for name in ("max_rate_mm_s", "accel_mm_s2"):
            v = np.asarray(getattr(self, name), float)
            if v.shape != (3,) or not (v > 0).all():
                raise ConfigError(name, getattr(self, name), "three positive numbers (X, Y, Z)")
        if self.junction_deviation_mm < 0:
            raise ConfigError("junction_deviation_mm", self.junction_deviation_mm, "must be ≥ 0")
        if self.lookahead_blocks < 1:
            raise ConfigError("lookahead_blocks", self.lookahead_blocks, "must be ≥ 1")
        if not self.block_rate_hz > 0:
            raise ConfigError("block_rate_hz", self.block_rate_hz, "must be > 0")
        if not self.arc_tolerance_mm > 0:
            raise ConfigError("arc_tolerance_mm", self.arc_tolerance_mm, "must be > 0")


@dataclass
class Blocks:
    """Planner blocks: chord end points, owning move, fraction of the move at the block end."""

    start: np.ndarray
    end: np.ndarray
    move: np.ndarray
    u_end: np.ndarray
    feed_mm_s: np.ndarray  # programmed (nan for rapids)


def to_blocks(tp: Toolpath, model: ControllerModel, feed_mm_min: np.ndarray | None = None) -> Blocks:
    """Lines as one block each, arcs as chords with sagitta ≤ arc_tolerance (grbl's mc_arc)."""
    feed = tp.feed_mm_min if feed_mm_min is None else np.asarray(feed_mm_min, float)
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
    return Blocks(start, end, move, u, feed[move] / 60.0)


@numba.njit(cache=True)
def _plan(L, vnom, acc, vj, depth):
    """Squared junction speeds (n+1, start and end at rest) honouring the caps vj (already ≤ the
    nominal speeds of both neighbours), the lookahead
    depth (stop at the end of the last visible block) and reachability (forward/backward passes)."""
    n = L.shape[0]
    v2 = np.empty(n + 1)
    v2[0] = 0.0
    v2[n] = 0.0
    for i in range(1, n):
        v2[i] = vj[i]
    # lookahead: from junction i the planner sees blocks i..i+depth−1 and must stop after them
    for i in range(1, n):
        last = min(i + depth, n)
        w = 0.0
        for k in range(last - 1, i - 1, -1):
            w = min(w + 2.0 * acc[k] * L[k], v2[k] if k > i else np.inf)
        v2[i] = min(v2[i], w)
    for i in range(n - 1, 0, -1):  # backward: can decelerate to the next junction
        v2[i] = min(v2[i], v2[i + 1] + 2.0 * acc[i] * L[i])
    for i in range(n):  # forward: can accelerate from the previous junction
        v2[i + 1] = min(v2[i + 1], v2[i] + 2.0 * acc[i] * L[i])
    return v2


def _trapezoid_time(L, vin, vout, vmax, a):
    """Time of a trapezoidal (or triangular) profile from vin to vout over L at acceleration a."""
    vpeak2 = (2 * a * L + vin**2 + vout**2) / 2
    vp = np.minimum(np.sqrt(np.maximum(vpeak2, 0)), vmax)
    d_acc = (vp**2 - vin**2) / (2 * a)
    d_dec = (vp**2 - vout**2) / (2 * a)
    cruise = np.maximum(L - d_acc - d_dec, 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return (vp - vin) / a + (vp - vout) / a + np.where(vp > 0, cruise / vp, 0.0)


@dataclass
class Execution:
    """Executed time (s) and per block entry speeds; `speed_at` gives the actual speed (mm/s)."""

    time_s: float
    block_time_s: np.ndarray
    blocks: Blocks
    length: np.ndarray
    vnom: np.ndarray
    acc: np.ndarray
    v_entry: np.ndarray  # (n+1,)

    def _locate(self, move: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Block index and distance into it (mm) of fraction u of move `move` (by fraction on chords)."""
        key = self.blocks.move.astype(float) + self.blocks.u_end
        q = np.asarray(move, float) + np.clip(u, 0, 1)
        k = np.clip(np.searchsorted(key, q - 1e-12), 0, len(key) - 1)
        ustart = np.where(k > 0, np.where(self.blocks.move[np.maximum(k - 1, 0)] == self.blocks.move[k],
                                          self.blocks.u_end[np.maximum(k - 1, 0)], 0.0), 0.0)
        frac = np.clip((np.clip(u, 0, 1) - ustart) / np.maximum(self.blocks.u_end[k] - ustart, 1e-300), 0, 1)
        return k, frac * self.length[k]

    def speed_at(self, move: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Actual speed at fraction u of move `move` (sample positions map onto chords by fraction)."""
        k, x = self._locate(move, u)
        a = self.acc[k]
        v = np.minimum.reduce([np.sqrt(self.v_entry[k] ** 2 + 2 * a * x), self.vnom[k],
                               np.sqrt(self.v_entry[k + 1] ** 2 + 2 * a * (self.length[k] - x))])
        return v

    def time_at(self, move: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Time (s from the program start) at which the tool passes fraction u of move `move`: the
        blocks before plus the time into the block's trapezoid (accelerate from the entry speed at a,
        cruise at the peak speed, decelerate to the exit speed)."""
        k, x = self._locate(move, u)
        a, L, v0, v1 = self.acc[k], self.length[k], self.v_entry[k], self.v_entry[k + 1]
        vp = np.minimum(np.sqrt(np.maximum((2 * a * L + v0**2 + v1**2) / 2, 0)), self.vnom[k])
        d_acc = (vp**2 - v0**2) / (2 * a)
        d_dec = (vp**2 - v1**2) / (2 * a)
        before = np.concatenate([[0.0], np.cumsum(self.block_time_s)])[k]
        with np.errstate(divide="ignore", invalid="ignore"):
            t_acc = (np.sqrt(v0**2 + 2 * a * np.minimum(x, d_acc)) - v0) / a
            t_cruise = np.where(vp > 0, np.clip(x - d_acc, 0, None) / vp, 0.0)
            t_dec = (np.sqrt(np.maximum(vp**2 - 2 * a * np.clip(x - (L - d_dec), 0, None), 0)) - vp) / -a
        t_cruise = np.minimum(t_cruise, np.where(vp > 0, np.maximum(L - d_acc - d_dec, 0) / vp, 0.0))
        return before + t_acc + t_cruise + t_dec

    def speed_at_samples(self, samples: Samples) -> np.ndarray:
        """Actual speed at every sample (mm/s); a sample's position along its move by arc length."""
        return self.speed_at(samples.move, self._sample_fractions(samples))

    @staticmethod
    def _sample_fractions(samples: Samples) -> np.ndarray:
        """Fraction of each sample along its move from the resampling (samples of a move are contiguous)."""
        s = samples.s_mm
        mv = samples.move
        u = np.zeros(len(s))
        starts = np.r_[0, np.flatnonzero(np.diff(mv) != 0) + 1]
        ends = np.r_[starts[1:], len(s)]
        for a, b in zip(starts, ends):
            s0 = s[a - 1] if a > 0 and not samples.segment_start[a] else s[a]
            span = s[b - 1] - s0
            u[a:b] = (s[a:b] - s0) / span if span > 0 else 1.0
        return u

    def time_at_samples(self, samples: Samples) -> np.ndarray:
        """Time (s) at which the tool passes every sample (motion only: no dwells or tool changes)."""
        return self.time_at(samples.move, self._sample_fractions(samples))


def execute(tp: Toolpath, model: ControllerModel, feed_mm_min: np.ndarray | None = None) -> Execution:
    """Plan and time the whole program (rapids at the axis rates). feed_mm_min overrides the
    programmed feed per move."""
    blk = to_blocks(tp, model, feed_mm_min)
    d = blk.end - blk.start
    L = np.linalg.norm(d, axis=1)
    u = d / np.maximum(L, 1e-300)[:, None]
    vmax, amax = np.asarray(model.max_rate_mm_s), np.asarray(model.accel_mm_s2)
    au = np.abs(u)
    with np.errstate(divide="ignore"):
        axis_rate = np.min(np.where(au > 1e-12, vmax / au, np.inf), axis=1)
        acc = np.min(np.where(au > 1e-12, amax / au, np.inf), axis=1)
    rapid = tp.kind[blk.move] == RAPID
    vnom = np.where(rapid | ~np.isfinite(blk.feed_mm_s), axis_rate, np.minimum(blk.feed_mm_s, axis_rate))
    vnom = np.minimum(vnom, L * model.block_rate_hz)
    n = len(L)
    vj = np.zeros(n + 1)
    if n > 1 and not model.exact_stop:
        u0, u1 = u[:-1], u[1:]
        cos_t = np.clip(-(u0 * u1).sum(1), -1, 1)  # grbl: cos of the angle between reversed in and out
        jv = u1 - u0
        jv /= np.maximum(np.linalg.norm(jv, axis=1), 1e-300)[:, None]
        aj = np.min(np.where(np.abs(jv) > 1e-12, amax / np.maximum(np.abs(jv), 1e-300), np.inf), axis=1)
        sin_half = np.sqrt(np.maximum(0.5 * (1 - cos_t), 0))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            v2 = np.where(cos_t < -0.999999, np.inf,  # grbl: collinear
                          np.where(cos_t > 0.999999, 0.0,  # grbl: reversal
                                   aj * model.junction_deviation_mm * sin_half / (1 - sin_half)))
        # a jump between blocks (not contiguous: e.g. program discontinuity) is a stop
        cont = np.linalg.norm(blk.start[1:] - blk.end[:-1], axis=1) < 1e-6
        vj[1:-1] = np.where(cont, np.minimum(v2, np.minimum(vnom[:-1], vnom[1:]) ** 2), 0.0)
    v2 = _plan(L, vnom, acc, vj, int(model.lookahead_blocks)) if n else np.zeros(1)
    ve = np.sqrt(np.maximum(v2, 0))
    t = _trapezoid_time(L, ve[:-1], ve[1:], vnom, acc) if n else np.zeros(0)
    return Execution(float(t.sum()), t, blk, L, vnom, acc, ve)
