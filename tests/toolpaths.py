"""Toolpaths built move by move for the solver and controller tests (tests/schedule, tests/controller)."""

from __future__ import annotations

import numpy as np

from millpost.toolpath import ARC_CCW, ARC_CW, FEED, RAPID, Toolpath


def make_toolpath(start, moves) -> Toolpath:
    """moves: ("line", end) | ("rapid", end) | ("arc", end, center, ccw[, turns])."""
    kinds, starts, ends, centers, turns = [], [], [], [], []
    p = np.asarray(start, float)
    for mv in moves:
        e = np.asarray(mv[1], float)
        starts.append(p)
        ends.append(e)
        if mv[0] == "arc":
            kinds.append(ARC_CCW if mv[3] else ARC_CW)
            centers.append(np.asarray(mv[2], float))
            turns.append(mv[4] if len(mv) > 4 else 0)
        else:
            kinds.append(RAPID if mv[0] == "rapid" else FEED)
            centers.append(np.full(3, np.nan))
            turns.append(0)
        p = e
    n = len(kinds)
    return Toolpath(kind=np.array(kinds, np.int8), start=np.array(starts), end=np.array(ends),
                    center=np.array(centers), plane=np.zeros(n, np.int8), turns=np.array(turns, np.int32),
                    feed_mm_min=np.full(n, 1000.0), rpm=np.full(n, 10000.0), tool=np.ones(n, np.int32),
                    line=np.arange(1, n + 1, dtype=np.int32), block=np.arange(n, dtype=np.int32))


def pocket_toolpath() -> Toolpath:
    """A helix ramp, zig-zag passes with sharp corners, and a filleted perimeter (r = 2 mm)."""
    r = 2.0
    return make_toolpath((4, 0, 0), [
        ("arc", (4, 0, -2), (0, 0, 0), True, 1),
        ("line", (20, 0, -2)), ("line", (20, 3, -2)), ("line", (0, 3, -2)), ("line", (0, 6, -2)),
        ("line", (20, 6, -2)),
        ("line", (30 - r, 6, -2)), ("arc", (30, 6 + r, -2), (30 - r, 6 + r, -2), True),
        ("line", (30, 20 - r, -2)), ("arc", (30 - r, 20, -2), (30 - r, 20 - r, -2), True),
        ("line", (r, 20, -2)), ("arc", (0, 20 - r, -2), (r, 20 - r, -2), True),
        ("line", (0, 10, -2)),
    ])
