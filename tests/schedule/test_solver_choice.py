"""`--solver clarabel` / `[limits] solver` forces Clarabel on every segment; the default accepts the
certified O(N) profile where it applies. Both give the same cycle time within 0.1 %."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from millpost.cli import main
from millpost.errors import ConfigError
from millpost.job import load_job
from millpost.optimize import optimize
from millpost.schedule import ScheduleOptions

POCKET = Path(__file__).resolve().parents[2] / "sample_jobs" / "adaptive_pocket"


def test_auto_and_clarabel_agree_on_the_adaptive_pocket():
    job = load_job(POCKET)
    auto = optimize(job, progress=False, options=ScheduleOptions.from_choices(jobs=1)).summary
    ref = optimize(job, progress=False, options=ScheduleOptions.from_choices(solver="clarabel", jobs=1)).summary
    assert auto["status"] == ref["status"] == "solved"
    assert auto["schedule_methods"]["reach"] >= 1  # the certificate closed on this job
    assert ref["schedule_methods"]["reach"] == 0 and ref["schedule_methods"]["windows"] >= 1
    assert auto["cycle_time_after_s"] <= ref["cycle_time_after_s"] * 1.001
    assert auto["cycle_time_after_s"] >= ref["cycle_time_after_s"] * 0.999


def test_solver_job_key_and_flag(tmp_path):
    folder = tmp_path / "job"
    shutil.copytree(POCKET, folder)
    toml = folder / "job.toml"
    toml.write_text(toml.read_text() + '\n[limits]\nsolver = "clarabel"\n')
    assert load_job(folder).settings.solver == "clarabel"
    toml.write_text(toml.read_text().replace('solver = "clarabel"', 'solver = "gurobi"'))
    with pytest.raises(ConfigError, match="solver"):
        load_job(folder)
    with pytest.raises(ValueError, match="solver"):
        ScheduleOptions.from_choices(solver="gurobi")
    with pytest.raises(SystemExit):
        main(["optimize", str(POCKET), "--jobs", "0"])
