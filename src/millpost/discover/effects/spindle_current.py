"""spindle_current: the spindle's output current where the machine file says too little about it (no K_t,
or a wrong one): a share per newton-metre of cutting torque and a no-load current growing with speed,
i = k_T·T_c + c₁·n + c₂·n² (T_c the cutting torque at K̂, N·m; n in 1000 rpm; zero when the spindle is
off), each term ≥ 0 (current grows with torque, drag with speed). k_T is the slope of the current over
the log's torques: with a no-load current I₀, i = √(I₀² + (T/K_t)²) rises slower than T/K_t at small T, so
k_T < 1/K_t there (`calibrate fit` fits K_t and I₀ themselves from power and current). Parameters
per_Nm_A (A per N·m), c1_A_per_krpm, c2_A_per_krpm2. Channel: spindle_current_A."""

from __future__ import annotations

import numpy as np

from .base import Context, Effect, Variant


class SpindleCurrent(Effect):
    name = "spindle_current"
    channels = ("spindle_current_A",)
    meaning = "spindle current per cutting torque (1/K_t) and no-load current growing with rpm"
    positive = ("per_Nm_A",)
    bounded = ("per_Nm_A", "c1_", "c2_")

    def variants(self, ctx: Context):
        if "spindle_current_A" not in ctx.rows.measured:
            return
        rpm = ctx.rows.features["rpm"]
        omega = 2 * np.pi * rpm / 60.0
        torque = np.where(omega > 0, ctx.cutting("spindle_power_W") / np.where(omega > 0, omega, 1.0), 0.0)
        n = rpm / 1000.0
        if n.max() > 0:
            yield Variant({}, {"spindle_current_A": {self.param("per_Nm_A"): torque, self.param("c1_A_per_krpm"): n,
                                                     self.param("c2_A_per_krpm2"): n * n}})
