"""Controller model against LinuxCNC 2.9's real trajectory planner (the headless harness in
../shared/tools/lcnc): the cycle time of every sample job, before and after `millpost optimize`, and
of the real third-party programs LinuxCNC runs, and of the real-program regression set (tests/real_jobs)
after `optimize`, within 2 % of LinuxCNC's (each run prints both times with `pytest -s`).

Skipped when LinuxCNC or the harness is absent. Each program runs once in LinuxCNC at a 5× clock
speed-up (about a fifth of its cycle time in wall time, some 8 minutes in all); programs of more
than 500 s of cycle time run only with MILLPOST_LCNC_LONG=1.
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

import pytest

import lcnc_harness
from conftest import shared_data
from test_controller import slot_into_ramp, steps
from millpost.errors import MillpostError
from millpost.job import load_job
from millpost.machine import Machine
from millpost.optimize import optimize

JOBS = Path(__file__).resolve().parents[2] / "sample_jobs"
REAL_JOBS = sorted(p.parent for p in (Path(__file__).resolve().parents[1] / "real_jobs").glob("*/job.toml"))
SAMPLES = sorted(p.parent.name for p in JOBS.glob("*/job.toml"))
# real programs LinuxCNC runs cleanly (left out: Fanuc G76/G87 and G41 in fusion-fanuc-benchmark, Centroid
# M25, a G1 with no F in compass/mt_kazbegi and sworn_brothers and test_linuxcnc_00, a '%' LinuxCNC
# refuses at the end of compass/bottom, compass, text and top, no M2 at the end of slant_test and heart/*; on
# camotics/vcarve LinuxCNC's task process died in every run)
REAL = [
    "fusion-ledfloor/1024_block_14bit.nc", "fusion-ledfloor/1055_utab_265bit.nc",
    "fusion-ledfloor/1071_surface_40mm_10overlap.nc", "fusion-ledfloor/1117_wall_28bit.nc",
    "freecad-tests/fanuc_legacy_drilling_peck__default.gcode", "camotics/examples/bear/bear.nc",
    "camotics/examples/buildbotics/buildbotics.gcode",
    "camotics/examples/cat/tiny_cat_outline.ngc", "camotics/examples/cds/cds.gcode",
    "camotics/examples/flower_mold/flower_mold.nc", "camotics/examples/genes-encoder/genes-encoder.ngc",
    "camotics/examples/scorpion/scorpion.nc", "camotics/examples/wave/wave.gcode",
]
# real-program jobs where the model is known to miss LinuxCNC by more than the tolerance, with the measure
MODEL_MISSES: dict[str, str] = {}
# programs of many tiny straight feeds (test_controller.steps): LinuxCNC's canon merges those within G64 Q
# of one line into that line (naive CAM); name -> (path mode, feeds, step mm, F mm/min, zigzag mm, the
# closed-form time of the merged line from rest to rest (s) or None where nothing merges)
STEPS = {"collinear Q0.01": ("G64 P0.01 Q0.01", 2000, 0.0005, 60, 0.0, 1.0 + 0.5 / 3000 + 0.5 / 1500 + 0.0005),
         "zigzag Q0.01": ("G64 P0.01 Q0.01", 2000, 0.005, 300, 0.005, None),
         "zigzag Q0.002": ("G64 P0.01 Q0.002", 2000, 0.005, 300, 0.005, None)}
MACHINE_FOR_REAL = "vmc-small"
LONG_S = 500.0
TOLERANCE = 0.02

pytestmark = pytest.mark.skipif(lcnc_harness.missing() is not None, reason=str(lcnc_harness.missing()))


@pytest.fixture(scope="module")
def models():
    """Per machine: the controller model with the simulator's measured command latencies."""
    cache = {}

    def get(name: str):
        if name not in cache:
            machine = Machine.load(name)
            cache[name] = (machine, lcnc_harness.model(machine, lcnc_harness.sim_latencies(machine)))
        return cache[name]
    return get


