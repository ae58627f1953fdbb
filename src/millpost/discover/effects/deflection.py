"""deflection: the tool (and machine) bend under the cutting force. With compliance C (mm/N) the tool
centre moves by C·F (F the in-plane force on the tool); in a side cut the part across the feed, toward or
away from the material, widens or narrows the radial engagement: ae' = ae + C·F·n (n the unit normal
from the tool axis toward the material), so the arc's inner boundary moves (cos φ changes by ∓Δae/R on
each axial slice of radius R) and every cutting channel follows the cutting law on that arc. The force
depends on the arc it narrows, so the deflected arc is the fixed point of a few iterations at the
coefficients K̂ (damped iterations: a stiff cut converges in a few). A slot keeps its full width (the tool cuts its own slot wherever it is pushed).

C is searched on a log grid, then by golden section; the cutting coefficients are refitted with each.
Parameter compliance_mm_per_N. Channels: forces and spindle power."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..rows import COEFS, Cuts
from .base import Context, Effect, Variant, cutting_channels

GRID = np.geomspace(1e-5, 3e-2, 16)
FREE = 0.1        # a boundary within 1 − |cos φ| < FREE of 0 or π is the free side of the arc
ITERATIONS = 10


def deflected(cuts: Cuts, coef: np.ndarray, compliance_mm_per_N: float):
    """(G, E) of the cutting samples on the arcs of a tool bent by C·F (fixed point at coefficients coef)."""
    eng = cuts.engagement
    st, ex = np.clip(eng.phi_st, 0.0, np.pi), np.clip(eng.phi_ex, 0.0, np.pi)
    inner_ex = (1 - np.cos(st) < FREE) & (1 + np.cos(ex) >= FREE)    # arc [0, ex]: material at φ = 0 side
    inner_st = (1 + np.cos(ex) < FREE) & (1 - np.cos(st) >= FREE)    # arc [st, π]: material at φ = π side
    toward = np.where(inner_ex, 1.0, np.where(inner_st, -1.0, 0.0))  # n·ŷ (feed frame)
    R = np.maximum(eng.r_mm, 1e-9)
    G, E = cuts.regressors()
    d_ae = 0.0
    for _ in range(ITERATIONS):
        fy = cuts.fz_mm * (G[:, 1, :] @ coef[:3]) + E[:, 1, :] @ coef[3:]    # force on the tool across the feed
        d_ae = 0.5 * (d_ae + compliance_mm_per_N * fy[:, None] * toward)     # (m, K) change of ae, damped
        new_ex = np.where(inner_ex, np.arccos(np.clip(np.cos(ex) - d_ae / R, -1, 1)), ex)
        new_st = np.where(inner_st, np.arccos(np.clip(np.cos(st) + d_ae / R, -1, 1)), st)
        new_st = np.minimum(new_st, new_ex)
        G, E = cuts.regressors(replace(eng, phi_st=np.where(np.isnan(eng.phi_st), np.nan, new_st),
                                       phi_ex=np.where(np.isnan(eng.phi_ex), np.nan, new_ex)))
    return G, E


class Deflection(Effect):
    name = "deflection"
    channels = ("fx_N", "fy_N", "fz_N", "spindle_power_W")
    meaning = "tool and machine compliance changing the radial engagement"
    positive = ("compliance_mm_per_N",)

    def unavailable(self, ctx: Context) -> str | None:
        f = ctx.rows.features
        side = (f["ae_mm"] > 0) & (f["ae_mm"] < 0.95 * f["diameter_mm"])
        if ctx.rows.cuts is None or not cutting_channels(ctx) or not side.any():
            return "no side cut (radial engagement below the diameter) with a cutting channel in the log"
        return None

    def at(self, ctx: Context, compliance: float) -> Variant:
        cuts = ctx.rows.cuts
        new = cuts.channels(*deflected(cuts, np.array([ctx.coef[n] for n in COEFS]), compliance))
        return Variant({"compliance_mm_per_N": compliance},
                       {c: {name: new[c][:, k] - ctx.rows.cut[c][:, k] for k, name in enumerate(COEFS)}
                        for c in cutting_channels(ctx)})

    def variants(self, ctx: Context):
        for compliance in GRID:
            yield self.at(ctx, float(compliance))

    def search(self, ctx: Context) -> tuple | None:
        return self.refine(ctx, super().search(ctx), GRID, lambda c: self.at(ctx, c))
