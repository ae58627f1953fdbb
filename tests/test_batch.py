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


def test_batch_on_a_running_scheduler(tmp_path):
    """--scheduler ADDRESS: the tasks go to a cluster that is already up (here a local one started by the
    test); job folders are numbered when two jobs share a name."""
    from dask.distributed import LocalCluster
    bad = tmp_path / "a" / "job"
    bad.mkdir(parents=True)
    (bad / "job.toml").write_text("program = 'none.nc'\n")
    other = tmp_path / "b" / "job"
    other.mkdir(parents=True)
    (other / "job.toml").write_text("not toml [\n")
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        out = tmp_path / "out"
        assert main(["batch", str(bad), str(other), "--out", str(out), "--scheduler", cluster.scheduler_address,
                     "--quiet"]) == 1
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert [r["status"] for r in rows] == ["error", "error"]
    assert "none.nc" in rows[0]["message"] and "file not found" in rows[0]["message"]
    assert rows[1]["message"]
    assert (out / "job").is_dir() and (out / "job-2").is_dir()
