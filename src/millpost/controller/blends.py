"""How LinuxCNC 2.9 passes a corner between two segments (blendmath.c, tp.c), speeds mm/s, lengths mm:
a blend arc tangent to both, at most the blend tolerance from the corner (G64 P; without P a quarter of
the shorter segment) and using at most half of each segment, run at √(0.87·a·R) with a in the corner's
plane; where no arc fits, a parabolic blend at half acceleration. `corner_speeds` and `blend_zones`
bound these at any feeds, for the limits and the F words."""

from __future__ import annotations

import math

import numba
import numpy as np

from .._kernels import compiling
from ..toolpath import FEED, Samples, Toolpath
from .model import EXACT_PATH, EXACT_STOP, ControllerModel, PathModes
from .segments import (ANGLE_EPS, KINK_RATIO, NORMAL_SHARE, SHARP_CORNER_COS, SQUARE, TANGENTIAL_SHARE, arc_maxvel,
                       build_segments, dot, inscribed)


_NO_ARC = (False, 0.0, 0.0, (0.0, 0.0, 0.0), 0.0, 0.0)


@numba.njit(cache=True)
def blend_geometry(segs, j: int):
    """The feed-independent part of LinuxCNC's blend arc between segments j − 1 and j (blendmath.c:
    blendInit3From*, blendComputeParameters): (fits, θ, φ, binormal, d_geom, r_geom); fits is False
    where no arc fits. θ is half the angle between the reversed incoming and the outgoing direction,
    φ = π − 2θ the turn; the arc may reach d_geom (mm) into each segment (at most the blend tolerance
    from the corner, half a line, a third/two thirds of an arc's sweep), so its radius is at most
    r_geom."""
    prev, cur = segs[j - 1], segs[j]
    u1, u2 = prev.t1, cur.t0
    cos = min(max(dot(u1, u2), -1.0), 1.0)
    theta = math.acos(-cos) / 2.0
    if math.pi / 2 - theta < ANGLE_EPS or theta < ANGLE_EPS:
        return _NO_ARC
    b = (u1[1] * u2[2] - u1[2] * u2[1], u1[2] * u2[0] - u1[0] * u2[2], u1[0] * u2[1] - u1[1] * u2[0])
    nb = math.sqrt(dot(b, b))
    binormal = (b[0] / nb, b[1] / nb, b[2] / nb)
    for s in (prev, cur):  # a blend arc lies in the plane of an arc it touches
        if s.arc and abs(abs(dot(binormal, s.normal)) - 1.0) > 1e-6:
            return _NO_ARC
    if prev.arc and cur.arc and theta < math.pi / 12:
        return _NO_ARC
    t1 = prev.tolerance if prev.tolerance > 0 else 0.25 * prev.nominal
    t2 = cur.tolerance if cur.tolerance > 0 else 0.25 * cur.nominal
    tol = min(min(t1, t2), min(0.25 * prev.nominal, 0.25 * cur.nominal))
    # how much of each segment the arc may use: half a line, up to a third (next) or two thirds (previous)
    # of an arc's sweep and at most a quarter turn (blendInit3From*)
    if prev.arc:
        L1 = min(prev.angle * 2.0 / 3.0, math.pi / 2) * prev.radius
    else:
        L1 = 0.5 * prev.nominal
    L1 = min(L1, prev.length)
    L2 = min(cur.angle / 3.0, math.pi / 2) * cur.radius if cur.arc else 0.5 * cur.length
    d_tol = math.cos(theta) * tol / (1.0 - math.sin(theta))
    d_geom = min(min(L1, L2), d_tol)
    return True, theta, math.pi - 2.0 * theta, binormal, d_geom, math.tan(theta) * d_geom


