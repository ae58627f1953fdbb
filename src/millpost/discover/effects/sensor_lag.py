"""sensor_lag: a sensor (or its filter) responds as a first-order lag, τ dy/dt = x − y: the dynamometer
(fx_N, fy_N, fz_N together), the spindle power or current reading, or the axis currents. The variants
are each sensor group × τ on a geometric grid from 2 log intervals to 2 s, then a golden-section search
between the best one's neighbours; the one with the smallest training residual is kept. Parameter tau_s (s).

The lag carries the model's error forward in time: where the forward model is known to be wrong (the rows
fits leave out, `Rows.use`: the tool entering or leaving the material), its prediction would leak into the
rows after them for a few τ. There the lag's input is the straight line between the nearest used rows on
either side (a cut's force ramping up or down), not the forward model's value."""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from .base import Context, Effect, Variant

GROUPS = (("fx_N", "fy_N", "fz_N"), ("spindle_power_W",), ("spindle_current_A",), ("ix_A", "iy_A", "iz_A"))


def first_order(dt_s: float, tau_s: float):
    """The discrete first-order lag at step dt along rows, exact for an input linear between rows (the
    forces are continuous in time; a step-held input would lag them by another half row):
    y_k+1 = a·y_k + b₀·x_k+1 + b₁·x_k with a = e^(−dt/τ), b₀ = 1 − (τ/dt)(1 − a), b₁ = (1 − a) − b₀;
    starting at rest at the first row's value."""
    a = float(np.exp(-dt_s / tau_s))
    b0 = 1.0 - tau_s / dt_s * (1.0 - a)
    b1 = (1.0 - a) - b0

    def apply(m: np.ndarray) -> np.ndarray:
        zi = (1.0 - b0) * m[:1]
        return lfilter([b0, b1], [1, -a], m, axis=0, zi=zi)[0]
    return apply


def bridge(use: np.ndarray | None):
    """Along rows: the values of rows not in `use` replaced by linear interpolation (in row number) between
    the nearest used rows before and after them (held at the ends)."""
    if use is None or use.all() or not use.any():
        return lambda m: m
    good = np.flatnonzero(use)
    bad = np.flatnonzero(~use)
    after = np.searchsorted(good, bad)
    left, right = np.maximum(after - 1, 0), np.minimum(after, len(good) - 1)
    span = good[right] - good[left]
    w = np.where(span > 0, (bad - good[left]) / np.where(span > 0, span, 1), 0.0)
    left, right = good[left], good[right]

    def apply(m: np.ndarray) -> np.ndarray:
        m = m.copy()
        ww = w if m.ndim == 1 else w[:, None]
        m[bad] = (1 - ww) * m[left] + ww * m[right]
        return m
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
        lag, bridged = first_order(ctx.rows.dt_s, tau_s), bridge(ctx.rows.use)
        return Variant({"tau_s": tau_s}, {}, {c: (lambda m: lag(bridged(m))) for c in group})

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
