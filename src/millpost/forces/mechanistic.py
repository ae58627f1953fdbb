"""Mechanistic (linear edge-force) milling model, Altintas, *Manufacturing Automation* 2nd ed., ch. 2.

Per tooth and disk: dF_t = (K_tc h + K_te) db, dF_r = (K_rc h + K_re) db, dF_a = (K_ac h + K_ae) db with
h = f_z sin φ sin κ. K_*c in N/mm², K_*e in N/mm. Averaged over a tooth period every load is exactly
affine in f_z: F = f_z·G·K_c + E·K_e, where the regressors G, E integrate the projections over the
engaged arc of each axial slice (`regressors`). The same regressors give `predict`, the exact
`linear_loads` for the scheduler, and the least-squares `fit` (the slot-test regression generalised
to any engagement).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..engagement import Engagement
from ..errors import MillpostError
from ..tools.cutter import Tool
from .base import (LinearLoads, Loads, Measurements, NotFittedError, assemble_loads, clipped_arcs, rpm_array,
                   to_feed, to_machine, tool_arrays)
from .timedomain import cutting_samples, simulate

COEF_NAMES = ("Ktc", "Krc", "Kac", "Kte", "Kre", "Kae")


def regressors(engagement: Engagement, flutes) -> tuple[np.ndarray, np.ndarray]:
    """G, E: (N, 4, 3) so that [F̄_x, F̄_y, F̄_z, T̄] (feed frame; N, N, N, N·mm) =
    f_z·G @ (K_tc, K_rc, K_ac) + E @ (K_te, K_re, K_ae)  (closed-form integrals, PHYSICS.md §1.3).
    flutes: one number, or one per sample. A sample where no slice cuts has G = E = 0."""
    return arc_regressors(clipped_arcs(engagement), engagement.kappa, engagement.r_mm, flutes)


def arc_regressors(arcs: tuple[np.ndarray, np.ndarray, np.ndarray], kappa: np.ndarray, r_mm: np.ndarray, flutes
                   ) -> tuple[np.ndarray, np.ndarray]:
    """`regressors` from the slices' `clipped_arcs` (entry, exit (rad), width b (mm)), κ (rad) and radii (mm)."""
    st, ex, b = arcs
    w = np.reshape(np.asarray(flutes, float), (-1, 1)) / (2 * np.pi) * b
    live = cutting_samples(b)  # only these are computed (b = 0: every term is 0)
    G, E = np.zeros((len(b), 4, 3)), np.zeros((len(b), 4, 3))
    G[live], E[live] = _regressors(st[live], ex[live], w[live], kappa[live], r_mm[live])
    return G, E