@numba.njit(cache=True)
def blend(segs, j: int, accel, rates, two: float):
    """LinuxCNC's blend arc between segments j − 1 and j (blendmath.c: blendParamKinematics,
    blendComputeParameters on `blend_geometry`; accel, rates: the axes' mm/s², mm/s): (fits, trim of
    each segment, arc length, arc speed, arc acceleration). The arc runs at up to the faster segment's
    requested speed."""
    fits, theta, phi, binormal, d_geom, r_geom = blend_geometry(segs, j)
    if not fits:
        return False, 0.0, 0.0, 0.0, 0.0
    prev, cur = segs[j - 1], segs[j]
    u1, u2 = prev.t1, cur.t0
    a_max = inscribed(binormal, accel, two)
    a_n = a_max * NORMAL_SHARE
    v_req = max(prev.req, cur.req)
    v_planar = inscribed(binormal, rates, two)
    phi_eff = min(phi, math.pi * 0.49)
    vm1 = min(prev.maxvel, cur.maxvel / math.cos(phi_eff))
    vm2 = min(cur.maxvel, prev.maxvel / math.cos(phi_eff))
    v_alt = 0.0
    if not prev.arc and not cur.arc:
        base = 0.0
        for i in range(3):
            base += (u2[i] * vm2 - u1[i] * vm1) ** two
        base = math.sqrt(base)
        v_alt = vm1 * vm2 * math.sin(phi) / base if base > 0 else 0.0
    v_goal = min(v_req, max(v_alt, v_planar))
    v_plan = min(math.sqrt(a_n * r_geom), v_goal)
    a_par = 0.5 * a_max
    t_blend = min(math.sqrt(2.0 * a_par * d_geom), v_plan) / a_par
    r_blend = min(t_blend * v_plan / phi, r_geom)
    r_plan = max(v_plan ** two / a_n, r_blend)
    d_plan = r_plan / math.tan(theta)
    s_arc = r_plan * phi
    if r_plan < 1e-12 or s_arc < 1e-6:
        return False, 0.0, 0.0, 0.0, 0.0
    return True, d_plan, s_arc, min(v_plan, v_req), a_max * TANGENTIAL_SHARE


@numba.njit(cache=True)
def parabolic_speed(segs, j: int) -> float:
    """tpComputeBlendVelocity: the speed at which segments j − 1 and j overlap in a parabolic blend
    (each at half acceleration, over at most half of each)."""
    out = np.empty(2)
    acc = np.empty(2)
    for k in range(2):
        s = segs[j - 1 + k]
        a = s.acc * 0.5 * (TANGENTIAL_SHARE if s.arc else 1.0)
        v_target = min(s.req, arc_maxvel(s, True) if s.arc else s.maxvel)
        out[k] = min(math.sqrt(a * s.length), v_target)
        acc[k] = a
    t_max = min(segs[j - 1].length / max(out[0], 1e-12), segs[j].length / max(out[1], 1e-12))
    t_blend = min(t_max, max(out[0] / acc[0], out[1] / acc[1]))
    return min(min(out[0], t_blend * acc[0]), min(out[1], t_blend * acc[1]))


@numba.njit(cache=True)
def kink_jump(prev, cur, accel) -> float:
    """The largest axis share of the velocity jump across a junction per unit speed: max |Δu_i| / a_i
    (s²/mm; times v/Δt the share of the axes' acceleration a tangent kink takes)."""
    return max(abs(cur.t0[0] - prev.t1[0]) / accel[0], abs(cur.t0[1] - prev.t1[1]) / accel[1],
               abs(cur.t0[2] - prev.t1[2]) / accel[2])


def _halts(segs: np.ndarray, tp: Toolpath, model: ControllerModel) -> np.ndarray:
    """Per junction (between segments j − 1 and j; row 0 unused) whether the motion stops there
    whatever the feeds: exact stop, G61/G61.1, a reversal (within 2°) or a jump in position."""
    prev, cur = segs[:-1], segs[1:]
    u, w = prev["t1"], cur["t0"]
    gap = tp.start[cur["move"]] - tp.end[prev["move"]]
    halts = (model.exact_stop | np.isin(prev["tolerance"], (EXACT_PATH, EXACT_STOP))
             | (u[:, 0] * w[:, 0] + u[:, 1] * w[:, 1] + u[:, 2] * w[:, 2] < SHARP_CORNER_COS)
             | (np.sqrt(gap[:, 0] * gap[:, 0] + gap[:, 1] * gap[:, 1] + gap[:, 2] * gap[:, 2]) > 1e-6))
    return np.r_[True, halts]


@numba.njit(cache=True)
def _arc_top_speed(binormal, r_geom: float, accel, two: float) -> float:
    """Top speed (mm/s) of the largest blend arc that fits a corner: √(0.87·a·r_geom), a the
    acceleration every direction of the corner's plane allows."""
    return math.sqrt(NORMAL_SHARE * inscribed(binormal, accel, two) * r_geom)


