"""The segments of LinuxCNC 2.9's trajectory queue (lengths mm, speeds mm/s, accelerations mm/s²), as
its canon layer (emccanon.cc) hands them to the planner: a line's speed and acceleration are the
largest the axes allow along it; an arc's those of its plane's weaker axis, its speed at most
√(0.87·a·r) (87 % of the acceleration normal to the path). Also LinuxCNC's constants (tp.c,
blendmath.h, tc_types.h and the [TRAJ] defaults) that the blends and the queue share."""

from __future__ import annotations

import math

import numba
import numpy as np

from ..toolpath import ARC_CW, RAPID, Toolpath
from .model import ControllerModel, PathModes
from .paths import naive_cam_chains
from .profile import axis_limited

NORMAL_SHARE = math.sqrt(1.0 - 0.5**2)  # BLEND_ACC_RATIO_NORMAL: share of a kept for the turn
TANGENTIAL_SHARE = 0.5  # BLEND_ACC_RATIO_TANGENTIAL: share of a along an arc
KINK_RATIO = 0.1  # ARC_BLEND_TANGENT_KINK_RATIO
GAP_CYCLES = 4  # ARC_BLEND_GAP_CYCLES: a line's rest shorter than this many periods joins the next blend arc
MIN_SEGMENT_CYCLES = 1.02  # TP_MIN_SEGMENT_CYCLES: a segment lasts at least this many periods
RAMP_TIME_S = 1.0 / 100.0  # 1 / ARC_BLEND_RAMP_FREQ: shorter feed segments ramp linearly end to end
SHARP_CORNER_COS = math.cos(math.pi * (1.0 - 2.0 / 180.0))  # reversal within 2°: stop
ANGLE_EPS = 1e-6
AXIS_TINY_MM = 1e-7  # canon drops a line whose every axis moves less than this (getStraightAcceleration's tiny)


SEGMENT = np.dtype([("move", np.int64), ("first", np.int64), ("length", float), ("nominal", float),
                    ("trim_start", float), ("trim_end", float), ("req", float), ("maxvel", float), ("acc", float),
                    ("arc", np.bool_), ("rapid", np.bool_), ("t0", float, (3,)), ("t1", float, (3,)),
                    ("normal", float, (3,)), ("radius", float), ("angle", float), ("halved", np.bool_),
                    ("kink_share", float), ("tolerance", float)], align=True)
"""One LinuxCNC trajectory segment while the queue is built (a record of a structured array; lengths mm,
speeds mm/s, accelerations mm/s²): a program move, or a chain of straight feeds merged into one line
(moves first..move). length: what is left of it between the blend arcs' trims (trim_start, trim_end)
of its nominal length; req: its requested speed, maxvel/acc: the axes' limits along it; t0/t1: unit
directions at its start/end; normal, radius, angle: an arc's plane normal, effective radius, sweep
(rad); halved: it runs at half acceleration (a parabolic blend); kink_share: the share of its
acceleration a tangent kink takes; tolerance: its blend tolerance (G64 P) or path mode (`PathModes`)."""

# Python's x ** 2 on a float is libm's pow(x, 2.0), which differs from x·x in the last bit for about
# 0.1 % of x; the kernels reproduce it exactly by passing this exponent at run time (a constant one
# LLVM folds into x·x)
SQUARE = 2.0


