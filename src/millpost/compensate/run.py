"""`compensate(job)`: the program with its cutting points moved against the predicted deflection.

1. The programmed path p: engagement through the stock, the executed speed (the machine's controller
   model), the surfaces it generates (`Surfaces`), and where the tool actually runs under load
   (`deflected_run`): the surface error before. Errors are measured across the surfaces p generates.
2. Wanted offset o = −δ(p) (the deflection at the programmed path's own forces: if the tool ran on p,
   this is what it would bend by) less its component along the horizontal feed direction (`across`),
   written as the program can carry it (`plan_offsets`: split lines,
   whole arcs, the controller's point spacing F·DT).
3. The commanded path c = p + o runs through the deflection model again (the tool meets p's cut moved
   across the surface to where it actually is); its miss a − p is taken off the wanted offset,
   o ← o − (a − p), and 2–3 repeat until the RMS surface error is within the tolerance, stops falling, or the passes run out;
   the pass with the smallest RMS error is written.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import controller, engagement
from ..gcode import read_program
from ..gcode.interpret import Program
from ..job import Job
from ..operations import program_operations
from ..progress import Progress, resolve
from ..safety import check_spindle
from ..signals import controller_model, predict
from ..toolpath import RAPID, Samples
from .deflection import deflection_vectors
from .model import Deflected, deflected_run
from .path import MoveOffsets, commanded, plan_offsets
from .surface import Surfaces, finished_errors_mm, per_operation, rms_mm
from .write import check_writable, write_offsets

TOLERANCE_MM = 0.002
MAX_PASSES = 6


@dataclass
class Compensation:
    """The compensated program's text, the summary, the plan (per moved move its written offsets), the
    nominal samples, the surfaces they generate and the tool under load before and after."""

    text: str
    summary: dict
    plan: dict[int, MoveOffsets]
    samples: Samples
    surfaces: Surfaces
    before: Deflected
    after: Deflected


def cutting_moves(program: Program, samples: Samples, eng) -> np.ndarray:
    """(moves,) bool: feed moves with an engaged sample."""
    cut = np.zeros(len(program.toolpath), bool)
    cut[np.asarray(samples.move)[(eng.ap_mm > 1e-9) & (samples.kind != RAPID)]] = True
    return cut


def point_spacing_mm(job: Job, program: Program) -> np.ndarray:
    """(moves,) the controller's least point spacing F·DT (mm): programmed feed (mm/s) × block period (s)."""
    return np.nan_to_num(program.toolpath.feed_mm_s) / job.machine.controller.block_rate_Hz


def across(samples: Samples, offset_mm: np.ndarray) -> np.ndarray:
    """The offsets (N, 3) without their component along the path's horizontal direction: a shift along
    the feed moves no surface, and would turn the written points back against the feed where it grows."""
    t = np.array(samples.tangent, float)
    t[:, 2] = 0.0
    length = np.linalg.norm(t, axis=1)
    t = np.divide(t, length[:, None], out=np.zeros_like(t), where=length[:, None] > 1e-9)
    return offset_mm - np.einsum("ij,ij->i", offset_mm, t)[:, None] * t


def rms_error_mm(surfaces: Surfaces, displacement: np.ndarray) -> float:
    """The RMS surface error (mm) over the wall and floor samples (0 without any)."""
    return rms_mm(*surfaces.errors_mm(displacement))


