"""Piecewise-constant feeds from a schedule: never above it, fragment and change bounds, and the
split program replayed through the controller model exceeds no limit."""

from __future__ import annotations

import numpy as np
import pytest
from test_schedule import AMAX, VMAX, make_toolpath, pocket_toolpath

from millpost.controller import ControllerModel, GrblPlanner, execute
from millpost.emit import SNAP_TO_PROGRAMMED, FeedPlan
from millpost.gcode import read_text
from millpost.schedule import AxisAcceleration, AxisVelocity, FeedLimit, Junction, SpeedLoad, schedule_samples
from millpost.emit import Fragment, emission_limit, piecewise_feeds
from millpost.schedule.rows import PathGrid
from millpost.toolpath import ARC_CW, PLANE_AXES, Toolpath


def fragment_feed_at_samples(samples, fragments, tp):
    """Programmed feed (mm/s) in force at every sample, found independently by arc-length position."""
    L = tp.lengths()
    out = np.full(len(samples), np.nan)
    s0 = {}
    for k in range(len(samples)):
        m = samples.move[k]
        s0.setdefault(m, samples.s_mm[k - 1] if k > 0 and not samples.segment_start[k] else samples.s_mm[k])
    for k in range(len(samples)):
        m = samples.move[k]
        u = (samples.s_mm[k] - s0[m]) / L[m]
        for f in fragments:
            if f.move == m and f.u_start - 1e-9 <= u <= f.u_end + 1e-9:
                out[k] = np.nanmin([out[k], f.feed_mm_s])
    return out


def split_toolpath(tp: Toolpath, fragments: list[Fragment]) -> Toolpath:
    """Test helper: the program with each fragmented move split at its fragment ends (arcs as arcs about the same
    centre) and the fragment feeds; other moves unchanged. Keeps line and block of the source."""
    by_move: dict[int, list[Fragment]] = {}
    for f in fragments:
        by_move.setdefault(f.move, []).append(f)
    idx, u0, u1, feed = [], [], [], []
    for m in range(len(tp)):
        frs = by_move.get(m)
        if not frs:
            idx.append(m), u0.append(0.0), u1.append(1.0), feed.append(tp.feed_mm_min[m])
            continue
        for f in sorted(frs, key=lambda f: f.u_start):
            idx.append(m), u0.append(f.u_start), u1.append(f.u_end), feed.append(f.feed_mm_s * 60.0)  # F words
    idx, u0, u1 = np.array(idx), np.array(u0), np.array(u1)
    out = tp.subset(idx)
    out.start = tp.points(idx, u0)
    out.end = tp.points(idx, u1)
    out.feed_mm_min = np.array(feed, float)
    arc = out.kind >= ARC_CW
    if arc.any():
        _, _, _, sweep, _, _ = tp.subset(idx[arc])._arc_params()
        sw = np.abs(sweep) * (u1[arc] - u0[arc])
        full = np.floor(sw / (2 * np.pi) + 1e-9)
        rem = sw - 2 * np.pi * full
        out.turns = out.turns.copy()
        out.turns[arc] = np.where(rem < 1e-9, full - 1, full).astype(np.int32)
        # the normal-axis component of a centre equals its move's start
        ax = np.array(PLANE_AXES)[out.plane[arc].astype(int)][:, 2]
        c = out.center[arc].copy()
        c[np.arange(len(c)), ax] = out.start[arc][np.arange(len(c)), ax]
        out.center = out.center.copy()
        out.center[arc] = c
    return out


def test_fragments_bound_the_limit_and_respect_length_and_count():
    tp = make_toolpath((0, 0, 0), [("line", (40, 0, 0)), ("arc", (40, 20, 0), (40, 10, 0), True),
                                   ("line", (35, 20, 0))])
    smp = tp.resample(0.05)
    rng = np.random.default_rng(5)
    lim = 50 + 30 * np.sin(smp.s_mm / 3.0) + 5 * rng.random(len(smp))
    frs = piecewise_feeds(smp, lim, min_fragment_mm=2.0, max_changes_per_mm=0.2, step=0.0)
    fed = fragment_feed_at_samples(smp, frs, tp)
    assert np.all(fed <= lim + 1e-12)
    L = tp.lengths()
    for m in range(len(tp)):
        mine = [f for f in frs if f.move == m]
        assert len(mine) <= 1 + int(L[m] * 0.2)
        lengths = [(f.u_end - f.u_start) * L[m] for f in mine]
        assert min(lengths) >= min(2.0, L[m]) - 1e-9
        assert sum(lengths) == pytest.approx(L[m])
    # more freedom → closer to the limit: time Σ l/F approaches ∫ ds/limit
    fine = piecewise_feeds(smp, lim, min_fragment_mm=0.05, max_changes_per_mm=100, step=0.0)
    t_fine = sum((f.u_end - f.u_start) * L[f.move] / f.feed_mm_s for f in fine)
    t_coarse = sum((f.u_end - f.u_start) * L[f.move] / f.feed_mm_s for f in frs)
    ideal = np.sum(np.diff(smp.s_mm) / np.minimum(lim[1:], lim[:-1]))
    assert ideal * (1 - 1e-3) <= t_fine <= ideal * 1.02 < t_coarse