@numba.njit(cache=True)
def dot(a, b) -> float:
    """Dot product of two 3-vectors, summed in axis order."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@numba.njit(cache=True)
def inscribed(normal, limits, two) -> float:
    """LinuxCNC's calculateInscribedDiameter: the largest rate every direction of the plane with this
    normal allows (axis limit over the axis's share of the plane). two: `SQUARE`."""
    best = math.inf
    for i in range(3):
        share = math.sqrt(max(1.0 - normal[i] ** two, 0.0))
        best = min(best, limits[i] / max(share, 1e-12))
    return best


@numba.njit(cache=True)
def place(s, ends, x: float) -> tuple[int, float]:
    """The move under the point x mm along segment s, and the fraction of that move there (a merged
    chain's moves by their end points' positions along the line, `ends`: per move, mm along its
    segment)."""
    count = s.move - s.first + 1
    k = 0
    if count > 1:  # the first end at or past x (searchsorted, left), at most the last
        while k < count - 1 and ends[s.first + k] < x - 1e-12:
            k += 1
    before = ends[s.first + k - 1] if k else 0.0
    span = ends[s.first + k] - before
    return s.first + k, min(max((x - before) / span, 0.0), 1.0) if span > 0 else 1.0


@numba.njit(cache=True)
def arc_maxvel(s, halved: bool) -> float:
    """pmCircleActualMaxVel: an arc's speed keeps the normal acceleration v²/r within 87 % of a."""
    a = s.acc * (0.5 if halved else 1.0)
    return min(s.maxvel, math.sqrt(NORMAL_SHARE * a * s.radius))


def build_segments(tp: Toolpath, model: ControllerModel, feed_mm_s, modes: PathModes | None,
                   merge: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Segments of LinuxCNC's queue (`SEGMENT` records) with the limits emccanon gives them: one per
    move, or with merge one per chain of straight feeds (`naive_cam_chains`); a line whose every axis
    moves less than AXIS_TINY_MM never reaches the planner (canon drops it), nor does an arc shorter
    than 1e-9 mm. And per move where it ends along its segment (mm, `place`)."""
    feed = tp.feed_mm_s if feed_mm_s is None else np.asarray(feed_mm_s, float)
    modes = PathModes.uniform(len(tp), model) if modes is None else modes
    vax, aax = np.asarray(model.max_rate_mm_s, float), np.asarray(model.accel_mm_s2, float)
    if not len(tp):
        return np.zeros(0, SEGMENT), np.zeros(0)
    first = naive_cam_chains(tp, modes, feed) if merge else np.arange(len(tp))
    last = np.flatnonzero(np.r_[first[1:] != first[:-1], True])
    head = first[last]
    arc = tp.kind[last] >= ARC_CW
    chord = tp.end[last] - tp.start[head]
    L = np.where(arc, tp.lengths()[last], np.linalg.norm(chord, axis=1))
    keep = np.where(arc, L > 1e-9, np.abs(chord).max(axis=1) >= AXIS_TINY_MM)
    idx, head, arc, chord, L = last[keep], head[keep], arc[keep], chord[keep], L[keep]
    if not len(idx):
        return np.zeros(0, SEGMENT), np.zeros(len(tp))
    t0 = chord / np.maximum(L, 1e-300)[:, None]
    t1 = t0.copy()
    vmax = axis_limited(t0, vax)
    acc = axis_limited(t0, aax)
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
    f = feed[idx]
    req = np.where(rapid | ~np.isfinite(f), vmax, np.minimum(f, vmax))
    segs = np.zeros(len(idx), SEGMENT)
    segs["move"], segs["first"], segs["length"], segs["nominal"] = idx, head, L, L
    segs["req"], segs["maxvel"], segs["acc"], segs["arc"], segs["rapid"] = req, vmax, acc, arc, rapid
    segs["t0"], segs["t1"], segs["normal"], segs["radius"], segs["angle"] = t0, t1, normal, radius, angle
    segs["tolerance"] = modes.blend_mm[idx]
    return segs, _chain_ends(tp, segs)


def _chain_ends(tp: Toolpath, segs: np.ndarray) -> np.ndarray:
    """Per move, the distance (mm) along its segment where it ends (`place`): a merged chain's moves'
    end points projected on its line, non-decreasing, the last at the line's end."""
    ends = np.zeros(len(tp))
    ends[segs["move"]] = segs["nominal"]
    for s in segs[segs["first"] < segs["move"]]:
        p = (tp.end[s["first"]:s["move"] + 1] - tp.start[s["first"]]) @ s["t0"].copy()
        p = np.minimum(np.maximum.accumulate(np.clip(p, 0.0, s["nominal"])), s["nominal"])
        p[-1] = s["nominal"]
        ends[s["first"]:s["move"] + 1] = p
    return ends
