"""Corner speeds are the controller's: an optimized program replayed through the planner of the machine
that runs it exceeds no limit. LinuxCNC (and the look-ahead controllers modelled by its planner) rounds
a corner with a blend arc run at the faster of the two moves' feeds, so the slower move's first
millimetres see the faster feed; optimize lowers both F words around such a corner to the lowest limit
of the arc's reach (`controller.blend_zones`, `emit.blend_limit`), and checks the arcs of the
program as emitted (`Execution.blends`: LinuxCNC merges naive-CAM feeds into lines at the F words
written, whose arcs reach much further), writing it again until none runs faster than its limits.

The jobs are seeded random jobs (`random_jobs.py`) on machines with LinuxCNC's planner whose emitted
programs, before corners were planned with it, replayed at 1.13-3.5 times a limit on LinuxCNC's model.
The check re-reads the emitted text and runs it through `ControllerModel.from_machine` here (not the
pipeline's own replay), at the same places of the emitted moves; every limit must hold within 1e-6
(the solver's and the feed quantisation's slack is below it: F words are rounded down)."""

from __future__ import annotations

import numpy as np
import pytest

import millpost.emit.blends as blends_module
from millpost.controller import ControllerModel, Execution, LinuxCNCPlanner, execute_program, path_modes
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
    assert isinstance(model.planner, LinuxCNCPlanner)
    programmed = read_text(programmed_text, "programmed.nc")
    original = programmed.toolpath
    v = execute_program(program, model).speed_at(*emitted_positions(original, program.toolpath, smp.move,
                                                                    Execution.sample_fractions(smp)))
    limits = build_limits(job, smp, eng, original, modes=path_modes(programmed, model))
    return replay(job, smp, eng, limits, v).ratios


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
    monkeypatch.setattr(blends_module, "blend_limit", lambda samples, limit, *_: limit)
    monkeypatch.setattr(blends_module, "blend_excess", lambda samples, limit, arcs, *_: arcs[:0])
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


def _chain_job(tmp_path):
    """A slot of 0.05 mm moves (a CAM's naive output, within 1 µm of one line) at 1200 mm/min into a
    4.3° ramp of such moves capped at 300 mm/min (`plunge_feed_max_mm_min`), then on at the bottom, in
    MDF on the hobby router with LinuxCNC's controller under G64 P0.05 Q0.05: its canon layer merges
    each straight run into lines of up to 101 points (5 mm), so the blend arc between the slot and the
    ramp reaches about 2 mm into the ramp (half the shorter line) at the slot's feed, where blend
    zones per programmed move reach 12 µm."""
    from dataclasses import replace

    from millpost.job import Job
    from millpost.machine import Machine
    from millpost.materials import Material
    from millpost.settings import JobSettings
    from millpost.tools import Tool

    lines = ["G21 G90 G94 G64 P0.05 Q0.05", "T1 M6", "S18000 M3", "G0 X-4 Y0 Z2", "G1 Z-0.3 F1200"]
    x = -4.0
    for k in range(1, 281):  # the slot, X-4 to X10
        lines.append(f"X{x + 0.05 * k:.3f} Y{0.001 * (k % 2):.3f}")
    for k in range(1, 81):  # the ramp down 0.3 mm over X10 to X14
        lines.append(f"X{10 + 0.05 * k:.3f} Z{-0.3 - 0.3 * k / 80:.4f}")
    for k in range(1, 201):  # on at the bottom, X14 to X24
        lines.append(f"X{14 + 0.05 * k:.3f} Y{0.001 * (k % 2):.3f}")
    lines += ["G0 Z5", "M30"]
    program = tmp_path / "chain.nc"
    program.write_text("\n".join(lines) + "\n")
    machine = Machine.load("hobby-router")
    machine = replace(machine, controller=replace(machine.controller, kind="linuxcnc"))
    tool = Tool(diameter_mm=6.0, flutes=2, flute_length_mm=16.0, stickout_mm=24.0, number=1)
    return Job(path=tmp_path / "job.toml", program=program, output=tmp_path / "out.nc",
               material=Material.load("mdf"), machine=machine, tools={1: tool},
               stock_box=((0.0, -10.0, -5.0), (30.0, 10.0, 0.0)), cell_mm=0.1,
               settings=JobSettings(plunge_feed_max_mm_min=300.0))


