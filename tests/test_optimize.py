"""`millpost optimize` end to end on the bundled sample jobs: golden summaries (fail on drift beyond the
stated tolerances), no limit exceeded on the emitted program replayed through the controller and force
models, the path unchanged (and accepted by LinuxCNC's rs274 when installed), and the solver-failure
fallback to the programmed feeds. The expected summaries are read here, never written: tests/goldens.py
rewrites them."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import goldens
import rs274_oracle
from millpost import optimize as opt_module
from millpost.cli import main
from millpost.errors import ConfigError
from millpost.gcode import read_program, read_text
from millpost.job import load_job
from millpost.optimize import optimize
from millpost.schedule import Status

JOBS = Path(__file__).resolve().parents[1] / "sample_jobs"
NAMES = ["adaptive_pocket", "slotting", "ball_roughing", "drill_and_mill", "offset_pocket", "sawcut_facing",
         "forging_contour"]
# cycle time under the baseline (per tool and programmed F the best constant feed: a careful machinist's
# tuned cutting, plunge and lead-in feeds), both timed by the machine's own planner: at least 25 % on two
# roughing samples. The adaptive pocket's many short segments meet vmc-small's contour tolerance
# (G64 P0.005) at every corner, where the controller, not the F word, sets the speed: 17 % (LinuxCNC
# itself runs the optimized program with G64 P0.005 in 42.3 s, the model says 42.5 s; without P LinuxCNC
# takes 31.0 s).
ROUGHING_GOAL = {"adaptive_pocket": 0.15, "slotting": 0.25, "drill_and_mill": 0.25, "offset_pocket": 0.25,
                 "sawcut_facing": 0.25, "forging_contour": 0.25}
# Below the goal (figures: programmed / baseline / optimized), since the air clearance (air within 3 mm of
# the stock as loaded keeps its programmed feed) and the baseline per programmed F: the gains measured
# before came from air moves raised right beside the stock and from one feed per tool held by its slowest
# group.
SHORT_OF_GOAL = {
    "slotting": "uniform full-width slots (60.6 / 27.0 / 27.0 s): the F700 slots pass φ = 90° (no chip "
                "thinning) and the F900 contour cuts 1 mm everywhere, so the chip-load maximum holds each at one "
                "feed along its whole length (F2082, F2707) in both, and the F300 plunges in the air beside the "
                "block keep F300; its 25 % came from a contour that ran 1 mm outside the block at F24000",
    "adaptive_pocket": "beside the block's -X face the entry plunge, the first loops' fronts and each loop's "
                       "turns within ~0.3 mm of the edge of what it swept are air not known clear within 3 mm of "
                       "the stock and keep F400/F1500 (87.1 / 54.7 / 47.5 s, the baseline with its blend arcs kept within the caps; returns in swept space are raised)",
    "drill_and_mill": "91.6 / 58.6 / 54.6 s: the face passes (1 mm deep, 4-6 mm of the 6 mm cutter: the "
                      "arc passes φ = 90°, no chip thinning) run at the chip-load maximum F2082 in both (21 s), "
                      "the G81/G83 cycles at the plunge cap 2 × their programmed F in both (14 s), the pocket "
                      "plunge at the end's chip load F520 in both; only the F900 pocket rings gain (8.0 → 4.1 "
                      "s: the first, a 4 mm deep full slot, holds the group at F1260 by deflection, the thin "
                      "rings and the air of the cleared pocket after it run faster); rapids, the tool change and "
                      "the spindle take 15.6 s in both",
}
TOL_TIME = 0.03  # relative drift allowed on cycle times
TOL_LIMIT = 1.005  # emitted program: no limit above its bound by more than 0.5 %


@pytest.fixture(scope="module", params=NAMES)
def run(request):
    job = load_job(JOBS / request.param)
    return request.param, job, optimize(job, progress=False)


def test_summary_matches_golden(run):
    name, job, result = run
    s = result.summary
    golden, keys = goldens.path(name), goldens.KEYS
    if not golden.exists():
        pytest.fail(f"{golden} is missing: write it with `PYTHONPATH=src python tests/goldens.py {name}` and review it")
    expected = json.loads(golden.read_text())
    assert s["status"] == expected["status"] == "solved"
    assert s["samples"] == expected["samples"]
    for k in keys[1:4]:
        assert s[k] == pytest.approx(expected[k], rel=TOL_TIME), k


def test_no_limit_exceeded_and_roughing_goal(run):
    name, job, result = run
    s = result.summary
    over = {k: v for k, v in s["limits"].items() if v > TOL_LIMIT}
    assert not over, f"{name}: limits exceeded on the emitted program: {over}"
    assert s["cycle_time_after_s"] <= s["cycle_time_baseline_s"] * (1 + 1e-3)
    if name in ROUGHING_GOAL:
        if s["improvement_vs_baseline"] < ROUGHING_GOAL[name] and name in SHORT_OF_GOAL:
            pytest.xfail(f"{name}: {s['improvement_vs_baseline']:.1%} under the baseline: {SHORT_OF_GOAL[name]}")
        assert s["improvement_vs_baseline"] >= ROUGHING_GOAL[name]


def test_emitted_program_keeps_the_path(run, tmp_path):
    name, job, result = run
    original = read_program(job.program)
    emitted = read_text(result.text, "emitted.nc")
    if not result.summary["status"].startswith("fallback"):
        assert len(emitted.toolpath) >= len(original.toolpath)  # moves may be split, never merged
    assert swept_path_deviation(original, emitted) < 2e-3  # mm: the 3-decimal output precision
    feeds = emitted.toolpath.feed_mm_min[emitted.toolpath.kind != 0]
    assert np.nanmax(feeds) <= job.machine.feed_cap_mm_min + 1e-9
    if rs274_oracle.RS274:
        out = tmp_path / "emitted.ngc"
        out.write_text(result.text)
        trace = rs274_oracle.run(out)
        assert trace.error is None or "%" in trace.error, trace.error


def swept_path_deviation(a, b, ds: float = 0.05) -> float:
    """Largest distance (mm) between the two paths at equal arc length (rapids included); splitting a
    move into pieces does not change it, any change of geometry does."""
    sa, sb = a.toolpath.resample(ds), b.toolpath.resample(ds)
    assert sa.s_mm[-1] == pytest.approx(sb.s_mm[-1], abs=1e-3)
    pb = np.column_stack([np.interp(sa.s_mm, sb.s_mm, sb.xyz_mm[:, k]) for k in range(3)])
    return float(np.abs(pb - sa.xyz_mm).max())


def test_solver_failure_keeps_programmed_feeds(monkeypatch, tmp_path):
    real = opt_module.schedule_samples

    def failing(samples, limits, options=None):
        sch = real(samples, limits, options)
        for _, _, seg in sch.segments:
            seg.status = Status.NUMERICAL_ERROR
            seg.message = "forced failure"
        return sch

    monkeypatch.setattr(opt_module, "schedule_samples", failing)
    job = load_job(JOBS / "slotting")
    result = optimize(job, progress=False)
    assert result.summary["status"] == "fallback_programmed_feeds"
    assert "forced failure" in result.summary["message"]
    assert result.text == job.program.read_text()


def test_cli_writes_program_and_summary(tmp_path):
    out, summary = tmp_path / "out.nc", tmp_path / "s.json"
    assert main(["optimize", str(JOBS / "slotting"), "-o", str(out), "--json", str(summary)]) == 0
    assert json.loads(summary.read_text())["output"] == str(out)
    assert out.read_text().startswith("(slots and contour")



def test_trace_is_built_only_when_asked(tmp_path, slotting_result):
    """The per-sample trace (~30 columns a sample: ~180 MB at 100 k blocks) is built for --trace and
    --report only, with the predicted surface error it carries; without it the program and the rest of
    the summary are the same."""
    job, traced = slotting_result  # optimize(..., trace=True)
    plain = optimize(job, progress=False)
    assert plain.trace == {} and plain.text == traced.text
    timing = ("stage_s", "solver_s", "total_s")
    assert "surface_error" in traced.summary and "surface_error" not in plain.summary
    assert ({k: v for k, v in plain.summary.items() if k not in timing}
            == {k: v for k, v in traced.summary.items() if k not in timing + ("surface_error",)})
    assert {"feed_schedule_mm_min", "feed_executed_mm_min", "peak_force_N", "current_ratio"} <= set(traced.trace)
    assert all(len(column) == traced.summary["samples"] for column in traced.trace.values())
    csv = tmp_path / "trace.csv"
    assert main(["optimize", str(JOBS / "slotting"), "-o", str(tmp_path / "out.nc"), "--trace", str(csv), "-q"]) == 0
    assert "feed_executed_mm_min" in csv.read_text().splitlines()[0]

@pytest.mark.parametrize("text,field", [
    ('program = "program.nc"\nmaterial = "al6061"\nmachine = "vmc-small"\n[stock]\nbox = [[0,0,0],[1,1,-1]]\n'
     '[tools.1]\ndiameter_mm = 6\n', "stock.box"),
    ('program = "program.nc"\nmaterial = "unobtainium"\nmachine = "vmc-small"\n[stock]\nbox = [[0,0,-1],[1,1,0]]\n'
     '[tools.1]\ndiameter_mm = 6\n', "material"),
    ('program = "program.nc"\nmaterial = "al6061"\nmachine = "vmc-small"\n[stock]\nbox = [[0,0,-1],[1,1,0]]\n'
     '[tools.1]\ndiameter_mm = -6\n', "tools.1.diameter_mm"),
    ('program = "program.nc"\nmaterial = "al6061"\nmachine = "vmc-small"\n[stock]\nbox = [[0,0,-1],[1,1,0]]\n'
     '[tools.1]\ndiameter_mm = 6\n[limits]\nspeed = 3\n', "limits.speed"),
])
def test_bad_job_files_name_the_field(tmp_path, text, field):
    (tmp_path / "program.nc").write_text("G21\nM30\n")
    (tmp_path / "job.toml").write_text(text)
    with pytest.raises(ConfigError) as info:
        load_job(tmp_path)
    assert info.value.field == field


def test_cli_report_says_why_slower():
    from millpost.commands.optimize import report
    s = {"status": "slower", "message": "", "cycle_time_before_s": 18.1, "cycle_time_after_s": 26.5,
         "cycle_time_baseline_s": 28.7, "binding": {"cutting force": 0.98}, "f_words": {"programmed": 7, "optimized": 9},
         "hard_limits": ["cutting_force", "feed"], "binding_limits": {"cutting_force": 0.98, "junction": 0.01},
         "limits_programmed": {"cutting_force": 1.56, "deflection": 2.0},
         "defaults_binding": {"cutting_force": "tool safety factor 3"},
         "held": {"deflection": {"kind": "quality", "lines": [20, 21], "line_count": 2, "reason": "reported",
                                  "over_bound": 1.8}},
         "tools": {1: {"programmed_s": 18.1, "optimized_s": 26.5, "programmed_feed_mm_min": [333.3, 1000.0],
                       "optimized_feed_mm_min": [594.9, 20000.0]}}}
    text = report(s, Path("out.nc"))
    assert text.startswith("millpost: slower: cycle time 18.1 s programmed → 26.5 s optimized")
    assert "F words 7 -> 9" in text.splitlines()[0]
    assert "cutting_force 98% (hard)" in text and "cutting_force 1.56; feeds lowered there, hence slower" in text
    assert "deflection 2.00" not in text  # a quality limit the program exceeds does not make it slower
    assert "default cutting_force: tool safety factor 3" in text and "deflection (quality) held on 2 lines" in text
    assert "up to 1.8 x its bound in the optimized program" in text
    assert "T1" in text and "333.3-1000" in text and "594.9-20000" in text


def test_micro_segments_do_not_write_a_crawl(tmp_path):
    """A program's 5 µm moves between long cuts (CAM arc fitting and V-carving leave such): the controller
    reads at most 1000 blocks/s (hobby-router), so it runs each at ≤ 5 µm × 1000/s = 0.3 mm/min by itself
    for one block's time; millpost's schedule counts that, but writes no F word for it (that wrote F3 on
    the next 2 mm of plywood and made the program 18× slower). Every F in force on the cuts stays at
    least the programmed F1200, and the optimized program is no slower."""
    (tmp_path / "p.nc").write_text("G21 G90 G17\nT1 M6\nS18000 M3\nG0 X-10 Y5 Z5\nG1 Z-3 F400\nG1 X20 F1200\n"
                                   "G1 X20.005\nG1 X40\nG1 X40.005\nG1 X60\nG0 Z5\nM5\nM30\n")
    (tmp_path / "job.toml").write_text(
        'program = "p.nc"\nmaterial = "plywood"\nmachine = "hobby-router"\n[stock]\nbox = [[0, 0, -12], [60, 10, 0]]\n'
        'cell_mm = 0.1\n[tools.1]\ndiameter_mm = 6.35\nflutes = 2\nshape = "flat"\nflute_length_mm = 22\n'
        'stickout_mm = 30\n')
    result = optimize(load_job(tmp_path / "job.toml"), progress=False)
    s = result.summary
    assert s["status"] == "solved" and s["cycle_time_after_s"] <= s["cycle_time_before_s"]
    tp = read_text(result.text).toolpath
    along_x = (tp.kind != 0) & (tp.end[:, 0] != tp.start[:, 0])
    assert tp.feed_mm_min[along_x].min() >= 1200


@pytest.mark.parametrize("machine", ["hobby-router", "vmc-small"])
def test_moves_between_stops_are_scheduled(tmp_path, machine):
    """Moves shorter than ds_mm that start and end at a stop: a lone cut between two rapids (CAMotics'
    V-carve enters the wood with one 0.1 mm G1 between G0s) and a zigzag of 50 µm reversals (the
    controller stops at each), between 0.5 µm moves (V-carving leaves hundreds). With one sample
    interval per move the schedule, which holds the acceleration constant between samples, could not
    leave rest (b = 0 at both ends: no finite time), the solve failed and the whole program kept its
    programmed feeds (or, inside a cut, it stood still: infinite time). Now every such move is scheduled:
    status solved, moving everywhere, no slower, no limit exceeded."""
    micro = "".join(f"G1 X{20 + 0.0005 * k:.4f}\n" for k in range(1, 201))
    zigzag = "".join(f"G1 X{40.1 - 0.05 * (k % 2):.2f}\n" for k in range(1, 21))
    (tmp_path / "p.nc").write_text("G21 G90 G17\nT1 M6\nS18000 M3\nG0 X-10 Y5 Z5\nG1 Z-1 F400\nG1 X20 F1200\n"
                                   f"{micro}G1 X40\n{zigzag}G1 X60\nG0 Z5\nG0 X62 Y5\nG0 Z0.05\nG1 Z-0.05\n"
                                   "G0 Z5\nM5\nM30\n")
    (tmp_path / "job.toml").write_text(
        f'program = "p.nc"\nmaterial = "plywood"\nmachine = "{machine}"\n[stock]\n'
        'box = [[0, 0, -12], [70, 10, 0]]\ncell_mm = 0.1\n[tools.1]\ndiameter_mm = 6.35\nflutes = 2\n'
        'shape = "flat"\nflute_length_mm = 22\nstickout_mm = 30\n')
    result = optimize(load_job(tmp_path / "job.toml"), progress=False, trace=True)
    s = result.summary
    assert s["status"] == "solved", s["message"]
    # every sample interval of the cuts is traversed in finite time: a speed above zero at one end at least
    f = result.trace["feed_schedule_mm_min"]
    cut = np.isfinite(f[:-1]) & np.isfinite(f[1:]) & ~result.samples.segment_start[1:]
    assert (f[:-1] + f[1:])[cut].min() > 0
    assert s["cycle_time_after_s"] <= s["cycle_time_before_s"] * (1 + 1e-3)
    over = {k: v for k, v in s["limits"].items() if v > TOL_LIMIT}
    assert not over, over


def test_feed_above_the_axis_rates_is_written_at_the_rates_of_each_direction(tmp_path):
    """A light 3D finish posted at F6000 on hobby-router (X, Y 3000, Z 2000 mm/min; no direction runs
    faster than √(3000² + 3000² + 2000²) = 4690), then air moves programmed at F500 far from the stock.
    An F word millpost writes above what its move runs at reads as a typo (F39395 on an X axis of 24000):
    every F it writes is at most the rate of its move's direction, min over the axes of vmax_i / |u_i|
    (u the unit direction: 3000 on X, 3000·√2 = 4243 on a 45° XY move). The programmed F6000 is over the
    machine's maximum feed, which the summary says (limits_programmed: the programmed F words against
    the caps they must hold)."""
    rows = []
    for k in range(6):
        y = 2.0 + 4.0 * k
        rows += [f"G1 X10 Y{y:.1f} Z-0.2", "G1 X25 Z-0.25", "G1 X40 Z-0.2", f"G1 X44 Y{y + 4.0:.1f}",
                 "G1 X10"] if k % 2 == 0 else [f"G1 X6 Y{y + 4.0:.1f}"]
    air = ["G1 Z20 F500", "G1 X-40 Y-40", "G1 X-80", "G1 X-80 Y-80", "G1 X-40 Y-40 Z30"]
    (tmp_path / "p.nc").write_text("G21 G90 G17\nT1 M6\nS18000 M3\nG0 X10 Y2 Z5\nG1 Z-0.2 F6000\n"
                                   + "\n".join(rows + air) + "\nG0 Z35\nM5\nM30\n")
    (tmp_path / "job.toml").write_text(
        'program = "p.nc"\nmaterial = "mdf"\nmachine = "hobby-router"\n[stock]\nbox = [[0, 0, -12], [50, 30, 0]]\n'
        'cell_mm = 0.1\n[tools.1]\ndiameter_mm = 3.175\nflutes = 2\nshape = "ball"\nflute_length_mm = 12\n'
        'stickout_mm = 20\n')
    job = load_job(tmp_path / "job.toml")
    result = optimize(job, progress=False)
    s = result.summary
    assert s["status"] in ("solved", "slower"), s["message"]
    assert s["limits_programmed"]["feed"] == pytest.approx(6000 / job.machine.feed_cap_mm_min, rel=1e-3)
    tp = read_text(result.text).toolpath
    feed = (tp.kind != 0) & (tp.lengths() > 0)
    u = np.abs(tp.end - tp.start)[feed] / tp.lengths()[feed, None]
    vmax = np.array([job.machine.axes[a].vmax_mm_min for a in "xyz"])
    with np.errstate(divide="ignore"):
        rate = np.min(np.where(u > 1e-12, vmax / u, np.inf), axis=1)
    f = tp.feed_mm_min[feed]
    assert np.all(f <= rate * (1 + 1e-9))
    assert f[u[:, 0] > 0.999] == pytest.approx(3000.0, rel=1e-3)  # the raster's and the air's X moves
    assert (f > 500.0 * (1 + 1e-9))[tp.line[feed] >= 6 + len(rows)].sum() >= 3  # the air moves, raised
