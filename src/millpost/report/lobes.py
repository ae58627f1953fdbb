"""The report's stability lobes: per tool with a tip FRF, the zero-order limiting depth a_lim (mm) against
spindle speed (rpm) over the machine's spindle range, at each radial immersion the tool cuts at, with the
program's (speed, depth) points marked, those cut above their stable depth apart.

The immersions and the check come from the trace's chatter columns (`Chatter.trace_columns`: the
checked arcs φ_st…φ_ex the optimize check grouped the samples by (`check.binned_arc`), the feed direction that swaps the
FRF's X and Y, and which samples are over); the FRF, the tool's flutes, the cutting coefficients and the
spindle range from the job. A curve is drawn for each of the `CURVES` immersions with the most samples
(a point belongs to its own immersion's curve; its colour says whether it is over its own limit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..materials import Material
from ..stability.check import limit_mm
from ..stability.frf import ToolTipFRF
from ..stability.lobes import Pocket, stable_pockets

SPEEDS = 600           # speeds per curve, evenly spaced over the spindle range
CURVES = 3             # immersions drawn per tool (the most cut)
LOWEST_RPM = 0.05      # a spindle range from 0 rpm starts at this fraction of its top
COLUMNS = ("rpm", "a_lim_mm", "phi_st_deg", "phi_ex_deg", "feed_along_y", "chatter_over")


@dataclass(frozen=True)
class LobeCurve:
    """a_lim (mm) at `rpm` for one immersion φ_st…φ_ex (degrees) and feed direction; its pockets; the
    number of samples cut at it."""

    phi_st_deg: float
    phi_ex_deg: float
    along_y: bool
    rpm: np.ndarray
    a_lim_mm: np.ndarray
    pockets: list[Pocket]
    samples: int


@dataclass(frozen=True)
class ToolLobes:
    """One tool's lobe diagram: its curves (most cut first), the distinct (rpm, ap mm) points the program
    cuts at, `points_over` where a sample there is cut above its stable depth, `lines_over` the source lines
    of those samples."""

    tool: int
    flutes: int
    curves: list[LobeCurve]
    points_rpm: np.ndarray
    points_ap_mm: np.ndarray
    points_over: np.ndarray
    lines_over: tuple[int, ...]


def has_chatter_columns(trace: dict[str, np.ndarray]) -> bool:
    return all(c in trace for c in COLUMNS)


def why_none(trace: dict[str, np.ndarray], job) -> str:
    """Why a report that could have lobes has none ("" when it has them, or when there is nothing to
    draw: no FRF and no chatter check)."""
    frf = job is not None and bool(job.frf)
    if has_chatter_columns(trace) and job is None:
        return ("the trace holds the chatter check, but the lobes need the tool tip's FRF, which is in the job: "
                "give --job (millpost report TRACE --job JOB)")
    if frf and not has_chatter_columns(trace):
        return ("the job gives a tool tip FRF but the trace has no chatter columns (the immersion per sample): "
                "written by an older millpost; run optimize --trace again")
    return ""


def tool_lobes(trace: dict[str, np.ndarray], job) -> list[ToolLobes]:
    """The lobe diagram of each tool the job gives an FRF for and that cuts (checked samples)."""
    if job is None or not job.frf or not has_chatter_columns(trace):
        return []
    checked = np.isfinite(trace["phi_st_deg"]) & (trace["rpm"] > 0)
    sp = job.machine.spindle
    rpm = np.linspace(max(sp.rpm_min, LOWEST_RPM * sp.rpm_max), sp.rpm_max, SPEEDS)
    out = []
    for tool in sorted(job.frf):
        mine = checked & (trace["tool"] == tool)
        if not mine.any():
            continue
        flutes = job.tools[tool].flutes
        keys = np.stack([trace["phi_st_deg"][mine], trace["phi_ex_deg"][mine], trace["feed_along_y"][mine]], axis=1)
        uniq, counts = np.unique(keys, axis=0, return_counts=True)
        curves = [_curve(job.frf[tool], job.material, flutes, *uniq[k], rpm, int(counts[k]))
                  for k in np.argsort(-counts, kind="stable")[:CURVES]]
        over = trace["chatter_over"][mine] > 0
        pts, at = np.unique(np.stack([trace["rpm"][mine], trace["ap_mm"][mine]], axis=1), axis=0, return_inverse=True)
        over_at = np.zeros(len(pts), bool)
        np.logical_or.at(over_at, at.reshape(-1), over)
        out.append(ToolLobes(tool, flutes, curves, pts[:, 0], pts[:, 1], over_at,
                             tuple(sorted({int(v) for v in trace["line"][mine][over]}))))
    return out


def _curve(frf: ToolTipFRF, material: Material, flutes: int, st_deg: float, ex_deg: float, along_y: float,
           rpm: np.ndarray, samples: int) -> LobeCurve:
    """One immersion's zero-order lobes (the FRF's X and Y swapped when the feed runs along Y, as the check)."""
    a = limit_mm(frf.oriented(bool(along_y)), material, flutes, math.radians(st_deg),
                 min(math.radians(ex_deg), math.pi), rpm)
    return LobeCurve(float(st_deg), float(ex_deg), bool(along_y), rpm, a, stable_pockets(rpm, a), samples)