def _chain_ratio(job, result) -> float:
    """The plunge cap's ratio where the machine's own planner runs the emitted program, re-read."""
    from millpost.engagement import engage
    from millpost.gcode import read_program
    from millpost.limits import build_limits

    program = read_program(job.program, job.reader_options())
    smp = result.samples
    _, eng, _ = engage(program, job.stock(), dict(job.tools), job.settings.ds_mm, job.allow,
                       clearance_mm=job.settings.air_clearance_mm)
    model = ControllerModel.from_machine(job.machine)
    emitted = read_text(result.text, "emitted.nc")
    v = execute_program(emitted, model).speed_at(*emitted_positions(program.toolpath, emitted.toolpath, smp.move,
                                                                    Execution.sample_fractions(smp)))
    limits = build_limits(job, smp, eng, program.toolpath, modes=path_modes(program, model))
    return replay(job, smp, eng, limits, v).ratios["plunge_feed"]


def test_blend_arcs_of_merged_chains_keep_the_plunge_cap(tmp_path, monkeypatch):
    from millpost.optimize import optimize

    job = _chain_job(tmp_path)
    result = optimize(job, progress=False)
    assert result.summary["limits"]["plunge_feed"] <= 1 + TOL
    assert _chain_ratio(job, result) <= 1 + TOL
    assert result.summary["blend_passes"]["over"] == 0
    # the check can fail: the F words of the first emission, from the zones of the programmed moves
    # alone, let the merged lines' arc run the slot's feed into the ramp
    monkeypatch.setattr(blends_module, "blend_excess", lambda samples, limit, arcs, *_: arcs[:0])
    unchecked = optimize(job, progress=False)
    assert _chain_ratio(job, unchecked) > 1.5


def test_merged_chains_run_no_slower_than_the_baseline(tmp_path):
    """The chain job's 0.05 mm moves at 500 blocks/s would each run at most 1500 mm/min, but LinuxCNC's
    canon merges them into 5 mm lines that its planner runs at the X axis rate (3000 mm/min): the block
    rate caps the blocks the planner receives. Capped per programmed move, the optimized program wrote
    F1500 where the baseline's F4690 runs 3000 (2.77 s against the baseline's 2.62 s)."""
    from millpost.optimize import optimize

    job = _chain_job(tmp_path)
    result = optimize(job, progress=False, trace=True)
    s, tr = result.summary, result.trace
    assert s["cycle_time_after_s"] <= s["cycle_time_baseline_s"] * (1 + 1e-3)
    assert s["limits"]["plunge_feed"] <= 1 + TOL
    # mid-slot the merged lines run at the X axis rate, above the 0.05 mm moves' block-rate speed
    mid = (tr["x"] > 0) & (tr["x"] < 7) & (np.abs(tr["z"] + 0.3) < 1e-9)
    x_rate = job.machine.axes["x"].vmax_mm_min
    assert x_rate > 1.5 * 0.05 * job.machine.controller.block_rate_Hz * 60
    assert np.median(tr["feed_executed_mm_min"][mid]) == pytest.approx(x_rate, rel=1e-3)


def _baseline_ratio(job, result) -> float:
    """The plunge cap's ratio where the machine's own planner runs the honest baseline (its feed per
    move, from the trace) on the programmed moves."""
    from millpost.engagement import engage
    from millpost.gcode import read_program

    program = read_program(job.program, job.reader_options())
    smp = result.samples
    feeds = program.toolpath.feed_mm_min.copy()
    base = result.trace["feed_baseline_mm_min"]
    cut = np.isfinite(base)
    feeds[smp.move[cut]] = base[cut]
    _, eng, _ = engage(program, job.stock(), dict(job.tools), job.settings.ds_mm, job.allow,
                       clearance_mm=job.settings.air_clearance_mm)
    model = ControllerModel.from_machine(job.machine)
    v = execute_program(program, model, feeds / 60.0).speed_at(smp.move, Execution.sample_fractions(smp))  # mm/s
    limits = build_limits(job, smp, eng, program.toolpath, modes=path_modes(program, model))
    return replay(job, smp, eng, limits, v).ratios["plunge_feed"]


def test_baseline_blend_arcs_keep_the_plunge_cap(tmp_path, monkeypatch):
    """The honest baseline runs one feed per programmed F, so the chain job's slot group runs F1200 up to
    the ramp, whose plunge cap is 300: the blend arc between them carried the slot's feed into the ramp
    (the baseline ran the cap 6.4 times, so "vs baseline" compared a safe program with an unsafe one).
    Its arcs are now kept within the caps like the optimized program's: the moves they reach run at the
    cap."""
    from millpost.optimize import optimize

    job = _chain_job(tmp_path)
    result = optimize(job, progress=False, trace=True)
    assert _baseline_ratio(job, result) <= 1 + TOL
    monkeypatch.setattr(blends_module, "blend_excess", lambda samples, limit, arcs, *_: arcs[:0])
    unchecked = optimize(job, progress=False, trace=True)
    assert _baseline_ratio(job, unchecked) > 1.5
    assert result.summary["cycle_time_baseline_s"] > unchecked.summary["cycle_time_baseline_s"]
