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


def test_processes_do_not_change_the_chunked_solve(long_case):
    """The chunk cuts depend on the segment only: one process and two give the same b, bit for bit."""
    grid, blocks, _ = long_case
    kw = dict(certify_gap=0.0, monolithic_max=1000, window=1000, overlap=100, chunk=2500)
    one = solve_path(grid, blocks, ScheduleOptions(processes=1, **kw))
    two = solve_path(grid, blocks, ScheduleOptions(processes=2, **kw))
    assert one.status == two.status == Status.SOLVED and one.windows > 3
    np.testing.assert_array_equal(one.b, two.b)


def test_segments_in_processes_match_one_process():
    """Several cutting segments (split by rapids) solved by two worker processes: the same schedule as
    one process, segment by segment and sample by sample."""
    from millpost.gcode import read_text
    from millpost.schedule import schedule_samples
    lines = ["G21 G90 G17 G94", "G0 X0 Y0 Z1", "G1 Z-1 F600"]
    for k in range(3):
        y = 10.0 * k
        lines += ["G0 Z1", f"G0 X0 Y{y}", "G1 Z-1 F600", f"G1 X40 Y{y} F3000", f"G3 X40 Y{y + 6} I0 J3",
                  f"G1 X0 Y{y + 6}", f"G1 X0 Y{y + 3}", f"G1 X{30 - 5 * k} Y{y + 3}"]
    smp = read_text("\n".join(lines) + "\nG0 Z5\nM30\n", "three.nc").toolpath.resample(0.02)
    n = len(smp)
    alpha = 1.0 + 0.5 * np.sin(smp.s_mm / 5.0) ** 2
    limits = [FeedLimit(60.0), AxisVelocity(VMAX), AxisAcceleration(AMAX), Junction(AMAX, 0.02),
              SpeedLoad(alpha, np.full(n, 2.0), 90.0, "force")]
    kw = dict(certify_gap=0.0, monolithic_max=1500, window=1000, overlap=100, chunk=3000)
    one = schedule_samples(smp, limits, ScheduleOptions(processes=1, **kw))
    two = schedule_samples(smp, limits, ScheduleOptions(processes=2, **kw))
    assert len(one.segments) >= 3 and one.ok and two.ok
    assert max(hi - lo for lo, hi, _ in one.segments) > kw["monolithic_max"]  # some segments are windowed
    np.testing.assert_array_equal(one.feed_mm_s, two.feed_mm_s)
    assert [(lo, hi, s.windows) for lo, hi, s in one.segments] == [(lo, hi, s.windows) for lo, hi, s in two.segments]
