"""size_effect: the specific cutting force rises at small chip thickness (Kienzle: k_c ∝ h^(−m)). Each edge
element's shearing force becomes K_c·(h/h_ref)^(−m)·h·db with the local chip h = f_z·sin φ·sin κ, so the
shearing share of every cutting channel becomes f_z·G_m·(K_tc, K_rc, K_ac), where G_m is the mechanistic
regressor with the integrand over the engaged arc weighted by (h/h_ref)^(−m) (integrated piecewise: the
arc of each slice in sub-arcs, exact trigonometric integrals, the weight at each sub-arc's middle). The
edge terms stay as they are. Unlike a refit of the edge coefficients, this follows the chip thickness
along the arc: a thin side cut (small h over its whole arc) and a slot at the same feed per tooth differ.

m (dimensionless, 0 < m < 1) is searched on a grid, then by golden section; the coefficients are refitted
with each m (they are then the shearing coefficients at chip thickness h_ref, the median feed per tooth of
the log's cuts). Parameters m, h_ref_mm. Channels: forces and spindle power."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..rows import COEFS, Cuts
from .base import Context, Effect, Variant, cutting_channels

GRID = np.linspace(0.05, 0.75, 15)
PIECES = 12     # sub-arcs per slice


def size_regressors(cuts: Cuts, m: float, h_ref_mm: float) -> np.ndarray:
    """G_m (cutting samples, 4, 3): the shearing regressors with each element weighted by (h/h_ref)^(−m)."""
    eng = cuts.engagement
    st = np.clip(eng.phi_st, 0.0, np.pi)
    ex = np.clip(eng.phi_ex, 0.0, np.pi)
    sk = np.maximum(np.sin(eng.kappa), 1e-6)
    G = 0.0
    for k in range(PIECES):
        a, b = st + (ex - st) * k / PIECES, st + (ex - st) * (k + 1) / PIECES
        h = cuts.fz_mm[:, None] * np.maximum(np.sin(0.5 * (a + b)), 1e-3) * sk
        w = np.nan_to_num((h / h_ref_mm) ** (-m), nan=0.0)
        G = G + cuts.regressors(replace(eng, phi_st=a, phi_ex=b, dz_mm=eng.dz_mm * w))[0]
    return G


class SizeEffect(Effect):
    name = "size_effect"
    channels = ("fx_N", "fy_N", "fz_N", "spindle_power_W")
    meaning = "specific cutting force rising at small chip thickness"
    positive = ("m",)

    def unavailable(self, ctx: Context) -> str | None:
        if ctx.rows.cuts is None or not cutting_channels(ctx) or not len(ctx.rows.cuts.fz_mm):
            return "no cutting channel or no cut in the log"
        return None

    def at(self, ctx: Context, m: float) -> Variant:
        cuts = ctx.rows.cuts
        _, E = cuts.regressors()
        new = cuts.channels(size_regressors(cuts, m, self.h_ref_mm_), E)
        return Variant({"m": m}, {c: {name: new[c][:, k] - ctx.rows.cut[c][:, k] for k, name in enumerate(COEFS[:3])}
                                  for c in cutting_channels(ctx)})

    def variants(self, ctx: Context):
        for m in GRID:
            yield self.at(ctx, float(m))

    def search(self, ctx: Context) -> tuple | None:
        self.h_ref_mm_ = float(np.median(ctx.rows.cuts.fz_mm))
        best = super().search(ctx)
        return self.refine(ctx, best, GRID, lambda m: self.at(ctx, m))

    def fit(self, ctx: Context) -> "SizeEffect":
        super().fit(ctx)
        if self.applicable:     # the reference chip thickness the refitted K_c belong to
            self.params_["h_ref_mm"], self.stderr_["h_ref_mm"] = self.h_ref_mm_, float("nan")
        return self

    @property
    def physical(self) -> bool:
        """0 < m < 1: the specific force rises at small chips but the force itself still grows with the
        chip (published Kienzle exponents are 0.1–0.45)."""
        return super().physical and self.params_["m"] < 1.0