def _regressors(st: np.ndarray, ex: np.ndarray, w: np.ndarray, kappa: np.ndarray, r: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """`regressors` of (M, K) slices: engaged arcs [st, ex] (rad), weights w = flutes/(2π)·b (mm), κ (rad),
    radii r (mm)."""
    s, c = np.sin(kappa), np.cos(kappa)
    d = lambda f: f(ex) - f(st)  # noqa: E731
    i_sc = d(lambda p: -np.cos(2 * p) / 4)           # ∫ sin φ cos φ
    i_ss = d(lambda p: (2 * p - np.sin(2 * p)) / 4)  # ∫ sin² φ
    i_c = d(np.sin)                                  # ∫ cos φ
    i_s = d(lambda p: -np.cos(p))                    # ∫ sin φ
    i_1 = ex - st
    G = _folded(w, [[-s * i_sc, -s * s * i_ss, -c * s * i_ss],
                    [s * i_ss, -s * s * i_sc, -c * s * i_sc],
                    [None, -c * s * i_s, s * s * i_s],
                    [r * s * i_s, None, None]])
    E = _folded(w, [[-i_c, -s * i_s, -c * i_s],
                    [i_s, -s * i_c, -c * i_c],
                    [None, -c * i_1, s * i_1],
                    [r * i_1, None, None]])
    return G, E


def _folded(w: np.ndarray, terms: list[list[np.ndarray | None]]) -> np.ndarray:
    """(M, 4, 3): Σ_k w·x over the slices k in slice order, for each (M, K) term x of the 4 × 3 `terms`
    (None: 0), all terms at once."""
    present = np.array([[x is not None for x in row] for row in terms])
    wx = w * np.stack([x for row in terms for x in row if x is not None])
    out = np.zeros(wx.shape[:2])
    for k in range(wx.shape[2]):
        out += wx[:, :, k]
    folded = np.zeros((w.shape[0], 4, 3))
    folded[:, present] = out.T
    return folded


def design(engagement: Engagement, measured: Measurements, tool: Tool | Sequence[Tool]
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The linear problem y = X·(K_tc, K_rc, K_ac, K_te, K_re, K_ae) of measured means (`Mechanistic.fit`):
    rows are the measured feed-frame force components (N) and the power as an equivalent tangential
    force P/(ω R) (N), in that order; rows whose measurement is nan are left out. Third: each row's kind
    (0, 1, 2: feed-frame x, y, z force; 3: power)."""
    n = len(engagement)
    fz = np.broadcast_to(np.asarray(measured.fz_mm, float), (n,)).astype(float)
    omega = 2 * np.pi * rpm_array(measured.rpm, n) / 60.0
    flutes, radius = tool_arrays(tool, n)
    G, E = regressors(engagement, flutes)
    X_all = np.concatenate([fz[:, None, None] * G, E], axis=2)  # (N, 4, 6)
    rows, ys, kinds = [], [], []
    if measured.force_N is not None:
        f_feed = to_feed(engagement.feed_dir, np.asarray(measured.force_N, float).reshape(n, 3))
        for q in range(3):
            ok = np.isfinite(f_feed[:, q])
            rows.append(X_all[ok, q]), ys.append(f_feed[ok, q]), kinds.append(np.full(ok.sum(), q))
    if measured.power_W is not None:
        p = np.broadcast_to(np.asarray(measured.power_W, float), (n,))
        ok = np.isfinite(p)
        rows.append(X_all[ok, 3] / radius[ok, None])                 # T̄/R (N)
        ys.append(p[ok] * 1000.0 / (omega[ok] * radius[ok]))          # P/(ω R) (N)
        kinds.append(np.full(ok.sum(), 3))
    if not rows or sum(len(y) for y in ys) == 0:
        raise MillpostError("fit needs measured forces or power")
    return np.concatenate(rows), np.concatenate(ys), np.concatenate(kinds)


class Mechanistic:
    """Linear edge-force model.

    Settings: runout_mm (per-flute radial offsets, peaks only), steps_per_rev (angular resolution of the
    time-domain peak), reweight_steps (see `fit`). Learned: coef_ (K_tc, K_rc, K_ac in N/mm², K_te, K_re,
    K_ae in N/mm — order `COEF_NAMES`), coef_cov_ (6×6 covariance from `fit`). Build with known
    coefficients through `from_coefficients`."""

    name = "mechanistic"

    def __init__(self, *, runout_mm: tuple[float, ...] | None = None, steps_per_rev: int = 360,
                 reweight_steps: int = 2) -> None:
        self.runout_mm = runout_mm
        self.steps_per_rev = steps_per_rev
        self.reweight_steps = reweight_steps

    @classmethod
    def from_coefficients(cls, Ktc: float, Krc: float, Kac: float, Kte: float, Kre: float, Kae: float,
                          **settings) -> "Mechanistic":
        model = cls(**settings)
        model.coef_ = np.array([Ktc, Krc, Kac, Kte, Kre, Kae], float)
        model.coef_cov_ = np.zeros((6, 6))
        return model

    @classmethod
    def from_material(cls, material, *, h0_mm: float = 0.05, **settings) -> "Mechanistic":
        """The material's published mechanistic set when it has one; otherwise the tangent of its Kienzle
        law at chip thickness h0 (mm): K_tc = (1 − m_c) k_c1.1 h0^(−m_c), K_te = m_c k_c1.1 h0^(1−m_c),
        radial and axial terms by the Kienzle ratios (the tangent bounds the Kienzle force from above)."""
        if material.mechanistic is not None:
            return cls.from_coefficients(*material.mechanistic.values(), **settings)
        if h0_mm <= 0:
            raise MillpostError(f"h0_mm must be > 0 mm, got {h0_mm}")
        k = material.kienzle
        ktc = (1 - k.mc) * k.kc11_N_mm2 * h0_mm ** (-k.mc)
        kte = k.mc * k.kc11_N_mm2 * h0_mm ** (1 - k.mc)
        return cls.from_coefficients(ktc, k.radial_ratio * ktc, k.axial_ratio * ktc,
                                     kte, k.radial_ratio * kte, k.axial_ratio * kte, **settings)

    @property
    def coefficients(self) -> dict[str, float]:
        return dict(zip(COEF_NAMES, self._coef().tolist()))

    def _coef(self) -> np.ndarray:
        if not hasattr(self, "coef_"):
            raise NotFittedError("Mechanistic model has no coefficients: call fit() or from_coefficients()")
        return self.coef_

    # --- prediction -----------------------------------------------------------------------------
    def _averages(self, engagement: Engagement, fz: np.ndarray, tool: Tool) -> np.ndarray:
        """(N, 4) [F̄_x, F̄_y, F̄_z (feed frame, N), T̄ (N·mm)] at feed per tooth fz (N,)."""
        G, E = regressors(engagement, tool.flutes)
        k = self._coef()
        return fz[:, None] * (G @ k[:3]) + E @ k[3:]

    def predict(self, engagement: Engagement, fz_mm, rpm, tool: Tool, *, peaks: bool = True) -> Loads:
        """Loads per sample at feed per tooth fz_mm (scalar or (N,), mm) and spindle speed rpm.
        peaks=False skips the time-domain run (peak fields are nan): averages only, much faster."""
        fz = np.broadcast_to(np.asarray(fz_mm, float), (len(engagement),)).astype(float)
        k = self._coef()
        return assemble_loads(engagement, tool, self._averages(engagement, fz, tool), fz, rpm, kc=k[:3], ke=k[3:],
                              p=1.0, runout_mm=self.runout_mm, steps_per_rev=self.steps_per_rev, peaks=peaks)

    def linear_loads(self, engagement: Engagement, tool: Tool, rpm, feed_ref_mm_min=None) -> LinearLoads:
        """Exact affine loads in the path feed (mm/s; `LinearLoads.per_minute`): f_z = v / (flutes·rpm) for v
        in mm/min. feed_ref is not needed.

        The peak bound is max_φ ‖A(φ)‖·f_z + max_φ ‖B(φ)‖ (triangle inequality on the instantaneous
        force f_z·A(φ) + B(φ)), shearing part at f_z = 1 and edge part from one time-domain run; runout is
        not included in this bound.
        """
        n = len(engagement)
        rpm_n = rpm_array(rpm, n)
        per_feed = 1.0 / (tool.flutes * rpm_n)           # f_z per (mm/min)
        st, ex, b = arcs = clipped_arcs(engagement)
        G, E = arc_regressors(arcs, engagement.kappa, engagement.r_mm, tool.flutes)
        k = self._coef()
        slope, icpt = G @ k[:3], E @ k[3:]               # per f_z, and at f_z = 0
        omega = 2 * np.pi * rpm_n / 60.0
        geo = (st, ex, b, engagement.z_mm, engagement.dz_mm, engagement.r_mm, engagement.kappa)
        peaks, _ = simulate(*geo, kc=k[:3], ke=k[3:], fz_mm=np.ones(n), p=1.0, flutes=tool.flutes,
                            helix_deg=tool.helix_deg, radius_mm=tool.radius_mm, steps_per_rev=self.steps_per_rev)
        pa, pb = peaks[:, 1], peaks[:, 2]
        fd = engagement.feed_dir
        return LinearLoads.per_minute(
            force_a=to_machine(fd, slope[:, :3]) * per_feed[:, None], force_b=to_machine(fd, icpt[:, :3]),
            peak_a=pa * per_feed, peak_b=pb,
            torque_a=slope[:, 3] / 1000 * per_feed, torque_b=icpt[:, 3] / 1000,
            power_a=slope[:, 3] / 1000 * per_feed * omega, power_b=icpt[:, 3] / 1000 * omega,
            exact=True, feed_ref_mm_min=None)

    # --- identification -------------------------------------------------------------------------
    def fit(self, engagement: Engagement, measured: Measurements, tool: Tool | Sequence[Tool]) -> "Mechanistic":
        """Least-squares coefficients from measured average forces and/or cutting power per sample
        (`tool`: the tool of every sample, or one per sample for cuts with several tools).

        Rows: the three feed-frame force components (measured machine-XYZ forces rotated by the feed
        direction) and the power as an equivalent tangential force P/(ω R). Measurement noise is taken
        to grow with the load (sensor gain errors, unsteady cutting): after an ordinary solve the rows
        are reweighted by 1/ŷ² (`reweight_steps` times, 0 = ordinary least squares). The covariance is
        the heteroscedasticity-consistent sandwich (HC3) of the weighted problem, valid either way.
        Columns with no information (K_r*, K_a* from power alone) keep the model's current values and
        get zero variance; a model without coefficients then refuses.
        """
        X, y, _ = design(engagement, measured, tool)
        informative = np.linalg.norm(X, axis=0) > 1e-12 * np.linalg.norm(X)
        coef = np.full(6, np.nan) if not hasattr(self, "coef_") else self.coef_.astype(float).copy()
        if not informative.all() and not np.isfinite(coef[~informative]).all():
            missing = [COEF_NAMES[i] for i in np.flatnonzero(~informative)]
            raise MillpostError(f"the measurements do not determine {', '.join(missing)} (power alone fixes "
                                "only Ktc and Kte); give force measurements or start from known coefficients")
        held = ~informative
        y_free = y - X[:, held] @ coef[held] if held.any() else y
        Xf = X[:, informative]
        if len(y) <= Xf.shape[1]:
            raise MillpostError(f"fit needs more than {Xf.shape[1]} measured values, got {len(y)}")
        scale = np.linalg.norm(Xf, axis=0)
        Xs = Xf / scale
        w = np.ones(len(y))
        for _ in range(self.reweight_steps + 1):
            sw = np.sqrt(w)
            sol, *_ = np.linalg.lstsq(Xs * sw[:, None], y_free * sw, rcond=None)
            mu = np.abs(Xs @ sol)
            w = 1.0 / np.maximum(mu, 1e-3 * np.median(mu) + 1e-12) ** 2
        Xw, rw = Xs * sw[:, None], (y_free - Xs @ sol) * sw
        bread = np.linalg.pinv(Xw.T @ Xw)
        lev = np.einsum("ij,jk,ik->i", Xw, bread, Xw)
        u = rw / np.maximum(1.0 - lev, 1e-9)
        cov_s = bread @ ((Xw * (u * u)[:, None]).T @ Xw) @ bread
        coef[informative] = sol / scale
        cov = np.zeros((6, 6))
        cov[np.ix_(informative, informative)] = cov_s / np.outer(scale, scale)
        self.coef_, self.coef_cov_ = coef, cov
        return self
