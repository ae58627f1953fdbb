"""The feed policy of `millpost.limits` end to end on cuts of known geometry (full-width slots of
growing depth, engagement given directly): a heavier cut never gets a higher feed than a lighter one;
by default only hard limits lower a programmed feed, and only as far as they need; no feed goes below
the minimum-chip feed unless a hard limit is exceeded there, which the summary lists; every limit
carries its identity."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from millpost.controller import path_modes
from millpost.engagement import Engagement
from millpost.gcode import read_text
from millpost.job import Job, load_job
from millpost.limits import HARD, QUALITY, build_limits
from millpost.machine import Machine
from millpost.materials import Material
from millpost.optimize import optimize, schedule_program
from millpost.settings import JobSettings
from millpost.signals import controller_model, predict
from millpost.toolpath import RAPID
from millpost.tools import Tool

DEPTHS = [0.3, 1.0, 3.0, 6.0, 10.0, 14.0]  # mm, one 10 mm slot each, heavier and heavier
PROGRAMMED = 1500.0  # mm/min


def _job(lower: str, material: str = "al6061", **extra) -> tuple[Job, str]:
    tool = Tool(diameter_mm=6.0, flutes=3, flute_length_mm=16.0, stickout_mm=24.0, number=1)
    job = Job(path=Path("t/job.toml"), program=Path("t/p.nc"), output=Path("t/o.nc"),
              material=Material.load(material), machine=Machine.load("vmc-small"), tools={1: tool},
              stock_box=((-5.0, -5.0, -20.0), (80.0, 5.0, 0.0)), settings=JobSettings(lower=lower, **extra),
              allow=frozenset({"slower", "overload"}))  # deliberately heavy cuts: the policy, not the refusal, is tested
    lines = ["G21 G90 G94", "T1 M6", "S8000 M3", "G0 X0 Y0 Z1", f"G1 Z0 F{PROGRAMMED:g}"]
    lines += [f"X{10 * (k + 1)}" for k in range(len(DEPTHS))] + ["G0 Z5", "M30"]
    return job, "\n".join(lines) + "\n"


def _run(lower: str, material: str = "al6061", **extra):
    job, text = _job(lower, material, **extra)
    program = read_text(text, "p.nc")
    samples = program.toolpath.resample(0.1)
    R = job.tools[1].radius_mm
    st, ex = np.zeros(len(samples)), np.full(len(samples), math.pi)
    depth = np.zeros(len(samples))
    first = int(np.flatnonzero(program.toolpath.line == 6)[0])  # the first slot's move
    for k, ap in enumerate(DEPTHS):
        depth[samples.move == first + k] = ap
    parts = [Engagement.uniform(st[i:i + 1], ex[i:i + 1], max(depth[i], 1e-3), R, slices=4) for i in range(len(st))]
    eng = Engagement.concatenate(parts)
    air = depth == 0
    eng.dz_mm[air], eng.ap_mm[air], eng.ae_mm[air], eng.area_mm2[air] = 0.0, 0.0, 0.0, 0.0
    eng.feed_dir = np.tile([1.0, 0.0, 0.0], (len(st), 1))
    result = schedule_program(job, program, samples, eng, trace=True)
    emitted = read_text(result.text, "o.nc").toolpath
    slot_feeds = [float(emitted.feed_mm_min[(emitted.line == 6 + k) & (emitted.kind != RAPID)].min())
                  for k in range(len(DEPTHS))]
    return job, program, samples, eng, result, np.array(slot_feeds)


@pytest.fixture(scope="module", params=["hard", "all"])
def run(request):
    return request.param, _run(request.param)


def test_heavier_cut_never_faster(run):
    lower, (job, program, samples, eng, result, feeds) = run
    assert result.summary["status"] in ("solved", "slower")
    assert np.all(np.diff(feeds) <= 1e-6 * feeds[:-1]), feeds


def test_only_hard_limits_lower_by_default(run):
    lower, (job, program, samples, eng, result, feeds) = run
    lim = build_limits(job, samples, eng, program.toolpath, modes=path_modes(program, controller_model(job)))
    hard_over = result.summary["limits_programmed"]
    hard = {k for k in hard_over if k in result.summary["hard_limits"]}
    cut = samples.kind != RAPID
    for k, ap in enumerate(DEPTHS):
        sel = cut & (samples.move == samples.move[np.flatnonzero(samples.line == 6 + k)[0]])
        v = PROGRAMMED / 60.0
        over_hard = any(np.any(l.constraint.alpha[sel] * v + l.constraint.beta[sel] > l.constraint.limit[sel] * 1.001)
                        for l in lim if hasattr(l.constraint, "alpha") and l.kind == HARD)
        if lower == "hard" and not over_hard:
            assert feeds[k] >= PROGRAMMED * (1 - 1e-3), (ap, feeds[k])
    # what was lowered obeys every limit it was lowered for
    assert all(result.summary["limits"][k] <= 1.005 for k in hard)


def test_feeds_not_below_min_chip_unless_hard_listed(run):
    lower, (job, program, samples, eng, result, feeds) = run
    floor = result.trace["feed_min_chip_mm_min"]
    held = result.summary["held"]
    for k, f in enumerate(feeds):
        sel = samples.line == 6 + k
        need = min(float(floor[sel].max()), PROGRAMMED)
        if f < need * (1 - 1e-3) - 0.1:  # F words are rounded down to 0.1 mm/min
            assert any(h["kind"] == "hard" and 6 + k in h["lines"] for h in held.values()), (k, f, need)


def test_hard_limit_needing_less_than_min_chip_is_held_and_listed():
    # a tool held to a tenth of its bending strength (safety factor 20) 14 mm deep in stainless steel:
    # the force is exceeded even at the minimum-chip feed; the feed is held there (min(min-chip,
    # programmed)), never crawls, and the lines are listed
    job, program, samples, eng, result, feeds = _run("hard", "ss304", tool_safety_factor=20.0)
    held = result.summary["held"]
    assert "cutting_force" in held and held["cutting_force"]["kind"] == "hard"
    last = 6 + len(DEPTHS) - 1
    assert last in held["cutting_force"]["lines"]
    floor = float(result.trace["feed_min_chip_mm_min"][samples.line == last].max())
    assert feeds[-1] >= min(floor, PROGRAMMED) * (1 - 1e-3) - 0.1
    assert feeds[-1] <= PROGRAMMED
    # the optimized program still breaks the tool's force bound there, and the summary says by how much:
    # the peak force over its bound before the policy, read from the trace
    tr = result.trace
    over = np.nanmax(tr["peak_force_N"] / tr["peak_force_limit_N"])
    assert over > 1.005
    assert result.summary["hard_limits_exceeded"]["cutting_force"] == pytest.approx(over, rel=1e-3)
    # and how far the programmed feeds break it: the peak force at the programmed feed (every slot reaches
    # it) over the same bound before the policy, not over the held bound (the policy's own load)
    cut = tr["ap_mm"] > 0
    at_programmed = predict(job, samples, eng, np.where(cut, PROGRAMMED / 60.0, 0.0), peaks=True)
    programmed_over = np.nanmax(at_programmed.peak_force_xy_N[cut] / tr["peak_force_limit_N"][cut])
    assert programmed_over > over
    assert result.summary["limits_programmed"]["cutting_force"] == pytest.approx(programmed_over, rel=1e-3)


def test_held_limits_say_how_far_over_their_bound(run):
    """A limit the policy held reports the largest value over its bound before the policy in the
    optimized program: for the deflection, the trace's deflection over its limit."""
    lower, (job, program, samples, eng, result, feeds) = run
    held, tr = result.summary["held"], result.trace
    assert "deflection" in held  # the deep slots bend the 6 mm tool over its limit at the programmed feed
    cut = tr["ap_mm"] > 0
    assert held["deflection"]["over_bound"] == pytest.approx(
        float(np.nanmax(tr["deflection_mm"][cut] / tr["deflection_limit_mm"][cut])), rel=2e-3)


