"""spindle_no_load: idle spindle power (bearings, windage, motor losses) beyond the machine file's,
growing with speed: P₀(n) = c₁·n + c₂·n² (n in 1000 rpm: Coulomb-like and viscous drag torques, each ≥ 0;
zero when the spindle is off). Parameters c1_W_per_krpm, c2_W_per_krpm2. Channel: spindle_power_W."""

from __future__ import annotations

from .base import Context, Effect, Variant


class SpindleNoLoad(Effect):
    name = "spindle_no_load"
    channels = ("spindle_power_W",)
    meaning = "idle spindle power growing with rpm"
    bounded = ("c1_", "c2_")     # drags take power: neither term below 0

    def variants(self, ctx: Context):
        n = ctx.rows.features["rpm"] / 1000.0
        if "spindle_power_W" in ctx.rows.measured and n.max() > 0:
            yield Variant({}, {"spindle_power_W": {self.param("c1_W_per_krpm"): n, self.param("c2_W_per_krpm2"): n * n}})
