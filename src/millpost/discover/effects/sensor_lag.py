"""sensor_lag: a sensor (or its filter) responds as a first-order lag, τ dy/dt = x − y: the dynamometer
(fx_N, fy_N, fz_N together), the spindle power or current reading, or the axis currents. The variants
are each sensor group × τ on a geometric grid from 2 log intervals to 2 s, then a finer grid between the
best one's neighbours; the one with the smallest training residual is kept. Parameter tau_s (s)."""

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

    def __init__(self, taus: np.ndarray | None = None, groups: tuple | None = None) -> None:
        self.taus, self.groups = taus, groups

    def fit(self, ctx: Context) -> "SensorLag":
        dt = self.dt_ = ctx.rows.dt_s
        if self.taus is not None or 2 * dt >= 2.0:
            return super().fit(ctx)
        coarse = np.geomspace(2 * dt, 2.0, 10)
        first = SensorLag(coarse).fit(ctx)
        if not first.applicable:
            self.variant_ = None
            return self
        k = int(np.argmin(np.abs(coarse - first.params_["tau_s"])))
        fine = np.geomspace(coarse[max(k - 1, 0)], coarse[min(k + 1, len(coarse) - 1)], 9)
        group = tuple(first.channels_)
        self.taus, self.groups = fine, (group,)
        return super().fit(ctx)

    def variants(self, ctx: Context):
        dt = ctx.rows.dt_s
        taus = self.taus if self.taus is not None else []
        for group in self.groups or GROUPS:
            chans = ctx.measured(group)
            if not chans:
                continue
            for tau in taus:
                f = first_order(dt, float(tau))
                yield Variant({"tau_s": float(tau)}, {}, {c: f for c in chans})
