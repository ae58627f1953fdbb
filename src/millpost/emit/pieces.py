"""The emitted program against the original: where each original move's pieces are (`write_feeds` splits
moves where the feed changes part-way), and positions and arc lengths carried between the two."""

from __future__ import annotations

import numpy as np

from ..errors import MillpostError
from ..toolpath import Toolpath


def pieces_of_moves(original: Toolpath, emitted: Toolpath, tol_mm: float = 1e-4) -> np.ndarray:
    """The map back of `write_feeds`'s splitting: per move of the original toolpath the index of its
    first piece in the emitted program's toolpath (len(original) + 1 entries, the last one
    len(emitted)). Moves keep their order and end points (a split move's last piece ends where the
    move did), so pieces are matched in order by their end points (within tol_mm)."""
    out = []
    ends, e_ends = original.end.tolist(), emitted.end.tolist()
    k = 0
    for i, p in enumerate(ends):
        out.append(k)
        while k < len(e_ends) and max(abs(e_ends[k][0] - p[0]), abs(e_ends[k][1] - p[1]),
                                      abs(e_ends[k][2] - p[2])) > tol_mm:
            k += 1
        if k == len(e_ends):
            raise MillpostError(f"the emitted program does not pass through the end of move {i} (line "
                                f"{int(original.line[i])}) at {p}")
        k += 1
    if k != len(e_ends):
        raise MillpostError(f"the emitted program has {len(e_ends) - k} moves after the original program's end")
    return np.array(out + [k], np.int64)


def emitted_positions(original: Toolpath, emitted: Toolpath, move: np.ndarray, u: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Where fraction u of original move `move` lies on the emitted program: (emitted move, fraction of
    it), by arc length along the move's pieces (`pieces_of_moves`)."""
    first = pieces_of_moves(original, emitted)
    length = emitted.lengths()
    before = np.r_[0.0, np.cumsum(length)]
    lo, hi = first[move], first[np.asarray(move) + 1] - 1
    s = before[lo] + np.clip(u, 0.0, 1.0) * (before[hi + 1] - before[lo])
    k = np.clip(np.searchsorted(before[1:], s - 1e-12, side="left"), lo, hi)
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.where(length[k] > 0, (s - before[k]) / length[k], 1.0)
    return k, np.clip(frac, 0.0, 1.0)


def original_arc_length(original: Toolpath, emitted: Toolpath, s_mm: np.ndarray) -> np.ndarray:
    """The original program's arc length (mm) at arc length s_mm of the emitted one: along each original
    move's pieces (`pieces_of_moves`) in proportion (they are its path within the written precision)."""
    first = pieces_of_moves(original, emitted)
    return np.interp(s_mm, np.r_[0.0, np.cumsum(emitted.lengths())][first], np.r_[0.0, np.cumsum(original.lengths())])
