"""Kienzle milling model: F_t = k_c1.1 · b · h^(1−m_c) per tooth (Kienzle–Victor; Sandvik; Tschätsch).

Radial and axial forces follow the tangential force by constant ratios (the tables of k_f1.1, k_p1.1
were not available; PHYSICS.md §2.2 suggests F_r/F_t ≈ K_rc/K_tc), so every load shares the exponent
p = 1 − m_c and the mean over a tooth period is exactly L = Q · f_z^p with Q from the integrals
∫ sin^p φ dφ (incomplete beta function) over each slice's engaged arc. No edge term.

For the scheduler: f_z^p is concave, so its tangent at a reference feed bounds it from above for every
feed and is exact at the reference (`linear_loads`); because all components share p, the tangent of the
force vector also bounds its norm.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import least_squares
from scipy.special import beta as beta_fn
from scipy.special import betainc

from ..engagement import Engagement
from ..errors import MillpostError
from ..tools.cutter import Tool
from .base import (LinearLoads, Loads, Measurements, NotFittedError, assemble_loads, clipped_arcs, rpm_array,
                   to_machine, tool_arrays)
from .timedomain import simulate

# Medians of K_rc/K_tc and K_ac/K_tc over the aluminium rows of PHYSICS.md §1.6 (CJME 2021 Table 5).
DEFAULT_RADIAL_RATIO = 0.30
DEFAULT_AXIAL_RATIO = 0.29


def sin_power_integral(q: float, a, b) -> np.ndarray:
    """∫_a^b sin^q φ dφ for 0 ≤ a ≤ b ≤ π, q > −1 (exact, via the incomplete beta function)."""
    total = beta_fn((q + 1) / 2, 0.5)

    def F(phi):
        phi = np.asarray(phi, float)
        low = np.minimum(phi, np.pi - phi)
        part = 0.5 * total * betainc((q + 1) / 2, 0.5, np.sin(low) ** 2)
        return np.where(phi <= np.pi / 2, part, total - part)

    return F(b) - F(a)


def power_law_coefficients(engagement: Engagement, flutes, mc: float, radial_ratio: float,
                           axial_ratio: float) -> np.ndarray:
    """Q: (N, 4) with [F̄_x, F̄_y, F̄_z (feed frame, N), T̄ (N·mm)] = k_c1.1 · Q · f_z^(1−m_c).
    flutes: one number, or one per sample."""
    p = 1.0 - mc
    st, ex, b = clipped_arcs(engagement)
    s, c = np.sin(engagement.kappa), np.cos(engagement.kappa)
    s_p = sin_power_integral(p, st, ex)
    s_p1 = sin_power_integral(p + 1, st, ex)
    c_p = (np.sin(ex) ** (p + 1) - np.sin(st) ** (p + 1)) / (p + 1)   # ∫ sin^p φ cos φ
    rad = s * radial_ratio + c * axial_ratio
    w = np.reshape(np.asarray(flutes, float), (-1, 1)) / (2 * np.pi) * b * np.power(s, p)
    Q = np.stack([-c_p - rad * s_p1, s_p1 - rad * c_p, (s * axial_ratio - c * radial_ratio) * s_p,
                  engagement.r_mm * s_p], -1)
    return (w[..., None] * Q).sum(1)


def log_problem(engagement: Engagement, measured: Measurements, tool: Tool | Sequence[Tool], radial_ratio: float,
                axial_ratio: float):
    """(y, model_log): the logs of the measured cutting power (W) and |F̄_xy| (N), and the function
    θ = (log k_c1.1, m_c) → the model's logs of the same (`Kienzle.fit`); non-positive values left out."""
    n = len(engagement)
    fz = np.broadcast_to(np.asarray(measured.fz_mm, float), (n,)).astype(float)
    omega = 2 * np.pi * rpm_array(measured.rpm, n) / 60.0
    flutes, _ = tool_arrays(tool, n)
    targets = []
    if measured.power_W is not None:
        targets.append(("power", np.broadcast_to(np.asarray(measured.power_W, float), (n,))))
    if measured.force_N is not None:
        f = np.asarray(measured.force_N, float).reshape(n, 3)
        targets.append(("fxy", np.hypot(f[:, 0], f[:, 1])))
    if not targets:
        raise MillpostError("fit needs measured forces or power")
    masks = [np.isfinite(v) & (v > 0) & (fz > 0) for _, v in targets]
    y = np.concatenate([np.log(v[m]) for (_, v), m in zip(targets, masks)])

    def model_log(theta):
        log_kc, mc = theta
        Q = power_law_coefficients(engagement, flutes, mc, radial_ratio, axial_ratio)
        base = np.log(fz) * (1 - mc) + log_kc
        out = []
        for (kind, _), m in zip(targets, masks):
            mag = Q[:, 3] / 1000 * omega if kind == "power" else np.hypot(Q[:, 0], Q[:, 1])
            out.append(base[m] + np.log(np.maximum(mag[m], 1e-300)))
        return np.concatenate(out)

    return y, model_log


