"""The feed modes (RS-274 modal group 5): how an F word is read."""

from __future__ import annotations

import enum


class FeedMode(enum.IntEnum):
    """G93, G94 and G95, valued as their G code × 10 (the interpreter's integer G codes), so that a
    mode is its G code and the per-move column `Program.feed_mode` keeps its integer dtype.

    INVERSE_TIME (G93): F is 1/minutes, the move takes 1/F minutes; an F on every feed move.
    PER_MINUTE (G94): F is program units per minute.
    PER_REV (G95): F is program units per spindle revolution (the feed depends on S).

    Comparing a numpy integer with a member is slow (numpy's path for int subclasses, ~4 µs): compare
    `int(program.feed_mode[i])` in per-move loops, whole arrays where it is one comparison."""

    INVERSE_TIME = 930
    PER_MINUTE = 940
    PER_REV = 950
