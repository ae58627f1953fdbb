"""The predicted surface error of a program as it runs, for any job: along the finished walls and floors
(`Surfaces`), the deflected tool's envelope against the programmed one, with the tool where it actually
runs under load (`deflected_run`: the fixed point a = p + δ(F(a)), δ the tool beam's and the machine's
compliance times the forward model's mean force, F depending on where the tool cuts) at the path
speeds of each state (e.g. as programmed and as optimized: a faster feed cuts a thicker chip, pushes
harder and bends the tool further). Errors in µm in the summary and trace; positive where material is
left (undercut), negative where too much is cut (overcut)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..engagement import Engagement
from ..gcode.interpret import Program
from ..job import Job
from ..operations import program_operations
from ..toolpath import Samples
from .model import deflected_run
from .surface import Surfaces, map_errors_um, per_operation, rms_mm


@dataclass
class SurfaceError:
    """Per state (name → per sample, mm; nan where the sample makes no such surface) the wall and floor
    errors, the per-operation table (`per_operation`) and the states whose deflection did not settle."""

    wall_mm: dict[str, np.ndarray]
    floor_mm: dict[str, np.ndarray]
    operations: list[dict]
    unsettled: tuple[str, ...] = ()
    name: ClassVar[str] = "surface_error"

    @classmethod
    def predict(cls, job: Job, program: Program, samples: Samples, eng: Engagement,
                speeds_mm_s: dict[str, np.ndarray]) -> "SurfaceError | None":
        """The errors at each state's path speed per sample (mm/s); None when the program finishes no
        wall or floor. `eng` needs its per-slice arcs (`Surfaces.of`)."""
        surfaces = Surfaces.of(eng)
        if not (surfaces.wall.any() or surfaces.floor.any()):
            return None
        p = samples.xyz_mm
        runs = {state: deflected_run(job, eng, surfaces, samples, p, speed) for state, speed in speeds_mm_s.items()}
        errors = {state: surfaces.errors_mm(run.actual_mm - p) for state, run in runs.items()}
        ops = program_operations(program, samples)
        return cls({s: e[0] for s, e in errors.items()}, {s: e[1] for s, e in errors.items()},
                   per_operation(ops, errors), tuple(s for s, run in runs.items() if not run.converged))

    def errors_um(self, state: str) -> np.ndarray:
        """Per sample its wall error, else its floor error (µm; nan where it makes neither)."""
        return map_errors_um(self.wall_mm[state], self.floor_mm[state])

    def rms_um(self, state: str) -> float:
        """The RMS error over the state's wall and floor samples (µm)."""
        return rms_mm(self.wall_mm[state], self.floor_mm[state]) * 1000.0

    def trace_columns(self) -> dict[str, np.ndarray]:
        """Per state the column surface_error_<state>_um (`errors_um`)."""
        return {f"surface_error_{state}_um": self.errors_um(state) for state in self.wall_mm}

    def summary(self) -> dict:
        """The summary's entry: per state the RMS over all walls and floors (µm), and per operation."""
        return {"rms_um": {state: round(self.rms_um(state), 1) for state in self.wall_mm},
                "operations": self.operations}

    def notes(self) -> list[str]:
        """A note when the deflection model did not settle for a state."""
        return [f"the predicted surface error ({', '.join(self.unsettled)}) did not settle: the cut is stiffer "
                "than the machine (see docs/compensation.md)"] if self.unsettled else []
