"""Align a 1 M-row log with positions to its program (`millpost.measure.align`, the monotone match by
place), against the simplest position alignment measured in the same run: each row to its nearest path
sample (a k-d tree query, no order along the path; wrong where the path retraces itself).

The program: a calibration plan of slots at many feeds and two depths (its slots' approach and retract
rapids retrace each other); the log: the forward model's positions and forces at 1 kHz on a clock of its
own (offset, rate 0.05 % fast) with two 5 s feed holds, 0.002 mm position noise. Prints one JSON
object: rows, align_s and peak_rss_mb of each method (each in its own process), the share of rows whose
program time is within 2 ms of the truth, ratio_vs_nearest = ours / nearest (time), and the goal.

    python benchmarks/align.py [--workdir DIR] [--rows 1000000]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

RATE_HZ = 1000.0
HOLDS = ((0.3, 5.0), (0.7, 5.0))   # (fraction of the program, seconds standing still)


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def generate(work: Path, rows: int) -> dict:
    """The calibration folder, its signals' path (cached) and the log with its true program times."""
    import numpy as np

    from millpost.calibrate.plan import PlanRequest, make_plan
    from millpost.job import load_job
    from millpost.machine import Machine
    from millpost.materials import Material
    from millpost.measure import Log, write_log
    from millpost.signals import simulate
    from millpost.tools.cutter import Tool

    log_path = work / f"log_{rows}.npz"
    if log_path.exists():
        return {"log": str(log_path)}
    tool = Tool(diameter_mm=6, flutes=3, helix_deg=35, flute_length_mm=16, stickout_mm=24)
    program_s = rows / RATE_HZ - sum(s for _, s in HOLDS)
    fz = tuple(np.round(np.linspace(0.006, 0.03, max(int(program_s / 60), 2)), 5))
    stock = ((0.0, 0.0, -10.0), (200.0, 8.0 * len(fz) * 2 + 10.0, 0.0))
    plan = make_plan(tool, Material.load("al6061"), Machine.load("vmc-small"),
                     PlanRequest(stock=stock, rpm=6000, slot_fz_mm=fz, slot_ap_mm=(1.0, 2.0), steps=False,
                                 axis_test=False), dialect="linuxcnc")
    plan.write(work, tool, "al6061", "vmc-small", stock, cell_mm=0.2, ds_mm=0.5)
    sig = simulate(load_job(work / "job.toml"))
    np.savez(work / "path.npz", xyz=sig.xyz_mm, s=sig.s_mm, t=sig.t_s, speed=sig.speed_mm_s)
    rng = np.random.default_rng(1)
    # the log's clock: holds stop the program's time; its own rate and origin
    t_log = np.arange(rows) / RATE_HZ
    tau = t_log.copy()
    for frac, secs in HOLDS:
        at = frac * sig.t_s[-1]
        tau = np.where(tau > at, np.maximum(tau - secs, at), tau)
    tau = np.clip(tau, 0.0, sig.t_s[-1])
    cols = {"t_s": 7.5 + 1.0005 * t_log}
    for k, c in enumerate(("x_mm", "y_mm", "z_mm")):
        cols[c] = np.interp(tau, sig.t_s, sig.xyz_mm[:, k]) + rng.normal(0, 0.002, rows)
    for k, c in enumerate(("fx_N", "fy_N", "fz_N")):
        cols[c] = -np.interp(tau, sig.t_s, sig.force_tool_N[:, k]) + rng.normal(0, 2.0, rows)
    write_log(log_path, Log(cols))
    np.save(work / f"tau_{rows}.npy", tau)
    return {"log": str(log_path)}


def ours(work: Path, log_path: str) -> dict:
    import numpy as np

    from millpost.job import load_job
    from millpost.measure import align, read_log
    from millpost.signals import simulate

    sig = simulate(load_job(work / "job.toml"))
    log = read_log(log_path)
    align(log.select(slice(0, 1000)), sig)            # compile the kernels outside the timing
    before = rss_mb()
    t0 = time.perf_counter()
    al = align(log, sig)
    dt = time.perf_counter() - t0
    truth = np.load(str(log_path).replace("log_", "tau_").replace(".npz", ".npy"))
    moving = np.interp(truth, sig.t_s, sig.speed_mm_s) > 1.0
    ok = np.abs(al.tau_s - truth) <= 0.002
    return {"rows": len(log), "align_s": round(dt, 3), "peak_rss_mb": round(rss_mb(), 1),
            "rss_before_mb": round(before, 1), "method": al.method,
            "within_2ms": round(float(np.mean(ok[moving])), 5), "position_max_mm": al.summary()["position_max_mm"]}


def nearest(work: Path, log_path: str) -> dict:
    """Each row to its nearest path sample: no order, no clock."""
    import numpy as np
    from scipy.spatial import cKDTree

    from millpost.measure import read_log

    path = np.load(work / "path.npz")
    log = read_log(log_path)
    before = rss_mb()
    t0 = time.perf_counter()
    xyz = np.column_stack([log[c] for c in ("x_mm", "y_mm", "z_mm")])
    _, j = cKDTree(path["xyz"]).query(xyz, workers=-1)
    tau = path["t"][j]
    dt = time.perf_counter() - t0
    truth = np.load(str(log_path).replace("log_", "tau_").replace(".npz", ".npy"))
    moving = np.interp(truth, path["t"], path["speed"]) > 1.0
    return {"align_s": round(dt, 3), "peak_rss_mb": round(rss_mb(), 1), "rss_before_mb": round(before, 1),
            "within_2ms": round(float(np.mean(np.abs(tau - truth)[moving] <= 0.002)), 5)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--workdir", default="/tmp/millpost-bench-align")
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--phase", choices=("generate", "ours", "nearest"), help=argparse.SUPPRESS)
    ap.add_argument("--log", help=argparse.SUPPRESS)
    args = ap.parse_args()
    work = Path(args.workdir)
    work.mkdir(parents=True, exist_ok=True)
    if args.phase:
        out = {"generate": lambda: generate(work, args.rows), "ours": lambda: ours(work, args.log),
               "nearest": lambda: nearest(work, args.log)}[args.phase]()
        json.dump(out, sys.stdout)
        return

    def phase(name: str, log: str | None = None) -> dict:
        cmd = [sys.executable, __file__, "--workdir", str(work), "--rows", str(args.rows), "--phase", name] + (
            ["--log", log] if log else [])
        res = subprocess.run(cmd, capture_output=True, text=True, env=dict(os.environ))
        if res.returncode:
            sys.exit(f"phase {name} failed:\n{res.stderr}")
        return json.loads(res.stdout.strip().splitlines()[-1])

    log = phase("generate")["log"]
    result = phase("ours", log)
    baseline = phase("nearest", log)
    result.update({"log": log, "nearest": baseline,
                   "ratio_vs_nearest": round(result["align_s"] / baseline["align_s"], 2),
                   "goal": "align_s <= 30, peak_rss_mb <= 1024"})
    json.dump(result, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
