"""The replay check predicts through the one forward model (`millpost.signals`): each limit's signal is
the very load its schedule rows bound, the exact model agrees with the schedule's affine loads where
they are exact and stays under them where they are tangents, and the kinematics of the executed
profile stay within the machine's accelerations, as the controller model plans them."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from millpost.controller import path_modes
from millpost.engagement import engage
from millpost.gcode import read_program
from millpost.job import load_job
from millpost.limits import build_limits
from millpost.optimize import optimize
from millpost.replay import baseline_feeds, replay
from millpost.schedule import SpeedLoad
from millpost.signals import predict
from millpost.signals import controller_model
from millpost.toolpath import RAPID

JOBS = Path(__file__).resolve().parents[1] / "sample_jobs"


@pytest.fixture(scope="module")
def drill_and_mill():
    """Slots, a contour and drilled holes (end cutting): the job, its samples, engagement, limits and the
    executed speed (mm/s) of the optimized program."""
    job = load_job(JOBS / "drill_and_mill")
    program = read_program(job.program, job.reader_options())
    samples, eng, _ = engage(program, job.stock(), dict(job.tools), job.settings.ds_mm, job.allow,
                             progress=False)
    limits = build_limits(job, samples, eng, program.toolpath, modes=path_modes(program, controller_model(job)))
    executed = optimize(job, progress=False, trace=True).trace["feed_executed_mm_min"] / 60.0
    return job, samples, eng, limits, executed


def test_each_limit_signal_is_its_rows_load(drill_and_mill):
    job, samples, eng, limits, _ = drill_and_mill
    rng = np.random.default_rng(5)
    v = rng.uniform(1.0, 60.0, len(samples))
    sig = predict(job, samples, eng, v, loads=limits.loads)
    cut = samples.kind != RAPID
    checked = 0
    for lim in limits:
        if isinstance(lim.constraint, SpeedLoad):
            rows = lim.constraint.alpha * v + lim.constraint.beta
            np.testing.assert_allclose(lim.signal(sig, slice(None))[cut], rows[cut], rtol=1e-9, atol=1e-12,
                                       err_msg=lim.name)
            checked += 1
    assert checked >= 10  # cutting force, power, torque, deflection, thrust, tool torque, chip load, 3 currents


def test_exact_model_against_the_schedules_affine_loads(drill_and_mill):
    job, samples, eng, limits, _ = drill_and_mill
    assert job.settings.model == "mechanistic"  # affine in the feed: the flank loads are exact
    v = np.nan_to_num(samples.feed_mm_s, nan=0.0)  # the tangents' reference feed
    exact = predict(job, samples, eng, v)
    affine = predict(job, samples, eng, v, loads=limits.loads)
    cut = (samples.kind != RAPID) & (eng.ap_mm > 1e-9)
    end = cut & (np.nan_to_num(eng.descent) > 0) if eng.descent is not None else np.zeros(len(samples), bool)
    assert end.sum() > 100 and (cut & ~end).sum() > 1000  # the job plunges and drills, and mills
    flank = cut & ~end
    np.testing.assert_allclose(exact.torque_Nm[flank], affine.torque_Nm[flank], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(exact.force_tool_N[flank], affine.force_tool_N[flank], rtol=1e-9, atol=1e-9)
    # the end's thrust and torque (Kienzle, concave in the feed) stay under their tangent, which the
    # schedule bounds; the exact model includes them (no thrust without them on a drill)
    assert np.all(exact.force_tool_N[end, 2] <= affine.force_tool_N[end, 2] * (1 + 1e-9) + 1e-9)
    assert np.all(exact.torque_Nm[end] <= affine.torque_Nm[end] * (1 + 1e-9) + 1e-12)
    assert np.max(exact.force_tool_N[end, 2]) > 50.0


def test_replayed_kinematics_stay_within_the_machines_accelerations(drill_and_mill):
    job, samples, eng, limits, executed = drill_and_mill
    checked = replay(job, samples, eng, limits, executed)
    sig = predict(job, samples, eng, executed, loads=limits.loads)  # the whole program at once
    amax = np.array([job.machine.axes[a].amax_mm_s2 for a in "xyz"])
    peak = np.abs(sig.axis_accel_mm_s2).max(axis=0)
    assert np.all(peak <= amax * 1.01), (peak, amax)  # the controller plans within them
    assert np.any(peak >= amax * 0.9)  # and uses them
    limit_A = np.array([job.machine.axes[a].motor.current_limit_A for a in "xyz"])
    keep = (samples.kind != RAPID) & ~limits.held["cutting_current"]
    assert checked.ratios["current"] == pytest.approx(float(np.max(np.abs(sig.axis_current_A[keep]) / limit_A)))


def test_replay_in_chunks_is_the_whole_programs(drill_and_mill, monkeypatch):
    """The replay predicts in chunks (memory) with one neighbour each side for the path acceleration:
    ratios and per-sample columns are those of chunks larger than the program (to rounding: np.gradient
    takes a chunk whose samples are evenly spaced with its uniform-step formula)."""
    import millpost.replay as replay_module
    job, samples, eng, limits, executed = drill_and_mill
    monkeypatch.setattr(replay_module, "LOAD_CHUNK", 10 * len(samples))
    whole = replay(job, samples, eng, limits, executed)
    monkeypatch.setattr(replay_module, "LOAD_CHUNK", 97)
    chunked = replay(job, samples, eng, limits, executed)
    assert len(samples) > 20 * 97
    assert chunked.ratios.keys() == whole.ratios.keys()
    for key, ratio in whole.ratios.items():
        assert chunked.ratios[key] == pytest.approx(ratio, rel=1e-12, abs=0), key
    for key, column in whole.trace_columns().items():
        np.testing.assert_allclose(chunked.trace_columns()[key], column, rtol=1e-12, atol=0, err_msg=key)


@pytest.mark.parametrize("plunge_f", [300.0, 100.0])
def test_baseline_per_programmed_feed_closed_form(tmp_path, plunge_f):
    """The baseline has one constant feed per tool and programmed F, each the highest its own moves
    allow. A 6 mm 3-flute flat end mill at 9000 rpm in al6061 plunges 1 mm (end enclosed: the chip-load
    limit takes plunge_fz_ratio of the chip load h_max on the axial feed per tooth, so
    F = z·n·h_max·ratio = F520) and slots 1 mm deep at F500 (the full slot passes φ = 90°, no chip
    thinning: F = z·n·h_max = F2082); at this depth both are held by the chip load, the slot's force and
    deflection allow more. Each group gets exactly its floored cap; the plunge then runs at most
    plunge_raise_max (2) × its programmed F, as a CAM user's separate plunge feed: F520 from F300, F200
    from F100."""
    (tmp_path / "p.nc").write_text(
        f"G21 G90 G17\nT1 M6\nS9000 M3\nG0 X5 Y5 Z2\nG1 Z-1 F{plunge_f:g}\nG1 X55 F500\nG0 Z5\nM30\n")
    (tmp_path / "job.toml").write_text(
        'program = "p.nc"\nmaterial = "al6061"\nmachine = "vmc-small"\n[stock]\nbox = [[0, 0, -5], [60, 10, 0]]\n'
        'cell_mm = 0.1\n[tools.1]\ndiameter_mm = 6\nflutes = 3\nshape = "flat"\nhelix_deg = 35\n'
        'flute_length_mm = 16\nstickout_mm = 24\n')
    job = load_job(tmp_path / "job.toml")
    program = read_program(job.program, job.reader_options())
    samples, eng, _ = engage(program, job.stock(), dict(job.tools), job.settings.ds_mm, job.allow,
                             progress=False)
    limits = build_limits(job, samples, eng, program.toolpath, modes=path_modes(program, controller_model(job)))
    feeds, per_tool, _ = baseline_feeds(program, samples, limits)
    h_max = job.material.chip_load_mm(6.0)[1]
    ratio = job.material.strategies.plunge_fz_ratio
    z_n = 3 * 9000.0  # teeth per minute
    plunge, slot = min(math.floor(z_n * h_max * ratio), 2 * plunge_f), math.floor(z_n * h_max)
    assert per_tool == {1: {plunge_f: plunge, 500.0: slot}}
    line = program.toolpath.line
    assert feeds[line == 6].min() == feeds[line == 6].max() == slot
    assert feeds[line == 5].max() == plunge
