"""Real third-party programs (tests/real_jobs/*/job.toml, programs under ../shared/data or, copied with their
licences, under tests/real_programs) through
`optimize` with the built-in machines (vmc-small, hobby-router, benchtop-belt, and the hobby router on
LinuxCNC), default feed policy:

- solved (no fallback to the programmed feeds);
- no slower than programmed on the controller model, unless the programmed feeds exceed a hard limit
  (then the status says `slower` and the replay of the programmed feeds shows the limit over 1);
- the executed speed within every speed cap the F words hold (max feed, plunge feed...), 0.5 % slack;
- no feed below the minimum-chip feed (or the programmed one, if lower) except on samples where the
  summary lists a hard limit as held, and none below the programmed feed but where a hard limit forces it;
- the emitted path within 1e-4 mm of the original (each emitted move's ends on the original move,
  read at full precision), and LinuxCNC's rs274 reads the emitted program as millpost does;
- at least 95 % of consecutive feed changes at least the feed step (5 %);
- every piece of a split move long enough for its F at the controller's block rate.

F words in and out and the cycle times are printed per job (`pytest -s`). Programs the reader refuses
with a clear error (e.g. cutter compensation) are reported as expected failures with that error.
Slow (minutes): every program runs twice.
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import machinist
import rs274_oracle
from conftest import SHARED_DATA
from millpost.controller import Execution, blend_zones, path_modes
from millpost.emit import emitted_positions
from millpost.errors import MillpostError
from millpost.gcode import read_program, read_text
from millpost.job import load_job
from millpost.machine import Machine
from millpost.optimize import optimize
from millpost.replay import feed_at_samples
from millpost.signals import controller_model
from millpost.toolpath import ARC_CW, RAPID

JOBS = sorted(p.parent for p in (Path(__file__).parent / "real_jobs").glob("*/job.toml"))
# the built-in machines, and the hobby router driven by LinuxCNC (whose canon merges naive-CAM feeds)
MACHINES = ["vmc-small", "hobby-router", "benchtop-belt", "hobby-router:linuxcnc"]
PATH_TOL_MM = 1e-4
REPO = Path(__file__).resolve().parents[1]


def _program_in_repo(folder: Path) -> bool:
    """Whether the job's program lies inside the repository (tests/real_programs), so it runs without ../shared."""
    program = (folder / tomllib.loads((folder / "job.toml").read_text())["program"]).resolve()
    return program.is_relative_to(REPO)


@pytest.fixture(scope="module", params=[(j, m) for j in JOBS for m in MACHINES],
                ids=[f"{j.name}-{m}" for j in JOBS for m in MACHINES])
def run(request):
    folder, machine = request.param
    if not SHARED_DATA.exists() and not _program_in_repo(folder):
        pytest.skip(f"{SHARED_DATA} is absent (third-party programs, not in the repo)")
    job = load_job(folder)
    name, _, kind = machine.partition(":")
    job = replace(job, machine=Machine.load(name))
    if kind:
        job = replace(job, machine=replace(job.machine, controller=replace(job.machine.controller, kind=kind)))
    job = replace(job, allow=job.allow | {"slower", "overload"})  # refusals are checked from their warnings (the other checks need the output)
    try:
        result = optimize(job, progress=False, trace=True)
    except MillpostError as exc:  # a feature the reader does not support yet, or a cutter-compensation
        # entry LinuxCNC would refuse with the guessed tool, named with file:line:column
        if "not supported" not in str(exc) and "cutter compensation entry move" not in str(exc):
            raise
        pytest.xfail(f"refused with a clear error: {exc}")
    s = result.summary
    print(f"\n{folder.name} on {machine}: {s['status']}; programmed {s['cycle_time_before_s']} s, baseline "
          f"{s['cycle_time_baseline_s']} s, optimized {s['cycle_time_after_s']} s; F words "
          f"{s['f_words']['programmed']} -> {s['f_words']['optimized']}; binding {json.dumps(s['binding_limits'])}")
    return folder.name, job, result


