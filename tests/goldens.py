"""The golden summaries of the bundled sample jobs (sample_jobs/*/expected.json): tests/test_optimize.py
reads them and never writes them, so a missing or drifted golden fails instead of passing against itself.
After a change that moves them on purpose, rewrite them here and review the diff in the commit:

    PYTHONPATH=src python tests/goldens.py [JOB ...]     (no JOB: every sample job)
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

JOBS = Path(__file__).resolve().parents[1] / "sample_jobs"
# the summary's keys a golden holds
KEYS = ["status", "cycle_time_before_s", "cycle_time_after_s", "cycle_time_baseline_s", "samples"]


def path(name: str) -> Path:
    return JOBS / name / "expected.json"


def write(name: str) -> Path:
    """Optimize the sample job and write its golden summary."""
    from millpost.job import load_job
    from millpost.optimize import optimize
    summary = optimize(load_job(JOBS / name), progress=False).summary
    out = path(name)
    out.write_text(json.dumps({k: summary[k] for k in KEYS}, indent=2) + "\n")
    return out


def main(argv: list[str]) -> int:
    for name in argv or sorted(p.parent.name for p in JOBS.glob("*/job.toml")):
        print(write(name))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