def compensate(job: Job, *, tolerance_mm: float = TOLERANCE_MM, max_passes: int = MAX_PASSES,
               progress: Progress | bool | None = None) -> Compensation:
    """Compensate the job's program (see the module docstring); tolerance_mm: the surface error and the
    offset's miss between written points aimed at (mm)."""
    report = resolve(progress)
    program = read_program(job.program, job.reader_options())
    check_writable(program)
    samples, eng, notes = engagement.engage(program, job.stock(), dict(job.tools), job.settings.ds_mm, job.allow,
                                            stage="simulate", progress=report)
    samples = check_spindle(program, samples, eng, job.spindle_rpm, job.allow, notes)
    speed = controller.execute(program.toolpath, controller_model(job)).speed_at_samples(samples)
    surfaces = Surfaces.of(eng)
    p = samples.xyz_mm
    before = deflected_run(job, eng, surfaces, samples, p, speed)
    cutting = cutting_moves(program, samples, eng)
    cycles = cutting & (np.asarray(program.cycle) != 0)
    if cycles.any():  # a drill's thrust bends no wall; a cycle block's words are its hole's, not a move's end
        lines = sorted({int(n) for n in program.toolpath.line[cycles]})
        notes.append(f"note: {len(lines)} canned-cycle line(s) kept as programmed (first: line {lines[0]}): "
                     "compensate moves the points of lines and arcs, not a cycle's holes")
        cutting &= ~cycles
    spacing = point_spacing_mm(job, program)
    wanted = across(samples, -deflection_vectors(job, predict(job, samples, eng, speed)))
    best = None
    for k in range(1, max_passes + 1):
        report("compensate", k, max_passes)
        plan = plan_offsets(program.toolpath, samples, wanted, cutting, tolerance_mm, spacing)
        run = deflected_run(job, eng, surfaces, samples, commanded(program.toolpath, samples, plan), speed)
        miss = run.actual_mm - p
        error = rms_error_mm(surfaces, miss)
        if best is not None and error >= best[0]:
            break
        best = (error, k, plan, run)
        if error <= tolerance_mm:
            break
        wanted = wanted - across(samples, miss)
    _, k, plan, after = best
    text = write_offsets(program, plan)
    summary = _summary(job, program, samples, surfaces, before, after, plan, spacing, k, tolerance_mm, notes)
    return Compensation(text, summary, plan, samples, surfaces, before, after)


def _summary(job: Job, program: Program, samples: Samples, surfaces: Surfaces, before: Deflected, after: Deflected,
             plan: dict[int, MoveOffsets], spacing: np.ndarray, passes: int, tolerance_mm: float,
             notes: list[str]) -> dict:
    """The summary: surface error per operation before and after (µm), the passes and what was written."""
    ops = program_operations(program, samples)
    p = samples.xyz_mm
    operations = per_operation(ops, {name: surfaces.errors_mm(run.actual_mm - p)
                                     for name, run in (("before", before), ("after", after))})
    rms = [rms_error_mm(surfaces, run.actual_mm - p) * 1000.0 for run in (before, after)]
    largest = [float(np.abs(finished_errors_mm(*surfaces.errors_mm(run.actual_mm - p))).max(initial=0.0)) * 1000.0
               for run in (before, after)]
    offsets = np.concatenate([mo.offset_mm for mo in plan.values()]) if plan else np.zeros((0, 3))
    unsettled = [name for name, run in (("before", before), ("after", after)) if not run.converged]
    moved = sorted(plan)
    return {
        "program": str(job.program), "machine": job.machine.name,
        "machine_compliance_mm_per_N": job.machine.compliance_matrix.round(9).tolist(),
        "tolerance_um": round(tolerance_mm * 1000.0, 3), "passes": passes,
        "deflection_iterations": {"before": before.iterations, "after": after.iterations},
        "surface_error_before_um": round(rms[0], 1), "surface_error_after_um": round(rms[1], 1),
        "reduction": round(1.0 - rms[1] / rms[0], 4) if rms[0] > 0 else 0.0,
        "largest_error_before_um": round(largest[0], 1), "largest_error_after_um": round(largest[1], 1),
        "moves_moved": len(plan), "points_added": int(sum(len(mo.u) - 1 for mo in plan.values())),
        "largest_offset_um": round(float(np.linalg.norm(offsets, axis=1).max(initial=0.0)) * 1000.0, 1),
        "least_point_spacing_mm": round(float(spacing[moved].min()), 5) if moved else None,
        "operations": operations,
        "notes": program.notes + notes + [f"the deflection model did not settle ({', '.join(unsettled)}): "
                                          "the cut is stiffer than the machine (see docs/compensation.md)"]
        * bool(unsettled),
    }
