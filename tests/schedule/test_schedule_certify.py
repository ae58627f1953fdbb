"""The certified O(N) profile on the full constraint set of real jobs (current rows with √b terms,
current slew, soft chip floors), against Clarabel on the same rows: random jobs from `random_jobs.py`."""

from __future__ import annotations

import numpy as np
import pytest

from millpost.controller import path_modes
from millpost.gcode import read_text
from millpost.limits import build_limits
from millpost.schedule import ScheduleOptions, schedule_samples
from millpost.schedule.assemble import soft_floor
from millpost.schedule.rows import PathGrid, StepRows
from millpost.signals import controller_model
from random_jobs import random_engagement, random_job


def _cost(grid: PathGrid, blocks: list, b: np.ndarray, penalty: float) -> float:
    """Traversal time plus the soft floors' penalty (the conic objective in seconds), rest to rest
    (Clarabel returns b ≈ 1e-8·vref² for the fixed b = 0 at the ends: worth 5e-5 of a short segment)."""
    ds = grid.ds
    v = np.sqrt(np.maximum(b, 0.0))
    v[0] = v[-1] = 0.0
    t = float(np.sum(2 * ds / (v[:-1] + v[1:])))
    if not penalty:
        return t
    floor = soft_floor(blocks, len(b))
    node = np.zeros(len(b))
    node[:-1] += ds / 2
    node[1:] += ds / 2
    vref = float(np.sqrt(min(blk.b_hi.max() for blk in blocks if hasattr(blk, "b_hi"))))
    return t + penalty * float(np.sum(node * np.maximum(floor - b, 0.0))) / vref**3


def _random_problem(seed: int):
    """The samples and limits of random job `seed` (tests/random_jobs.py) with a random engagement."""
    rng = np.random.default_rng(seed)
    job, text = random_job(rng)
    program = read_text(text, "random.nc")
    samples = program.toolpath.resample(job.settings.ds_mm)
    eng = random_engagement(rng, samples, job.tools[1])
    return samples, build_limits(job, samples, eng, program.toolpath, modes=path_modes(program, controller_model(job)))


@pytest.mark.parametrize("seed", range(40))
def test_certified_profile_matches_clarabel_on_random_jobs(seed):
    samples, limits = _random_problem(seed)
    auto = schedule_samples(samples, limits, ScheduleOptions(processes=1))
    ref = schedule_samples(samples, limits, ScheduleOptions.from_choices(solver="clarabel", jobs=1))
    grid = PathGrid.from_samples(samples)
    blocks = [blk for lim in limits for blk in lim.blocks(grid)]
    for (lo, hi, a), (_, _, c) in zip(auto.segments, ref.segments):
        assert c.method == "socp"
        if a.method != "reach":
            continue
        g = grid.window(lo, hi)
        bl = [blk.window(lo, hi) for blk in blocks]
        assert all(v <= 1e-9 for v in a.excess.values()), a.excess  # every row holds exactly (√b)
        # the proven gap holds against Clarabel, and the profile is never 0.1 % slower than Clarabel's;
        # it may be faster: Clarabel's own answer carries its tolerance and linearised rows (seed 9:
        # feeds near 1 mm/s against a 100 mm/s scale, Clarabel 2.5 % slower than the certified optimum)
        j_a, j_c = _cost(g, bl, a.b, 10.0), _cost(g, bl, c.b, 10.0)
        assert j_a <= j_c * (1 + a.gap_bound) * (1 + 1e-5)
        assert a.time_s <= _cost(g, [], c.b, 0.0) * (1 + 1e-3)


def test_certified_profile_covers_current_slew():
    """Some random jobs with current-slew rows are accepted by the certificate (not all fall back)."""
    accepted = 0
    for seed in range(40):
        samples, limits = _random_problem(seed)
        grid = PathGrid.from_samples(samples)
        if not any(isinstance(blk, StepRows) for lim in limits for blk in lim.blocks(grid)):
            continue
        sched = schedule_samples(samples, limits, ScheduleOptions(processes=1))
        accepted += sum(s.method == "reach" for _, _, s in sched.segments)
    assert accepted >= 5
