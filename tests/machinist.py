"""What a machinist checks in an optimized program before running it, computed from the programs' text
(read back) and the job alone, not from millpost's schedule or limits:

- `axis_rate_excess`: feed moves with an F millpost wrote above what the machine's axes run in that
  direction, min over the axes of vmax_i / |t_i| over the move's tangents t (an arc: over its whole
  sweep);
- `descent_excess`: feed moves going down whose end lies below the stock's top with an F above
  `raise_max` × their programmed F (a restart from a later line, a skipped operation or a broken tool
  makes any of them a plunge into solid material);
- `approach_excess`: pieces of feed moves going down through the clearance above the stock's top (the
  entry from a CAM's feed height, the air part of a plunge) with an F above the programmed one.

Each returns "line N: ..." strings, empty when all is well. Moves are matched between the programs by
`emit.pieces_of_moves` (a split move's pieces belong to their original move)."""

from __future__ import annotations

import numpy as np

from millpost.emit import pieces_of_moves
from millpost.toolpath import ARC_CW, RAPID, Toolpath

ROUNDING_MM_MIN = 0.11  # F words are written rounded to 0.1 mm/min (0.01 in/min = 0.254 mm/min in inch)


def _rounding(inch: bool) -> float:
    return 0.26 if inch else ROUNDING_MM_MIN


def axis_rates(tp: Toolpath, vmax_mm_min: np.ndarray) -> np.ndarray:
    """Per move the highest path speed (mm/min) at which no axis exceeds its rate anywhere on it."""
    out = np.full(len(tp), np.inf)
    lengths = tp.lengths()
    for i in np.flatnonzero((tp.kind != RAPID) & (lengths > 0)):
        u = np.linspace(0.0, 1.0, 65) if tp.kind[i] >= ARC_CW else np.array([0.5])
        _, t, _ = tp.points(np.full(len(u), i), u, derivatives=True)
        t = np.abs(t) / np.linalg.norm(t, axis=1, keepdims=True)  # a spiral arc's d/ds is not unit
        with np.errstate(divide="ignore"):
            out[i] = float(np.min(np.where(t > 1e-12, vmax_mm_min / np.maximum(t, 1e-12), np.inf)))
    return out


def axis_rate_excess(original: Toolpath, emitted: Toolpath, vmax_mm_min, inch: bool = False) -> list[str]:
    """F words millpost wrote above the axis rates of their move (the program's own F on a move is the
    programmer's: not counted)."""
    rate = axis_rates(emitted, np.asarray(vmax_mm_min, float))
    f = emitted.feed_mm_min
    first = pieces_of_moves(original, emitted)
    own = np.zeros(len(emitted), bool)
    for i in range(len(original)):
        own[first[i]:first[i + 1]] = np.isclose(f[first[i]:first[i + 1]], original.feed_mm_min[i], rtol=1e-9)
    bad = np.flatnonzero(np.isfinite(rate) & ~own & (f > rate * (1 + 1e-5) + _rounding(inch)))
    return [f"line {emitted.line[i]}: F{f[i]:.1f} mm/min above the axis rate {rate[i]:.1f} of its direction"
            for i in bad]


def _descending(tp: Toolpath) -> np.ndarray:
    return (tp.kind != RAPID) & (tp.end[:, 2] < tp.start[:, 2] - 1e-6)


def descent_excess(original: Toolpath, emitted: Toolpath, top_mm: float, raise_max: float = 2.0,
                   inch: bool = False) -> list[str]:
    first = pieces_of_moves(original, emitted)
    out = []
    for i in np.flatnonzero(_descending(original)):
        for k in range(first[i], first[i + 1]):
            if emitted.end[k, 2] < emitted.start[k, 2] - 1e-6 and emitted.end[k, 2] < top_mm - 1e-6:
                cap = raise_max * original.feed_mm_min[i] + _rounding(inch)
                if emitted.feed_mm_min[k] > cap:
                    out.append(f"line {original.line[i]}: a descent to Z{emitted.end[k, 2]:.3f} below the top at "
                               f"F{emitted.feed_mm_min[k]:.1f}, programmed F{original.feed_mm_min[i]:.1f}")
    return out


def approach_excess(original: Toolpath, emitted: Toolpath, top_mm: float, clearance_mm: float,
                    xy_box: np.ndarray, inch: bool = False) -> list[str]:
    """xy_box: [[xmin, ymin], [xmax, ymax]] over which the stock's top lies (grown by the tool's radius and
    the clearance: an approach beside the stock farther than that may be raised)."""
    first = pieces_of_moves(original, emitted)
    out = []
    for i in np.flatnonzero(_descending(original)):
        for k in range(first[i], first[i + 1]):
            z, z0, xy = emitted.end[k, 2], emitted.start[k, 2], emitted.end[k, :2]
            over = bool(np.all(xy >= xy_box[0]) and np.all(xy <= xy_box[1]))
            # a piece going down through any of the zone (an entry from the feed height into the cut too)
            if over and z < z0 - 1e-6 and z < top_mm + clearance_mm and z0 > top_mm + 1e-6:
                if emitted.feed_mm_min[k] > original.feed_mm_min[i] + _rounding(inch):
                    out.append(f"line {original.line[i]}: an approach to Z{z:.3f} within {clearance_mm:g} mm over "
                               f"the top at F{emitted.feed_mm_min[k]:.1f}, programmed F{original.feed_mm_min[i]:.1f}")
    return out
