"""sensor_drift: a sensor's zero drifts linearly with time (warm-up of a dynamometer's charge amplifier,
of a current transducer): each measured channel gains d·(t − t̄). Parameters drift_<channel>_per_s
(channel units per s)."""

from __future__ import annotations

from .base import Context, Effect, Variant


class SensorDrift(Effect):
    name = "sensor_drift"
    channels = ("fx_N", "fy_N", "fz_N", "spindle_power_W", "spindle_current_A", "ix_A", "iy_A", "iz_A")
    meaning = "sensor offset drifting with time"

    def variants(self, ctx: Context):
        t = ctx.rows.t_s - ctx.rows.t_s.mean()
        chans = ctx.measured(self.channels)
        if chans:
            yield Variant({}, {c: {self.param(f"drift_{c}_per_s"): t} for c in chans})
