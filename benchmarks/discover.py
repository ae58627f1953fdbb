"""discover's search on a 1-hour 100 Hz log (360 k rows) with 11 candidate effects.

The rows come from one seeded measured run of tests/discover_runs.py (straight passes in a box, hidden sensor
lag, 3 % noise; aligned and mapped to the forward model once), repeated end to end in time to an
hour. The 11 candidates are the ten built-ins plus one registered here (sensor drift under another
name), so the search fits each, scores it on the held-out blocks and runs a second greedy round.

Prints one JSON object: rows, candidates, base_fit_s (the refitted base model alone, the baseline
measured in the same run), select_s (base + all candidates, two rounds), ratio_vs_base_fit, the same
as process CPU seconds (base_fit_cpu_s, select_cpu_s: on a machine shared with other work the wall
clock says more about the neighbours than about discover), peak_rss_mb (whole process), effects named.

    python benchmarks/discover.py [--minutes 60]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def tile(rows, copies: int):
    """The rows repeated `copies` times back to back in time (cut length keeps growing)."""
    from millpost.discover.rows import Rows
    span = rows.t_s[-1] - rows.t_s[0] + rows.dt_s
    cat = lambda v: np.concatenate([v] * copies)  # noqa: E731
    t = np.concatenate([rows.t_s + k * span for k in range(copies)])
    feats = {k: cat(v) for k, v in rows.features.items()}
    L = rows.features["cut_length_m"]
    feats["cut_length_m"] = np.concatenate([L + k * L.max() for k in range(copies)])
    fz_scale = None if rows.cuts.fz_scale is None else cat(rows.cuts.fz_scale)
    cuts = dataclasses.replace(rows.cuts, sample=cat(rows.cuts.sample), weight=cat(rows.cuts.weight),   # visited again
                               fz_scale=fz_scale)
    return Rows(t, {c: cat(v) for c, v in rows.measured.items()}, {c: cat(v) for c, v in rows.cut.items()},
                {c: {k: cat(v) for k, v in d.items()} for c, d in rows.columns.items()},
                {c: cat(v) for c, v in rows.fixed.items()}, feats, None, cat(rows.use), cuts)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=60.0)
    args = ap.parse_args()
    from discover_runs import make_run

    from millpost.discover.effects.sensor_drift import SensorDrift
    from millpost.discover.rows import from_log
    from millpost.discover.search import candidates, fit_base, select, split
    from millpost.job import load_job
    from millpost.measure import align

    with tempfile.TemporaryDirectory() as tmp:
        cache: dict = {}
        r = make_run(Path(tmp) / "job", 0, "sensor_lag", noise=0.03, signals_cache=cache)
        job = load_job(r.job_path)
        sig = cache[str(r.job_path)]
        rows = from_log(r.log, align(r.log, sig), sig, job)
    copies = max(1, int(round(args.minutes * 60 / (rows.t_s[-1] - rows.t_s[0]))))
    big = tile(rows, copies)

    class Copy(SensorDrift):
        name = "sensor_drift_copy"

    effects = candidates() | {"sensor_drift_copy": Copy}
    nominal = job.material.force_model("mechanistic").coefficients
    t0, c0 = time.perf_counter(), time.process_time()
    train, _ = split(big.t_s, big.use)
    fit_base(big, train)
    t_base, c_base = time.perf_counter() - t0, time.process_time() - c0
    t0, c0 = time.perf_counter(), time.process_time()
    sel = select(big, nominal, effects)
    t_sel, c_sel = time.perf_counter() - t0, time.process_time() - c0
    print(json.dumps({"rows": len(big), "hours": round((big.t_s[-1] - big.t_s[0]) / 3600, 3),
                      "candidates": len(effects), "base_fit_s": round(t_base, 3), "select_s": round(t_sel, 2),
                      "ratio_vs_base_fit": round(t_sel / t_base, 1), "base_fit_cpu_s": round(c_base, 3),
                      "select_cpu_s": round(c_sel, 2), "cpu_ratio_vs_base_fit": round(c_sel / c_base, 1),
                      "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
                      "effects": [e.name for e in sel.effects]}))


if __name__ == "__main__":
    main()