def test_a_slow_move_does_not_hold_the_next_moves_first_fragment():
    """A plunge limited to 5 mm/s, then a 20 mm cut limited to 20 mm/s: the sample at the corner is the
    plunge's (its step arrives there), so the cut runs at 20 mm/s from the corner on (the corner itself
    is held by the plunge's F and the controller's blend, `blend_limit`); each move's fragments at its
    own limit."""
    tp = make_toolpath((0, 0, 2), [("line", (0, 0, -1)), ("line", (20, 0, -1))])
    smp = tp.resample(0.1)
    lim = np.where(smp.move == 0, 5.0, 20.0)
    frs = piecewise_feeds(smp, lim, min_fragment_mm=2.0, max_changes_per_mm=0.2, step=0.0)
    assert [(f.move, f.u_start, f.u_end, f.feed_mm_s) for f in frs] == [(0, 0.0, 1.0, 5.0), (1, 0.0, 1.0, 20.0)]


def test_split_toolpath_keeps_geometry():
    tp = make_toolpath((4, 0, 0), [("arc", (4, 0, -3), (0, 0, 0), True, 2), ("line", (10, 0, -3))])
    smp = tp.resample(0.05)
    lim = 40 + 20 * np.cos(smp.s_mm / 4.0)
    frs = piecewise_feeds(smp, lim, min_fragment_mm=3.0, max_changes_per_mm=0.5)
    sp = split_toolpath(tp, frs)
    assert len(sp) == len(frs) > 2
    assert sp.lengths().sum() == pytest.approx(tp.lengths().sum(), rel=1e-9)
    np.testing.assert_allclose(sp.start[1:], sp.end[:-1], atol=1e-9)
    assert set(sp.line) == set(tp.line)
    # points of the split arcs stay on the helix radius
    r = np.hypot(*sp.points(np.arange(len(sp)), np.full(len(sp), 0.5))[:, :2].T)
    np.testing.assert_allclose(r[sp.kind >= 2], 4.0, rtol=1e-9)


def test_scheduled_program_replayed_through_controller_exceeds_no_limit():
    tp = pocket_toolpath()
    smp = tp.resample(0.05)
    grid = PathGrid.from_samples(smp)
    n = len(grid)
    alpha = 1.0 + 0.8 * np.sin(grid.s_mm / 7.0) ** 2
    force_cap = 160.0
    limits = [FeedLimit(150.0), AxisVelocity(VMAX), AxisAcceleration(AMAX), Junction(AMAX, 0.01),
              SpeedLoad(alpha, np.full(n, 5.0), force_cap, "force")]
    ps = schedule_samples(smp, limits)
    assert ps.ok
    lim = emission_limit(smp, limits, ps, ("axis_velocity", "axis_acceleration", "junction"))
    assert np.all(lim[np.isfinite(lim)] >= ps.feed_mm_s[np.isfinite(lim)] - 1e-9)
    frs = piecewise_feeds(smp, lim, min_fragment_mm=1.0, max_changes_per_mm=0.5)
    sp = split_toolpath(tp, frs)
    ctl = ControllerModel(VMAX, AMAX, junction_deviation_mm=0.01, lookahead_blocks=32, planner=GrblPlanner())
    ex = execute(sp, ctl)
    v = ex.speed_at_samples(sp.resample(0.05))
    # same sampling of the same geometry: compare loads at the controller's actual speed
    v_on_orig = np.interp(smp.s_mm, sp.resample(0.05).s_mm, v)
    force = alpha * v_on_orig + 5.0
    assert force.max() <= force_cap * 1.005
    assert v_on_orig.max() <= 150.0 * 1.005
    # and the optimised program is faster than the best single constant feed meeting the force cap
    best_const = (force_cap - 5.0) / alpha.max()  # mm/s
    base = execute(tp, ctl, np.full(len(tp), best_const))
    assert ex.time_s < base.time_s


def test_settle_and_cluster_never_raise_and_space_the_feeds():
    from millpost.emit import cluster, settle
    rng = np.random.default_rng(1)
    f = 1000 * np.exp(np.cumsum(rng.normal(0, 0.03, 3000)))
    for out, consecutive in ((settle(f, 0.05), True), (cluster(f, 0.05), False)):
        assert np.all(out <= f)
        assert np.all(out >= f.min())
        v = np.diff(out) if consecutive else np.diff(np.unique(out))
        base = np.minimum(out[1:], out[:-1]) if consecutive else np.unique(out)[:-1]
        rel = np.abs(v) / base
        assert np.all((rel == 0) | (rel >= 0.05 - 1e-12))
    assert np.array_equal(settle(np.array([100.0, 103.0, 120.0, 119.0]), 0.05), [100.0, 100.0, 119.0, 119.0])