def test_solved_and_not_slower_without_cause(run):
    name, job, result = run
    s = result.summary
    assert s["status"] in ("solved", "slower"), s["message"]
    over = any(s["limits_programmed"].get(k, 0.0) > 1.0 for k in s["hard_limits"])
    if s["status"] == "slower":
        assert over, f"{name}: slower ({s['cycle_time_after_s']} > {s['cycle_time_before_s']} s) with no hard " \
                     f"limit exceeded by the programmed feeds"
    else:
        assert s["cycle_time_after_s"] <= s["cycle_time_before_s"] * (1 + 1e-3)
    # much slower, the program or a tool's work: refused (written here only because the fixture allows
    # it), naming the limits
    slower_max = job.settings.slower_max
    slow = (s["cycle_time_after_s"] > slower_max * s["cycle_time_before_s"]
            or any(row["optimized_s"] > slower_max * row["programmed_s"] for row in s["tools"].values()))
    loads = ("cutting_force", "power", "torque", "thrust", "tool_torque", "cutting_current")
    over_load = any(s["limits_programmed"].get(k, 0.0) > 1.0 for k in loads)
    assert any(n.startswith("warning (slower, allowed)") for n in s["notes"]) == (slow and over_load), name
    # a cut over a hard limit even at the lowest feed written: refused too (gate overload)
    assert any(n.startswith("warning (overload, allowed)") for n in s["notes"]) == bool(s["hard_limits_exceeded"])


def test_what_a_machinist_checks_descents_approaches_and_axis_rates(run):
    """Read from the programs' text (`machinist`): every descent below the stock's top within
    plunge_raise_max × its programmed F (a restart from an operation's start, a skipped operation or a
    broken tool makes it a plunge into solid material; the programmed F where the material has no
    end-cutting data), every descent into the clearance over the top (an approach) within its
    programmed F, and no F word above the axis rates of its move's direction."""
    name, job, result = run
    original = read_text(job.program.read_text(), str(job.program), job.reader_options())
    emitted = read_text(result.text, "emitted.nc", job.reader_options()).toolpath
    bounds = job.stock().bounds()
    top, c = float(bounds[1][2]), job.settings.air_clearance_mm
    reach = max(t.radius_mm for t in job.tools.values()) + c
    box = np.array([bounds[0][:2] - reach, bounds[1][:2] + reach])
    raise_max = job.settings.plunge_raise_max if job.material.end_cutting else 1.0
    inch = bool(original.move_inch.any())
    assert machinist.descent_excess(original.toolpath, emitted, top, raise_max, inch) == [], name
    assert machinist.approach_excess(original.toolpath, emitted, top, c, box, inch) == [], name
    vmax = [job.machine.axes[a].vmax_mm_min for a in "xyz"]
    assert machinist.axis_rate_excess(original.toolpath, emitted, vmax, inch) == [], name


def test_executed_speed_within_every_f_word_cap(run):
    """The speed caps the F words hold (`JobLimits.f_word_caps`: the maximum feed, the plunge feed cap,
    the air clearance...) hold where the machine's controller model runs the emitted program, blend
    arcs (LinuxCNC's run at the faster of two feeds, over its merged lines) included."""
    name, job, result = run
    s = result.summary
    assert s["f_word_caps"] and set(s["f_word_caps"]) <= set(s["limits"])
    over = {k: s["limits"][k] for k in s["f_word_caps"] if s["limits"][k] > 1.005}
    assert not over, f"{name}: the executed speed exceeds F-word caps {over}"


def test_no_feed_below_min_chip_unless_hard_forced(run):
    name, job, result = run
    tr = result.trace
    need = np.minimum(tr["feed_min_chip_mm_min"], np.nan_to_num(tr["feed_programmed_mm_min"], nan=np.inf))
    low, unforced = _runs_below(job, result, need)
    assert result.summary["below_min_chip"]["samples"] == int(low.sum())
    assert not unforced, f"{name}: below the minimum-chip feed with no hard cause: " + ", ".join(unforced[:5])


