"""runout: a cutter whose axis is offset from the spindle's by ρ takes a thicker chip on one flute: the
force gains a once-per-revolution part, ≈ ε·|F_xy|·cos(Ω t − ψ) along each in-plane axis (Ω the spindle's
angular speed). It shows only when the log samples the revolution (at least 4 rows per revolution at the
log's fastest spindle speed); slower logs average it out and the effect is not applicable. Parameters per
in-plane channel: the cos and sin amplitudes (fractions of |F_xy|); the spindle phase is held constant
within each cut (the accumulated angle ∫Ω dt from the first row)."""

from __future__ import annotations

import numpy as np

from .base import Context, Effect, Variant


class Runout(Effect):
    name = "runout"
    channels = ("fx_N", "fy_N")
    meaning = "once-per-revolution force from cutter runout"

    def variants(self, ctx: Context):
        rows = ctx.rows
        chans = ctx.measured(self.channels)
        rpm = rows.features["rpm"]
        if not chans or rpm.max() <= 0 or 1.0 / rows.dt_s < 4 * rpm.max() / 60.0:
            return
        angle = np.cumsum(2 * np.pi * rpm / 60.0 * np.gradient(rows.t_s))
        mag = ctx.force_xy_N()
        yield Variant({}, {c: {self.param(f"cos_{c}"): mag * np.cos(angle), self.param(f"sin_{c}"): mag * np.sin(angle)}
                           for c in chans})
