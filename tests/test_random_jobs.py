"""Seeded random jobs end to end (issue 5): every emitted program, replayed through the machine's own
controller model (grbl's planner on the benchtop machine, LinuxCNC's blending planner on the others)
and the force model, exceeds no limit (beyond the summary's rounding to 4 decimals). Jobs come from
`random_jobs.py` (random programs, tools, built-in materials and machines, user limits and cuts).

Two checks: the pipeline's own replay (`summary["limits"]`, every job), and an independent one on
every tenth job, which re-evaluates the force model's nonlinear law (Kienzle's f_z^(1−mc), not the
linear bound the scheduler used) in the time domain at the feed per tooth the controller actually
runs, against the tool's breaking force, the deflection limit and the spindle curve (within 0.5 %:
the linear bound is a chord of the nonlinear law)."""

from __future__ import annotations

import multiprocessing
import os

import numpy as np
import pytest

from millpost.gcode import read_text
from millpost.signals import running_rpm
from millpost.toolpath import RAPID
from millpost.tools.beam import ToolBeam
from random_jobs import run_job

COUNT = 1000
TOL = 1.005  # the independent nonlinear check
REPLAY_TOL = 1.0 + 1e-4  # the pipeline's replay: the summary rounds ratios to 4 decimals


def _check(seed: int) -> dict:
    job, eng, result = run_job(seed)
    s = result.summary
    out = {"seed": seed, "status": s["status"], "limits": s["limits"], "held": s["held"]}
    emitted = read_text(result.text, "emitted.nc").toolpath
    feeds = emitted.feed_mm_min[emitted.kind != RAPID]
    out["feed_over"] = float(np.nanmax(feeds, initial=0.0)) / min(job.machine.feed_cap_mm_min,
                                                                   job.settings.feed_max_mm_min or np.inf)
    if seed % 10 == 0 and s["status"] in ("solved", "slower"):
        out["independent"] = _independent(job, eng, result)
    return out


def _independent(job, eng, result) -> dict:
    """Ratios to bound of peak force, deflection and power from `model.predict` at the executed feed."""
    tool = job.tools[1]
    tr = result.trace
    smp = result.samples
    cut = (smp.kind != RAPID) & (eng.ap_mm > 0) & (smp.rpm > 0)
    rpm = running_rpm(job, np.where(smp.rpm > 0, smp.rpm, 1.0))
    fz = tr["feed_executed_mm_min"] / (tool.flutes * rpm)
    loads = job.material.force_model(job.settings.model).predict(eng, fz, rpm, tool)
    beam = ToolBeam.of(tool)
    k_xy = min(job.machine.axes["x"].stiffness_N_per_mm, job.machine.axes["y"].stiffness_N_per_mm)
    ratios = {
        "cutting_force": loads.peak_force_xy_N / beam.breaking_force_N(eng.ap_mm),
        "deflection": loads.peak_force_xy_N * (beam.compliance_mm_per_N(eng.ap_mm, at_tip=True) + 1 / k_xy)
        / job.settings.deflection_mm,
        "power": loads.power_W / np.maximum(job.machine.spindle.power_available_W(rpm), 1e-9),
    }
    out = {}
    for name, r in ratios.items():
        # where the policy held the bound (min-chip feed) the pipeline reports it
        keep = cut & (tr[f"held_{name}"] == 0)
        out[name] = float(np.max(r[keep], initial=0.0))
    return out


@pytest.fixture(scope="module")
def outcomes():
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(max(1, min(4, os.cpu_count() or 1))) as pool:
        return pool.map(_check, range(COUNT), chunksize=10)


def test_emitted_programs_exceed_no_limit(outcomes):
    bad = [(o["seed"], {k: v for k, v in o["limits"].items() if v > REPLAY_TOL})
           for o in outcomes if max(o["limits"].values(), default=0.0) > REPLAY_TOL]
    assert not bad, f"{len(bad)} of {COUNT} jobs exceed a limit on replay: {bad[:5]}"


def test_emitted_feeds_within_machine_and_user_limits(outcomes):
    assert max(o["feed_over"] for o in outcomes) <= 1.0 + 1e-9


def test_solver_does_not_fall_back(outcomes):
    failed = [o["seed"] for o in outcomes if o["status"].startswith("fallback")]
    assert len(failed) <= 0.01 * COUNT, failed[:10]


def test_independent_force_evaluation_exceeds_no_limit(outcomes):
    checked = [o for o in outcomes if "independent" in o]
    assert len(checked) >= 0.09 * COUNT
    worst = {k: max(o["independent"][k] for o in checked) for k in checked[0]["independent"]}
    assert all(v <= TOL for v in worst.values()), worst
