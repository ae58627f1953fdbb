"""How LinuxCNC 2.9 passes a corner between two segments (blendmath.c, tp.c), speeds mm/s, lengths mm:
a blend arc tangent to both, at most the blend tolerance from the corner (G64 P; without P a quarter of
the shorter segment) and using at most half of each segment, run at √(0.87·a·R) with a in the corner's
plane; where no arc fits, a parabolic blend at half acceleration. `corner_speeds` and `blend_zones`
bound these at any feeds, for the limits and the F words."""

from __future__ import annotations

import math

import numpy as np

from ..toolpath import FEED, Samples, Toolpath
from .model import EXACT_PATH, EXACT_STOP, ControllerModel, PathModes
from .segments import (ANGLE_EPS, KINK_RATIO, NORMAL_SHARE, SHARP_CORNER_COS, TANGENTIAL_SHARE, Segment, arc_maxvel,
                       build_segments, dot, inscribed)


def blend_geometry(prev: Segment, cur: Segment):
    """The feed-independent part of LinuxCNC's blend arc between two segments (blendmath.c:
    blendInit3From*, blendComputeParameters): (θ, φ, binormal, d_geom, r_geom), or None where no arc
    fits. θ is half the angle between the reversed incoming and the outgoing direction, φ = π − 2θ the
    turn; the arc may reach d_geom (mm) into each segment (at most the blend tolerance from the
    corner, half a line, a third/two thirds of an arc's sweep), so its radius is at most r_geom."""
    u1, u2 = prev.t1, cur.t0
    cos = min(max(dot(u1, u2), -1.0), 1.0)
    theta = math.acos(-cos) / 2.0
    if math.pi / 2 - theta < ANGLE_EPS or theta < ANGLE_EPS:
        return None
    b = (u1[1] * u2[2] - u1[2] * u2[1], u1[2] * u2[0] - u1[0] * u2[2], u1[0] * u2[1] - u1[1] * u2[0])
    nb = math.sqrt(dot(b, b))
    binormal = (b[0] / nb, b[1] / nb, b[2] / nb)
    for s in (prev, cur):  # a blend arc lies in the plane of an arc it touches
        if s.arc and abs(abs(dot(binormal, s.normal)) - 1.0) > 1e-6:
            return None
    if prev.arc and cur.arc and theta < math.pi / 12:
        return None
    t1 = prev.tolerance if prev.tolerance > 0 else 0.25 * prev.nominal
    t2 = cur.tolerance if cur.tolerance > 0 else 0.25 * cur.nominal
    tol = min(t1, t2, 0.25 * prev.nominal, 0.25 * cur.nominal)
    # how much of each segment the arc may use: half a line, up to a third (next) or two thirds (previous)
    # of an arc's sweep and at most a quarter turn (blendInit3From*)
    if prev.arc:
        L1 = min(prev.angle * 2.0 / 3.0, math.pi / 2) * prev.radius
    else:
        L1 = 0.5 * prev.nominal
    L1 = min(L1, prev.length)
    L2 = min(cur.angle / 3.0, math.pi / 2) * cur.radius if cur.arc else 0.5 * cur.length
    d_tol = math.cos(theta) * tol / (1.0 - math.sin(theta))
    d_geom = min(L1, L2, d_tol)
    return theta, math.pi - 2.0 * theta, binormal, d_geom, math.tan(theta) * d_geom