def check(program: Path, machine_name: str, models) -> float:
    machine, ctl = models(machine_name)
    try:
        t_model = lcnc_harness.model_seconds(program, ctl)
    except MillpostError as exc:  # e.g. a Centroid postamble's G49 H0, which LinuxCNC refuses too
        pytest.skip(f"LinuxCNC's dialect refuses {program.name}: {exc}")
    if t_model > LONG_S and not os.environ.get("MILLPOST_LCNC_LONG"):
        pytest.skip(f"{program.name}: {t_model:.0f} s of cycle time (set MILLPOST_LCNC_LONG=1 to run it)")
    res = lcnc_harness.run(program, machine, t_model)
    if res.get("errors"):
        pytest.skip(f"LinuxCNC refuses {program.name}: {res['errors']}")
    assert res.get("ok"), f"LinuxCNC did not run {program}: {res.get('error')}"
    t_lcnc = float(res["seconds"])
    print(f"\n{program.name}: model {t_model:.3f} s, LinuxCNC {t_lcnc:.3f} s ({t_model / t_lcnc - 1.0:+.2%})")
    assert abs(t_model / t_lcnc - 1.0) <= TOLERANCE, f"{program.name}: model {t_model:.3f} s, LinuxCNC {t_lcnc:.3f} s"
    return t_lcnc


def _machine_of(name: str) -> str:
    """A sample job's machine as `Machine.load` takes it: a built-in name, or its own file's path."""
    machine = tomllib.loads((JOBS / name / "job.toml").read_text())["machine"]
    return str(JOBS / name / machine) if machine.endswith(".toml") else machine


@pytest.mark.parametrize("name", SAMPLES)
def test_sample_job(name, models):
    job = load_job(JOBS / name)
    check(job.program, _machine_of(name), models)


@pytest.mark.parametrize("name", SAMPLES)
def test_optimized_sample_job(name, models, tmp_path):
    job = load_job(JOBS / name)
    out = tmp_path / f"{name}.nc"
    out.write_text(optimize(job, progress=False).text)
    check(out, _machine_of(name), models)


@pytest.mark.parametrize("rel", REAL)
def test_real_program(rel, models):
    check(shared_data(*rel.split("/")), MACHINE_FOR_REAL, models)


@pytest.mark.parametrize("folder", REAL_JOBS, ids=[f.name for f in REAL_JOBS])
def test_optimized_real_job(folder, models, tmp_path, request):
    """The real-program regression set (tests/real_jobs) after `optimize`, on the job's machine."""
    shared_data()  # skips without ../shared/data
    if folder.name in MODEL_MISSES:
        request.applymarker(pytest.mark.xfail(reason=MODEL_MISSES[folder.name], strict=False))
    job = load_job(folder)
    try:
        text = optimize(job, progress=False).text
    except MillpostError as exc:  # refused with a clear error (see test_real_jobs)
        pytest.skip(f"{folder.name}: {exc}")
    out = tmp_path / f"{folder.name}.nc"
    out.write_text(text)
    check(out, job.machine.name, models)


@pytest.mark.parametrize("name", STEPS)
def test_naive_cam_merge(name, models, tmp_path):
    """Feeds far shorter than a servo period's travel: merged within Q, LinuxCNC runs 2000 of them as 20
    lines (the closed form of one 1 mm line at F60: 1 mm / (1 mm/s) plus the acceleration lag); the same
    zigzag with a Q below its amplitude is not merged (LinuxCNC: 4.02 s against 2.00 s merged)."""
    mode, n, step, feed, zig, closed_form = STEPS[name]
    program = tmp_path / f"{name.replace(' ', '_')}.ngc"
    program.write_text(steps(mode, n, step, feed, zig))
    t_lcnc = check(program, "vmc-small", models)
    if closed_form is not None:
        assert t_lcnc == pytest.approx(closed_form, rel=0.005)


@pytest.mark.parametrize("slow", [300, 600])
def test_blend_arc_of_merged_lines(slow, models, tmp_path):
    """A slot of naive-CAM feeds at F3000 into a ramp of them at a slow feed: the blend arc between the
    merged lines runs the slot's feed 1 mm into the ramp (test_controller: 0.689 s and 0.477 s, against
    1.05 s and 0.65 s with arcs per programmed move)."""
    program = tmp_path / f"slot_into_ramp_{slow}.ngc"
    program.write_text(slot_into_ramp(slow))
    check(program, "vmc-small", models)