def test_nothing_reported_exceeded_where_no_hard_limit_is_held(run):
    lower, (job, program, samples, eng, result, feeds) = run
    forced = {k for k, h in result.summary["held"].items() if h["kind"] == "hard"}
    assert set(result.summary["hard_limits_exceeded"]) <= forced


def test_every_limit_carries_its_identity(run):
    lower, (job, program, samples, eng, result, feeds) = run
    lim = build_limits(job, samples, eng, program.toolpath, modes=path_modes(program, controller_model(job)))
    kinds = {l.name: l.kind for l in lim}
    assert kinds["cutting_force"] == kinds["power"] == kinds["torque"] == kinds["feed"] == HARD
    assert kinds["deflection"] == kinds["chip_load_max"] == kinds["chip_load_min"] == QUALITY
    assert {l.name for l in lim if l.controller} >= {"axis_acceleration", "junction"}
    assert set(result.summary["binding"]) <= {l.effect for l in lim}


def test_binding_shares_are_shares_of_the_time_the_program_runs(tmp_path):
    """A 100 mm full slot 1 mm deep from a standstill at one programmed feed (Al 6061, 6 mm 3-flute):
    the chip-load maximum sets the feed along the slot, and the axes only accelerate over v²/(2a) at its
    start, well under 1 % of its time. The shares are weighted by the time the emitted program runs
    (a schedule's speed at a standstill's first step may be far below what the controller runs there;
    weighted by it, one step took most of the time and 'inertia' most of the share)."""
    (tmp_path / "job.toml").write_text(
        'program = "p.nc"\nmaterial = "al6061"\nmachine = "vmc-small"\n'
        "[stock]\nbox = [[-5, -5, -5], [110, 5, 0]]\ncell_mm = 0.1\n"
        "[tools.1]\ndiameter_mm = 6\nflutes = 3\nshape = \"flat\"\nflute_length_mm = 16\nstickout_mm = 24\n")
    (tmp_path / "p.nc").write_text("G21 G90 G94\nT1 M6\nS9000 M3\nG0 X-4 Y0 Z1\nG1 Z-1 F300\n"
                                   "G1 X105 F1500\nG0 Z5\nM30\n")
    job = load_job(tmp_path)
    result = optimize(job, progress=False, trace=True)
    tr = result.trace
    slot = (tr["line"] == 6) & (tr["ae_mm"] > 5.9)
    v = float(np.median(tr["feed_executed_mm_min"][slot])) / 60.0
    a = min(ax.amax_mm_s2 for ax in job.machine.axes.values())
    assert np.mean(tr["chip_mm"][slot] >= 0.99 * tr["chip_limit_mm"][slot]) > 0.95  # the chip load sets it
    accel_share = (v / (2 * a)) / (100.0 / v)  # the time of a ramp to v, over the slot's time
    assert accel_share < 0.01
    shares = result.summary["binding"]
    assert shares.get("chip load", 0.0) >= 0.9, shares
    assert shares.get("inertia", 0.0) <= 0.05, shares