def test_no_feed_below_programmed_unless_hard_forced(run):
    """By default (`lower = "hard"`) only a hard limit lowers a feed below the programmed one: not the
    settling of F words into runs, nor the feed step (a change smaller than the step is written)."""
    name, job, result = run
    _, unforced = _runs_below(job, result, np.nan_to_num(result.trace["feed_programmed_mm_min"], nan=0.0))
    assert not unforced, f"{name}: below the programmed feed with no hard cause: " + ", ".join(unforced[:5])


def _runs_below(job, result, need: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The cutting samples whose emitted F is under `need` (mm/min per sample), and the emitted F words
    ("line N FX") among them that no hard limit forces. Forced: a hard limit caps the F somewhere on
    the run of moves it covers (one F word, settled over consecutive moves; a fragment's F is the lowest
    limit of the samples it touches, so the run's samples include the one before it and the one after
    it) under `need`, or one needs less than the chip floor there (a cut too heavy at any feed: the
    policy holds the floor); and the F is at that cap or floor but for one feed step down (the F
    words quantise down: `emit.write._stepped` makes a fall smaller than the step a whole step)."""
    emitted = read_text(result.text, "emitted.nc", job.reader_options()).toolpath
    program = read_program(job.program, job.reader_options())
    feed = feed_at_samples(program.toolpath, emitted, result.samples)
    tr = result.trace
    cut = (result.samples.kind != RAPID) & (tr["feed_min_chip_mm_min"] > 0)
    low = cut & (feed < need * (1 - 1e-3) - 0.1)  # F words are rounded down to 0.1 mm/min
    move, _ = emitted_positions(program.toolpath, emitted, result.samples.move,
                                Execution.sample_fractions(result.samples))
    f = emitted.feed_mm_min
    run_id = np.cumsum(np.r_[True, (f[1:] != f[:-1]) & (emitted.kind[1:] != RAPID)])
    sample_run = run_id[move]
    # the hard speed caps, and the schedule's speed where a hard limit without a cap of its own binds
    cap = np.minimum(tr["feed_hard_cap_mm_min"], np.where(tr["binding_hard"] == 1, tr["feed_schedule_mm_min"], np.inf))
    # a blending controller runs a corner's arc at the faster of its two feeds, so the F words on both sides
    # of a blended corner fit the lowest limit within the arc's reach (`controller.blend_zones`)
    model = controller_model(job)
    zones = blend_zones(program.toolpath, model, path_modes(program, model))[:, :2]
    ds, step = job.settings.ds_mm, job.settings.feed_step
    held_hard = np.zeros(len(result.samples), bool)
    for limit in result.summary["hard_limits"]:
        held_hard |= tr.get(f"held_{limit}", held_hard) > 0
    unforced = []
    for r in np.unique(sample_run[low]):
        on = sample_run == r
        on |= np.r_[on[1:], False] | np.r_[False, on[:-1]]
        for a, b in zones:
            near = (result.samples.s_mm >= a - ds) & (result.samples.s_mm <= b + ds)
            if (near & on).any():
                on |= near
        k = int(move[np.flatnonzero(sample_run == r)[0]])
        wanted = need[low & (sample_run == r)].min()
        if cap[on].min() < wanted * (1 - 1e-3):
            bound = cap[on].min()  # a hard limit caps the run under what was needed
        elif held_hard[on].any():
            bound = wanted  # a hard limit held at the floor
        else:
            unforced.append(f"line {emitted.line[k]} F{f[k]:g}")
            continue
        if f[k] < bound * (1 - step) * (1 - 1e-3) - 0.1:
            unforced.append(f"line {emitted.line[k]} F{f[k]:g} (more than a step under {bound:.1f})")
    return low, unforced


def _distance_to_move(tp, i: int, p: np.ndarray) -> float:
    """Distance (mm) from point p to move i of a toolpath (arcs as fine chords: error < 1e-6 mm)."""
    if tp.kind[i] >= ARC_CW:
        r = float(np.linalg.norm(tp.start[i] - tp.center[i]))
        n = max(2, int(math.ceil(tp.lengths()[i] / max(math.sqrt(8 * r * 1e-7), 1e-6))) + 1)
        pts = tp.points(np.full(n, i), np.linspace(0.0, 1.0, n))
    else:
        pts = np.array([tp.start[i], tp.end[i]])
    a, b = pts[:-1], pts[1:]
    d = b - a
    t = np.clip(((p - a) * d).sum(1) / np.maximum((d * d).sum(1), 1e-300), 0.0, 1.0)
    return float(np.linalg.norm(a + t[:, None] * d - p, axis=1).min())


def test_emitted_path_within_tolerance(run, tmp_path):
    name, job, result = run
    original = read_text(job.program.read_text(), str(job.program), job.reader_options()).toolpath
    emitted = read_text(result.text, "emitted.nc", job.reader_options()).toolpath
    j, worst = 0, 0.0
    for k in range(len(emitted)):
        if emitted.lengths()[k] <= 0:
            continue
        while j < len(original) and _distance_to_move(original, j, emitted.end[k]) > PATH_TOL_MM:
            j += 1  # the emitted move ends on a later original move (or the path is broken: fails below)
        assert j < len(original), f"{name}: emitted move {k} (line {emitted.line[k]}) is off the original path"
        worst = max(worst, _distance_to_move(original, j, emitted.end[k]))
    assert worst <= PATH_TOL_MM
    if rs274_oracle.RS274:
        out = tmp_path / "emitted.ngc"
        out.write_text(result.text)
        # the job's tool diameters, for the cutter compensation (G41/G42) rs274 applies as millpost does
        trace = rs274_oracle.run(out, diameters_mm={n: t.diameter_mm for n, t in job.tools.items()})
        ours = read_text(result.text, str(out), job.reader_options())
        assert rs274_oracle.mismatches(ours, trace, prefix=trace.error is not None) == []


def test_feed_changes_are_meaningful(run):
    """At least 95 % of the feed changes millpost writes are at least the feed step; a change between two
    feeds the program itself has there (CAMotics' wave steps its own F by 1-5 %) is the program's."""
    name, job, result = run
    tp = read_text(result.text, "emitted.nc", job.reader_options()).toolpath
    original = read_text(job.program.read_text(), str(job.program), job.reader_options()).toolpath
    programmed: dict[int, float] = {}  # the program's feed at each source line
    for line, feed in zip(original.line[original.kind != RAPID], original.feed_mm_min[original.kind != RAPID]):
        programmed.setdefault(int(line), float(feed))
    moving = (tp.kind != RAPID) & np.isfinite(tp.feed_mm_min)
    f = tp.feed_mm_min[moving]
    own = np.isclose(f, [programmed.get(int(line), np.nan) for line in tp.line[moving]], rtol=1e-9)
    changes = np.abs(np.diff(f)) / np.minimum(f[1:], f[:-1])
    changed = (changes > 1e-9) & ~(own[1:] & own[:-1])
    if changed.sum() < 5:
        return
    step = job.settings.feed_step
    share = float(np.mean(changes[changed] >= step * 0.98))
    assert share >= 0.95, f"{name}: only {share:.1%} of {int(changed.sum())} feed changes are >= {step:.0%}"


def test_block_rate_bounds_every_new_block(run):
    """A move of length L runs at most L × block rate. The blocks millpost adds (the pieces of a split
    move) are never so short that their F asks more than that; the program's own short moves keep the F
    in force (the controller slows there by itself and the schedule counts it: an F word carrying the cap
    of a micro-segment would write a crawl into the moves around it)."""
    name, job, result = run
    original = read_text(job.program.read_text(), str(job.program), job.reader_options()).toolpath
    tp = read_text(result.text, "emitted.nc", job.reader_options()).toolpath
    rate = job.machine.controller.block_rate_Hz
    key = lambda t: {(tuple(np.round(a, 6)), tuple(np.round(b, 6))) for a, b in zip(t.start, t.end)}  # noqa: E731
    old = key(original)
    new = np.array([(tuple(np.round(a, 6)), tuple(np.round(b, 6))) not in old for a, b in zip(tp.start, tp.end)], bool)
    piece = new & (tp.kind != RAPID) & (tp.lengths() > 0)
    over = tp.feed_mm_min[piece] / 60.0 > tp.lengths()[piece] * rate * (1 + 1e-6)
    assert not over.any(), f"{name}: {int(over.sum())} split pieces faster than the block rate allows"
