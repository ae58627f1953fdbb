"""size_effect: the specific cutting force rises at small chip thickness (Kienzle: k_c ∝ h^(−m)). The
shearing coefficients become K_c·(f_z/f_ref)^(−m) ≈ K_c·(1 − m·ln(f_z/f_ref)) (the mean chip thickness
of an engagement is proportional to f_z; f_ref the median feed per tooth of the log's cuts), so each
cutting channel gains −m × its shearing share × ln(f_z/f_ref). Parameter m (dimensionless), reported
as `m`. Channels: forces and spindle power."""

from __future__ import annotations

import numpy as np

from .base import Context, Effect, Variant, cutting_channels


class SizeEffect(Effect):
    name = "size_effect"
    channels = ("fx_N", "fy_N", "fz_N", "spindle_power_W")
    meaning = "specific cutting force rising at small chip thickness"
    positive = ("m",)

    def variants(self, ctx: Context):
        chans = cutting_channels(ctx)
        fz = ctx.rows.features["fz_mm"]
        on = fz > 0
        if not chans or not on.any():
            return
        lnr = np.where(on, np.log(np.where(on, fz, 1.0) / np.median(fz[on])), 0.0)
        yield Variant({"fz_ref_mm": float(np.median(fz[on]))},
                      {c: {self.param("minus_m"): ctx.cutting(c, slice(0, 3)) * lnr} for c in chans})

    @property
    def physical(self) -> bool:
        """0 < m < 1: the specific force rises at small chips but the force itself still grows with the
        chip (published Kienzle exponents are 0.1–0.45)."""
        return super().physical and self.params_["m"] < 1.0

    def fit(self, ctx: Context) -> "SizeEffect":
        super().fit(ctx)
        if self.applicable:   # report m (the term's coefficient is −m)
            self.params_["m"] = -self.params_.pop("minus_m")
            self.stderr_["m"] = self.stderr_.pop("minus_m")
        return self