def test_a_plunge_cap_relative_to_the_program_never_lowers_the_move_after_it(tmp_path):
    """A plunge at F100 into plywood, then the cut at F300 (a Tweakie.CNC program): the controller blends
    the corner at the bottom at the faster feed, so the programmed program itself runs the plunge's end
    above 2 × F100. The plunge cap (plunge_raise_max × the programmed feed) is relative to the program:
    the programmed program never reads over it, and the F300 move is not lowered for it (it was written
    F200, and the summary said the programmed feeds broke a hard limit, 1.12 ×)."""
    (tmp_path / "job.toml").write_text(
        'program = "p.nc"\nmaterial = "plywood"\nmachine = "vmc-small"\n'
        "[stock]\nbox = [[0, -10, -6], [40, 10, 0]]\ncell_mm = 0.1\n"
        "[tools.1]\ndiameter_mm = 3.175\nflutes = 2\nshape = \"flat\"\nflute_length_mm = 12\nstickout_mm = 20\n")
    (tmp_path / "p.nc").write_text("G21 G90 G94\nT1 M6\nS12000 M3\nG0 X5 Y0 Z6\nG1 Z-2 F100\n"
                                   "G1 X5.04 Y0.02 F300\nG1 X30 Y0.5\nG0 Z5\nM30\n")
    result = optimize(load_job(tmp_path), progress=False)
    s = result.summary
    assert s["limits_programmed"]["plunge_feed"] <= 1.0 + 1e-9
    assert s["limits"]["plunge_feed"] <= 1.005
    emitted = read_text(result.text, "o.nc").toolpath
    fed = emitted.kind != RAPID
    level = fed & (np.abs(emitted.start[:, 2] + 2.0) < 1e-9) & (np.abs(emitted.end[:, 2] + 2.0) < 1e-9)
    assert emitted.feed_mm_min[level].min() >= 300.0
    into = fed & (emitted.end[:, 2] < emitted.start[:, 2]) & (emitted.end[:, 2] < 0.0)
    assert emitted.feed_mm_min[into].max() <= 200.0 + 1e-9  # the plunge's cut: at most 2 × F100


