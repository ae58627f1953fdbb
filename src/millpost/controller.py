"""What a real motion planner does with a program: cycle time and the speed actually reached.

Two planners, chosen by the machine's controller kind (`planner`):

- "grbl": arcs are cut into chords within `arc_tolerance_mm` (grbl's mc_arc); each block runs a
  trapezoidal velocity profile (constant acceleration, no jerk limit) at the smallest axis
  acceleration along its direction, at most the programmed feed (rapids: the axis rates). Junction
  speeds follow grbl's junction deviation δ: a virtual arc of deviation δ run at the centripetal
  acceleration the axes allow along the direction change. The planner sees `lookahead_blocks` blocks
  and must be able to stop at the end of the last one.
- "linuxcnc": LinuxCNC 2.9's trajectory planner (tp.c, blendmath.c), the model for look-ahead
  controllers that blend corners within a tolerance (LinuxCNC, Mach3, Fanuc-like). Lines and arcs are
  segments of their own, except consecutive straight feeds whose points all lie within the naive-CAM
  tolerance (G64 Q) of one line: up to 101 of them run as that line (LinuxCNC's canon layer merges them
  before its planner sees them; `naive_cam_chains`). A line's speed and acceleration are the largest
  the axes allow along it; an arc's are those of its plane's weaker axis, its speed at most √(0.87·a·r)
  (87 % of the acceleration normal to the path) and its acceleration along the path half of a (the
  other half is kept for the turn). A corner between two segments is, in this order: a stop (rapid ↔
  feed, a reversal, a command between them); "tangent" when the velocity jump v·Δu in one servo period
  (1 ms) needs less than 10 % of the axes' acceleration (both segments then lose that share of their
  acceleration); otherwise a blend arc tangent to both segments, at most the blend tolerance from the
  corner (`G64 P`; without P: a quarter of the shorter segment), using at most half of each segment,
  run at √(0.87·a·R) with a in the corner's plane; where no arc fits, a parabolic blend at half
  acceleration. The rest of a line before a blend arc that would take less than 4 servo periods at the
  arc's speed is no segment of its own: it runs as the arc's straight lead-in, at the arc's speed and
  acceleration. Speeds are planned backwards over `lookahead_blocks` segments (LinuxCNC: 50), a segment
  lasts at least 1.02 servo periods (its speed is at most its length over that), and one that ends at
  rest ends half a servo period late on average (the period's rest is lost). A feed segment that takes
  less than 10 ms (1/ARC_BLEND_RAMP_FREQ) and flows into the next changes speed linearly from end to
  end. The last segment before the motion queue runs empty (a command, the end) keeps its parabolic end
  and half its acceleration.

A controller that processes at most `block_rate_hz` blocks per second cannot finish a block of
length L faster than 1/rate (speed ≤ L·rate). Commands between moves stop the motion and take time:
a dwell its P, a tool change `tool_change_s`, a spindle start `spindle_start_s`, coolant `coolant_s`, any
other command that waits for motion to end (spindle stop or speed, tool length, user M codes)
`command_s`. Times count from the first motion to the end of the last one.
"""

from __future__ import annotations

import math
from array import array
from dataclasses import dataclass, field

import numba
import numpy as np

from millpost._kernels import compiling
from millpost.errors import ConfigError
from millpost.toolpath import ARC_CW, FEED, RAPID, Samples, Toolpath

PLANNERS = ("grbl", "linuxcnc")
# LinuxCNC 2.9 constants (tp.c, blendmath.h, tc_types.h and the [TRAJ] defaults)
NORMAL_SHARE = math.sqrt(1.0 - 0.5**2)  # BLEND_ACC_RATIO_NORMAL: share of a kept for the turn
TANGENTIAL_SHARE = 0.5  # BLEND_ACC_RATIO_TANGENTIAL: share of a along an arc
KINK_RATIO = 0.1  # ARC_BLEND_TANGENT_KINK_RATIO
GAP_CYCLES = 4  # ARC_BLEND_GAP_CYCLES: a line's rest shorter than this many periods joins the next blend arc
MIN_SEGMENT_CYCLES = 1.02  # TP_MIN_SEGMENT_CYCLES: a segment lasts at least this many periods
RAMP_TIME_S = 1.0 / 100.0  # 1 / ARC_BLEND_RAMP_FREQ: shorter feed segments ramp linearly end to end
SHARP_CORNER_COS = math.cos(math.pi * (1.0 - 2.0 / 180.0))  # reversal within 2°: stop
ANGLE_EPS = 1e-6
# events that wait for the motion to stop, and which time of the model each costs
PAUSE_KINDS = {"dwell": None, "tool_change": "tool_change_s", "coolant": "coolant_s", "tool_length": "command_s",
               "m_code": "command_s", "stop": None}


