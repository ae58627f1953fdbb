"""An independent check of a program's finished surfaces under deflection: cut a fine height field with
the tool where it actually runs, sample after sample, and measure the walls and floors it leaves against
those the program would leave with a rigid tool.

The tool at sample k stands at a_k = c_k + δ(F_k(a_k)): c_k the commanded point, F_k the mean force
(`millpost.signals.predict`) of the cut the tool meets at a_k in the stock that the samples before it
left (the step a_{k−1} → a_k through the height field, `engagement.simulate`), δ the static deflection
(`deflection_vectors`) less its component along the horizontal feed (a lag along the feed moves no
surface; the chip is set by the feed per tooth, not by the spacing of the samples). Each a_k is its own
fixed point, bracketed and bisected from the previous sample's deflection (`_solve`): a relaxed
iteration does not settle, as the step's cut is very stiff against a move out of the wall (the tool
backs into the crescent the previous sample left: 10 µm cost 40 % of the force on the sample). Unlike the
compensator's model, which moves the programmed path's cut across the surface it generates, the
material here is what the deflected tool left: a real machine's sequence.

Measured (`surface_errors`): in a horizontal slice at height z, each wall cell the rigid cut leaves
(material with a machined neighbour) gets the signed distance to the deflected cut's wall, + where
material is left (undercut), − where too much is cut (overcut), in whole cells (the error of a cell
centre; take cells a few times finer than the error sought); where both cut a column the floor error is
the height difference (+ material left).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import distance_transform_edt

from .. import controller, engagement, stock as stocks
from ..gcode.interpret import Program
from ..job import Job
from ..signals import controller_model, predict
from ..toolpath import RAPID
from .deflection import deflection_vectors
from .run import across

REACH_MM = 1.0  # beyond the tool's radius: the largest deflection looked for


def _near(lo: np.ndarray, hi: np.ndarray, xyz: np.ndarray, reach_mm: float) -> bool:
    """Whether any of the points comes within reach_mm of the box [lo, hi] in the plane (and below its top)."""
    gap = np.maximum(np.maximum(lo[:2] - xyz[:, :2], xyz[:, :2] - hi[:2]), 0.0)
    return bool(np.any((np.hypot(gap[:, 0], gap[:, 1]) < reach_mm) & (xyz[:, 2] < hi[2])))


def _solve(miss, d0: np.ndarray, tolerance_mm: float, max_iterations: int):
    """The deflection d with miss(d) = δ(d) − d ≈ 0, from d0: along u = miss(d0) the miss's component
    g(t) = miss(d0 + t·u)·u falls as t grows (the tool moves out of the cut), so t is bracketed by
    doubling and bisected until the bracket is under the tolerance. Returns d, the stock cut there and
    whether it settled."""
    u, trial = miss(d0)
    size = float(np.linalg.norm(u))
    if size <= tolerance_mm:
        return d0, trial, True
    lo, hi, best = 0.0, 1.0, (d0, trial)
    for _ in range(max_iterations):
        g, cut = miss(d0 + hi * u)
        if g @ u <= 0.0:
            break
        lo, hi, best = hi, 2.0 * hi, (d0 + hi * u, cut)
    for _ in range(max_iterations):
        if (hi - lo) * size <= tolerance_mm:
            break
        t = 0.5 * (lo + hi)
        g, cut = miss(d0 + t * u)
        if g @ u > 0.0:
            lo, best = t, (d0 + t * u, cut)
        else:
            hi = t
    return best[0], best[1], (hi - lo) * size <= tolerance_mm


@dataclass
class DeflectedCut:
    """The fine height field the deflected tool left and the number of samples whose placement did not
    settle within the iterations."""

    stock: stocks.Stock
    unsettled: int


def deflected_cut(job: Job, program: Program, cell_mm: float, *, rigid: bool = False, tolerance_mm: float = 5e-4,
                  max_iterations: int = 40) -> DeflectedCut:
    """Cut the job's stock, in cells of `cell_mm`, along `program` with the tool deflected (rigid: at
    the commanded points, the nominal cut)."""
    samples = program.toolpath.resample(job.settings.ds_mm)
    speed = controller.execute(program.toolpath, controller_model(job)).speed_at_samples(samples)
    start = engagement.known_start(program, samples)
    work = replace(job, cell_mm=cell_mm).stock()
    tools = dict(job.tools)
    c = np.asarray(samples.xyz_mm, float)
    if rigid:
        engagement.simulate(work, tools, samples, start=start)
        return DeflectedCut(work, 0)
    a = c.copy()
    d = np.zeros(3)
    lo, hi = work.bounds()
    reach = {n: t.radius_mm + REACH_MM for n, t in tools.items()}
    unsettled = 0
    for k in range(start, len(samples)):
        joined = k > start and not samples.segment_start[k]
        idx = np.array([k - 1, k]) if joined else np.array([k])
        sub = samples.select(idx)
        if samples.kind[k] == RAPID or not _near(lo, hi, c[idx], reach[samples.tool[k]]):
            d = np.zeros(3)  # a rapid, or out of reach of the stock: no force, nothing to cut
            a[k] = c[k]
            continue

        def miss(d: np.ndarray):
            trial = work.copy()
            at = replace(sub, xyz_mm=np.vstack([a[idx[:-1]], c[k] + d]))
            sig = predict(job, at, engagement.simulate(trial, tools, at, start=0, smooth_steps=0.0), speed[idx])
            return across(sub, deflection_vectors(job, sig))[-1] - d, trial

        d, work, settled = _solve(miss, d, tolerance_mm, max_iterations)
        unsettled += not settled
        a[k] = c[k] + d
    return DeflectedCut(work, unsettled)


def surface_errors(original: stocks.Stock, nominal: stocks.Stock, actual: stocks.Stock,
                   z_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """(wall errors at the slice z, floor errors) in mm of the `actual` cut against the `nominal` one, both
    cut from `original` on the same grid (see the module docstring)."""
    h = nominal.cell_mm
    at = z_mm - nominal.z0
    solid = lambda s: np.pad(s.top > at, 1, constant_values=True)  # noqa: E731  outside the grid: not cut
    was, nom, act = solid(original), solid(nominal), solid(actual)
    machined = was & ~nom
    near = np.zeros_like(nom)
    for axis in (0, 1):
        for shift in (1, -1):
            near |= np.roll(machined, shift, axis=axis)
    wall = nom & near
    wall[[0, -1], :] = wall[:, [0, -1]] = False  # the padding
    inside = distance_transform_edt(act)   # material cells: distance to the actual cut
    outside = distance_transform_edt(~act)  # cut cells: distance to the actual material
    wall_err = np.where(act, inside - 1.0, -outside)[wall] * h
    cut = (nominal.top < original.top - 0.5 * h) & (actual.top < original.top - 0.5 * h)
    floor_err = (actual.top - nominal.top)[cut].astype(float)
    return wall_err, floor_err
