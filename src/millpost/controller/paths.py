"""Path modes (G61, G61.1, G64 P Q) and the naive-CAM merging of straight feeds they set: LinuxCNC's
canon layer sends consecutive straight feeds that lie within the naive-CAM tolerance of one line to its
planner as that line (`naive_cam_chains`), so the planner's blocks are the chains (`block_lengths`)."""

from __future__ import annotations

import numba
import numpy as np

from .._kernels import compiling
from ..toolpath import FEED, Toolpath
from .model import EXACT_PATH, EXACT_STOP, ControllerModel, PathModes

CHAIN_POINTS = 101  # LinuxCNC's canon chains at most this many points into one line (linkable: size > 100)
# the comments LinuxCNC's canon passes on (to the operator or the log): they flush its chain of straight
# feeds like every other command; other comments do not
_FLUSHING_COMMENTS = ("MSG,", "DEBUG,", "LOG,")


def path_modes(program, model: ControllerModel) -> PathModes:
    """The path modes the program sets (`PathModes`); before it sets one, the controller's own
    (`blend_tolerance_mm`, `naive_cam_mm`). A G64 P/Q sets a naive-CAM tolerance only on a controller
    that merges straight feeds (`Planner.merges_naive_cam`).
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
            merging = (p, q) != (None, None) and model.planner.merges_naive_cam
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


def naive_cam_chains(tp: Toolpath, modes: PathModes, feed_mm_s: np.ndarray | None = None) -> np.ndarray:
    """LinuxCNC's naive-CAM detector (its canon layer, emccanon.cc: see_segment, linkable and
    flush_segments): consecutive straight feeds are chained while every point of the chain lies within
    the naive-CAM tolerance of the line from the chain's start to the newest end point (its nearest point
    on that segment), the chain holds at most 101 points, the new end point differs from the chain's start,
    and nothing flushes the chain before the move: a rapid or an arc, a feed rate that changes, a path
    mode (G61, G61.1, G64; a plain G64 or G61 sets no tolerance), a command (`PathModes.flush`). The chain
    goes to the planner as one line from its start to its last point at the current feed. Returns per
    move the index of the first move of its chain (its own index where nothing is merged)."""
    feed = tp.feed_mm_s if feed_mm_s is None else np.asarray(feed_mm_s, float)
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
