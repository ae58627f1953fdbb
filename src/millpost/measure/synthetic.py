"""Synthetic logs from the forward model: what a sensor would record while the program runs, sampled at
a fixed rate on a clock that starts `offset_s` before the program, with seeded noise. For tests,
benchmarks and trying the calibration without a machine.

Noise per channel: relative (a fraction of the channel's RMS over the log, Gaussian and white: sensor
and cutting noise) plus absolute (Gaussian, channel units). Positions get `position_noise_mm`.
"""

from __future__ import annotations

import numpy as np

from ..signals import Signals
from .log import Log



def synthetic_log(signals: Signals, *, rate_hz: float, offset_s: float = 0.0, noise: float = 0.03,
                  absolute_noise: dict[str, float] | None = None, position_noise_mm: float = 0.0,
                  columns: tuple[str, ...] = ("fx_N", "fy_N", "fz_N", "spindle_power_W"), lead_s: float = 0.0,
                  tail_s: float = 0.0, seed: int = 0, phase: float | None = None) -> Log:
    """A log of `columns` (log names) at `rate_hz`: row times t = offset_s + τ for program times τ from
    −lead_s to the program's end + tail_s, starting at a random phase of the sample interval (seeded)
    unless `phase` (0..1) is given. noise: relative noise level (e.g. 0.03 = 3 % of the channel's RMS)."""
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    phase = rng.uniform(0, 1) if phase is None else phase
    tau = -lead_s + (phase + np.arange(int(np.floor((signals.t_s[-1] + lead_s + tail_s) / dt)))) * dt
    pred = signals.log_columns()
    out = {"t_s": tau + offset_s}
    absolute_noise = absolute_noise or {}
    for c in columns:
        clean = np.interp(tau, signals.t_s, pred[c])
        if c in ("x_mm", "y_mm", "z_mm"):
            out[c] = clean + rng.normal(0.0, position_noise_mm, len(tau)) if position_noise_mm else clean
            continue
        rms = float(np.sqrt(np.mean(clean * clean)))
        out[c] = clean + rng.normal(0.0, noise * rms + absolute_noise.get(c, 0.0), len(tau))
    return Log(out, path="<synthetic>")
