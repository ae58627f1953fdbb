"""The path grid and the four kinds of rows a limit can produce, in path variables.

Along arc length s the state is b = v² (mm²/s², v the path speed in mm/s) at every sample and the
path acceleration a (mm/s²) on every interval (collocation: b_{i+1} − b_i = 2·ds_i·a_i, so a_i
belongs to sample i and the last sample has none). Every limit in millpost is one of:

- `SpeedBounds`  b_lo ≤ b_i ≤ b_hi per sample (caps and hard floors on the speed).
- `SoftFloor`    b_i ≥ floor_i where reachable; a slack with a penalty elsewhere (reported).
- `LocalRows`    u·a_i + w·b_i + g·√b_i ≤ h per sample. g ≤ 0 is convex (a cone row through the
                 objective's c ≤ √b); g > 0 is not and is replaced by its tangent upper bound
                 √b ≤ (b + v0²)/(2·v0) at a reference speed v0 (conservative, re-linearised).
- `StepRows`     |e_{i+1} − e_i| ≤ (h0/v − h1)·dsm_i, e_i = u_i·a_i + w_i·b_i, v the speed at sample
                 i+1 and dsm_i = (ds_i + ds_{i+1})/2 the distance between the two collocation
                 points (Δt = dsm/v): a bounded rate of change per unit time de/dt ≤ h0 − h1·v.
                 h0/v = h0/√b is convex in b, so its tangent at v0 bounds it from below and gives
                 a conservative linear row (re-linearised at the solution). Couples neighbouring a.

All arrays are per sample (length N) so any block can be cut to a window of samples.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from millpost.toolpath import Samples


@dataclass(frozen=True)
class PathGrid:
    """Geometry of a path segment: s (N,) mm, tangent dq/ds (N, 3), curvature d²q/ds² (N, 3) 1/mm."""

    s_mm: np.ndarray
    tangent: np.ndarray
    curvature: np.ndarray

    @classmethod
    def from_samples(cls, samples: Samples, index: np.ndarray | slice = slice(None)) -> "PathGrid":
        return cls(samples.s_mm[index] - samples.s_mm[index][0], samples.tangent[index], samples.curvature[index])

    def __len__(self) -> int:
        return len(self.s_mm)

    @property
    def ds(self) -> np.ndarray:
        return np.diff(self.s_mm)

    @property
    def length_mm(self) -> float:
        return float(self.s_mm[-1] - self.s_mm[0])

    def window(self, lo: int, hi: int) -> "PathGrid":
        return PathGrid(self.s_mm[lo:hi], self.tangent[lo:hi], self.curvature[lo:hi])

    @cached_property
    def moving_axes(self) -> tuple[bool, bool, bool]:
        """Whether each axis moves somewhere on the grid (a nonzero tangent component); computed once."""
        return tuple(bool(x) for x in np.abs(self.tangent).max(axis=0) > 0)


def _cut(x: np.ndarray, lo: int, hi: int) -> np.ndarray:
    return x[..., lo:hi]


@dataclass(frozen=True)
class SpeedBounds:
    name: str
    b_lo: np.ndarray  # (N,) mm²/s²
    b_hi: np.ndarray  # (N,) mm²/s²

    def window(self, lo: int, hi: int) -> "SpeedBounds":
        return SpeedBounds(self.name, self.b_lo[lo:hi], self.b_hi[lo:hi])


@dataclass(frozen=True)
class SoftFloor:
    name: str
    b_floor: np.ndarray  # (N,) mm²/s²

    def window(self, lo: int, hi: int) -> "SoftFloor":
        return SoftFloor(self.name, self.b_floor[lo:hi])


@dataclass(frozen=True)
class LocalRows:
    """M rows per sample: u·a + w·b + g·√b ≤ h, arrays (M, N). `scale` (M, N) > 0 is the physical
    bound the row encodes (for reporting the excess as a fraction of it)."""

    name: str
    u: np.ndarray
    w: np.ndarray
    g: np.ndarray
    h: np.ndarray
    scale: np.ndarray

    def window(self, lo: int, hi: int) -> "LocalRows":
        return replace(self, **{k: _cut(getattr(self, k), lo, hi) for k in ("u", "w", "g", "h", "scale")})

    def value(self, b: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Row values u·a + w·b + g·√b, (M, N); the last sample has no a and uses only w·b + g·√b."""
        aa = np.append(a, 0.0)
        return self.u * aa + self.w * b + self.g * np.sqrt(np.maximum(b, 0.0))

    def excess(self, b: np.ndarray, a: np.ndarray) -> np.ndarray:
        """(value − h)/scale per sample (max over rows); ≤ 0 means satisfied."""
        return ((self.value(b, a) - self.h) / self.scale).max(axis=0)


@dataclass(frozen=True)
class StepRows:
    """M rows: |e_{i+1} − e_i| ≤ (h0/v_{i+1} − h1)·dsm_i, e = u·a + w·b; arrays (M, N), h0 and h1
    indexed by the sample where the change happens."""

    name: str
    u: np.ndarray
    w: np.ndarray
    h0: np.ndarray
    h1: np.ndarray

    def window(self, lo: int, hi: int) -> "StepRows":
        return replace(self, **{k: _cut(getattr(self, k), lo, hi) for k in ("u", "w", "h0", "h1")})

    def linearised(self, grid: PathGrid, v0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tangent of the bound at v0: |Δe_i| + kb_i·b_{i+1} ≤ rhs_i, both (M, N−2), from
        h0/v ≥ 3·h0/(2·v0) − h0·b/(2·v0³)."""
        ds = grid.ds
        dsm = 0.5 * (ds[:-1] + ds[1:])
        v = np.maximum(v0[1:-1], 1e-300)
        h0, h1 = self.h0[:, 1:-1], self.h1[:, 1:-1]
        return dsm * h0 / (2 * v**3), dsm * (1.5 * h0 / v - h1)

    def excess(self, grid: PathGrid, b: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Rate of change per unit time minus its bound, as a fraction of h0, per change (N−2,)."""
        e = self.u[:, :-1] * a + self.w[:, :-1] * b[:-1]  # (M, N−1)
        ds = grid.ds
        v = np.sqrt(np.maximum(b[1:-1], 0.0))
        dt = 0.5 * (ds[:-1] + ds[1:]) / np.maximum(v, 1e-300)
        rate = np.abs(np.diff(e, axis=1)) / dt
        lim = self.h0[:, 1:-1] - self.h1[:, 1:-1] * v
        return ((rate - lim) / np.maximum(self.h0[:, 1:-1], 1e-300)).max(axis=0)


Block = SpeedBounds | SoftFloor | LocalRows | StepRows
