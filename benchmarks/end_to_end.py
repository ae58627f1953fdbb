"""End-to-end optimize benchmark: prints one JSON object {"rows": [...], "baseline": {...}, ...}.

Jobs: seeded adaptive-pocket programs of the requested block counts, with the tool, material and
machine of `sample_jobs/adaptive_pocket` (6 mm 3-flute flat end mill, Al 6061, vmc-small, stock
cells 0.05 mm). The generator cuts rows of adaptive slots (trochoidal loops of radius 4 mm in 36
linear blocks a loop, 6 mm deep) across a 200 mm wide block, each row starting beside the stock;
the loop advance (0.5–0.7 mm) and the programmed feed (1200–1800 mm/min) vary per row from the seed.

Per size, each run in its own process: `wall_s`, `cpu_s` (user + system, the process and its worker
processes), `peak_mb` (largest resident set of the process or of one worker), `samples`,
`stage_s` (wall seconds per stage, from the summary), `cycle_time_after_s`, `status`, `method`.
The baseline, measured in the same run, is the 10 k job with `--solver clarabel --jobs 1`
(Clarabel windows everywhere in one process); every row carries `wall_ratio` and `cpu_ratio`
(seconds per block against the baseline's) and `peak_ratio`, and the 10 k row its cycle time
against the baseline's (`cycle_vs_clarabel` = T / T_clarabel − 1; the goal is within 0.1 %).

Usage: python benchmarks/end_to_end.py [--sizes 10000 100000 300000] [--repeat 1] [--jobs N]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SAMPLE = Path(__file__).resolve().parents[1] / "sample_jobs" / "adaptive_pocket"
WIDTH_MM, PITCH_MM, R_MM, DEPTH_MM = 200.0, 20.0, 4.0, -6.0


def program(blocks: int, seed: int = 1) -> tuple[str, int]:
    """An adaptive-pocket program of exactly `blocks` loop blocks (plus header and links), and its row count."""
    rnd = random.Random(seed)
    out = ["(adaptive pocket rows, 6 mm 3F flat, Al 6061)", "G21 G90 G17 G94", "T1 M6", "S9000 M3", "G0 Z10"]
    left, row = blocks, 0
    while left > 0:
        step, feed = rnd.uniform(0.5, 0.7), rnd.randrange(1200, 1801, 50)
        y0 = PITCH_MM * row + 7.0
        x = -8.0
        out += [f"G0 X{x + R_MM:.3f} Y{y0:.3f}", "G0 Z2", f"G1 Z{DEPTH_MM:g} F400", f"F{feed}"]
        while x + R_MM <= WIDTH_MM - 3.0 and left > 0:
            for k in range(1, 37):
                th = 2 * math.pi * k / 36
                out.append(f"G1 X{x + R_MM * math.cos(th) + step * k / 36:.3f} "
                           f"Y{y0 + R_MM * math.sin(th):.3f}")
                left -= 1
                if not left:
                    break
            x += step
        out += ["G0 Z10"]
        row += 1
    out += ["M30"]
    return "\n".join(out) + "\n", row


def write_job(folder: Path, blocks: int, seed: int) -> Path:
    text, rows = program(blocks, seed)
    (folder / "program.nc").write_text(text)
    job = (SAMPLE / "job.toml").read_text()
    job = job.replace("box = [[0, 0, -10], [50, 14, 0]]", f"box = [[0, 0, -10], [{WIDTH_MM:g}, {rows * PITCH_MM:g}, 0]]")
    assert "box = [[0, 0, -10], [50" not in job, "sample job's stock line changed: update the benchmark"
    (folder / "job.toml").write_text(job)
    return folder / "job.toml"


def run_one(job_path: str, solver: str | None, jobs: int | None) -> dict:
    """In a fresh process: optimize the job and report times, memory and the summary figures."""
    from millpost.job import load_job
    from millpost.optimize import optimize
    from millpost.schedule import ScheduleOptions

    options = ScheduleOptions.from_choices(solver=solver, jobs=jobs)
    t0, c0 = time.perf_counter(), os.times()
    result = optimize(load_job(job_path), progress=False, options=options)
    c1 = os.times()
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    s = result.summary
    return {"wall_s": round(time.perf_counter() - t0, 2),
            "cpu_s": round(c1.user - c0.user + c1.system - c0.system + c1.children_user + c1.children_system
                           - c0.children_user - c0.children_system, 2),
            "peak_mb": round(max(me.ru_maxrss, kids.ru_maxrss) / 1024, 1), "samples": s["samples"],
            "stage_s": s["stage_s"], "cycle_time_after_s": s["cycle_time_after_s"], "status": s["status"],
            "method": s.get("schedule_methods", {})}


def measure(blocks: int, seed: int, solver: str | None, jobs: int | None, repeat: int) -> dict:
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        job = write_job(Path(tmp), blocks, seed)
        for _ in range(repeat):
            cmd = [sys.executable, __file__, "--one", str(job), "--solver", solver or "auto",
                   "--jobs", str(jobs or 0)]
            out = subprocess.run(cmd, check=True, capture_output=True, text=True)
            runs.append(json.loads(out.stdout))
    best = min(runs, key=lambda r: r["cpu_s"])  # the machine is shared: the least-disturbed run
    best.update(blocks=blocks, solver=solver or "auto", jobs=jobs or os.cpu_count(),
                cpu_s_runs=[r["cpu_s"] for r in runs], wall_s_runs=[r["wall_s"] for r in runs])
    print(json.dumps(best), file=sys.stderr, flush=True)  # progress: one line per measured job
    return best


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 300_000])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=0, help="processes (0: all cores)")
    ap.add_argument("--solver", default="auto")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(run_one(args.one, None if args.solver == "auto" else args.solver, args.jobs or None)))
        return
    base = measure(10_000, args.seed, "clarabel", 1, args.repeat)
    rows = []
    for n in args.sizes:
        r = measure(n, args.seed, None, args.jobs or None, args.repeat)
        per = n / base["blocks"]
        r.update(wall_ratio=round(r["wall_s"] / (base["wall_s"] * per), 3),
                 cpu_ratio=round(r["cpu_s"] / (base["cpu_s"] * per), 3),
                 peak_ratio=round(r["peak_mb"] / base["peak_mb"], 3))
        if n == base["blocks"]:
            r["cycle_vs_clarabel"] = round(r["cycle_time_after_s"] / base["cycle_time_after_s"] - 1, 6)
        rows.append(r)
    print(json.dumps({"baseline": base, "rows": rows, "cores": os.cpu_count(),
                      "goals": {"100k_wall_s": 20, "100k_peak_mb": 700, "300k_wall_s": 100,
                                "cycle_vs_clarabel": 0.001}}, indent=1))


if __name__ == "__main__":
    main()