@numba.njit(cache=True)
def _corner_speeds(segs, halts, accel, dt: float, two: float):
    """Per segment the speed (mm/s) of the corner before it (see `corner_speeds`)."""
    out = np.full(len(segs), np.inf)
    for j in range(1, len(segs)):
        prev, cur = segs[j - 1], segs[j]
        if prev.rapid != cur.rapid or halts[j]:
            out[j] = 0.0
            continue
        jump = kink_jump(prev, cur, accel)
        if jump < 1e-12:
            continue
        v = KINK_RATIO * dt / jump * (TANGENTIAL_SHARE if prev.arc or cur.arc else 1.0)
        fits, _, _, binormal, _, r_geom = blend_geometry(segs, j)
        out[j] = max(v, _arc_top_speed(binormal, r_geom, accel, two) if fits else parabolic_speed(segs, j))
    return out


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
    segs, _ = build_segments(tp, model, np.full(len(tp), np.inf), modes)
    if len(segs) > 1:
        accel = np.asarray(model.accel_mm_s2, float)
        with compiling(_corner_speeds):
            speeds = _corner_speeds(segs, _halts(segs, tp, model), accel, model.servo_period_s, SQUARE)
        out[segs["move"][1:]] = speeds[1:]
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
    loads see the faster move's feed unless both F words fit it. A planner that blends no corners
    (grbl: it never runs a junction above the slower block's feed) has no zones. modes: the path modes
    (`path_modes`). Per programmed move, not merged: the canon layer's merging depends on the F words
    written, and its longer lines reach further; the arcs of the program as emitted are
    `Execution.blends`. Stops (rapid ↔ feed, reversals, jumps, G61/G61.1) have no zone; pauses are not
    looked at (a zone there only costs time)."""
    if not model.planner.blends_corners:
        return np.zeros((0, 3))
    segs, _ = build_segments(tp, model, None, modes)
    if len(segs) < 2:
        return np.zeros((0, 3))
    with compiling(_largest_arcs):
        arcs = _largest_arcs(segs, _halts(segs, tp, model), np.asarray(model.accel_mm_s2, float), SQUARE)
    at = np.cumsum(tp.lengths())[segs["move"]]
    fits = ~np.isnan(arcs[:, 0])
    return np.column_stack([at[:-1] - arcs[1:, 0], at[:-1] + arcs[1:, 0], arcs[1:, 1]])[fits[1:]]


@numba.njit(cache=True)
def _largest_arcs(segs, halts, accel, two: float):
    """Per junction (between segments j − 1 and j; row 0 unused) the reach d_geom (mm) and top speed
    (mm/s) of the largest blend arc between two feeds that do not stop there; nan where none."""
    out = np.full((len(segs), 2), np.nan)
    for j in range(1, len(segs)):
        if segs[j - 1].rapid or segs[j].rapid or halts[j]:
            continue
        fits, _, _, binormal, d_geom, r_geom = blend_geometry(segs, j)
        if fits:
            out[j, 0] = d_geom
            out[j, 1] = _arc_top_speed(binormal, r_geom, accel, two)
    return out


def zone_samples(samples: Samples, zones: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per zone (start, end (mm of the samples' arc length), top speed): the samples it covers (those
    within it and the next one on each side: a speed is linear between samples), as (sample index,
    zone index) pairs."""
    s = samples.s_mm
    lo = np.maximum(np.searchsorted(s, zones[:, 0], side="left") - 1, 0)
    hi = np.minimum(np.searchsorted(s, zones[:, 1], side="right") + 1, len(s))
    count = np.maximum(hi - lo, 0)
    owner = np.repeat(np.arange(len(zones)), count)
    idx = np.repeat(lo - np.r_[0, np.cumsum(count)[:-1]], count) + np.arange(count.sum())
    return idx, owner


def programmed_arcs(samples: Samples, v_prog_mm_s: np.ndarray, zones: np.ndarray) -> np.ndarray:
    """Per sample the speed (mm/s) the programmed program's blend arcs pass it at: over each zone (see
    `blend_limit`) the faster programmed feed it covers, at most the arc's top speed (0 off the zones).
    A cap set relative to the programmed feeds is never below it: the program runs that fast there."""
    zones = np.asarray(zones, float).reshape(-1, 3)
    idx, owner = zone_samples(samples, zones)
    top = np.zeros(len(zones))
    np.maximum.at(top, owner, np.nan_to_num(np.asarray(v_prog_mm_s, float)[idx], nan=0.0))
    out = np.zeros(len(samples))
    np.maximum.at(out, idx, np.minimum(top, zones[:, 2])[owner])
    return out
