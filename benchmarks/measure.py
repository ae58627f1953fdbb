"""Align and fit a 1-hour measurement log at 1 kHz (3.6 M rows): a calibration program of 74 slots at 37
feeds and two depths (about an hour of cutting), its forward-model signals, and a seeded synthetic log
(forces, spindle power, positions; 3 % noise; unknown offset). Prints one JSON object:

- read_s (the CSV log through `read_log`), simulate_s (engagement and signals of the program, once per
  program), align_s, fit_s (one observation per steady cut, mechanistic and Kienzle fits), total_s =
  read + align + fit, peak_rss_mb of that phase, the alignment error and coefficient errors;
- the same pipeline with the simple implementations a first script would use (Python's csv module,
  a direct correlation lag by lag over ±3 s on the force channel, per-cut boolean masks), measured in the
  same run, and ratio_vs_simple = simple total / ours.

Each phase runs in its own process (peak memory per phase). The generated log is cached in --workdir.

    python benchmarks/measure.py [--workdir DIR] [--minutes 60] [--rate 1000]
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

TRUE_OFFSET_S = 2.345


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def generate(work: Path, minutes: float, rate: float) -> dict:
    """The calibration folder (program, plan, job) and the synthetic log, unless cached."""
    import numpy as np

    from millpost.calibrate.plan import PlanRequest, make_plan
    from millpost.job import load_job
    from millpost.machine import Machine
    from millpost.materials import Material
    from millpost.measure import write_log
    from millpost.measure.synthetic import synthetic_log
    from millpost.signals import simulate
    from millpost.tools.cutter import Tool

    log_path = work / f"log_{minutes:g}min_{rate:g}Hz.csv"
    if log_path.exists():
        return {"log": str(log_path)}
    tool = Tool(diameter_mm=6, flutes=3, helix_deg=35, flute_length_mm=16, stickout_mm=24)
    slots = int(round(74 * minutes / 60))   # about a minute of cutting per slot on average
    fz = tuple(np.round(np.linspace(0.006, 0.03, max(slots // 2, 2)), 5))
    stock = ((0.0, 0.0, -10.0), (200.0, 8.0 * len(fz) * 2 + 10.0, 0.0))
    plan = make_plan(tool, Material.load("al6061"), Machine.load("vmc-small"),
                     PlanRequest(stock=stock, rpm=6000, slot_fz_mm=fz, slot_ap_mm=(1.0, 2.0), steps=False,
                                 axis_test=False, idle_rpm=(3000, 6000)), dialect="linuxcnc")
    plan.write(work, tool, "al6061", "vmc-small", stock, cell_mm=0.2, ds_mm=0.5)
    sig = simulate(load_job(work / "job.toml"))
    log = synthetic_log(sig, rate_hz=rate, offset_s=TRUE_OFFSET_S, noise=0.03, lead_s=2.0, tail_s=2.0,
                        columns=("fx_N", "fy_N", "fz_N", "spindle_power_W", "x_mm", "y_mm", "z_mm"),
                        position_noise_mm=0.002, seed=1)
    write_log(log_path, log)
    return {"log": str(log_path)}


def ours(work: Path, log_path: str) -> dict:
    import numpy as np

    from millpost.calibrate.coefficients import fit_models
    from millpost.calibrate.logfit import observations, steady_samples
    from millpost.calibrate.plan import read_plan
    from millpost.job import load_job
    from millpost.measure import align, read_log
    from millpost.signals import simulate

    job = load_job(work / "job.toml")
    t0 = time.perf_counter()
    sig = simulate(job)
    simulate_s = time.perf_counter() - t0
    moves = read_plan(work / "plan.csv")
    steady = steady_samples(sig, moves)
    before = rss_mb()
    t0 = time.perf_counter()
    log = read_log(log_path)
    t1 = time.perf_counter()
    al = align(log, sig)
    t2 = time.perf_counter()
    obs = observations(log, al, sig, job, steady)
    fit = fit_models(sig.engagement.select(obs.index), obs.measurements, obs.tools, job.material, log_path)
    t3 = time.perf_counter()
    truth = np.array([631.0, 99.0, 273.0, 13.0, 10.0, 2.8])
    return {"rows": len(log), "cuts": len(obs.index), "simulate_s": round(simulate_s, 3), "read_s": round(t1 - t0, 3),
            "align_s": round(t2 - t1, 3), "fit_s": round(t3 - t2, 3), "total_s": round(t3 - t0, 3),
            "peak_rss_mb": round(rss_mb(), 1), "rss_before_mb": round(before, 1),
            "offset_error_s": abs(al.offset_s - TRUE_OFFSET_S), "alignment": al.method,
            "max_coefficient_error": float(np.max(np.abs(fit.mechanistic.coef_ / truth - 1)))}


def simple(work: Path, log_path: str) -> dict:
    """What a first script would do: csv module, lag-by-lag direct correlation, masks per cut."""
    import csv

    import numpy as np

    from millpost.calibrate.plan import read_plan
    from millpost.job import load_job
    from millpost.signals import simulate

    job = load_job(work / "job.toml")
    sig = simulate(job)
    moves = read_plan(work / "plan.csv")
    t0 = time.perf_counter()
    with open(log_path, newline="") as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    header, data = rows[0], np.array(rows[1:], dtype=float)
    cols = {h: data[:, i] for i, h in enumerate(header)}
    t1 = time.perf_counter()
    t = cols["t_s"]
    dt = float(np.median(np.diff(t)))
    grid = np.arange(t[0], t[-1], dt)
    a = np.interp(grid, t, cols["fy_N"])
    b = np.interp(np.arange(0, sig.t_s[-1], dt), sig.t_s, -sig.force_tool_N[:, 1])
    a, b = a - a.mean(), b - b.mean()
    best, lag_best = -np.inf, 0
    n = min(len(a), len(b))
    for lag in range(-int(3 / dt), int(3 / dt) + 1):      # offsets of ±3 s around the log's start
        lo = max(lag, 0)
        m = min(n, len(a) - lo) - max(-lag, 0)
        score = float(np.dot(a[lo:lo + m], b[max(-lag, 0):max(-lag, 0) + m]))
        if score > best:
            best, lag_best = score, lag
    offset = t[0] + lag_best * dt
    t2 = time.perf_counter()
    tau = t - offset
    means = []
    for m in moves:
        if m.kind != "slot":
            continue
        on = sig.line == m.line
        ts = sig.t_s[on]
        sel = (tau > ts[0] + 0.2 * (ts[-1] - ts[0])) & (tau < ts[-1] - 0.2 * (ts[-1] - ts[0]))
        means.append([cols[c][sel].mean() for c in ("fx_N", "fy_N", "fz_N")])
    t3 = time.perf_counter()
    return {"read_s": round(t1 - t0, 3), "align_s": round(t2 - t1, 3), "fit_s": round(t3 - t2, 3),
            "total_s": round(t3 - t0, 3), "peak_rss_mb": round(rss_mb(), 1), "cuts": len(means),
            "offset_error_s": abs(offset - TRUE_OFFSET_S)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--workdir", default="/tmp/millpost-bench-measure")
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--phase", choices=("generate", "ours", "simple"), help=argparse.SUPPRESS)
    ap.add_argument("--log", help=argparse.SUPPRESS)
    args = ap.parse_args()
    work = Path(args.workdir)
    work.mkdir(parents=True, exist_ok=True)
    if args.phase:
        out = {"generate": lambda: generate(work, args.minutes, args.rate), "ours": lambda: ours(work, args.log),
               "simple": lambda: simple(work, args.log)}[args.phase]()
        json.dump(out, sys.stdout)
        return

    def phase(name: str, log: str | None = None) -> dict:
        cmd = [sys.executable, __file__, "--workdir", str(work), "--minutes", str(args.minutes), "--rate",
               str(args.rate), "--phase", name] + (["--log", log] if log else [])
        res = subprocess.run(cmd, capture_output=True, text=True, env=dict(os.environ))
        if res.returncode:
            sys.exit(f"phase {name} failed:\n{res.stderr}")
        return json.loads(res.stdout.strip().splitlines()[-1])

    t0 = time.perf_counter()
    log = phase("generate")["log"]
    generate_s = time.perf_counter() - t0
    result = phase("ours", log)
    baseline = phase("simple", log)
    result.update({"log": log, "log_mb": round(os.path.getsize(log) / 1e6, 1), "generate_s": round(generate_s, 1),
                   "simple": baseline, "ratio_vs_simple": round(baseline["total_s"] / result["total_s"], 2),
                   "goal": "total_s <= 30, peak_rss_mb <= 1024"})
    json.dump(result, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
