"""Windowed and chunked (2-process) solves against the monolithic optimum of the same problem."""

from __future__ import annotations

import numpy as np
import pytest
from test_schedule import AMAX, VMAX, check_limits, pocket_toolpath

from millpost.schedule import (AxisAcceleration, AxisVelocity, FeedLimit, Junction, PathGrid, ScheduleOptions,
                               SpeedLoad, Status, path_blocks, solve_path)


@pytest.fixture(scope="module")
def long_case():
    smp = pocket_toolpath().resample(0.025)
    grid = PathGrid.from_samples(smp)
    n = len(grid)
    rng = np.random.default_rng(11)
    # an engagement-like load varying along the path, capping the feed between ~60 and 150 mm/s
    alpha = 1.0 + 0.8 * np.sin(grid.s_mm / 7.0) ** 2 + 0.1 * rng.random(n)
    limits = [FeedLimit(150.0), AxisVelocity(VMAX), AxisAcceleration(AMAX), Junction(AMAX, 0.02),
              SpeedLoad(alpha, np.full(n, 5.0), 160.0, "force")]
    return grid, path_blocks(grid, limits), alpha


def test_windowed_and_two_process_chunks_match_monolithic(long_case):
    grid, blocks, alpha = long_case
    assert len(grid) > 6000
    kw = dict(certify_gap=0.0)  # always the conic solve (the O(N) certified profile is tested elsewhere)
    mono = solve_path(grid, blocks, ScheduleOptions(monolithic_max=10**9, **kw))
    win = solve_path(grid, blocks, ScheduleOptions(monolithic_max=1000, window=1000, overlap=100, **kw))
    par = solve_path(grid, blocks, ScheduleOptions(monolithic_max=1000, window=1000, overlap=100, processes=2, **kw))
    assert mono.status == win.status == par.status == Status.SOLVED
    assert win.windows > 5 and par.windows > 5
    for s in (win, par):
        assert s.time_s >= mono.time_s * (1 - 1e-6)  # cannot beat the global optimum
        assert s.time_s <= mono.time_s * 1.001
        r = check_limits(grid.tangent, grid.curvature, grid.s_mm, s.b, vmax=VMAX, amax=AMAX, feed=150.0,
                         loads=[(alpha, np.full(len(grid), 5.0), 160.0)])
        assert max(r.values()) <= 1.001, r


def test_jerk_limited_windows_match_monolithic():
    """Jerk rows couple neighbouring a: windows fix two samples at their start and overlap more."""
    from millpost.schedule import PathJerk
    smp = pocket_toolpath().resample(0.05)
    grid = PathGrid.from_samples(smp)
    blocks = path_blocks(grid, [FeedLimit(150.0), AxisVelocity(VMAX), AxisAcceleration(AMAX), Junction(AMAX, 0.02),
                                PathJerk(5e4)])
    mono = solve_path(grid, blocks, ScheduleOptions(monolithic_max=10**9))
    win = solve_path(grid, blocks, ScheduleOptions(monolithic_max=1000, window=1000, overlap=300))
    assert mono.status == win.status == Status.SOLVED and win.windows > 3
    assert mono.time_s * (1 - 1e-6) <= win.time_s <= mono.time_s * 1.001
    assert max(win.excess.values()) <= 1e-5  # jerk evaluated exactly (actual speeds), not linearised
