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
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .frf import ToolTipFRF

FREQ_POINTS = 6000  # chatter-frequency grid: uniform over the FRF's band, plus as many around each mode
SD_STEPS = 40  # semi-discretisation steps per tooth period


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


def _modal_model(frf: ToolTipFRF) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(ω_n rad/s, ζ, modal mass N·s²/mm, P) of the modes in X then Y; P (2, d) sums them into X and Y."""
    if not (frf.x.modes and frf.y.modes):
        raise ConfigError("frf", "measured table", "semi-discretisation integrates the delay equation in time and "
                          "needs modes (fn_hz, zeta, k_N_per_mm) in X and Y; fit modes to the measured FRF first, "
                          "or use the zero-order method, which reads the table directly")
    modes = frf.x.modes + frf.y.modes
    wn = np.array([2 * np.pi * m.fn_hz for m in modes])
    zeta = np.array([m.zeta for m in modes])
    mass = np.array([m.k_N_per_mm for m in modes]) / wn**2
    P = np.zeros((2, len(modes)))
    P[0, :len(frf.x.modes)] = 1.0
    P[1, len(frf.x.modes):] = 1.0
    return wn, zeta, mass, P


def _mean_directional(kr: float, flutes: int, phi_st: float, phi_ex: float, m: int) -> np.ndarray:
    """H̄_i (m, 2, 2): the directional matrix Σ_j g(φ_j)[[−cs − K_r s², −c² − K_r sc], [s² − K_r sc, sc − K_r c²]]
    (s = sin φ_j, c = cos φ_j) averaged over each of the m equal steps of a tooth period; g = 1 in cut."""
    pitch = 2 * np.pi / flutes
    H = np.zeros((m, 2, 2))
    for i in range(m):
        for j in range(flutes):
            lo, hi = j * pitch + i * pitch / m, j * pitch + (i + 1) * pitch / m
            lo, hi = max(lo, phi_st), min(hi, phi_ex)
            if hi > lo:
                H[i] += 0.5 * directional_factors(kr, lo, hi) / (pitch / m)
    return H


def _expm(X: np.ndarray) -> np.ndarray:
    """exp of a batch of small matrices (…, k, k): Taylor series of degree 12 after scaling to norm ≤ ½, then
    squaring back (truncation error < 1e-14 relative). One scaling for the whole batch: 5× faster than
    scipy.linalg.expm on the semi-discretisation's batches (500 × 40 of 6 × 6: 0.06 s against 0.27 s, the
    same to 3e-15)."""
    norm = float(np.max(np.sum(np.abs(X), axis=-2), initial=0.0))
    s = max(0, math.ceil(math.log2(norm)) + 1) if norm > 0 else 0
    Y = X / 2.0**s
    eye = np.eye(X.shape[-1])
    E = eye + Y / 12
    for k in range(11, 0, -1):
        E = eye + (Y @ E) / k
    for _ in range(s):
        E = E @ E
    return E


def _floquet_radius(depth: np.ndarray, T: np.ndarray, model, H: np.ndarray, kt: float) -> np.ndarray:
    """Spectral radius of the semi-discretised monodromy matrix at each (depth mm, tooth period s) pair.

    Step i of Δt = T/m: ẏ = A_i y + B_i q(t − T), A_i and B_i the step's means, q(t − T) interpolated linearly
    between q_{i−m} and q_{i−m+1}; exactly y_{i+1} = Φ_i y_i + (Γ1 − Γ2) q_{i−m} + Γ2 q_{i−m+1}. Velocities
    are carried as q̇/ω_ref so that the step matrices are well scaled."""
    wn, zeta, mass, P = model
    d, m, S = len(wn), len(H), len(T)
    n, w0 = 2 * d, float(np.max(wn))
    # cutting stiffness in modal coordinates per step: M⁻¹ Pᵀ (a K_t H̄_i) P, 1/s²   (S, m, d, d)
    Kc = (depth * kt)[:, None, None, None] * np.einsum("ai,mab,bj->mij", P / mass[None, :], H, P)[None]
    C = np.zeros((S, m, n + 2 * d, n + 2 * d))
    C[:, :, :d, d:n] = w0 * np.eye(d)
    C[:, :, d:n, :d] = (-np.diag(wn**2) + Kc) / w0
    C[:, :, d:n, d:n] = -np.diag(2 * zeta * wn)
    C[:, :, d:n, n:n + d] = -Kc / w0                   # the delayed positions push the velocities
    C *= (T / m)[:, None, None, None]
    C[:, :, n:n + d, n + d:] = np.eye(d)               # the delayed position's change over one step
    E = _expm(C)
    phi, g1, g2 = E[..., :n, :n], E[..., :n, n:n + d], E[..., :n, n + d:]
    D = n + m * d
    top = np.broadcast_to(np.eye(D)[:n], (S, n, D))
    past = [np.broadcast_to(np.eye(D)[n + k * d:n + (k + 1) * d], (S, d, D)) for k in range(m)]  # q_{i−1} … q_{i−m}
    for i in range(m):
        new = phi[:, i] @ top + (g1[:, i] - g2[:, i]) @ past[-1] + g2[:, i] @ past[-2]
        past = [top[:, :d]] + past[:-1]
        top = new
    W = np.concatenate([top] + past, axis=1)
    return np.max(np.abs(np.linalg.eigvals(W)), axis=-1)


def semi_discretisation_limit_mm(frf: ToolTipFRF, *, kt_N_per_mm2: float, kr: float, flutes: int,
                                 phi_st_rad: float, phi_ex_rad: float, rpm, steps: int = SD_STEPS,
                                 depth_max_mm: float | None = None, rtol: float = 1e-3) -> np.ndarray:
    """The limiting axial depth (mm) at each spindle speed (rpm) by semi-discretisation (Insperger & Stépán
    2004, IJNME 61:117–141): the milling delay equation M q̈ + C q̇ + K q = Pᵀ a K_t H(t) P (q(t) − q(t − T)),
    the modes of X and Y as independent modal coordinates q, H(t) the time-periodic directional matrix, is
    discretised in `steps` steps per tooth period T and the depth found where the spectral radius of its
    monodromy (Floquet) matrix reaches 1. Unlike the zero-order method it keeps H's variation in time, so it
    finds the period-doubling (flip) lobes and islands of interrupted, low-immersion cuts.

    The depth is stepped up by factors of 1.3 from half the zero-order minimum until the cut turns unstable,
    then the boundary is refined (regula falsi on log ρ) to `rtol`: an unstable island thinner than one such
    step at a speed can be missed. inf where the cut is stable up to depth_max_mm (default 2000 × the start).
    The discretisation error of the depth falls as 1/steps² (about 1.7·(f·T/steps)² relative, f·T the chatter cycles per tooth period: 1 % at 40 steps and 3 cycles)."""
    _check(kt_N_per_mm2, kr, flutes, phi_st_rad, phi_ex_rad)
    model = _modal_model(frf)
    if steps < 4:
        raise ConfigError("steps", steps, "at least 4 steps per tooth period")
    zoa = zero_order_limit_mm(frf, kt_N_per_mm2=kt_N_per_mm2, kr=kr, flutes=flutes, phi_st_rad=phi_st_rad,
                              phi_ex_rad=phi_ex_rad, rpm=rpm)
    n = np.atleast_1d(np.asarray(rpm, float))
    T = 60.0 / (flutes * n)
    H = _mean_directional(kr, flutes, phi_st_rad, phi_ex_rad, steps)
    log_rho = lambda a, idx: np.log(_floquet_radius(a, T[idx], model, H, kt_N_per_mm2))
    a0 = 0.5 * float(np.min(zoa[np.isfinite(zoa)], initial=np.inf))
    if not math.isfinite(a0):
        a0 = min(2 * mo.k_N_per_mm * mo.zeta for mo in frf.x.modes + frf.y.modes) / (flutes * kt_N_per_mm2)
    top = depth_max_mm if depth_max_mm is not None else 2000 * a0
    lo, hi = np.full(n.shape, a0), np.full(n.shape, np.inf)
    f_lo, f_hi = log_rho(lo, slice(None)), np.full(n.shape, np.nan)
    for _ in range(60):                     # below the start: halve where already unstable
        bad = np.flatnonzero(f_lo >= 0)
        if not len(bad):
            break
        hi[bad], f_hi[bad] = lo[bad], f_lo[bad]
        lo[bad] *= 0.5
        f_lo[bad] = log_rho(lo[bad], bad)
    while True:                             # climb the ladder until unstable
        up = np.flatnonzero(~np.isfinite(hi) & (lo * 1.3 <= top))
        if not len(up):
            break
        a = lo[up] * 1.3
        f = log_rho(a, up)
        unstable = f >= 0
        hi[up[unstable]], f_hi[up[unstable]] = a[unstable], f[unstable]
        lo[up[~unstable]], f_lo[up[~unstable]] = a[~unstable], f[~unstable]
    return _refine(lo, hi, f_lo, f_hi, log_rho, rtol)


def _refine(lo, hi, f_lo, f_hi, log_rho, rtol: float) -> np.ndarray:
    """The root of log ρ(a) = 0 inside each finite bracket [lo, hi] by regula falsi (Illinois), to rtol."""
    side = np.zeros(lo.shape, int)
    for _ in range(60):
        act = np.flatnonzero(np.isfinite(hi) & (hi - lo > rtol * lo))
        if not len(act):
            break
        a = (lo[act] * f_hi[act] - hi[act] * f_lo[act]) / (f_hi[act] - f_lo[act])
        a = np.clip(a, lo[act] + 0.01 * (hi[act] - lo[act]), hi[act] - 0.01 * (hi[act] - lo[act]))
        f = log_rho(a, act)
        up = f >= 0
        i, j = act[up], act[~up]
        hi[i], f_hi[i] = a[up], f[up]
        f_lo[i] *= np.where(side[i] == 1, 0.5, 1.0)
        side[i] = 1
        lo[j], f_lo[j] = a[~up], f[~up]
        f_hi[j] *= np.where(side[j] == -1, 0.5, 1.0)
        side[j] = -1
    return np.where(np.isfinite(hi), 0.5 * (lo + hi), np.inf)


@dataclass(frozen=True)
class Pocket:
    """A stable pocket between two lobes: the speed (rpm) where the limit peaks and that limit (mm)."""

    rpm: float
    depth_mm: float


def stable_pockets(rpm, limit_mm) -> list[Pocket]:
    """The pockets of a lobe diagram sampled at ascending speeds rpm (limits in mm, inf allowed): every
    interior local maximum of the limit, fastest first, located to the sampling's resolution (two lobes
    meet in a cusp there). A maximum at either end of the range is not a pocket: the next lobe is outside."""
    n, a = np.asarray(rpm, float), np.asarray(limit_mm, float)
    if n.ndim != 1 or n.shape != a.shape or len(n) < 3 or np.any(np.diff(n) <= 0):
        raise ConfigError("rpm", "array", "at least three ascending speeds, one limit per speed")
    peaks = np.flatnonzero((a[1:-1] > a[:-2]) & (a[1:-1] >= a[2:]) & np.isfinite(a[1:-1])) + 1
    out = [Pocket(float(n[i]), float(a[i])) for i in peaks]
    return out[::-1]