class Kienzle:
    """Kienzle model. Settings: radial_ratio = F_r/F_t, axial_ratio = F_a/F_t, steps_per_rev (peaks).
    Learned: coef_ = (k_c1.1 [N/mm²], m_c), coef_cov_ (2×2). Known values via `from_coefficients`."""

    name = "kienzle"

    def __init__(self, *, radial_ratio: float = DEFAULT_RADIAL_RATIO, axial_ratio: float = DEFAULT_AXIAL_RATIO,
                 steps_per_rev: int = 360) -> None:
        self.radial_ratio, self.axial_ratio, self.steps_per_rev = radial_ratio, axial_ratio, steps_per_rev

    @classmethod
    def from_coefficients(cls, kc11: float, mc: float, **settings) -> "Kienzle":
        if not (kc11 > 0 and 0 <= mc < 1):
            raise MillpostError(f"Kienzle needs kc1.1 > 0 and 0 <= mc < 1, got kc1.1={kc11}, mc={mc}")
        model = cls(**settings)
        model.coef_ = np.array([kc11, mc], float)
        model.coef_cov_ = np.zeros((2, 2))
        return model

    @classmethod
    def from_material(cls, material, **settings) -> "Kienzle":
        """The material's published Kienzle set (k_c1.1, m_c and the F_r/F_t, F_a/F_t ratios)."""
        k = material.kienzle
        return cls.from_coefficients(k.kc11_N_mm2, k.mc, radial_ratio=k.radial_ratio, axial_ratio=k.axial_ratio,
                                     **settings)

    def _coef(self) -> np.ndarray:
        if not hasattr(self, "coef_"):
            raise NotFittedError("Kienzle model has no coefficients: call fit() or from_coefficients()")
        return self.coef_

    def power_law(self, engagement: Engagement, tool: Tool) -> tuple[np.ndarray, float]:
        """(Q (N, 4), p): exact mean [F_x, F_y, F_z (feed frame, N), T (N·mm)] = Q · f_z^p."""
        kc11, mc = self._coef()
        Q = power_law_coefficients(engagement, tool.flutes, mc, self.radial_ratio, self.axial_ratio)
        return kc11 * Q, 1.0 - mc

    def predict(self, engagement: Engagement, fz_mm, rpm, tool: Tool, *, peaks: bool = True) -> Loads:
        """Loads per sample at feed per tooth fz_mm (scalar or (N,), mm) and spindle speed rpm.
        peaks=False skips the time-domain run (peak fields are nan): averages only, much faster."""
        fz = np.broadcast_to(np.asarray(fz_mm, float), (len(engagement),)).astype(float)
        Q, p = self.power_law(engagement, tool)
        kc = self._coef()[0] * np.array([1.0, self.radial_ratio, self.axial_ratio])
        return assemble_loads(engagement, tool, Q * fz[:, None] ** p, fz, rpm, kc=kc, ke=np.zeros(3), p=p,
                              steps_per_rev=self.steps_per_rev, peaks=peaks)

    def linear_loads(self, engagement: Engagement, tool: Tool, rpm, feed_ref_mm_min=None) -> LinearLoads:
        """Tangent at feed_ref (the F word, mm/min, scalar or (N,)) of the exact law, affine in the path
        feed (mm/s; `LinearLoads.per_minute`): an upper bound for every feed ≥ 0, exact at the reference:
        f_z^p ≤ p f_0^(p−1) f_z + (1 − p) f_0^p."""
        if feed_ref_mm_min is None:
            raise MillpostError("the Kienzle model needs a reference feed for its linear bound")
        n = len(engagement)
        rpm_n = rpm_array(rpm, n)
        per_feed = 1.0 / (tool.flutes * rpm_n)
        f0 = np.broadcast_to(np.asarray(feed_ref_mm_min, float), (n,)) * per_feed
        if np.any(f0 <= 0):
            raise MillpostError("the reference feed must be > 0")
        Q, p = self.power_law(engagement, tool)
        slope = p * f0 ** (p - 1) * per_feed          # d(f_z^p)/dv at the reference
        icpt = (1 - p) * f0 ** p
        omega = 2 * np.pi * rpm_n / 60.0
        kc11 = self._coef()[0]
        st, ex, b = clipped_arcs(engagement)
        peaks, _ = simulate(
            st, ex, b, engagement.z_mm, engagement.dz_mm, engagement.r_mm, engagement.kappa,
            kc=kc11 * np.array([1.0, self.radial_ratio, self.axial_ratio]), ke=np.zeros(3), p=p,
            flutes=tool.flutes, helix_deg=tool.helix_deg, radius_mm=tool.radius_mm, fz_mm=np.ones(n),
            steps_per_rev=self.steps_per_rev)           # peak ∝ f_z^p as well
        peak1 = peaks[:, 0]
        fd = engagement.feed_dir
        F = to_machine(fd, Q[:, :3])
        T = Q[:, 3] / 1000.0
        return LinearLoads.per_minute(
            force_a=F * slope[:, None], force_b=F * icpt[:, None], peak_a=peak1 * slope, peak_b=peak1 * icpt,
            torque_a=T * slope, torque_b=T * icpt, power_a=T * slope * omega, power_b=T * icpt * omega,
            exact=False, feed_ref_mm_min=f0 / per_feed)

    def fit(self, engagement: Engagement, measured: Measurements, tool: Tool | Sequence[Tool]) -> "Kienzle":
        """k_c1.1 and m_c by least squares in log space on cutting power and/or |F̄_xy| (`tool`: the tool of
        every sample, or one per sample).

        log L = log k_c1.1 + p log f_z + log Q(m_c): linear in log k_c1.1 and nearly linear in m_c
        (Gauss–Newton from m_c = 0.25). Covariance s²(JᵀJ)⁻¹ (relative noise is constant in log space),
        mapped to k_c1.1 by the delta method.
        """
        y, model_log = log_problem(engagement, measured, tool, self.radial_ratio, self.axial_ratio)
        if len(y) <= 2:
            raise MillpostError(f"fit needs more than 2 positive measured values, got {len(y)}")
        start = np.array([np.log(1000.0), 0.25])
        start[0] += np.mean(y - model_log(start))
        res = least_squares(lambda t: model_log(t) - y, start, bounds=([-np.inf, 0.0], [np.inf, 0.95]),
                            method="trf", x_scale=[1.0, 0.1])
        dof = len(y) - 2
        s2 = float(res.fun @ res.fun) / dof
        cov_t = s2 * np.linalg.pinv(res.jac.T @ res.jac)
        kc11 = float(np.exp(res.x[0]))
        J = np.diag([kc11, 1.0])
        self.coef_ = np.array([kc11, res.x[1]])
        self.coef_cov_ = J @ cov_t @ J
        return self
