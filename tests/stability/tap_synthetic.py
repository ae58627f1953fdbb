"""Independent synthetic tap logs and chatter recordings (no millpost code): the hammer's half-sine force
pulses driven through uncoupled modes by integrating their equations of motion
m_i q_i'' + c_i q_i' + k_i q_i = F(t) (scipy.integrate.solve_ivp, RK45), the tool tip's motion x = Σ q_i;
a chattering cut as tooth-passing harmonics plus a component at f_c that grows and settles to a limit
cycle."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp


def tap_log(path: Path, modes, *, hits=(0.05, 0.45, 0.85, 1.25), duration_s=1.65, fs_hz=51200.0,
            peak_N=300.0, pulse_s=2.5e-4, noise=0.03, response="accel_m_s2", seed=0, clip_N=None) -> Path:
    """Write a tap log: modes as (fn Hz, ζ, k N/mm); Gaussian noise σ = `noise` × each channel's peak."""
    wn = [2 * math.pi * fn for fn, _, _ in modes]
    m = [k * 1e3 / w**2 for (_, _, k), w in zip(modes, wn)]           # kg (k in N/m)

    def force(t):
        return sum(peak_N * math.sin(math.pi * (t - h) / pulse_s) for h in hits if h <= t <= h + pulse_s)

    def rhs(t, y):
        f = force(t)
        out = []
        for i, (_, z, _) in enumerate(modes):
            q, v = y[2 * i], y[2 * i + 1]
            out += [v, f / m[i] - 2 * z * wn[i] * v - wn[i] ** 2 * q]
        return out

    t = np.arange(int(duration_s * fs_hz)) / fs_hz
    y, y0 = np.zeros((2 * len(modes), len(t))), np.zeros(2 * len(modes))
    edges = sorted({0.0, t[-1], *hits, *(h + pulse_s for h in hits)})
    for a, b in zip(edges[:-1], edges[1:]):   # short steps on a pulse, free vibration between pulses
        sol = solve_ivp(rhs, (a, b), y0, method="DOP853", rtol=1e-10, atol=1e-16, dense_output=True,
                        max_step=pulse_s / 8 if a in hits else np.inf)
        on = (t >= a) & (t <= b)
        y[:, on], y0 = sol.sol(t[on]), sol.y[:, -1]
    f = np.array([force(ti) for ti in t])
    q = y[0::2]
    v = y[1::2]
    a = np.array([f / mi - 2 * z * w * vi - w**2 * qi for (_, z, _), w, mi, qi, vi in zip(modes, wn, m, q, v)])
    resp = {"accel_m_s2": a.sum(0), "vel_mm_s": 1e3 * v.sum(0), "disp_mm": 1e3 * q.sum(0)}[response]
    rng = np.random.default_rng(seed)
    f_noisy = f + noise * peak_N * rng.standard_normal(len(t))
    r_noisy = resp + noise * np.max(np.abs(resp)) * rng.standard_normal(len(t))
    if clip_N is not None:
        f_noisy = np.minimum(f_noisy, clip_N)
    np.savetxt(path, np.column_stack([t, f_noisy, r_noisy]), delimiter=",", header=f"t_s,force_N,{response}",
               comments="", fmt="%.9g")
    return path


def chatter_recording(path: Path, *, rpm, flutes, f_chatter_hz, fs_hz=20000.0, duration_s=2.0, noise=0.05,
                      seed=0, rpm_column=False) -> Path:
    """Write a recording: spindle and tooth-passing harmonics (runout: a little of every spindle harmonic)
    plus a chatter component at f_chatter_hz growing as 1 − exp(−t/0.2 s) to twice the tooth-passing
    amplitude, and white noise of σ = `noise` × the tooth-passing amplitude."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration_s * fs_hz)) / fs_hz
    fs_ = rpm / 60.0
    x = np.zeros_like(t)
    for k in range(1, int(0.45 * fs_hz / fs_)):
        amp = (1.0 / (k // flutes) if k % flutes == 0 else 0.1 / k)
        x += amp * np.sin(2 * math.pi * k * fs_ * t + rng.uniform(0, 2 * math.pi))
    x += 2.0 * (1 - np.exp(-t / 0.2)) * np.sin(2 * math.pi * f_chatter_hz * t + 0.3)
    x += noise * rng.standard_normal(len(t))
    cols, names = [t, x], "t_s,signal"
    if rpm_column:
        cols.append(np.full_like(t, rpm))
        names += ",spindle_rpm"
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=names, comments="", fmt="%.9g")
    return path