def blend(prev: Segment, cur: Segment, model: ControllerModel):
    """LinuxCNC's blend arc between two segments (blendmath.c: blendParamKinematics,
    blendComputeParameters on `blend_geometry`): (trim of each segment, arc length, arc speed, arc
    acceleration), or None. The arc runs at up to the faster segment's requested speed."""
    geometry = blend_geometry(prev, cur)
    if geometry is None:
        return None
    theta, phi, binormal, d_geom, r_geom = geometry
    u1, u2 = prev.t1, cur.t0
    a_max = inscribed(binormal, model.accel_mm_s2)
    a_n = a_max * NORMAL_SHARE
    v_req = max(prev.req, cur.req)
    v_planar = inscribed(binormal, model.max_rate_mm_s)
    phi_eff = min(phi, math.pi * 0.49)
    vm1 = min(prev.maxvel, cur.maxvel / math.cos(phi_eff))
    vm2 = min(cur.maxvel, prev.maxvel / math.cos(phi_eff))
    v_alt = 0.0
    if not prev.arc and not cur.arc:
        base = math.sqrt(sum((u2[i] * vm2 - u1[i] * vm1) ** 2 for i in range(3)))
        v_alt = vm1 * vm2 * math.sin(phi) / base if base > 0 else 0.0
    v_goal = min(v_req, max(v_alt, v_planar))
    v_plan = min(math.sqrt(a_n * r_geom), v_goal)
    a_par = 0.5 * a_max
    t_blend = min(math.sqrt(2.0 * a_par * d_geom), v_plan) / a_par
    r_blend = min(t_blend * v_plan / phi, r_geom)
    r_plan = max(v_plan**2 / a_n, r_blend)
    d_plan = r_plan / math.tan(theta)
    s_arc = r_plan * phi
    if r_plan < 1e-12 or s_arc < 1e-6:
        return None
    return d_plan, s_arc, min(v_plan, v_req), a_max * TANGENTIAL_SHARE


def parabolic_speed(prev: Segment, cur: Segment) -> float:
    """tpComputeBlendVelocity: the speed at which two segments overlap in a parabolic blend (each at
    half acceleration, over at most half of each)."""
    out = []
    acc = []
    for s in (prev, cur):
        a = s.acc * 0.5 * (TANGENTIAL_SHARE if s.arc else 1.0)
        v_target = min(s.req, arc_maxvel(s, True) if s.arc else s.maxvel)
        out.append(min(math.sqrt(a * s.length), v_target))
        acc.append(a)
    t_max = min(prev.length / max(out[0], 1e-12), cur.length / max(out[1], 1e-12))
    t_blend = min(t_max, max(out[0] / acc[0], out[1] / acc[1]))
    return min(min(out[0], t_blend * acc[0]), min(out[1], t_blend * acc[1]))


def _halts(prev: Segment, cur: Segment, tp: Toolpath, model: ControllerModel) -> bool:
    """Whether the motion stops between two programmed moves whatever the feeds: exact stop, G61/G61.1,
    a reversal (within 2°) or a jump in position."""
    return bool(model.exact_stop or prev.tolerance in (EXACT_PATH, EXACT_STOP)
                or dot(prev.t1, cur.t0) < SHARP_CORNER_COS
                or np.linalg.norm(tp.start[cur.move] - tp.end[prev.move]) > 1e-6)


def _arc_top_speed(binormal, r_geom: float, model: ControllerModel) -> float:
    """Top speed (mm/s) of the largest blend arc that fits a corner: √(0.87·a·r_geom), a the
    acceleration every direction of the corner's plane allows."""
    return math.sqrt(NORMAL_SHARE * inscribed(binormal, model.accel_mm_s2) * r_geom)


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
    segs = build_segments(tp, model, np.full(len(tp), np.inf), modes)
    amax, dt = model.accel_mm_s2, model.servo_period_s
    for prev, cur in zip(segs[:-1], segs[1:]):
        if prev.rapid != cur.rapid or _halts(prev, cur, tp, model):
            out[cur.move] = 0.0
            continue
        jump = max(abs(cur.t0[i] - prev.t1[i]) / amax[i] for i in range(3))
        if jump < 1e-12:
            continue
        v = KINK_RATIO * dt / jump * (TANGENTIAL_SHARE if prev.arc or cur.arc else 1.0)
        geometry = blend_geometry(prev, cur)
        if geometry is not None:
            v = max(v, _arc_top_speed(geometry[2], geometry[4], model))
        else:
            v = max(v, parabolic_speed(prev, cur))
        out[cur.move] = v
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
    out = []
    if not model.planner.blends_corners:
        return np.zeros((0, 3))
    segs = build_segments(tp, model, None, modes)
    end = np.cumsum(tp.lengths())
    for prev, cur in zip(segs[:-1], segs[1:]):
        if prev.rapid or cur.rapid or _halts(prev, cur, tp, model):
            continue
        geometry = blend_geometry(prev, cur)
        if geometry is None:
            continue
        _, _, binormal, d_geom, r_geom = geometry
        out.append((end[prev.move] - d_geom, end[prev.move] + d_geom, _arc_top_speed(binormal, r_geom, model)))
    return np.asarray(out, float).reshape(-1, 3)


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
