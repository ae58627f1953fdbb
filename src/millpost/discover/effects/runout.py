"""runout: a cutter whose axis is off the spindle's by ρ has one flute further out than the next, so the
chips differ from flute to flute: flute j's chip is f_z·sin φ + r_j − r_(j−1) with r_j = ρ·cos(θ_j − ψ).
Over a revolution this is a once-per-revolution change of the chip, about ρ_eff·cos(Ω t − ψ), and the
shearing share of every cutting channel (proportional to the chip) changes by that over f_z:
ΔF_c = F_shear,c(K̂)/f_z · (a·cos θ + b·sin θ), θ = ∫Ω dt the spindle angle from the first row (the
logged speed must hold the angle coherent). Parameters a_mm, b_mm (one pair for all channels) and the
amplitude runout_mm = √(a² + b²) (the chip-thickness change, about 2ρ·sin(π/N) for N flutes).

It shows only when the log samples the revolution: at least 4 rows per revolution at the log's fastest
spindle speed. A slower log averages it out (or aliases it): the effect is then not applicable and says
so. Channels: forces and spindle power."""

from __future__ import annotations

import numpy as np

from .base import Context, Effect, Variant, cutting_channels

ROWS_PER_REV = 4


class Runout(Effect):
    name = "runout"
    channels = ("fx_N", "fy_N", "fz_N", "spindle_power_W")
    meaning = "once-per-revolution chip change from cutter runout"
    slow = False

    def unavailable(self, ctx: Context) -> str | None:
        rows = ctx.rows
        rpm = float(rows.features["rpm"].max()) if len(rows) else 0.0
        if not cutting_channels(ctx) or rpm <= 0:
            return "no cutting channel or no spindle speed in the log"
        rate = 1.0 / rows.dt_s
        need = ROWS_PER_REV * rpm / 60.0
        if rate < need:
            return (f"the log's {rate:.4g} Hz cannot show once-per-revolution content ({rpm:.0f} rpm is "
                    f"{rpm / 60:.4g} Hz; {ROWS_PER_REV} rows per revolution need ≥ {need:.4g} Hz)")
        return None

    def variants(self, ctx: Context):
        rows = ctx.rows
        angle = np.cumsum(2 * np.pi * rows.features["rpm"] / 60.0 * np.gradient(rows.t_s))
        fz = rows.features["fz_mm"]
        per_chip = np.where(fz > 0, 1.0 / np.where(fz > 0, fz, 1.0), 0.0)
        cos, sin = np.cos(angle), np.sin(angle)
        terms = {}
        for c in cutting_channels(ctx):
            shear = ctx.cutting(c, slice(0, 3)) * per_chip
            terms[c] = {self.param("a_mm"): shear * cos, self.param("b_mm"): shear * sin}
        yield Variant({}, terms)

    def fit(self, ctx: Context) -> "Runout":
        super().fit(ctx)
        if self.applicable:
            a, b = self.params_["a_mm"], self.params_["b_mm"]
            sa, sb = self.stderr_["a_mm"], self.stderr_["b_mm"]
            amp = float(np.hypot(a, b))
            self.params_["runout_mm"] = amp
            self.stderr_["runout_mm"] = float(np.hypot(a * sa, b * sb) / amp) if amp > 0 else float("nan")
        return self
