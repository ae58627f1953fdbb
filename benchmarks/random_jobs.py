"""Seeded random jobs end to end, at scale (issue 5: ≥ 10 000 jobs; the test suite runs 1 000).

Each job (tests/random_jobs.py: random program, tool, built-in material and machine, user limits and
cuts) goes through limits, schedule, emission, the controller model and the replay check. Prints one
JSON object: jobs, seconds, jobs_per_s, status counts, the worst replayed ratio per limit (value /
bound on the emitted program; must stay ≤ 1.005), the jobs over it, and the emitted cycle time as a
ratio of the honest baseline (per tool and programmed F one constant feed) measured in the same run
(median and quartiles), plus peak memory of the worker processes.

Run: python benchmarks/random_jobs.py [--jobs 10000] [--processes N]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from random_jobs import run_job  # noqa: E402


def one(seed: int) -> tuple[int, str, dict, float]:
    _, _, result = run_job(seed)
    s = result.summary
    base = s["cycle_time_baseline_s"]
    ratio = s["cycle_time_after_s"] / base if base else float("nan")
    return seed, s["status"], s["limits"], ratio


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=10_000)
    ap.add_argument("--processes", type=int, default=os.cpu_count() or 1)
    args = ap.parse_args()
    t0 = time.perf_counter()
    with multiprocessing.get_context("fork").Pool(args.processes) as pool:
        rows = pool.map(one, range(args.jobs), chunksize=20)
    seconds = time.perf_counter() - t0
    worst: dict[str, float] = {}
    over, status = [], {}
    for seed, st, limits, _ in rows:
        status[st] = status.get(st, 0) + 1
        for k, v in limits.items():
            worst[k] = max(worst.get(k, 0.0), v)
        if max(limits.values(), default=0.0) > 1.005:
            over.append(seed)
    ratios = np.array([r for *_, r in rows if np.isfinite(r)])
    rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(json.dumps({
        "jobs": args.jobs, "processes": args.processes, "seconds": round(seconds, 1),
        "jobs_per_s": round(args.jobs / seconds, 1), "status": status,
        "worst_limit_ratio": {k: round(v, 4) for k, v in sorted(worst.items())},
        "jobs_over_1.005": len(over), "first_over": over[:10],
        "cycle_time_ratio_vs_baseline": {q: round(float(np.quantile(ratios, p)), 4)
                                         for q, p in (("p25", 0.25), ("median", 0.5), ("p75", 0.75))},
        "peak_rss_mb_per_worker": round(rss, 1),
    }, indent=2))


if __name__ == "__main__":
    main()
