"""sensor_lag: a sensor (or its filter) responds as a first-order lag, τ dy/dt = x − y: the dynamometer
(fx_N, fy_N, fz_N together), the spindle power or current reading, or the axis currents. The variants
are each sensor group × τ on a geometric grid from 2 log intervals to 2 s; the one with the smallest
training residual is kept. Parameter tau_s (s)."""

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

    def variants(self, ctx: Context):
        dt = ctx.rows.dt_s
        taus = np.geomspace(2 * dt, 2.0, 10) if 2 * dt < 2.0 else []
        for group in GROUPS:
            chans = ctx.measured(group)
            if not chans:
                continue
            for tau in taus:
                f = first_order(dt, float(tau))
                yield Variant({"tau_s": float(tau)}, {}, {c: f for c in chans})