@pytest.mark.parametrize("machine", ["vmc-small", "hobby-router"])
def test_a_micro_arc_is_the_controllers_to_slow_for_not_the_f_words(machine, tmp_path):
    """CAM output with arcs of radius 0.0127 mm (0.0005 in, ~0.02 µm long) where two arcs meet (a
    pygcode Alien.tap): √(a·r) is ~5 mm/s there. LinuxCNC's planner clamps each arc at √(a_n·r) by itself,
    so the F words need not carry it: written on the ≥ 2 mm fragments around it, the cap ran millimetres
    of cut at F340 and the optimized program came out slower than the one-feed baseline (Alien.tap 26.4 s
    against 24.4 s), its lines listed below the chip floor (here one line on each machine). Now no line is below the floor, the program is no
    slower than the baseline, and the replay (the controller's own speed there) keeps every limit."""
    (tmp_path / "job.toml").write_text(
        f'program = "p.nc"\nmaterial = "mdf"\nmachine = "{machine}"\n'
        "[stock]\nbox = [[-40, -40, -6], [40, 40, 0]]\ncell_mm = 0.1\n"
        "[tools.1]\ndiameter_mm = 3.175\nflutes = 2\nshape = \"flat\"\nflute_length_mm = 12\nstickout_mm = 20\n")
    lines = ["G21 G90 G94 G17", "T1 M6", "S18000 M3", "G0 X0 Y0 Z2", "G1 Z-1.5 F300", "G1 X-10 F800"]
    x, y = -10.0, 0.0
    for k in range(12):  # arcs of radius 8 mm, 3 mm long, a micro-arc where each pair meets
        x, y = x + (0.9 if k % 2 else -0.9), y + 3.0
        lines.append(f"G2 X{x:.5f} Y{y:.5f} R8")
        x, y = x - 0.00003, y + 0.00025
        lines.append(f"G3 X{x:.5f} Y{y:.5f} R0.0127")
    lines += ["G0 Z5", "M30"]
    (tmp_path / "p.nc").write_text("\n".join(lines) + "\n")
    result = optimize(load_job(tmp_path), progress=False)
    s = result.summary
    assert s["status"] == "solved"
    assert s["below_min_chip"]["line_count"] == 0
    assert s["cycle_time_after_s"] <= s["cycle_time_baseline_s"] * (1 + 1e-3)
    assert max(s["limits"].values()) <= 1.005
