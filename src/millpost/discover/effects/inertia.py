"""inertia: a table dynamometer moves with the table, so it also reads the workpiece's mass m times the
axis acceleration: F_measured = F_cut − m·a per axis. Parameter mass_kg (one mass for X, Y, Z).
Channels: forces."""

from __future__ import annotations

from .base import Context, Effect, Variant


class Inertia(Effect):
    name = "inertia"
    channels = ("fx_N", "fy_N", "fz_N")
    meaning = "mass × acceleration of the moving workpiece in the force signal"
    positive = ("mass_kg",)

    def variants(self, ctx: Context):
        acc = ctx.rows.features["accel_mm_s2"] / 1000.0     # m/s²
        chans = ctx.measured(self.channels)
        if chans and abs(acc).max() > 0:
            yield Variant({}, {c: {self.param("mass_kg"): -acc[:, self.channels.index(c)]} for c in chans})
