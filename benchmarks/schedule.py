"""Feed-schedule benchmark: prints one JSON object {"rows": [...], ...}, one row per size.

Program: a pocket (helix ramp, zig-zag with sharp corners, filleted perimeter) repeated side by
side and joined by cutting moves until the resampled path (ds = 0.02 mm) has the requested number
of samples. Limits: max feed 150 mm/s, axis velocity and acceleration, junction deviation 0.01 mm
and an engagement-like force load capping the feed between ~85 and 150 mm/s.

Per size: `seconds` and `peak_rss_mb` of the production default (`method` "reach": the O(N)
reachability profile accepted with a proven optimality `gap_bound` ≤ 0.1 %, certify.py; otherwise
"socp"); `socp_*` the windowed SOCP forced (windows of 2000 samples, overlap 200, 2 processes,
chunks cut at cruise anchors); `gap_vs_monolithic` = T/T_monolithic − 1 of the production result
(monolithic SOCP only up to --mono-max samples, default 150 000), `socp_windowed_gap_vs_monolithic`
the same for the windowed SOCP; `time_ratio_vs_toppra` = SOCP traversal time / toppra's (velocity +
acceleration limits only, same grid, collocation); `time_ratio_vs_grbl_planner` = SOCP time / the
grbl-like controller model's time for the program at the max feed with the same axis limits and
junction deviation (velocity + acceleration + junction only, so both know the same limits;
grbl-style junction deviation on arc chords has no centripetal limit, so > 1 is expected: the
planner's own arcs exceed the axis acceleration model).

Usage: python benchmarks/schedule.py [--sizes 10000 100000 1000000] [--mono-max 100000]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import resource
import subprocess
import sys
import time

import numpy as np

DS = 0.02
VMAX = (150.0, 150.0, 80.0)
AMAX = (1500.0, 1200.0, 800.0)
FEED = 150.0


def program(samples_wanted: int):
    from millpost.toolpath import ARC_CCW, FEED as KFEED, Toolpath

    r = 2.0
    base = [("arc", (4, 0, -2), (0, 0, 0), 1),
            ("line", (20, 0, -2)), ("line", (20, 3, -2)), ("line", (0, 3, -2)), ("line", (0, 6, -2)),
            ("line", (20, 6, -2)), ("line", (30 - r, 6, -2)), ("arc", (30, 6 + r, -2), (30 - r, 6 + r, -2), 0),
            ("line", (30, 20 - r, -2)), ("arc", (30 - r, 20, -2), (30 - r, 20 - r, -2), 0),
            ("line", (r, 20, -2)), ("arc", (0, 20 - r, -2), (r, 20 - r, -2), 0), ("line", (0, 10, -2))]
    kinds, starts, ends, centers, turns = [], [], [], [], []
    p = np.array([4.0, 0, 0])
    copy = 0
    total = 0.0
    while True:
        off = np.array([40.0 * copy, 0, 0])
        if copy:
            kinds.append(KFEED), starts.append(p), ends.append(off + (4, 0, 0)), centers.append([np.nan] * 3)
            turns.append(0)
            p = off + np.array([4.0, 0, 0])
        for mv in base:
            e = off + np.asarray(mv[1], float)
            kinds.append(ARC_CCW if mv[0] == "arc" else KFEED)
            starts.append(p), ends.append(e)
            centers.append(off + np.asarray(mv[2], float) if mv[0] == "arc" else [np.nan] * 3)
            turns.append(mv[3] if mv[0] == "arc" else 0)
            p = e
        copy += 1
        n = len(kinds)
        tp = Toolpath(np.array(kinds, np.int8), np.array(starts), np.array(ends), np.array(centers, float),
                      np.zeros(n, np.int8), np.array(turns, np.int32), np.full(n, FEED * 60), np.full(n, 10000.0),
                      np.ones(n, np.int32), np.arange(1, n + 1, dtype=np.int32), np.arange(n, dtype=np.int32))
        total = tp.lengths().sum()
        if total / DS >= samples_wanted:
            break
    ds = total / samples_wanted
    return tp, tp.resample(ds * (1 + 1e-9))


def limits(grid, full: bool):
    from millpost.schedule import AxisAcceleration, AxisVelocity, FeedLimit, Junction, SpeedLoad
    lim = [FeedLimit(FEED), AxisVelocity(VMAX), AxisAcceleration(AMAX), Junction(AMAX, 0.01)]
    if full:
        alpha = 1.0 + 0.8 * np.sin(grid.s_mm / 7.0) ** 2
        lim.append(SpeedLoad(alpha, np.full(len(grid), 5.0), 160.0, "force"))
    return lim


def rss_mb() -> float:
    me = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    kids = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return max(me, kids) / 1024.0


def one(size: int, mono_max: int) -> dict:
    import toppra
    import toppra.algorithm
    import toppra.constraint
    from toppra.interpolator import AbstractGeometricPath

    from millpost.controller import ControllerModel, GrblPlanner, execute
    from millpost.schedule import PathGrid, ScheduleOptions, path_blocks, solve_path

    tp, smp = program(size)
    grid = PathGrid.from_samples(smp)
    blocks = path_blocks(grid, limits(grid, True))
    opts = ScheduleOptions(window=2000, overlap=200, processes=2, monolithic_max=4000)
    socp_opts = dataclasses.replace(opts, certify_gap=0.0)
    solve_path(grid.window(0, 3000), [b.window(0, 3000) for b in blocks], socp_opts)  # warm numba
    t0 = time.perf_counter()
    sch = solve_path(grid, blocks, opts)  # production default: certified O(N) profile or windowed SOCP
    seconds = time.perf_counter() - t0
    gap = sch.gap_bound if np.isfinite(sch.gap_bound) else None
    row = {"samples": len(grid), "ds_mm": float(np.mean(grid.ds)), "seconds": round(seconds, 3),
           "peak_rss_mb": round(rss_mb(), 1), "method": sch.method, "gap_bound": gap,
           "status": sch.status.value, "time_s": sch.time_s, "max_excess": max(sch.excess.values())}
    t0 = time.perf_counter()
    soc = solve_path(grid, blocks, socp_opts)
    row.update(socp_seconds=round(time.perf_counter() - t0, 3), socp_peak_rss_mb=round(rss_mb(), 1),
               socp_windows=soc.windows, socp_status=soc.status.value, socp_time_s=soc.time_s,
               socp_max_excess=max(soc.excess.values()))
    row["gap_vs_socp_windowed"] = sch.time_s / soc.time_s - 1
    if len(grid) <= mono_max:
        t0 = time.perf_counter()
        mono = solve_path(grid, blocks, ScheduleOptions(monolithic_max=10**9, certify_gap=0.0))
        row["monolithic_seconds"] = round(time.perf_counter() - t0, 3)
        row["gap_vs_monolithic"] = sch.time_s / mono.time_s - 1 if mono.status.ok else None
        row["socp_windowed_gap_vs_monolithic"] = soc.time_s / mono.time_s - 1 if mono.status.ok else None
    else:
        row["gap_vs_monolithic"] = None

    # velocity + acceleration only, against toppra on the same grid
    from millpost.schedule import AxisAcceleration, AxisVelocity, FeedLimit
    va = path_blocks(grid, [FeedLimit(1e4), AxisVelocity(VMAX), AxisAcceleration(AMAX)])  # toppra has no feed cap
    ours_va = solve_path(grid, va, socp_opts)

    class Path(AbstractGeometricPath):
        def __call__(self, ss, order=0):
            idx = np.clip(np.searchsorted(grid.s_mm, np.atleast_1d(ss) - 1e-12), 0, len(grid) - 1)
            arr = (smp.xyz_mm, grid.tangent, grid.curvature)[order][idx]
            return arr if np.ndim(ss) else arr[0]

        dof = 3
        path_interval = property(lambda self: np.array([grid.s_mm[0], grid.s_mm[-1]]))

    vlim = np.array([[-v, v] for v in VMAX])
    alim = np.array([[-a, a] for a in AMAX])
    t0 = time.perf_counter()
    algo = toppra.algorithm.TOPPRA(
        [toppra.constraint.JointVelocityConstraint(vlim),
         toppra.constraint.JointAccelerationConstraint(alim, toppra.constraint.DiscretizationType.Collocation)],
        Path(), gridpoints=grid.s_mm, solver_wrapper="seidel")
    sd = algo.compute_parameterization(0, 0)[1]
    row["toppra_seconds"] = round(time.perf_counter() - t0, 3)
    t_toppra = float(np.sum(2 * grid.ds / (sd[:-1] + sd[1:])))
    row["time_ratio_vs_toppra"] = ours_va.time_s / t_toppra

    # kinematics + junction, against the grbl-like planner at the max feed
    kin = path_blocks(grid, limits(grid, False))
    ours_kin = solve_path(grid, kin, socp_opts)
    grbl = ControllerModel(VMAX, AMAX, junction_deviation_mm=0.01, lookahead_blocks=16, planner=GrblPlanner())
    ex = execute(tp, grbl)
    row["time_ratio_vs_grbl_planner"] = ours_kin.time_s / ex.time_s
    row["time_s_full_limits"] = sch.time_s
    row["time_s_grbl_planner"] = ex.time_s
    return row


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    ap.add_argument("--mono-max", type=int, default=150_000)
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.one, args.mono_max)))
        return 0
    rows = []
    for n in args.sizes:  # each size in a fresh process so peak RSS is its own
        out = subprocess.run([sys.executable, __file__, "--one", str(n), "--mono-max", str(args.mono_max)],
                             capture_output=True, text=True, check=True)
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
    print(json.dumps({"rows": rows, "ds_mm_target": DS, "processes": 2, "window": 2000, "overlap": 200}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
