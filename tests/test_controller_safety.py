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
from millpost.replay import replay
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
    return replay(job, smp, eng, build_limits(job, smp, eng, original), v).ratios


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


def test_replay_reads_the_same_place_of_split_moves():
    # the replay maps a sample of the programmed move to its place on the emitted pieces (split lines
    # and arcs at rounded points, so arc lengths differ slightly): the same point of the path
    from millpost.emit import FeedPlan, write_feeds

    text = "G21 G90 G17\nG0 X0 Y0 Z1\nG1 Z-1 F300\nG1 X10.3 Y0.7 F600\nG2 X20 Y0 I4.85 J-0.35 F600\nG0 Z5\nM2\n"
    program = read_text(text, "p.nc")
    plan = FeedPlan.programmed(program)
    plan.fragments = {2: [(1 / 3, 500.0), (0.77777, 700.0), (1.0, 650.0)], 3: [(0.123456, 300.0), (1.0, 900.0)]}
    emitted = read_text(write_feeds(program, plan), "e.nc").toolpath
    assert len(emitted) == len(program.toolpath) + 3
    move = np.repeat(np.arange(len(program.toolpath)), 50)
    u = np.tile(np.linspace(0.0, 1.0, 50), len(program.toolpath))
    k, frac = emitted_positions(program.toolpath, emitted, move, u)
    gap = np.linalg.norm(program.toolpath.points(move, u) - emitted.points(k, frac), axis=1)
    assert gap.max() < 2e-4  # split points written to 4 decimals
    assert (emitted.feed_mm_min[k[(move == 2) & (u > 0.34) & (u < 0.77)]] == 700.0).all()
