"""deflection: the tool (and machine) bend away from the cut under the in-plane force: with compliance C
(mm/N) the radial engagement of a side cut falls by δ = C·|F_xy|, and its force, about proportional to
ae at small immersion, by the factor (1 − δ/ae). Slots (ae ≥ 0.95 D) keep their width. Each cutting
channel gains −C × its cutting share × |F_xy| / ae. Parameter compliance_mm_per_N. Channels: forces and
spindle power."""

from __future__ import annotations

import numpy as np

from .base import Context, Effect, Variant, cutting_channels


class Deflection(Effect):
    name = "deflection"
    channels = ("fx_N", "fy_N", "fz_N", "spindle_power_W")
    meaning = "tool and machine compliance reducing the radial engagement"
    positive = ("compliance_mm_per_N",)

    def variants(self, ctx: Context):
        chans = cutting_channels(ctx)
        f = ctx.rows.features
        side = (f["ae_mm"] > 0) & (f["ae_mm"] < 0.95 * f["diameter_mm"])
        if not chans or not side.any():
            return
        lever = np.where(side, ctx.force_xy_N() / np.where(side, f["ae_mm"], 1.0), 0.0)
        yield Variant({}, {c: {self.param("minus_compliance_mm_per_N"): ctx.cutting(c) * lever} for c in chans})

    def fit(self, ctx: Context) -> "Deflection":
        super().fit(ctx)
        if self.applicable:
            self.params_["compliance_mm_per_N"] = -self.params_.pop("minus_compliance_mm_per_N")
            self.stderr_["compliance_mm_per_N"] = self.stderr_.pop("minus_compliance_mm_per_N")
        return self