@dataclass(frozen=True)
class ControllerModel:
    """Planner settings. Rates mm/s, accelerations mm/s², lengths mm, times s (grbl: $110-$112 in
    mm/min, $120-$122, $11 junction deviation, $12 arc tolerance; a buffer of 16 blocks on an AVR.
    LinuxCNC: [AXIS_*] MAX_VELOCITY/MAX_ACCELERATION, G64 P, ARC_BLEND_OPTIMIZATION_DEPTH 50).
    merges_naive_cam: the controller merges consecutive straight feeds within the naive-CAM tolerance
    into one line (LinuxCNC's canon layer: `naive_cam_chains`; a program's G64 P/Q sets the tolerance);
    naive_cam_mm: that tolerance before the program sets a path mode (LinuxCNC's startup G64 Q, or P
    without Q; 0 where the controller merges nothing)."""

    max_rate_mm_s: tuple[float, float, float]
    accel_mm_s2: tuple[float, float, float]
    junction_deviation_mm: float = 0.01
    lookahead_blocks: int = 16
    block_rate_hz: float = float("inf")
    arc_tolerance_mm: float = 0.002
    exact_stop: bool = False
    planner: str = "grbl"
    blend_tolerance_mm: float = 0.0
    merges_naive_cam: bool = False
    naive_cam_mm: float = 0.0
    servo_period_s: float = 0.001
    tool_change_s: float = 0.0
    spindle_start_s: float = 0.0
    coolant_s: float = 0.0
    command_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("max_rate_mm_s", "accel_mm_s2"):
            v = np.asarray(getattr(self, name), float)
            if v.shape != (3,) or not (v > 0).all():
                raise ConfigError(name, getattr(self, name), "three positive numbers (X, Y, Z)")
        for name in ("junction_deviation_mm", "blend_tolerance_mm", "naive_cam_mm", "tool_change_s", "spindle_start_s",
                     "coolant_s", "command_s"):
            if not getattr(self, name) >= 0:
                raise ConfigError(name, getattr(self, name), "must be ≥ 0")
        if self.lookahead_blocks < 1:
            raise ConfigError("lookahead_blocks", self.lookahead_blocks, "must be ≥ 1")
        if not self.block_rate_hz > 0:
            raise ConfigError("block_rate_hz", self.block_rate_hz, "must be > 0")
        if not self.arc_tolerance_mm > 0:
            raise ConfigError("arc_tolerance_mm", self.arc_tolerance_mm, "must be > 0")
        if not self.servo_period_s > 0:
            raise ConfigError("servo_period_s", self.servo_period_s, "must be > 0")
        if self.planner not in PLANNERS:
            raise ConfigError("planner", self.planner, f"one of {', '.join(PLANNERS)}")
        if self.naive_cam_mm > 0 and not self.merges_naive_cam:
            raise ConfigError("naive_cam_mm", self.naive_cam_mm, "0 for a controller that merges no straight feeds")

    @classmethod
    def from_machine(cls, machine) -> "ControllerModel":
        """The model of a machine's controller: its axis rates and accelerations, its planner (a
        LinuxCNC controller's blend tolerance is its startup G64 P, which sets the naive-CAM tolerance
        too; only LinuxCNC merges naive-CAM feeds, `Controller.merges_naive_cam`)."""
        ax = [machine.axes[a] for a in "xyz"]
        c = machine.controller
        return cls(max_rate_mm_s=tuple(a.vmax_mm_min / 60.0 for a in ax), accel_mm_s2=tuple(a.amax_mm_s2 for a in ax),
                   junction_deviation_mm=c.junction_deviation_mm, block_rate_hz=c.block_rate_Hz,
                   planner=c.planner, lookahead_blocks=16 if c.planner == "grbl" else 50,
                   blend_tolerance_mm=c.blend_tolerance_mm, tool_change_s=c.tool_change_s,
                   merges_naive_cam=c.merges_naive_cam,
                   naive_cam_mm=c.blend_tolerance_mm if c.merges_naive_cam else 0.0,
                   spindle_start_s=c.spindle_start_s, coolant_s=c.coolant_s, command_s=c.command_s)


@dataclass
class Blocks:
    """Planner blocks: chord end points, owning move, fraction of the move at the block end."""

    start: np.ndarray
    end: np.ndarray
    move: np.ndarray
    u_end: np.ndarray
    feed_mm_s: np.ndarray  # programmed (nan for rapids)


