"""Where the tool actually runs under load: the fixed point a = c + δ(F(a)) of the commanded path c.

The cut, and with it the force, depends on where the deflected tool actually is: a tool pushed off a
wall by x cuts a radial depth a_e − x, one lifted off a floor by z an axial depth a_p − z. The programmed
path p is stepped through the stock once (`engagement.simulate`, by the caller); the tool at a meets
that cut moved across the surface it generates by a − p (`Surfaces`): on a wall the engaged arc's
entry (down milling; exit for up milling) moves to the immersion of the new radial depth,
φ = π − arccos(1 − a_e'/r) per slice of radius r; on a floor the slices' thicknesses scale by a_p'/a_p.
Where the material ends along the feed (a wall's exit) stays where p meets it: stepping the commanded
path instead, whose offsets turn it off the wall where they ramp out, would lose the cut there early.
A step through the height field cannot resolve a displacement finer than its cells either, so the local
relation is what keeps the fixed point smooth; `compensate.check` measures the envelope independently,
sample after sample in a fine height field.

The fixed point is found by the relaxed step a ← a + ω g, g = c + δ − a, until 99 % of the samples
move less than the tolerance (where the tool just touches, a_e → 0, the edge forces make the force
steep in the depth, and a few samples at a wall's ends may keep moving). On a thin cut the force grows about linearly with the radial depth, F ≈ k_c·(a_e − x)
against a stiffness k (N/mm), so g changes by −(1 + k_c/k) per mm the tool moves: plain iteration (ω = 1)
converges only while k_c < k; with ω = 0.3 the error contracts by |1 − 0.3(1 + k_c/k)| a pass, for
k_c < 5.6 k.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..engagement import Engagement
from ..job import Job
from ..signals import predict
from ..toolpath import Samples
from .deflection import deflection_vectors
from .surface import Surfaces

RELAX = 0.3
SETTLED = 0.99  # the share of samples that must move less than the tolerance


@dataclass
class Deflected:
    """The tool under load along the samples: actual positions (mm, (N, 3)), the passes run and the last
    pass's move at the 99th percentile of the samples (mm; inf: not settled)."""

    actual_mm: np.ndarray
    iterations: int
    residual_mm: float

    @property
    def converged(self) -> bool:
        return bool(np.isfinite(self.residual_mm))


def displaced(eng: Engagement, surfaces: Surfaces, d_mm: np.ndarray) -> Engagement:
    """The engagement of each sample moved by d (N, 3) mm across the surface it generates: on a wall each
    slice's radial depth grows by d·n (n into the wall) and its arc's free end moves to the new depth's
    immersion (the wall at φ = π: cos(π − φ_st') = cos(π − φ_st) − d·n/r; at φ = 0: cos φ_ex' = cos φ_ex −
    d·n/r), so d = 0 gives the cut as stepped; on a floor a_p' = a_p − d_z, the slices' thicknesses scaled.
    Samples that generate neither keep their cut."""
    st, ex, dz = eng.phi_st.copy(), eng.phi_ex.copy(), eng.dz_mm.copy()
    ae, ap = eng.ae_mm.copy(), eng.ap_mm.copy()
    wall = surfaces.wall
    if wall.any():
        n = surfaces.wall_normal[wall]
        into = np.einsum("ij,ij->i", d_mm[wall], n)
        ae[wall] = np.maximum(eng.ae_mm[wall] + into, 0.0)
        # the wall at φ = π (the normal is −y of the feed frame) or at φ = 0 (+y), as `Surfaces.of` found it
        feed = eng.feed_dir[wall]
        right = (n[:, 0] * feed[:, 1] - n[:, 1] * feed[:, 0]) > 0
        r = eng.r_mm[wall]
        shift = into[:, None] / np.where(r > 0, r, np.inf)
        s0, e0 = eng.phi_st[wall], eng.phi_ex[wall]
        with np.errstate(invalid="ignore"):
            depth = np.where(right[:, None], -np.cos(s0), np.cos(e0)) - shift  # cos of the free end's angle
        gone = (depth >= 1.0) | ~np.isfinite(s0)
        angle = np.arccos(np.clip(depth, -1.0, 1.0))
        st[wall] = np.where(gone, np.nan, np.where(right[:, None], np.pi - angle, s0))
        ex[wall] = np.where(gone, np.nan, np.where(right[:, None], e0, angle))
        dz[wall] = np.where(gone, 0.0, dz[wall])
    floor = surfaces.floor
    if floor.any():
        ap[floor] = np.maximum(eng.ap_mm[floor] - d_mm[floor, 2], 0.0)
        scale = np.where(eng.ap_mm[floor] > 0, ap[floor] / np.where(eng.ap_mm[floor] > 0, eng.ap_mm[floor], 1.0), 0.0)
        dz[floor] = dz[floor] * scale[:, None]
    return replace(eng, phi_st=st, phi_ex=ex, dz_mm=dz, ae_mm=ae, ap_mm=ap)


def deflected_run(job: Job, eng: Engagement, surfaces: Surfaces, samples: Samples, commanded_mm: np.ndarray,
                  speed_mm_s: np.ndarray, *, tolerance_mm: float = 1e-4, max_iterations: int = 100) -> Deflected:
    """Solve a = c + δ(F(a)) for the commanded positions `commanded_mm` (N, 3) at `samples` (their
    order, moves and feeds; programmed at `samples.xyz_mm`), the path speed per sample (mm/s), with `eng`
    the programmed positions' engagement through the stock and `surfaces` the surfaces it makes."""
    c, p = np.asarray(commanded_mm, float), np.asarray(samples.xyz_mm, float)
    # a sample's force is its own cut's at its own speed, and only the cuts of the samples that make a
    # wall or a floor move with the tool (`displaced`): the others' deflection is computed once
    delta = deflection_vectors(job, predict(job, samples, eng, speed_mm_s))
    on = np.flatnonzero(surfaces.wall | surfaces.floor)
    at, cut, speed = samples.select(on), eng.select(on), np.asarray(speed_mm_s, float)[on]
    made = Surfaces(surfaces.wall_normal[on], surfaces.floor[on])
    a = c.copy()
    for k in range(1, max_iterations + 1):
        delta[on] = deflection_vectors(job, predict(job, at, displaced(cut, made, a[on] - p[on]), speed))
        step = c + delta - a
        moved = float(np.quantile(np.abs(step).max(axis=1), SETTLED)) if len(step) else 0.0
        a = a + (1.0 if moved <= tolerance_mm else RELAX) * step
        if moved <= tolerance_mm:
            return Deflected(a, k, moved)
    return Deflected(a, max_iterations, float("inf"))
