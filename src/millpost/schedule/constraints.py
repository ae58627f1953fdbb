"""Physical limits as row producers. Each takes plain numbers/arrays (no Machine object) and returns
rows (see rows.py) for a PathGrid of N samples; per-sample arrays have length N.

Which limits are caps and which need real rows:
- speed-only limits at a sample (feed, axis velocity, a load α·v + β ≤ L: a force, a power, the chip
  per tooth) depend on v alone, so their feasible set in v is an interval
  and they reduce to a cap b ≤ v_hi² (and possibly a floor b ≥ v_lo²): SpeedBounds / SoftFloor;
- axis acceleration t·a + κ·b couples a and b: linear LocalRows;
- motor current adds a term γ·√b (cutting + viscous force): the side where √b helps is convex and
  becomes a real cone row (through c ≤ √b); the other side is replaced by the tangent of √b
  (conservative) and re-linearised at the solution;
- path jerk and current slew couple neighbouring samples: StepRows.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Callable

import numpy as np

from millpost.schedule.rows import Block, LocalRows, PathGrid, SoftFloor, SpeedBounds, StepRows

_TINY_B = 1e-6  # mm²/s²: the cap used where a limit is exceeded even at standstill (reported)


def _per_sample(x, n: int) -> np.ndarray:
    return np.broadcast_to(np.asarray(x, float), (n,)).astype(float)


@dataclass(frozen=True, eq=False)
class Derived:
    """A per-sample array (first axis: the samples) computed on demand, `f(*inputs)` with f elementwise
    along the samples: `x[index]` is f of the inputs' rows `index`, the same numbers as the whole array's
    rows (memory: a limit scaled from shared loads stores only its inputs, e.g. the deflection
    peak_a·compliance). `np.asarray(x)` computes the whole array."""

    f: Callable[..., np.ndarray]
    inputs: tuple
    shape: tuple[int, ...]

    @property
    def ndim(self) -> int:
        return len(self.shape)

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, index) -> np.ndarray:
        return self.f(*(x[index] for x in self.inputs))

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        return np.asarray(self.f(*self.inputs), dtype)


def rows_at(x, index, n: int) -> np.ndarray:
    """Rows `index` of a per-sample array of n samples (an ndarray or `Derived`) or of a scalar broadcast to n."""
    return x[index] if isinstance(x, (np.ndarray, Derived)) else np.broadcast_to(np.asarray(x, float), (n,))[index]


@dataclass(frozen=True)
class FeedLimit:
    """Path speed ≤ max_feed_mm_s (scalar or per sample): the user's and the machine's max feed."""

    max_feed_mm_s: float | np.ndarray
    name: str = "feed"

    def blocks(self, grid: PathGrid) -> list[Block]:
        v = _per_sample(self.max_feed_mm_s, len(grid))
        return [SpeedBounds(self.name, np.zeros(len(grid)), v**2)]


@dataclass(frozen=True)
class AxisVelocity:
    """|tangent_k|·v ≤ vmax_k per axis (mm/s): b ≤ min_k vmax_k²/t_k²."""

    vmax_mm_s: tuple[float, float, float]
    name: str = "axis_velocity"

    def blocks(self, grid: PathGrid) -> list[Block]:
        t2 = grid.tangent**2
        with np.errstate(divide="ignore"):
            cap = np.min(np.where(t2 > 0, np.asarray(self.vmax_mm_s, float) ** 2 / t2, np.inf), axis=1)
        return [SpeedBounds(self.name, np.zeros(len(grid)), cap)]


@dataclass(frozen=True)
class AxisAcceleration:
    """|t_k·a + κ_k·b| ≤ amax_k per axis (mm/s²): axis acceleration from tangent and curvature."""

    amax_mm_s2: tuple[float, float, float]
    name: str = "axis_acceleration"
    caps = False  # no SpeedBounds among its rows (see `window_blocks`)

    def blocks(self, grid: PathGrid) -> list[Block]:
        A = np.asarray(self.amax_mm_s2, float)[:, None] * np.ones((1, len(grid)))
        t, k = grid.tangent.T, grid.curvature.T
        return [LocalRows(self.name, np.r_[t, -t], np.r_[k, -k], np.zeros((6, len(grid))), np.r_[A, A], np.r_[A, A])]


@dataclass(frozen=True)
class Centripetal:
    """|κ_k|·b ≤ amax_k per axis as a speed cap: the centripetal share of the axis acceleration
    alone. AxisAcceleration implies it at steady speed; as a cap it also bounds the F word of an arc,
    which a controller that runs arcs as chains of short lines may not hold to it by itself."""

    amax_mm_s2: tuple[float, float, float]
    name: str = "centripetal"

    def blocks(self, grid: PathGrid) -> list[Block]:
        A = np.asarray(self.amax_mm_s2, float)[:, None]
        k = np.abs(grid.curvature.T)
        with np.errstate(divide="ignore"):
            cap = np.min(np.where(k > 0, A / k, np.inf), axis=0)
        return [SpeedBounds(self.name, np.zeros(len(grid)), cap)]


@dataclass(frozen=True)
class Junction:
    """Speed cap at sharp corners (tangent discontinuities between moves), so that ds does not decide
    the corner speed. The controller rounds the corner with an arc deviating at most deviation_mm
    from it and runs that arc at the acceleration the axes allow along the direction change
    (grbl's junction deviation): v² = A·δ·sin(θ/2)/(1 − sin(θ/2)), θ the angle between the reversed
    incoming and the outgoing tangent, A = min_k amax_k/|u_k| with u the unit direction change.
    deviation_mm = 0 is an exact stop (G61)."""

    amax_mm_s2: tuple[float, float, float]
    deviation_mm: float
    min_angle_rad: float = 1e-3
    name: str = "junction"

    def blocks(self, grid: PathGrid) -> list[Block]:
        n = len(grid)
        cap = np.full(n, np.inf)
        if n >= 3:
            t_in = grid.tangent[1:-1]
            t_out = grid.tangent[2:] - grid.curvature[2:] * grid.ds[1:, None]  # tangent where the next move starts
            t_out /= np.maximum(np.linalg.norm(t_out, axis=1), 1e-300)[:, None]
            cos_turn = np.clip((t_in * t_out).sum(1), -1, 1)
            corner = np.arccos(cos_turn) > self.min_angle_rad
            d = t_out - t_in
            u = d / np.maximum(np.linalg.norm(d, axis=1), 1e-300)[:, None]
            with np.errstate(divide="ignore"):
                acc = np.min(np.where(np.abs(u) > 1e-12, np.asarray(self.amax_mm_s2) / np.abs(u), np.inf), axis=1)
            sin_half = np.sqrt(np.maximum(0.0, (1 + cos_turn) / 2))  # θ = π − turn
            with np.errstate(divide="ignore", over="ignore"):
                v2 = np.minimum(acc, 1e300) * self.deviation_mm * sin_half / np.maximum(1 - sin_half, 1e-300)
            cap[1:-1] = np.where(corner, v2, np.inf)
        return [SpeedBounds(self.name, np.zeros(n), cap)]


@dataclass(frozen=True)
class CornerSpeed:
    """Speed cap (mm/s, per sample) at the corners a blending planner rounds by itself: the highest
    speed it passes each corner at (`controller.corner_speeds` on the sample before the corner), inf
    elsewhere. The corner rule of LinuxCNC-like controllers, as Junction is grbl's."""

    cap_mm_s: np.ndarray
    name: str = "junction"

    def blocks(self, grid: PathGrid) -> list[Block]:
        cap = _per_sample(self.cap_mm_s, len(grid))
        return [SpeedBounds(self.name, np.zeros(len(grid)), cap**2)]


@dataclass(frozen=True)
class PathJerk:
    """Bounded change of path acceleration: |da/dt| ≤ jerk_mm_s3 (mm/s³) between collocation points,
    |a_{i+1} − a_i| ≤ J·Δs/v (Δt = Δs/v). Makes a an explicit variable."""

    jerk_mm_s3: float
    name: str = "jerk"
    caps = False  # no SpeedBounds among its rows (see `window_blocks`)

    def blocks(self, grid: PathGrid) -> list[Block]:
        n = len(grid)
        return [StepRows(self.name, np.ones((1, n)), np.zeros((1, n)), np.full((1, n), float(self.jerk_mm_s3)),
                         np.zeros((1, n)))]


def _load_interval(a1: np.ndarray, a0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """v ≥ 0 with 2·a1·v + a0 ≤ 0: returns (v_lo, v_hi, impossible) per sample."""
    n = len(a0)
    v_lo, v_hi = np.zeros(n), np.full(n, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        root = -a0 / (2 * a1)
        v_hi = np.where(a1 > 0, root, v_hi)
        v_lo = np.where(a1 < 0, np.maximum(root, 0), v_lo)
    impossible = ((a1 == 0) & (a0 > 0)) | ((a1 > 0) & (v_hi < 0))
    v_hi = np.where(impossible, np.sqrt(_TINY_B), v_hi)
    v_lo = np.where(impossible, 0.0, v_lo)
    return v_lo, v_hi, impossible


@dataclass(frozen=True)
class SpeedLoad:
    """A load linear in path speed under a bound: alpha·v + beta ≤ limit per sample (any unit;
    alpha per mm/s). E.g. a force or power component from the mechanistic model. alpha > 0 gives
    the cap b ≤ ((limit − beta)/alpha)²; alpha < 0 a (soft) floor. Per-sample fields may be `Derived`
    (computed from shared loads when a window reads them)."""

    alpha: np.ndarray | Derived
    beta: np.ndarray | Derived
    limit: float | np.ndarray | Derived
    name: str = "load"

    def blocks(self, grid: PathGrid) -> list[Block]:
        n = len(grid)
        al, be, L = _per_sample(self.alpha, n), _per_sample(self.beta, n), _per_sample(self.limit, n)
        v_lo, v_hi, _ = _load_interval(al / 2, be - L)
        return [SpeedBounds(self.name, np.zeros(n), v_hi**2), SoftFloor(self.name + "_floor", v_lo**2)]

    def impossible(self, n: int) -> np.ndarray:
        """Samples where the load exceeds its limit at every speed (cap set to ~0)."""
        al, be, L = _per_sample(self.alpha, n), _per_sample(self.beta, n), _per_sample(self.limit, n)
        return _load_interval(al / 2, be - L)[2]


@dataclass(frozen=True)
class MinSpeed:
    """Path speed ≥ v_min_mm_s per sample where the dynamics allow it (a soft floor, reported where
    not met): e.g. the minimum-chip feed, below which the edge rubs instead of cutting."""

    v_min_mm_s: np.ndarray
    name: str = "min_speed"

    def blocks(self, grid: PathGrid) -> list[Block]:
        return [SoftFloor(self.name, _per_sample(self.v_min_mm_s, len(grid)) ** 2)]


@dataclass(frozen=True)
class MotorCurrent:
    """|i_k| ≤ current_limit_A per axis with
        i_k·kf_k = m_k·1e-3·(t_k·a + κ_k·b) + (cut_alpha_k + viscous_k·t_k)·v
                   + cut_beta_k + friction_k·sgn(t_k)
    kf = force per amp at the carriage (N/A, = K_t·2π·η/lead), m = moving mass plus reflected rotor
    and screw inertia (kg), cut_alpha/cut_beta (N, 3): cutting force on the axis, linear in v
    (N per mm/s, N), friction (N), viscous (N per mm/s). The √b term is convex on one side (cone row)
    and tangent-bounded on the other."""

    mass_kg: tuple[float, float, float]
    force_per_amp_N_A: tuple[float, float, float]
    current_limit_A: tuple[float, float, float]
    friction_N: tuple[float, float, float] = (0.0, 0.0, 0.0)
    viscous_N_s_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    cut_alpha: np.ndarray | None = None
    cut_beta: np.ndarray | Derived | None = None
    name: str = "current"
    caps = False  # no SpeedBounds among its rows (see `window_blocks`)

    def blocks(self, grid: PathGrid) -> list[Block]:
        n = len(grid)
        t, k = grid.tangent.T, grid.curvature.T
        m = np.asarray(self.mass_kg, float)[:, None] * 1e-3
        kfI = (np.asarray(self.force_per_amp_N_A, float) * np.asarray(self.current_limit_A, float))[:, None] \
            * np.ones((1, n))
        ca = np.zeros((3, n)) if self.cut_alpha is None else np.asarray(self.cut_alpha, float).reshape(n, 3).T
        cb = np.zeros((3, n)) if self.cut_beta is None else np.asarray(self.cut_beta, float).reshape(n, 3).T
        g = ca + np.asarray(self.viscous_N_s_mm, float)[:, None] * t
        static = cb + np.asarray(self.friction_N, float)[:, None] * np.sign(t)
        u, w = m * t, m * k
        return [LocalRows(self.name, np.r_[u, -u], np.r_[w, -w], np.r_[g, -g], np.r_[kfI - static, kfI + static],
                          np.r_[kfI, kfI])]


@dataclass(frozen=True)
class CurrentSlew:
    """di/dt of the inertial current ≤ (V_bus − R·I_max − K_e·ω)/L per axis, ω = rad_per_mm·|t_k|·v
    the motor speed (back-EMF grows with feed), and the voltage limit where that reaches zero:
    |t_k|·v ≤ (V_bus − R·I_max)/(K_e·rad_per_mm). i_k = m_k·1e-3·(t_k·a + κ_k·b)/kf_k; the cutting
    share of the current is taken as slowly varying and not included."""

    mass_kg: tuple[float, float, float]
    force_per_amp_N_A: tuple[float, float, float]
    current_limit_A: tuple[float, float, float]
    resistance_ohm: tuple[float, float, float]
    inductance_H: tuple[float, float, float]
    ke_V_s_rad: tuple[float, float, float]
    bus_V: float
    rad_per_mm: tuple[float, float, float]
    axes: tuple[bool, bool, bool] | None = None  # axes with rows (None: those that move on the grid)
    name: str = "current_slew"

    def pin(self, grid: PathGrid) -> "CurrentSlew":
        """The same limit with its rows' axes fixed to those that move on `grid` (see `window_blocks`)."""
        return self if self.axes is not None else replace(self, axes=grid.moving_axes)

    def blocks(self, grid: PathGrid) -> list[Block]:
        n = len(grid)
        f = lambda x: np.asarray(x, float)[:, None]  # noqa: E731
        t, k = grid.tangent.T, grid.curvature.T
        g = f(self.mass_kg) * 1e-3 / f(self.force_per_amp_N_A)  # A per mm/s²
        h0 = (self.bus_V - f(self.resistance_ohm) * f(self.current_limit_A)) / f(self.inductance_H) * np.ones((1, n))
        h1 = f(self.ke_V_s_rad) * f(self.rad_per_mm) * np.abs(t) / f(self.inductance_H)
        keep = np.abs(t).max(axis=1) > 0 if self.axes is None else np.array(self.axes, bool)
        with np.errstate(divide="ignore"):
            vmax = np.min(np.where(h1 > 0, h0 / h1, np.inf), axis=0)
        return [StepRows(self.name, (g * t)[keep], (g * k)[keep], h0[keep], h1[keep]),
                SpeedBounds(self.name + "_voltage", np.zeros(n), vmax**2)]


def path_blocks(grid: PathGrid, limits: list) -> list[Block]:
    """All rows of a list of limit objects."""
    return [blk for lim in limits for blk in lim.blocks(grid)]


def window_blocks(grid: PathGrid, limits: list, lo: int, hi: int, *, caps_only: bool = False) -> list[Block]:
    """The rows of `limits` on samples [lo, hi) of `grid`, computed on that stretch alone (memory and
    time in proportion to it): equal to `path_blocks(grid, limits)` cut to [lo, hi). A limit object
    (or its `constraint`) has per-sample arrays of length len(grid), which are cut to the stretch and
    one sample beyond each end (a junction looks at the next sample); what a limit reads off the
    whole grid is fixed first (`pin`). caps_only: only the SpeedBounds (limits whose class says
    `caps = False` are skipped)."""
    n = len(grid)
    a, b = max(lo - 1, 0), min(hi + 1, n)
    sub = grid.window(a, b)
    out: list[Block] = []
    for lim in limits:
        c = getattr(lim, "constraint", lim)
        if caps_only and not getattr(c, "caps", True):
            continue
        if hasattr(c, "pin"):
            c = c.pin(grid)
        cut = {f.name: v[a:b] for f in fields(c)
               if isinstance(v := getattr(c, f.name), (np.ndarray, Derived)) and v.ndim and v.shape[0] == n}
        out += [blk.window(lo - a, hi - a) for blk in replace(c, **cut).blocks(sub)
                if not caps_only or isinstance(blk, SpeedBounds)]
    return out
