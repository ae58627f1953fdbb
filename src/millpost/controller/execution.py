"""What the planner did with a program (`Execution`): per block its time, length, speed cap,
acceleration and entry speed, placed on the program's moves; the speed and the time at any point."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..toolpath import Samples
from .profile import peak_speed


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
        vp = peak_speed(L, v0, v1, self.vnom[k], a)
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
        """Fraction of each sample along its move from the resampling (samples of a move are contiguous):
        by arc length from the move's start (the previous move's last sample, unless the move starts a
        segment of its own) to its last sample; 1 on a move of no length."""
        s = samples.s_mm
        if not len(s):
            return np.zeros(0)
        new = np.r_[True, samples.move[1:] != samples.move[:-1]]
        starts = np.flatnonzero(new)
        ends = np.r_[starts[1:], len(s)]
        s0 = np.where((starts > 0) & ~samples.segment_start[starts], s[np.maximum(starts - 1, 0)], s[starts])
        span = s[ends - 1] - s0
        group = np.cumsum(new) - 1
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(span[group] > 0, (s - s0[group]) / span[group], 1.0)

    def time_at_samples(self, samples: Samples) -> np.ndarray:
        """Time (s) at which the tool passes every sample (motion only: no dwells or tool changes)."""
        return self.time_at(samples.move, self.sample_fractions(samples))

