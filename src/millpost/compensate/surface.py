"""Which finished surface each path sample generates, and the error the deflected tool leaves there.

A wall is generated where the flank's engaged arc reaches the side of the cutter: immersion φ = π (the
right of the feed, down milling's exit) or φ = 0 (the left, up milling's entry), in the convention of
`millpost.engagement` (x the feed, y its left, φ clockwise from +y). Its normal n points from the tool
axis into the wall, in the plane. A floor is generated where the cut reaches the tool's end (the lowest
engaged slice starts at the tip). With the tool's actual position a and the programmed one p, the
envelope of the deflected tool stands off the programmed surface by

    wall:  e = −(a − p)·n        floor:  e = (a − p)_z            (mm)

positive where material is left (undercut), negative where too much is cut (overcut). A slot makes two
walls with errors of equal size and opposite sign: its right wall is taken. Flat-end geometry: on a
ball or a corner radius the floor's normal is taken as Z.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..engagement import Engagement
from ..operations import Operation

SIDE_TOLERANCE_RAD = math.radians(2.0)  # the engaged arc reaches the side within this
FLOOR_TOLERANCE_MM = 0.02  # the lowest engaged slice starts this close to the tip


@dataclass
class Surfaces:
    """Per sample (N): wall_normal (N, 3) unit in-plane normal into the wall (0 where the sample makes
    no wall) and floor (N,) whether it makes a floor."""

    wall_normal: np.ndarray
    floor: np.ndarray

    @property
    def wall(self) -> np.ndarray:
        return np.any(self.wall_normal != 0.0, axis=1)

    @classmethod
    def of(cls, eng: Engagement) -> "Surfaces":
        """The surfaces the programmed path generates, from its engagement."""
        n = len(eng)
        cuts = eng.ap_mm > 1e-9
        with np.errstate(all="ignore"):
            st = np.nanmin(np.where(np.isnan(eng.phi_st), np.inf, eng.phi_st), axis=1)
            ex = np.nanmax(np.where(np.isnan(eng.phi_ex), -np.inf, eng.phi_ex), axis=1)
            bottom = np.min(np.where(eng.dz_mm > 0, eng.z_mm - 0.5 * eng.dz_mm, np.inf), axis=1)
        fx, fy = eng.feed_dir[:, 0], eng.feed_dir[:, 1]
        right = cuts & (ex >= math.pi - SIDE_TOLERANCE_RAD)
        left = cuts & ~right & (st <= SIDE_TOLERANCE_RAD)
        normal = np.zeros((n, 3))
        normal[right, 0], normal[right, 1] = fy[right], -fx[right]    # −y of the feed frame
        normal[left, 0], normal[left, 1] = -fy[left], fx[left]        # +y
        length = np.linalg.norm(normal, axis=1)
        normal = np.divide(normal, length[:, None], out=np.zeros_like(normal), where=length[:, None] > 0)
        floor = cuts & (bottom <= FLOOR_TOLERANCE_MM)
        return cls(normal, floor)

    def errors_mm(self, displacement_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(wall error, floor error) per sample (mm; nan where the sample makes no such surface) for the
        tool's displacement a − p (N, 3) from the programmed path."""
        d = np.asarray(displacement_mm, float)
        wall = np.where(self.wall, -np.einsum("ij,ij->i", d, self.wall_normal), np.nan)
        floor = np.where(self.floor, d[:, 2], np.nan)
        return wall, floor


def map_errors_um(wall_mm: np.ndarray, floor_mm: np.ndarray) -> np.ndarray:
    """Per sample its wall error, else its floor error (µm; nan where it finishes neither): what the
    surface-error map colours."""
    return np.where(np.isfinite(wall_mm), wall_mm, floor_mm) * 1000.0


def finished_errors_mm(wall_mm: np.ndarray, floor_mm: np.ndarray) -> np.ndarray:
    """The errors (mm) of all wall and floor samples (`Surfaces.errors_mm` without its nans)."""
    return np.concatenate([wall_mm[np.isfinite(wall_mm)], floor_mm[np.isfinite(floor_mm)]])


def rms_mm(wall_mm: np.ndarray, floor_mm: np.ndarray) -> float:
    """The RMS error (mm) over the wall and floor samples (0 without any)."""
    e = finished_errors_mm(wall_mm, floor_mm)
    return float(np.sqrt(np.mean(e**2))) if len(e) else 0.0


def error_table(operations: list[Operation], wall_mm: np.ndarray, floor_mm: np.ndarray) -> list[dict]:
    """Per operation the surface error on its walls and floors: the largest |e|, the RMS, the most
    undercut and overcut (µm, rounded to 0.1) and the samples; surfaces it does not make are left out, and
    operations that make none."""
    out = []
    for op in operations:
        row: dict = {"operation": op.name, "tool": op.tool, "line": op.line}
        for name, err in (("wall", wall_mm), ("floor", floor_mm)):
            e = err[op.index]
            e = e[np.isfinite(e)] * 1000.0
            if len(e):
                row[name] = {"max_um": round(float(np.abs(e).max()), 1),
                             "rms_um": round(float(np.sqrt(np.mean(e**2))), 1),
                             "undercut_um": round(float(max(e.max(), 0.0)), 1) + 0.0,
                             "overcut_um": round(float(max(-e.min(), 0.0)), 1) + 0.0, "samples": int(len(e))}
        if "wall" in row or "floor" in row:
            out.append(row)
    return out


def per_operation(operations: list[Operation], errors: dict[str, tuple[np.ndarray, np.ndarray]]) -> list[dict]:
    """Per operation that makes a wall or floor: its name, tool and line and, per state of the tool (e.g.
    "before" and "after"; errors: that state's (wall, floor) error per sample, mm, as `Surfaces.errors_mm`
    gives them), the `error_table` entries of its surfaces."""
    tables = {state: error_table(operations, *e) for state, e in errors.items()}
    first = next(iter(tables.values()), [])
    return [{"operation": row["operation"], "tool": row["tool"], "line": row["line"],
             **{state: {s: t[k][s] for s in ("wall", "floor") if s in t[k]} for state, t in tables.items()}}
            for k, row in enumerate(first)]
