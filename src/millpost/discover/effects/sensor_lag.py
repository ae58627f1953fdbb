"""sensor_lag: a sensor (or its filter) responds as a first-order lag, τ dy/dt = x − y: the dynamometer
(fx_N, fy_N, fz_N together), the spindle power or current reading, or the axis currents. The variants
are each sensor group × τ on a geometric grid from 2 log intervals to 2 s, then a golden-section search
between the best one's neighbours; the one with the smallest training residual is kept. Parameter tau_s (s)."""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from .base import Context, Effect, Variant

GROUPS = (("fx_N", "fy_N", "fz_N"), ("spindle_power_W",), ("spindle_current_A",), ("ix_A", "iy_A", "iz_A"))


def first_order(dt_s: float, tau_s: float):
    """The discrete first-order lag at step dt (exact for a signal held over each step), along rows."""
    a = float(np.exp(-dt_s / tau_s))

    def apply(m: np.ndarray) -> np.ndarray:
        zi = (a * m[:1]) if m.ndim == 1 else a * m[0][None, :]
        return lfilter([1 - a], [1, -a], m, axis=0, zi=zi)[0]
    return apply


class SensorLag(Effect):
    name = "sensor_lag"
    channels = tuple(c for g in GROUPS for c in g)
    meaning = "first-order lag of a sensor"
    positive = ("tau_s",)

    @property
    def physical(self) -> bool:
        """τ > 0, and longer than 2.5 log intervals: a shorter lag is within the sampling and alignment
        resolution (a timing mismatch of the model, not a sensor's dynamics)."""
        return super().physical and self.params_["tau_s"] > 2.5 * self.dt_

    def at(self, ctx: Context, group: tuple[str, ...], tau_s: float) -> Variant:
        f = first_order(ctx.rows.dt_s, tau_s)
        return Variant({"tau_s": tau_s}, {}, {c: f for c in group})

    def variants(self, ctx: Context):
        for group in GROUPS:
            chans = tuple(ctx.measured(group))
            if chans:
                for tau in self.grid_:
                    yield self.at(ctx, chans, float(tau))

    def search(self, ctx: Context) -> tuple | None:
        self.dt_ = ctx.rows.dt_s
        self.grid_ = np.geomspace(2 * self.dt_, max(2.0, 4 * self.dt_), 10)
        best = super().search(ctx)
        if best is None:
            return None
        group = tuple(best[1].filters)
        return self.refine(ctx, best, self.grid_, lambda tau: self.at(ctx, group, tau))
