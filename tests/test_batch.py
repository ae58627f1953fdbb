"""millpost batch on a 2-worker Dask LocalCluster: every job's program and summary are the same as
running it alone, a failing job is a row with its error while the others finish, and the results table
(CSV and HTML) links each report."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from millpost.cli import main
from millpost.job import load_job
from millpost.optimize import optimize

pytest.importorskip("dask.distributed")

ROOT = Path(__file__).resolve().parents[1]
JOBS = [ROOT / "sample_jobs" / "slotting", ROOT / "sample_jobs" / "drill_and_mill"]
KEYS = ("status", "samples", "cycle_time_before_s", "cycle_time_after_s", "cycle_time_baseline_s", "limits",
        "binding", "baseline_feed_mm_min", "notes")


def test_batch_gives_what_each_job_gives_alone(tmp_path):
    bad = tmp_path / "broken"
    bad.mkdir()
    (bad / "job.toml").write_text('program = "missing.nc"\nmaterial = "al6061"\nmachine = "vmc-small"\n'
                                  '[stock]\nbox = [[0, 0, -5], [10, 10, 0]]\n[tools.1]\ndiameter_mm = 6\n')
    out = tmp_path / "out"
    code = main(["batch", *map(str, JOBS), str(bad), "--out", str(out), "--quiet"])
    assert code == 1  # one job failed; the others ran
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert [r["status"] for r in rows] == ["solved", "solved", "error"]
    assert "missing.nc" in rows[2]["message"]
    page = (out / "results.html").read_text()
    for job, row in zip(JOBS, rows):
        alone = optimize(load_job(job), progress=False)
        folder = out / job.name
        assert (folder / load_job(job).output.name).read_text() == alone.text  # the same program, byte for byte
        summary = json.loads((folder / "summary.json").read_text())
        assert {k: summary[k] for k in KEYS} == json.loads(json.dumps({k: alone.summary[k] for k in KEYS}))
        assert float(row["cycle_time_after_s"]) == alone.summary["cycle_time_after_s"]
        assert (folder / "report.html").stat().st_size > 10_000
        assert f'href="{job.name}/report.html"' in page