def test_settle_lowers_a_feed_below_its_programmed_one_only_for_a_limit():
    """CAMotics' wave programs F392.055 then F410.849 (+4.8 %): one run would write F392.055 over moves
    programmed F410.849 with no limit asking for it. A feed a limit holds under its programmed one
    still pulls its run down (one F for a run a limit slows in part)."""
    from millpost.emit import settle
    f = np.array([392.055, 410.849])
    np.testing.assert_array_equal(settle(f, 0.05), [392.055, 392.055])
    np.testing.assert_array_equal(settle(f, 0.05, f), f)
    np.testing.assert_array_equal(settle(np.array([400.0, 410.0, 420.0]), 0.05, np.array([500.0, 300.0, 410.0])),
                                  [400.0, 400.0, 400.0])
    rng = np.random.default_rng(2)
    f = 1000 * np.exp(np.cumsum(rng.normal(0, 0.03, 3000)))
    keep = f * rng.uniform(0.8, 1.0, len(f))  # every feed at or above its programmed one
    out = settle(f, 0.05, keep)
    assert np.all(out <= f) and np.all(out >= keep)
    keep = f * rng.uniform(0.8, 1.2, len(f))  # some held under it by a limit
    out = settle(f, 0.05, keep)
    assert np.all(out <= f)
    # a feed under its programmed one takes the feed of one a limit holds under its own
    held = f < keep
    lowered = out < np.minimum(f, keep)
    assert lowered.any() and np.all(np.isin(out[lowered], f[held]))


def test_reachable_joins_short_peaks_only():
    from millpost.emit import reachable
    joined = np.array([False, True, True, True])
    f = np.array([10.0, 11.0, 10.0, 100.0])  # mm/s (F600, F660, F600, F6000); 0.1 mm pieces at 3000 mm/s²
    out = reachable(f, np.full(4, 0.1), np.full(4, 3000.0), joined, 0.05)
    # piece 1 peaks at sqrt(10² + 300) = 20 mm/s (1200 mm/min) > 1.05 × 600: it keeps its F
    np.testing.assert_array_equal(out, f)
    out = reachable(f, np.full(4, 0.001), np.full(4, 3000.0), joined, 0.05)
    # 1 µm: it peaks at sqrt(100 + 3) mm/s = 609 mm/min, within 5 % of 600: joined to its neighbours
    np.testing.assert_array_equal(out, [10.0, 10.0, 10.0, 100.0])
    # unless that takes it under its programmed feed (F630 programmed there): only a limit lowers a feed
    # below the programmed one (a short G3 F39.37 carried the plunge's F12.46 before it)
    out = reachable(f, np.full(4, 0.001), np.full(4, 3000.0), joined, 0.05, np.array([10.0, 10.5, 10.0, 100.0]))
    np.testing.assert_array_equal(out, f)


def test_feeds_within_solver_tolerance_under_the_programmed_are_the_programmed():
    """A bound held at the programmed feed is met by the solver to ~1e-4: F400 would be written F399.9
    (an F word that changes nothing on the machine). Within 0.1 % under the programmed feed, and no hard
    cap under it, the plan keeps the programmed feed, on whole moves and on fragments; under a hard cap
    below the programmed feed, a feed within 0.1 % of the cap is the cap (the solver met that bound),
    never above it; a feed 1 % under is kept as the schedule gave it."""
    prog = read_text("G21 G90\nG0 X0 Y0 Z1\nG1 Z-1 F400\nG1 X50\nG1 X100\n")
    near = 400 * (1 - SNAP_TO_PROGRAMMED / 2)
    frags = [Fragment(1, 0.0, 1.0, near / 60), Fragment(2, 0.0, 0.5, near / 60), Fragment(2, 0.5, 1.0, 700.0 / 60),
             Fragment(3, 0.0, 1.0, 396.0 / 60)]  # mm/s
    plan = FeedPlan.from_fragments(prog, frags, 0.05, np.full(4, np.inf))
    assert plan.feed_mm_min[1] == 400 and plan.fragments[2][0] == (0.5, 400.0)
    assert plan.fragments[2][1] == (1.0, pytest.approx(700.0, rel=1e-15))
    assert plan.feed_mm_min[3] == pytest.approx(396.0, rel=1e-15)
    capped = FeedPlan.from_fragments(prog, frags, 0.05, np.full(4, 399.9 / 60))
    assert capped.feed_mm_min[1] == pytest.approx(399.9, rel=1e-15)
    assert capped.feed_mm_min[3] == pytest.approx(396.0, rel=1e-15)