def to_blocks(tp: Toolpath, model: ControllerModel, feed_mm_min: np.ndarray | None = None) -> Blocks:
    """grbl: lines as one block each, arcs as chords with sagitta ≤ arc_tolerance (grbl's mc_arc)."""
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
    """Executed time (s, first motion to the end of the last, pauses between included), per block
    times, lengths, speed caps, accelerations and entry speeds (mm/s); `speed_at` gives the actual
    speed. Blocks are in path order; `move` and `u_end` place each on the program's moves."""

    time_s: float
    block_time_s: np.ndarray
    move: np.ndarray
    u_end: np.ndarray
    length: np.ndarray
    vnom: np.ndarray
    acc: np.ndarray
    v_entry: np.ndarray  # (n+1,)
    # per block: a short feed segment LinuxCNC runs as one linear ramp (constant acceleration) from its
    # entry to its exit speed, no faster than either
    ramp: np.ndarray
    move_start_mm: np.ndarray  # (len(program moves)+1,): the program's arc length where each move starts
    pause_s: float = 0.0  # of time_s, spent stopped between moves (dwells, tool changes, commands)
    # (k, 3): the blend arcs LinuxCNC runs at up to the faster of its two segments' feeds, each with the
    # straight lead-in it absorbed: the program's arc length (mm) where it starts and ends, the highest
    # speed (mm/s) reached on it
    blends: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def _locate(self, move: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Block index and distance into it (mm) of fraction u of move `move`: by the program's arc
        length between the places where the blocks end, so that moves no block ends on (too short for
        a block, inside a blend arc or a merged line) lie in proportion along the block over them."""
        move = np.asarray(move, np.int64)
        at = self.move_start_mm
        length = np.diff(at)
        end = at[self.move] + self.u_end * length[self.move]
        q = at[move] + np.clip(u, 0, 1) * length[move]
        k = np.clip(np.searchsorted(end, q - 1e-12), 0, len(end) - 1)
        start = np.where(k > 0, end[np.maximum(k - 1, 0)], 0.0)
        frac = np.clip((q - start) / np.maximum(end[k] - start, 1e-300), 0, 1)
        return k, frac * self.length[k]

    def speed_at(self, move: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Actual speed at fraction u of move `move` (sample positions map onto blocks by fraction): the
        block's trapezoid, or its linear ramp from entry to exit speed."""
        k, x = self._locate(move, u)
        a, v0, v1, L = self.acc[k], self.v_entry[k], self.v_entry[k + 1], self.length[k]
        v = np.minimum.reduce([np.sqrt(v0**2 + 2 * a * x), self.vnom[k], np.sqrt(v1**2 + 2 * a * (L - x))])
        with np.errstate(divide="ignore", invalid="ignore"):
            linear = np.sqrt(np.maximum(v0**2 + (v1**2 - v0**2) * np.where(L > 0, x / L, 1.0), 0.0))
        return np.where(self.ramp[k], linear, v)

    def time_at(self, move: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Time (s from the program start) at which the tool passes fraction u of move `move`: the
        blocks before plus the time into the block's trapezoid (accelerate from the entry speed at a,
        cruise at the peak speed, decelerate to the exit speed) or linear ramp."""
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
        v = self.speed_at(move, u)  # a linear ramp: constant acceleration from v0, t = 2x / (v0 + v(x))
        with np.errstate(divide="ignore", invalid="ignore"):
            ramp = np.where(v0 + v > 0, 2 * x / (v0 + v), 0.0)
        return before + np.where(self.ramp[k], ramp, t_acc + t_cruise + t_dec)

    def speed_at_samples(self, samples: Samples) -> np.ndarray:
        """Actual speed at every sample (mm/s); a sample's position along its move by arc length."""
        return self.speed_at(samples.move, self.sample_fractions(samples))

    @staticmethod
    def sample_fractions(samples: Samples) -> np.ndarray:
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
        return self.time_at(samples.move, self.sample_fractions(samples))


def pauses_s(program, model: ControllerModel) -> np.ndarray:
    """Per junction of the program's toolpath (len(moves)+1; index i = before move i): the time the
    controller stands still there for the program's commands, nan where nothing waits for the motion
    to end. Dwells last their P; a spindle start `spindle_start_s`, other spindle commands
    `command_s`; a tool change `tool_change_s`; coolant `coolant_s`; tool length and user M codes
    `command_s`."""
    out = np.full(len(program.toolpath) + 1, np.nan)
    for e in program.events:
        if e.kind == "spindle":
            cost = model.spindle_start_s if e.value[0] in ("cw", "ccw") else model.command_s
        elif e.kind in PAUSE_KINDS:
            name = PAUSE_KINDS[e.kind]
            cost = float(e.value) if e.kind == "dwell" else getattr(model, name) if name else 0.0
        else:
            continue
        out[e.move] = np.nan_to_num(out[e.move]) + cost
    return out


EXACT_PATH, EXACT_STOP = -1.0, -2.0  # path modes in a blend-tolerance array: G61, G61.1
CHAIN_POINTS = 101  # LinuxCNC's canon chains at most this many points into one line (linkable: size > 100)
AXIS_TINY_MM = 1e-7  # canon drops a line whose every axis moves less than this (getStraightAcceleration's tiny)
# the comments LinuxCNC's canon passes on (to the operator or the log): they flush its chain of straight
# feeds like every other command; other comments do not
_FLUSHING_COMMENTS = ("MSG,", "DEBUG,", "LOG,")


@dataclass(frozen=True)
class PathModes:
    """Per move, the path control LinuxCNC runs it in. blend_mm: the blend tolerance (G64 P, mm; 0 for a
    G64 without P) or EXACT_PATH (G61: stop at corners) or EXACT_STOP (G61.1: stop after every move).
    merge_mm: the naive-CAM tolerance (G64 Q, mm; P when Q is absent, 0 for a plain G64, in G61/G61.1,
    in canned cycles and on a controller that merges nothing, `ControllerModel.merges_naive_cam`):
    consecutive straight feeds whose points lie this close to one line are sent to the planner as that
    one line (`naive_cam_chains`). flush: a command before the move ends the chain
    being merged (a pause, a spindle speed, an offset, a path mode, an operator message)."""

    blend_mm: np.ndarray
    merge_mm: np.ndarray
    flush: np.ndarray

    @classmethod
    def uniform(cls, n: int, model: "ControllerModel") -> "PathModes":
        """The controller's own modes on every move."""
        return cls(np.full(n, model.blend_tolerance_mm), np.full(n, model.naive_cam_mm), np.zeros(n, bool))


def path_modes(program, model: ControllerModel) -> PathModes:
    """The path modes the program sets (`PathModes`); before it sets one, the controller's own
    (`blend_tolerance_mm`, `naive_cam_mm`). A G64 P/Q sets a naive-CAM tolerance only on a controller
    that merges straight feeds (`ControllerModel.merges_naive_cam`).
    The moves of a canned cycle (after its climb to R) run in exact path whatever the mode (LinuxCNC's
    convert_cycle sets G61 for them and restores it after). Tolerances in a G20 program are inches."""
    n = len(program.toolpath)
    modes = PathModes.uniform(n, model)
    out, merge, flush = modes.blend_mm, modes.merge_mm, modes.flush
    inch = np.asarray(program.move_inch, bool)
    cycles = []
    for e in program.events:
        if e.kind == "canned_cycle":
            cycles.append((e.value, e.move))
        if e.move < n and (e.kind != "comment" or str(e.value).lstrip().upper().startswith(_FLUSHING_COMMENTS)):
            flush[e.move] = True
        if e.kind != "path_mode" or e.move >= n:
            continue
        name, p, q = e.value
        unit = 25.4 if inch[e.move] else 1.0
        if name == "blend":
            out[e.move:] = 0.0 if p is None else p * unit
            merging = (p, q) != (None, None) and model.merges_naive_cam
            merge[e.move:] = (p if q is None else q) * unit if merging else 0.0
        else:
            out[e.move:] = EXACT_PATH if name == "exact path" else EXACT_STOP
            merge[e.move:] = 0.0
    for first, end in cycles:  # a canned cycle's moves (after the climb to R) in exact path, as LinuxCNC runs them
        out[first:end] = np.where(out[first:end] == EXACT_STOP, EXACT_STOP, EXACT_PATH)
        merge[first:end] = 0.0
    return modes


@numba.njit(cache=True)
def _chains(start, end, straight, merge_mm, flush, max_points):
    """Per move, the first move of the chain it is merged into (see `naive_cam_chains`)."""
    n = start.shape[0]
    first = np.arange(n)
    head = -1
    for i in range(n):
        if not straight[i]:
            head = -1
            continue
        if head >= 0:
            tol = merge_mm[i]
            b = start[head]
            m = end[i] - b
            mm = m[0] * m[0] + m[1] * m[1] + m[2] * m[2]
            ok = not flush[i] and tol > 0 and i - head < max_points and mm > 0.0
            k = head
            while ok and k < i:
                d = end[k] - b
                t = min(max((d[0] * m[0] + d[1] * m[1] + d[2] * m[2]) / mm, 0.0), 1.0)
                r = d - t * m
                ok = r[0] * r[0] + r[1] * r[1] + r[2] * r[2] <= tol * tol
                k += 1
            if not ok:
                head = -1
        if head < 0:
            head = i
        first[i] = head
    return first


def naive_cam_chains(tp: Toolpath, modes: PathModes, feed_mm_min: np.ndarray | None = None) -> np.ndarray:
    """LinuxCNC's naive-CAM detector (its canon layer, emccanon.cc: see_segment, linkable and
    flush_segments): consecutive straight feeds are chained while every point of the chain lies within
    the naive-CAM tolerance of the line from the chain's start to the newest end point (its nearest point
    on that segment), the chain holds at most 101 points, the new end point differs from the chain's start,
    and nothing flushes the chain before the move: a rapid or an arc, a feed rate that changes, a path
    mode (G61, G61.1, G64; a plain G64 or G61 sets no tolerance), a command (`PathModes.flush`). The chain
    goes to the planner as one line from its start to its last point at the current feed. Returns per
    move the index of the first move of its chain (its own index where nothing is merged)."""
    feed = tp.feed_mm_min if feed_mm_min is None else np.asarray(feed_mm_min, float)
    flush = np.asarray(modes.flush, bool).copy()
    if len(tp) > 1:
        flush[1:] |= feed[1:] != feed[:-1]
        flush[1:] |= np.any(tp.start[1:] != tp.end[:-1], axis=1)
    with compiling(_chains):
        return _chains(np.ascontiguousarray(tp.start, float), np.ascontiguousarray(tp.end, float),
                       tp.kind == FEED, np.asarray(modes.merge_mm, float), flush, CHAIN_POINTS)


def block_lengths(tp: Toolpath, modes: PathModes) -> np.ndarray:
    """Per move the length (mm) of the block the planner receives it in, at the programmed feeds: the
    move itself, or in a chain of straight feeds the controller merges (`naive_cam_chains`) the line
    from the chain's start to its last point. A controller that reads at most `block_rate_hz` blocks
    per second runs a block of length L at most at L·rate (mm/s)."""
    first = naive_cam_chains(tp, modes)
    chain = np.cumsum(np.r_[True, first[1:] != first[:-1]]) - 1
    last = np.flatnonzero(np.r_[first[1:] != first[:-1], True])[chain]
    merged = last != first
    out = tp.lengths().astype(float)
    out[merged] = np.linalg.norm(tp.end[last[merged]] - tp.start[first[merged]], axis=1)
    return out


def execute_program(program, model: ControllerModel, feed_mm_min: np.ndarray | None = None,
                    modes: PathModes | None = None) -> Execution:
    """`execute` on an interpreted program: its pauses (dwells, tool changes, commands) stop the
    motion and take their time, its path modes (G61/G64 P Q; `path_modes`, computed here unless
    given) set the corners and the merging of straight feeds; feed_mm_min overrides the programmed
    feed per move."""
    return execute(program.toolpath, model, feed_mm_min, pauses=pauses_s(program, model),
                   modes=path_modes(program, model) if modes is None else modes)


def program_time(program, model: ControllerModel) -> float:
    """Cycle time of an interpreted program (s): motion and the pauses between its first and last
    move, in the path modes (G61/G64) the program sets."""
    return execute_program(program, model).time_s


def execute(tp: Toolpath, model: ControllerModel, feed_mm_min: np.ndarray | None = None,
            pauses: np.ndarray | None = None, modes: PathModes | None = None) -> Execution:
    """Plan and time the whole program (rapids at the axis rates). feed_mm_min overrides the
    programmed feed per move; pauses (see `pauses_s`, len(tp)+1) stop the motion between moves;
    modes (see `path_modes`; default: the controller's own) set the LinuxCNC planner's path modes."""
    blends = np.zeros((0, 3))
    if model.planner == "linuxcnc":
        L, vnom, acc, vj2, move, u_end, ramps, cuts, blends = _linuxcnc_blocks(tp, model, feed_mm_min, pauses, modes)
    else:
        cuts = []
        L, vnom, acc, vj2, move, u_end = _grbl_blocks(tp, model, feed_mm_min, pauses)
    vj2 = vj2.copy()
    vj2[1:-1] = np.minimum(vj2[1:-1], np.minimum(vnom[:-1], vnom[1:]) ** 2)
    n = len(L)
    with compiling(_plan):
        v2 = _plan(L, vnom, acc, vj2, int(model.lookahead_blocks)) if n else np.zeros(1)
    ve = np.sqrt(np.maximum(v2, 0))
    t = _trapezoid_time(L, ve[:-1], ve[1:], vnom, acc) if n else np.zeros(0)
    ramp = np.zeros(n, bool)
    if model.planner == "linuxcnc":
        # a feed segment run in less than RAMP_TIME_S that flows into the next changes speed linearly
        # from end to end (no cruise above both ends); one ending at rest ends half a period late
        with np.errstate(divide="ignore", invalid="ignore"):
            t_ramp = np.where(ve[:-1] + ve[1:] > 0, 2.0 * L / (ve[:-1] + ve[1:]), np.inf)
            v_end = ve[:-1] + np.minimum(ve[1:], vnom)
            t_est = np.where(v_end > 0, 2.0 * L / v_end, np.inf)
        ramp = ramps & (ve[1:] > 0) & (t_est < RAMP_TIME_S)
        t = np.where(ramp, t_ramp, t) + np.where(ve[1:] == 0.0, 0.5 * model.servo_period_s, 0.0)
        if len(blends):  # the top of each arc's profile: a linear ramp's faster end, else the trapezoid's peak
            k = blends[:, 2].astype(np.int64)
            v0, v1 = ve[k], ve[k + 1]
            peak = np.minimum(np.sqrt(np.maximum((2 * acc[k] * L[k] + v0**2 + v1**2) / 2, 0)), vnom[k])
            blends = np.column_stack([blends[:, :2], np.where(ramp[k], np.maximum(v0, v1), peak)])
    pause = 0.0
    if pauses is not None and n:
        first, last = move[0], move[-1]
        inside = np.arange(len(pauses))
        pause = float(np.nansum(np.where((inside > first) & (inside <= last), pauses, 0.0)))
    if cuts:
        t, L, vnom, acc, ve, move, u_end, ramp = _cut_blocks(cuts, t, L, vnom, acc, ve, ramp, move, u_end)
    return Execution(float(t.sum()) + pause, t, move, u_end, L, vnom, acc, ve, ramp,
                     np.r_[0.0, np.cumsum(tp.lengths())], pause, blends)


def _cut_blocks(cuts, t, L, vnom, acc, ve, ramp, move, u_end):
    """Blocks cut where they pass from one program move onto the next (a blend arc's two halves, a
    merged chain's moves), so that every piece lies on one move. cuts: (block, fraction of it at the
    cut, the move and the fraction of it where the piece before the cut ends); the piece after the last
    cut keeps the block's own place. A piece runs the block's speed profile between the cut points
    (constant acceleration on a linear ramp, the trapezoid elsewhere); the pieces' times share the
    block's time in proportion to those runs. Returns the pieces' t, L, vnom, acc, entry speeds (n+1),
    move, u_end and ramp."""
    n = len(L)
    k = np.array([c[0] for c in cuts], np.int64)
    blk = np.r_[k, np.arange(n)]
    f_end = np.r_[np.clip([c[1] for c in cuts], 0.0, 1.0), np.ones(n)]
    mv = np.r_[np.array([c[2] for c in cuts], np.int64), move]
    uu = np.r_[np.array([c[3] for c in cuts], float), u_end]
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
        run = np.where(ramp[blk], np.where(vs + vf > 0, 2.0 * Lp / (vs + vf), 0.0), _trapezoid_time(Lp, vs, vf, vm, a))
        total = np.bincount(blk, run, minlength=n)
        share = np.where(total[blk] > 0, run / total[blk], f_end - f_start)
    return t[blk] * share, Lp, vm, a, np.r_[vs, ve[-1]], mv, uu, ramp[blk]


def _stops(tp: Toolpath, pauses: np.ndarray | None) -> np.ndarray:
    """Per move: whether the motion must stop before it (a pause or a jump in position)."""
    stop = np.zeros(len(tp), bool)
    if pauses is not None:
        stop |= np.isfinite(np.asarray(pauses, float)[:len(tp)])
    if len(tp) > 1:
        stop[1:] |= np.linalg.norm(tp.start[1:] - tp.end[:-1], axis=1) > 1e-6
    return stop


def _axis_limited(u: np.ndarray, limits) -> np.ndarray:
    """Largest path rate (speed or acceleration) along unit directions u that no axis exceeds."""
    au = np.abs(u)
    with np.errstate(divide="ignore"):
        return np.min(np.where(au > 1e-12, np.asarray(limits, float) / np.maximum(au, 1e-300), np.inf), axis=1)


def _grbl_blocks(tp, model, feed_mm_min, pauses):
    """Chord blocks with grbl's junction-deviation corner speeds."""
    blk = to_blocks(tp, model, feed_mm_min)
    d = blk.end - blk.start
    L = np.linalg.norm(d, axis=1)
    u = d / np.maximum(L, 1e-300)[:, None]
    amax = np.asarray(model.accel_mm_s2)
    axis_rate = _axis_limited(u, model.max_rate_mm_s)
    acc = _axis_limited(u, amax)
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
        aj = _axis_limited(jv, amax)
        sin_half = np.sqrt(np.maximum(0.5 * (1 - cos_t), 0))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            v2 = np.where(cos_t < -0.999999, np.inf,  # grbl: collinear
                          np.where(cos_t > 0.999999, 0.0,  # grbl: reversal
                                   aj * model.junction_deviation_mm * sin_half / (1 - sin_half)))
        # a jump between blocks or a pause before the next move is a stop
        cont = np.linalg.norm(blk.start[1:] - blk.end[:-1], axis=1) < 1e-6
        first_of_move = np.r_[True, blk.move[1:] != blk.move[:-1]][1:]
        paused = _stops(tp, pauses)[blk.move[1:]] & first_of_move
        vj[1:-1] = np.where(cont & ~paused, v2, 0.0)
    return L, vnom, acc, vj, blk.move, blk.u_end


def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _inscribed(normal, limits) -> float:
    """LinuxCNC's calculateInscribedDiameter: the largest rate every direction of the plane with this
    normal allows (axis limit over the axis's share of the plane)."""
    best = math.inf
    for i in range(3):
        share = math.sqrt(max(1.0 - normal[i] ** 2, 0.0))
        best = min(best, limits[i] / max(share, 1e-12))
    return best


class _Segment:
    """One LinuxCNC trajectory segment while the queue is built (lengths mm, speeds mm/s): a program
    move, or a chain of straight feeds merged into one line (moves first..move; `ends`: the distance
    along the segment at the end of each of them)."""

    __slots__ = ("move", "first", "ends", "length", "nominal", "trim_start", "trim_end", "req", "maxvel", "acc",
                 "arc", "rapid", "t0", "t1", "normal", "radius", "angle", "halved", "kink_share", "tolerance")


def _place(s: _Segment, x: float) -> tuple[int, float]:
    """The move under the point x mm along a segment, and the fraction of that move there (a merged
    chain's moves by their end points' positions along the line)."""
    ends = s.ends
    k = 0 if len(ends) == 1 else min(int(np.searchsorted(ends, x - 1e-12)), len(ends) - 1)
    before = float(ends[k - 1]) if k else 0.0
    span = float(ends[k]) - before
    return s.first + k, min(max((x - before) / span, 0.0), 1.0) if span > 0 else 1.0


def _segments(tp: Toolpath, model: ControllerModel, feed_mm_min, modes: PathModes | None,
              merge: bool = False) -> list[_Segment]:
    """Segments of LinuxCNC's queue with the limits emccanon gives them: one per move, or with merge
    one per chain of straight feeds (`naive_cam_chains`); a line whose every axis moves less than
    AXIS_TINY_MM never reaches the planner (canon drops it), nor does an arc shorter than 1e-9 mm."""
    feed = tp.feed_mm_min if feed_mm_min is None else np.asarray(feed_mm_min, float)
    modes = PathModes.uniform(len(tp), model) if modes is None else modes
    vax, aax = np.asarray(model.max_rate_mm_s, float), np.asarray(model.accel_mm_s2, float)
    if not len(tp):
        return []
    first = naive_cam_chains(tp, modes, feed) if merge else np.arange(len(tp))
    last = np.flatnonzero(np.r_[first[1:] != first[:-1], True])
    head = first[last]
    arc = tp.kind[last] >= ARC_CW
    chord = tp.end[last] - tp.start[head]
    L = np.where(arc, tp.lengths()[last], np.linalg.norm(chord, axis=1))
    keep = np.where(arc, L > 1e-9, np.abs(chord).max(axis=1) >= AXIS_TINY_MM)
    idx, head, arc, chord, L = last[keep], head[keep], arc[keep], chord[keep], L[keep]
    if not len(idx):
        return []
    t0 = chord / np.maximum(L, 1e-300)[:, None]
    t1 = t0.copy()
    vmax = _axis_limited(t0, vax)
    acc = _axis_limited(t0, aax)
    radius = np.full(len(idx), np.inf)
    angle = np.zeros(len(idx))
    normal = np.zeros((len(idx), 3))
    if arc.any():
        sub = tp.subset(idx[arc])
        m = np.arange(len(sub))
        _, t0[arc], _ = sub.points(m, np.zeros(len(m)), derivatives=True)
        _, t1[arc], _ = sub.points(m, np.ones(len(m)), derivatives=True)
        r0, r1, _, sweep, dn, ax = sub._arc_params()
        planar = np.abs(sweep) * 0.5 * (r0 + r1)
        length = np.hypot(planar, dn)
        c, s = planar / length, np.abs(dn) / length
        a1, a2, an = ax[:, 0], ax[:, 1], ax[:, 2]
        v_plane, a_plane = np.minimum(vax[a1], vax[a2]), np.minimum(aax[a1], aax[a2])
        # a helix: the plane's share c and the normal axis's share s of the path (emccanon's ARC_FEED)
        c, s = np.maximum(c, 1e-12), np.maximum(s, 1e-12)
        vmax[arc] = np.minimum(v_plane / c, np.where(s > 1e-12, vax[an] / s, np.inf))
        acc[arc] = np.minimum(a_plane / c, np.where(s > 1e-12, aax[an] / s, np.inf))
        rmin = np.minimum(r0, r1)
        spiral = (r1 - r0) / np.maximum(np.abs(sweep), 1e-12)
        radius[arc] = np.sqrt(rmin**2 + spiral**2)  # pmCircleEffectiveMinRadius
        vmax[arc] = np.minimum(vmax[arc], np.sqrt(NORMAL_SHARE * acc[arc] * radius[arc]))  # pmCircleActualMaxVel
        angle[arc] = np.abs(sweep)
        nrm = np.zeros((arc.sum(), 3))
        nrm[np.arange(arc.sum()), an] = 1.0
        normal[arc] = nrm
    rapid = tp.kind[idx] == RAPID
    f = feed[idx] / 60.0
    req = np.where(rapid | ~np.isfinite(f), vmax, np.minimum(f, vmax))
    segs = []
    for k in range(len(idx)):
        s = _Segment()
        s.move, s.first, s.length, s.nominal = int(idx[k]), int(head[k]), float(L[k]), float(L[k])
        s.ends = np.array([s.nominal])
        if s.first < s.move:  # a merged chain: its moves' end points projected on the line
            p = (tp.end[s.first:s.move + 1] - tp.start[s.first]) @ t0[k]
            s.ends = np.minimum(np.maximum.accumulate(np.clip(p, 0.0, s.nominal)), s.nominal)
            s.ends[-1] = s.nominal
        s.trim_start = s.trim_end = 0.0
        s.req, s.maxvel, s.acc = float(req[k]), float(vmax[k]), float(acc[k])
        s.arc, s.rapid = bool(arc[k]), bool(rapid[k])
        s.t0, s.t1, s.normal = tuple(t0[k].tolist()), tuple(t1[k].tolist()), tuple(normal[k].tolist())
        s.radius, s.angle = float(radius[k]), float(angle[k])
        s.halved, s.kink_share = False, 0.0
        s.tolerance = float(modes.blend_mm[idx[k]])
        segs.append(s)
    return segs


def _arc_maxvel(s: _Segment, halved: bool) -> float:
    """pmCircleActualMaxVel: an arc's speed keeps the normal acceleration v²/r within 87 % of a."""
    a = s.acc * (0.5 if halved else 1.0)
    return min(s.maxvel, math.sqrt(NORMAL_SHARE * a * s.radius))


def _blend_geometry(prev: _Segment, cur: _Segment, model: ControllerModel):
    """The feed-independent part of LinuxCNC's blend arc between two segments (blendmath.c:
    blendInit3From*, blendComputeParameters): (θ, φ, binormal, d_geom, r_geom), or None where no arc
    fits. θ is half the angle between the reversed incoming and the outgoing direction, φ = π − 2θ the
    turn; the arc may reach d_geom (mm) into each segment (at most the blend tolerance from the
    corner, half a line, a third/two thirds of an arc's sweep), so its radius is at most r_geom."""
    u1, u2 = prev.t1, cur.t0
    dot = min(max(_dot(u1, u2), -1.0), 1.0)
    theta = math.acos(-dot) / 2.0
    if math.pi / 2 - theta < ANGLE_EPS or theta < ANGLE_EPS:
        return None
    b = (u1[1] * u2[2] - u1[2] * u2[1], u1[2] * u2[0] - u1[0] * u2[2], u1[0] * u2[1] - u1[1] * u2[0])
    nb = math.sqrt(_dot(b, b))
    binormal = (b[0] / nb, b[1] / nb, b[2] / nb)
    for s in (prev, cur):  # a blend arc lies in the plane of an arc it touches
        if s.arc and abs(abs(_dot(binormal, s.normal)) - 1.0) > 1e-6:
            return None
    if prev.arc and cur.arc and theta < math.pi / 12:
        return None
    t1 = prev.tolerance if prev.tolerance > 0 else 0.25 * prev.nominal
    t2 = cur.tolerance if cur.tolerance > 0 else 0.25 * cur.nominal
    tol = min(t1, t2, 0.25 * prev.nominal, 0.25 * cur.nominal)
    # how much of each segment the arc may use: half a line, up to a third (next) or two thirds (previous)
    # of an arc's sweep and at most a quarter turn (blendInit3From*)
    if prev.arc:
        L1 = min(prev.angle * 2.0 / 3.0, math.pi / 2) * prev.radius
    else:
        L1 = 0.5 * prev.nominal
    L1 = min(L1, prev.length)
    L2 = min(cur.angle / 3.0, math.pi / 2) * cur.radius if cur.arc else 0.5 * cur.length
    d_tol = math.cos(theta) * tol / (1.0 - math.sin(theta))
    d_geom = min(L1, L2, d_tol)
    return theta, math.pi - 2.0 * theta, binormal, d_geom, math.tan(theta) * d_geom


def _blend(prev: _Segment, cur: _Segment, model: ControllerModel):
    """LinuxCNC's blend arc between two segments (blendmath.c: blendParamKinematics,
    blendComputeParameters on `_blend_geometry`): (trim of each segment, arc length, arc speed, arc
    acceleration), or None. The arc runs at up to the faster segment's requested speed."""
    geometry = _blend_geometry(prev, cur, model)
    if geometry is None:
        return None
    theta, phi, binormal, d_geom, r_geom = geometry
    u1, u2 = prev.t1, cur.t0
    a_max = _inscribed(binormal, model.accel_mm_s2)
    a_n = a_max * NORMAL_SHARE
    v_req = max(prev.req, cur.req)
    v_planar = _inscribed(binormal, model.max_rate_mm_s)
    phi_eff = min(phi, math.pi * 0.49)
    vm1 = min(prev.maxvel, cur.maxvel / math.cos(phi_eff))
    vm2 = min(cur.maxvel, prev.maxvel / math.cos(phi_eff))
    v_alt = 0.0
    if not prev.arc and not cur.arc:
        base = math.sqrt(sum((u2[i] * vm2 - u1[i] * vm1) ** 2 for i in range(3)))
        v_alt = vm1 * vm2 * math.sin(phi) / base if base > 0 else 0.0
    v_goal = min(v_req, max(v_alt, v_planar))
    v_plan = min(math.sqrt(a_n * r_geom), v_goal)
    a_par = 0.5 * a_max
    t_blend = min(math.sqrt(2.0 * a_par * d_geom), v_plan) / a_par
    r_blend = min(t_blend * v_plan / phi, r_geom)
    r_plan = max(v_plan**2 / a_n, r_blend)
    d_plan = r_plan / math.tan(theta)
    s_arc = r_plan * phi
    if r_plan < 1e-12 or s_arc < 1e-6:
        return None
    return d_plan, s_arc, min(v_plan, v_req), a_max * TANGENTIAL_SHARE


def corner_speeds(tp: Toolpath, model: ControllerModel, modes: PathModes | None = None) -> np.ndarray:
    """LinuxCNC's planner: per junction (len(tp) + 1; index j: before move j) the highest speed (mm/s)
    at which it passes the corner whatever the feeds: 0 where it stops (rapid ↔ feed, a reversal, a
    jump, G61/G61.1), else the larger of the tangent-kink speed (the velocity jump v·Δu in one servo
    period within 10 % of the axes' acceleration) and the blend arc's top speed √(0.87·a·r_geom) (or,
    where no arc fits, the parabolic blend's); inf at the ends and between collinear moves, and between
    two straight feeds wherever a naive-CAM tolerance is set (`naive_cam_chains`): which corners the
    canon layer merges away, and the directions of the lines it makes, follow the feeds written."""
    out = np.full(len(tp) + 1, np.inf)
    modes = PathModes.uniform(len(tp), model) if modes is None else modes
    segs = _segments(tp, model, np.full(len(tp), np.inf), modes)
    amax, dt = model.accel_mm_s2, model.servo_period_s
    for prev, cur in zip(segs[:-1], segs[1:]):
        if (prev.rapid != cur.rapid or model.exact_stop or prev.tolerance in (EXACT_PATH, EXACT_STOP)
                or _dot(prev.t1, cur.t0) < SHARP_CORNER_COS
                or np.linalg.norm(tp.start[cur.move] - tp.end[prev.move]) > 1e-6):
            out[cur.move] = 0.0
            continue
        jump = max(abs(cur.t0[i] - prev.t1[i]) / amax[i] for i in range(3))
        if jump < 1e-12:
            continue
        v = KINK_RATIO * dt / jump * (TANGENTIAL_SHARE if prev.arc or cur.arc else 1.0)
        geometry = _blend_geometry(prev, cur, model)
        if geometry is not None:
            _, _, binormal, _, r_geom = geometry
            v = max(v, math.sqrt(NORMAL_SHARE * _inscribed(binormal, model.accel_mm_s2) * r_geom))
        else:
            v = max(v, _parabolic_speed(prev, cur))
        out[cur.move] = v
    # a junction of two straight feeds that a naive-CAM chain may absorb (at some feeds) has no corner
    # of its own: its three points lie within the tolerance of one line, so the triangle's width, its
    # smallest altitude |AB × AC| / longest side, is at most twice the tolerance
    straight = tp.kind == FEED
    a, b, c = tp.start[:-1], tp.end[:-1], tp.end[1:]
    sides = np.maximum.reduce([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                               np.linalg.norm(c - a, axis=1)])
    width = np.linalg.norm(np.cross(b - a, c - a), axis=1) / np.maximum(sides, 1e-300)
    merging = np.r_[False, straight[:-1] & straight[1:] & (modes.merge_mm[1:] > 0) & ~modes.flush[1:]
                    & (width <= 2.0 * modes.merge_mm[1:]), False]
    out[merging] = np.inf
    return out


def blend_zones(tp: Toolpath, model: ControllerModel, modes: PathModes) -> np.ndarray:
    """Corners where the controller may run a blend arc at the faster of its two moves' feeds (LinuxCNC
    blends at max(F_in, F_out)), bounded at any feeds: per corner between two programmed moves (k, 3):
    the arc length (mm) where the arc may start and end (the corner ∓ d_geom) and its top speed
    √(0.87·a·r_geom) (mm/s), the same columns as `Execution.blends`. On such a zone the slower move's
    loads see the faster move's feed unless both F words fit it. grbl never runs a junction above the
    slower block's feed: no zones. modes: the path modes (`path_modes`). Per programmed move, not
    merged: the canon layer's merging depends on the F words written, and its longer lines reach
    further; the arcs of the program as emitted are `Execution.blends`. Stops (rapid ↔ feed, reversals,
    jumps, G61/G61.1) have no zone; pauses are not looked at (a zone there only costs time)."""
    out = []
    if model.planner != "linuxcnc":
        return np.zeros((0, 3))
    segs = _segments(tp, model, None, modes)
    end = np.cumsum(tp.lengths())
    for prev, cur in zip(segs[:-1], segs[1:]):
        if (prev.rapid or cur.rapid or model.exact_stop
                or prev.tolerance in (EXACT_PATH, EXACT_STOP) or _dot(prev.t1, cur.t0) < SHARP_CORNER_COS
                or np.linalg.norm(tp.start[cur.move] - tp.end[prev.move]) > 1e-6):
            continue
        geometry = _blend_geometry(prev, cur, model)
        if geometry is None:
            continue
        _, _, binormal, d_geom, r_geom = geometry
        v_top = math.sqrt(NORMAL_SHARE * _inscribed(binormal, model.accel_mm_s2) * r_geom)
        out.append((end[prev.move] - d_geom, end[prev.move] + d_geom, v_top))
    return np.asarray(out, float).reshape(-1, 3)


def _linuxcnc_blocks(tp: Toolpath, model: ControllerModel, feed_mm_min, pauses, modes):
    """LinuxCNC 2.9's queue: segments, blend arcs and the speed caps at their junctions; and the blend
    arcs' spans and top speeds (`Execution.blends`)."""
    segs = _segments(tp, model, feed_mm_min, modes, merge=True)
    at = np.r_[0.0, np.cumsum(tp.lengths())]

    def arc_length(s: _Segment, x: float) -> float:  # the program's arc length x mm along segment s
        m, u = _place(s, x)
        return float(at[m] + u * (at[m + 1] - at[m]))

    stop = _stops(tp, pauses).tolist()
    dt = model.servo_period_s
    amax = model.accel_mm_s2
    exact = model.exact_stop
    # per junction between segments j-1 and j: ("stop"|"tangent"|"blend"|"parabolic", cap, blend)
    joints: list = [None] * len(segs)
    for j in range(1, len(segs)):
        prev, cur = segs[j - 1], segs[j]
        if any(stop[prev.move + 1:cur.first + 1]):
            joints[j] = ("pause", 0.0, None)
            continue
        if exact or prev.rapid != cur.rapid or prev.tolerance == EXACT_STOP:
            joints[j] = ("stop", 0.0, None)
            continue
        if _dot(prev.t1, cur.t0) < SHARP_CORNER_COS:
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
        blend = _blend(prev, cur, model)
        if blend is not None and min(blend[2], blend[1] / dt) < kink_vel:
            joints[j] = ("tangent", kink_vel, None)
            prev.kink_share = max(prev.kink_share, KINK_RATIO)
            cur.kink_share = max(cur.kink_share, KINK_RATIO)
        elif blend is not None:
            joints[j] = ("blend", 0.0, blend)
            prev.trim_end = blend[0]
            prev.length -= blend[0]
            cur.length -= blend[0]
            cur.trim_start = blend[0]
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
            m, u = _place(s, d)
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
            start_vj2 = _parabolic_speed(segs[j - 1], s) ** 2
        if consumed[j]:
            lead, lead_vj2 = max(s.length, 0.0), start_vj2
            continue
        vj2.append(start_vj2)
        a = s.acc * (0.5 if s.halved else 1.0) * (1.0 - s.kink_share)
        vmax = min(s.req, _arc_maxvel(s, s.halved) if s.arc else s.maxvel, s.nominal * model.block_rate_hz)
        if s.length > 0:
            vmax = min(vmax, s.length / (MIN_SEGMENT_CYCLES * dt))
        if s.arc:
            a *= TANGENTIAL_SHARE
        L.append(max(s.length, 0.0))
        vnom.append(vmax)
        acc.append(a)
        m, u = _place(s, s.nominal - s.trim_end)
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


def _parabolic_speed(prev: _Segment, cur: _Segment) -> float:
    """tpComputeBlendVelocity: the speed at which two segments overlap in a parabolic blend (each at
    half acceleration, over at most half of each)."""
    out = []
    acc = []
    for s in (prev, cur):
        a = s.acc * 0.5 * (TANGENTIAL_SHARE if s.arc else 1.0)
        v_target = min(s.req, _arc_maxvel(s, True) if s.arc else s.maxvel)
        out.append(min(math.sqrt(a * s.length), v_target))
        acc.append(a)
    t_max = min(prev.length / max(out[0], 1e-12), cur.length / max(out[1], 1e-12))
    t_blend = min(t_max, max(out[0] / acc[0], out[1] / acc[1]))
    return min(min(out[0], t_blend * acc[0]), min(out[1], t_blend * acc[1]))
