"""Stability lobes of milling: the largest chatter-free axial depth of cut (mm) against spindle speed (rpm).

Conventions (those of `millpost.forces`, after Altintas): x = feed, y = in-plane normal, immersion angle φ
measured clockwise from +y, cutter turning clockwise seen from the spindle; a tooth cuts between the entry
and exit angles φ_st < φ_ex (rad) that `millpost.forces.base.immersion(ae, D, climb)` returns: up (conventional)
milling φ_st = 0, φ_ex = φ_s; down (climb) milling φ_st = π − φ_s, φ_ex = π; a slot 0…π. A tooth at φ takes the
dynamic chip h = Δx sin φ + Δy cos φ (Δ = tool displacement now minus one tooth period ago) and pushes the tool
with F_x = −F_t cos φ − F_r sin φ, F_y = F_t sin φ − F_r cos φ, F_t = K_t a h, F_r = K_r F_t. K_t is the
tangential cutting coefficient (N/mm²), K_r = K_rc/K_tc the radial-to-tangential ratio.

Zero-order (Altintas & Budak 1995, CIRP Annals 44(1):357–362): the time-periodic directional matrix is replaced
by its average (N/4π)·α, α_xx = ½[cos 2φ − 2K_rφ + K_r sin 2φ], α_xy = ½[−sin 2φ − 2φ + K_r cos 2φ],
α_yx = ½[−sin 2φ + 2φ + K_r cos 2φ], α_yy = ½[−cos 2φ − 2K_rφ − K_r sin 2φ] (each taken from φ_st to φ_ex).
With the oriented FRF the characteristic equation a₀Λ² + a₁Λ + 1 = 0, a₀ = G_xx G_yy (α_xx α_yy − α_xy α_yx),
a₁ = α_xx G_xx + α_yy G_yy, gives at each chatter frequency ω_c the eigenvalue Λ = Λ_R + iΛ_I, the depth
a_lim = −2πΛ_R(1 + κ²)/(N K_t), κ = Λ_I/Λ_R, and the phase ε = π − 2 atan κ; the tooth period is
T = (ε + 2kπ)/ω_c for lobe k = 0, 1, 2, …
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError
from .frf import ToolTipFRF

FREQ_POINTS = 6000  # chatter-frequency grid: uniform over the FRF's band, plus as many around each mode


def _check(kt: float, kr: float, flutes: int, phi_st: float, phi_ex: float) -> None:
    for name, ok, value in (("kt_N_per_mm2", kt > 0, kt), ("kr", kr >= 0, kr), ("flutes", flutes >= 1, flutes),
                            ("phi_st_rad", 0 <= phi_st < phi_ex, phi_st), ("phi_ex_rad", phi_st < phi_ex <= math.pi, phi_ex)):
        if not (math.isfinite(value) and ok):
            raise ConfigError(name, value, "kt > 0 N/mm², kr ≥ 0, flutes ≥ 1, 0 ≤ φ_st < φ_ex ≤ π rad")


def directional_factors(kr: float, phi_st: float, phi_ex: float) -> np.ndarray:
    """α (2×2, dimensionless): the directional matrix averaged over a tooth period is (N/4π)·α."""
    def at(p: float) -> np.ndarray:
        s2, c2 = math.sin(2 * p), math.cos(2 * p)
        return 0.5 * np.array([[c2 - 2 * kr * p + kr * s2, -s2 - 2 * p + kr * c2],
                               [-s2 + 2 * p + kr * c2, -c2 - 2 * kr * p - kr * s2]])
    return at(phi_ex) - at(phi_st)


def _frequency_grid(frf: ToolTipFRF, points: int) -> np.ndarray:
    """Chatter frequencies (Hz) to scan: the FRF's band, refined around every mode's resonance."""
    lo = max(frf.x.band_hz[0], frf.y.band_hz[0])
    measured = frf.x.f_hz is not None or frf.y.f_hz is not None
    hi = (min if measured else max)(frf.x.band_hz[1], frf.y.band_hz[1])
    parts = [np.linspace(max(lo, 1e-3 * hi), hi, points)]
    for m in frf.x.modes + frf.y.modes:
        w = 30 * m.zeta * m.fn_hz
        parts.append(np.linspace(max(lo, m.fn_hz - w), min(hi, m.fn_hz + w), points // 2))
    return np.unique(np.concatenate(parts))


def _zoa_roots(frf: ToolTipFRF, alpha: np.ndarray, f_hz: np.ndarray) -> np.ndarray:
    """The two eigenvalues Λ (2, F) of the zero-order characteristic equation at each frequency, each row
    followed continuously along the frequency axis (the quadratic's two roots would otherwise swap)."""
    gx, gy = frf.x.receptance_mm_per_N(f_hz), frf.y.receptance_mm_per_N(f_hz)
    a0 = gx * gy * (alpha[0, 0] * alpha[1, 1] - alpha[0, 1] * alpha[1, 0])
    a1 = alpha[0, 0] * gx + alpha[1, 1] * gy
    disc = np.sqrt(a1 * a1 - 4 * a0 + 0j)
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.stack([-(a1 + disc) / (2 * a0), -(a1 - disc) / (2 * a0)])
        lam = np.where(np.abs(a0) > 1e-300, lam, np.stack([-1 / a1, np.full_like(a1, np.nan)]))
    keep = np.abs(lam[0, 1:] - lam[0, :-1]) + np.abs(lam[1, 1:] - lam[1, :-1])
    swap = np.abs(lam[0, 1:] - lam[1, :-1]) + np.abs(lam[1, 1:] - lam[0, :-1]) < keep
    odd = np.concatenate([[False], np.cumsum(swap) % 2 == 1])
    return np.where(odd, lam[::-1], lam)


def zero_order_lobes(frf: ToolTipFRF, *, kt_N_per_mm2: float, kr: float, flutes: int, phi_st_rad: float,
                     phi_ex_rad: float, rpm, freq_points: int = FREQ_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """(limiting depth mm, chatter frequency Hz) at each spindle speed by the zero-order method.

    At a speed the tooth period T = 60/(N·rpm) is fixed; a chatter frequency f solves it when
    f·T − ε(f)/2π is a whole number k ≥ 0 with a_lim(f) > 0. Every such crossing on the frequency grid
    (both eigenvalue roots) is found and interpolated; the speed's limit is the smallest. inf where none."""
    _check(kt_N_per_mm2, kr, flutes, phi_st_rad, phi_ex_rad)
    n = np.atleast_1d(np.asarray(rpm, float))
    if not np.all(np.isfinite(n) & (n > 0)):
        raise ConfigError("rpm", rpm, "spindle speeds must be > 0")
    alpha = directional_factors(kr, phi_st_rad, phi_ex_rad)
    f = _frequency_grid(frf, freq_points)
    lam = _zoa_roots(frf, alpha, f)
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = lam.imag / lam.real
        depth = -2 * np.pi * lam.real * (1 + kappa**2) / (flutes * kt_N_per_mm2)
        eps = np.pi - 2 * np.arctan(kappa)
    out = [_crossings(f, depth, eps, 60.0 / (flutes * n[i:i + 64])) for i in range(0, len(n), 64)]
    return np.concatenate([o[0] for o in out]), np.concatenate([o[1] for o in out])


def _crossings(f: np.ndarray, depth: np.ndarray, eps: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest positive depth (mm) and its frequency (Hz) among the lobes crossing each tooth period T (s)."""
    best = np.full(T.shape, np.inf)
    f_best = np.full(T.shape, np.nan)
    rows = np.arange(len(T))
    for d, e in zip(depth, eps):
        theta = f[None, :] * T[:, None] - (e / (2 * np.pi))[None, :]      # (speeds, frequencies)
        t0, t1 = theta[:, :-1], theta[:, 1:]
        k = np.floor(np.maximum(t0, t1))
        ok = ((k >= np.minimum(t0, t1)) & (k >= 0) & (np.abs(t1 - t0) < 0.5)
              & (d[None, :-1] > 0) & (d[None, 1:] > 0) & np.isfinite(t0) & np.isfinite(t1))
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.where(ok, (k - t0) / (t1 - t0), 0.0)
        a = np.where(ok, d[None, :-1] + w * (d[None, 1:] - d[None, :-1]), np.inf)
        i = np.argmin(a, axis=1)
        better = a[rows, i] < best
        best = np.where(better, a[rows, i], best)
        f_best = np.where(better, f[i] + w[rows, i] * (f[i + 1] - f[i]), f_best)
    return best, f_best


def zero_order_limit_mm(frf: ToolTipFRF, *, kt_N_per_mm2: float, kr: float, flutes: int, phi_st_rad: float,
                        phi_ex_rad: float, rpm) -> np.ndarray:
    """The limiting axial depth (mm) at each spindle speed (rpm), zero-order method (Altintas–Budak): the
    smallest over the lobes k = 0, 1, 2, … and both eigenvalue roots."""
    return zero_order_lobes(frf, kt_N_per_mm2=kt_N_per_mm2, kr=kr, flutes=flutes, phi_st_rad=phi_st_rad,
                            phi_ex_rad=phi_ex_rad, rpm=rpm)[0]
