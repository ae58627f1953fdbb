"""Corner speeds are the controller's: an optimized program replayed through the planner of the machine
that runs it exceeds no limit. LinuxCNC (and the look-ahead controllers modelled by its planner) rounds
a corner with a blend arc run at the faster of the two moves' feeds, so the slower move's first
millimetres see the faster feed; optimize lowers both F words around such a corner to the lowest limit
of the arc's reach (`controller.blend_zones`, `schedule.feeds.blend_limit`).

The jobs are seeded random jobs (`random_jobs.py`) on machines with LinuxCNC's planner whose emitted
programs, before corners were planned with it, replayed at 1.13-3.5 times a limit on LinuxCNC's model.
The check re-reads the emitted text and runs it through `ControllerModel.from_machine` here (not the
pipeline's own replay), at the same places of the emitted moves; every limit must hold within 1e-6
(the solver's and the feed quantisation's slack is below it: F words are rounded down)."""

from __future__ import annotations

import numpy as np
import pytest

import millpost.optimize as optimize_module
from millpost.controller import ControllerModel, Execution, execute_program
from millpost.emit import emitted_positions
from millpost.gcode import read_text
from millpost.limits import build_limits
from millpost.replay import limit_ratios
from random_jobs import random_job, run_job

SEEDS = [195, 284, 318, 432, 488, 670, 726, 822]
TOL = 1e-6


def replayed(job, eng, result, programmed_text: str) -> dict[str, float]:
    """Limit ratios of the emitted program run by the machine's own planner."""
    program = read_text(result.text, "emitted.nc")
    smp = result.samples
    model = ControllerModel.from_machine(job.machine)
    assert model.planner == "linuxcnc"
    original = read_text(programmed_text, "programmed.nc").toolpath
    v = execute_program(program, model).speed_at(*emitted_positions(original, program.toolpath, smp.move,
                                                                    Execution.sample_fractions(smp)))
    return limit_ratios(smp, build_limits(job, smp, eng, original), v, job)


def _run(seed: int):
    """The random job, its engagement, optimize's result and the programmed text."""
    return (*run_job(seed), random_job(np.random.default_rng(seed))[1])


@pytest.mark.parametrize("seed", SEEDS)
def test_optimized_program_exceeds_no_limit_on_linuxcnc_planner(seed):
    job, eng, result, text = _run(seed)
    ratios = replayed(job, eng, result, text)
    over = {k: v for k, v in ratios.items() if v > 1 + TOL}
    assert not over, over
    assert max(result.summary["limits"].values()) <= 1 + 1e-4  # the pipeline's own replay agrees


def test_without_blend_limits_the_corners_overrun(monkeypatch):
    # the check can fail: the same job with F words that ignore the blend arcs exceeds its limits
    monkeypatch.setattr(optimize_module, "blend_limit", lambda samples, limit, *_: limit)
    job, eng, result, text = _run(822)
    ratios = replayed(job, eng, result, text)
    assert ratios["deflection"] > 1.5
