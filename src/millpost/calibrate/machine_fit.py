"""Machine constants from measurements: axis drive mass and friction from motor currents, spindle no-load
power and current, machine stiffness from load vs displacement.

Axis drive (machine.py's model, at one axis): the motor current is

    i = k_a·a + k_c·sgn(v) + k_v·v (+ i₀)

with k_a = (J_rotor/ρ + m ρ/η)/K_t (inertia), k_c = F_c ρ/(η K_t) (Coulomb), k_v = c ρ/(η K_t) (viscous)
— a linear regression in the current's own units, so it needs no drive constants; with them
(`AxisDrive.axis_constants`) the fitted k's become the moving mass (kg), F_c (N) and c (N·s/mm) that a
machine file holds. i₀ absorbs an offset of the current sensor or a constant load (gravity on Z).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import MillpostError
from ..forces import NotFittedError
from ..machine import Axis

TERMS = ("inertia", "coulomb", "viscous")


class AxisDrive:
    """Motor current of one axis from its velocity (mm/s) and acceleration (mm/s²), least squares.

    Settings: terms (a subset of TERMS, in order), intercept. Learned: coef_ (A per mm/s², A, A per mm/s,
    in the order of `terms`), intercept_ (A), cov_ (covariance of [coef_, intercept_]), r2_."""

    def __init__(self, terms: tuple[str, ...] = TERMS, *, intercept: bool = True) -> None:
        unknown = [t for t in terms if t not in TERMS]
        if unknown or not terms:
            raise MillpostError(f"axis terms must be among {', '.join(TERMS)}, got {terms}")
        self.terms, self.intercept = tuple(terms), intercept

    def _design(self, velocity_mm_s, accel_mm_s2) -> np.ndarray:
        v, a = np.asarray(velocity_mm_s, float), np.asarray(accel_mm_s2, float)
        cols = {"inertia": a, "coulomb": np.sign(v), "viscous": v}
        X = [cols[t] for t in self.terms]
        if self.intercept:
            X.append(np.ones_like(v))
        return np.column_stack(X)

    def fit(self, velocity_mm_s, accel_mm_s2, current_A) -> "AxisDrive":
        X = self._design(velocity_mm_s, accel_mm_s2)
        y = np.asarray(current_A, float)
        ok = np.isfinite(X).all(1) & np.isfinite(y)
        X, y = X[ok], y[ok]
        if len(y) <= X.shape[1]:
            raise MillpostError(f"axis fit needs more than {X.shape[1]} samples, got {len(y)}")
        scale = np.maximum(np.linalg.norm(X, axis=0), 1e-300)
        sol, *_ = np.linalg.lstsq(X / scale, y, rcond=None)
        beta = sol / scale
        r = y - X @ beta
        dof = max(len(y) - X.shape[1], 1)
        self.cov_ = float(r @ r) / dof * np.linalg.pinv(X.T @ X)
        self.coef_ = beta[:len(self.terms)]
        self.intercept_ = float(beta[-1]) if self.intercept else 0.0
        ss = float(np.sum((y - y.mean()) ** 2))
        self.r2_ = 1.0 - float(r @ r) / ss if ss > 0 else float("nan")
        return self

    def predict(self, velocity_mm_s, accel_mm_s2) -> np.ndarray:
        if not hasattr(self, "coef_"):
            raise NotFittedError("AxisDrive: call fit() first")
        X = self._design(velocity_mm_s, accel_mm_s2)
        return X[:, :len(self.terms)] @ self.coef_ + self.intercept_

    def axis_constants(self, axis: Axis) -> dict[str, float]:
        """The fitted current coefficients as a machine file's axis fields (kg, N, N·s/mm), through the
        axis's K_t, transmission ρ, efficiency η and rotor inertia."""
        if not hasattr(self, "coef_"):
            raise NotFittedError("AxisDrive: call fit() first")
        k = dict(zip(self.terms, self.coef_))
        kt, rho, eta = axis.motor.kt_Nm_per_A, axis.rho_m_per_rad, axis.efficiency
        out = {}
        if "inertia" in k:   # A per mm/s² → per m/s²: ×1000
            out["moving_mass_kg"] = (k["inertia"] * 1000.0 * kt - axis.motor.rotor_inertia_kgm2 / rho) * eta / rho
        if "coulomb" in k:
            out["friction_coulomb_N"] = k["coulomb"] * kt * eta / rho
        if "viscous" in k:
            out["friction_viscous_N_s_per_mm"] = k["viscous"] * kt * eta / rho
        return out


@dataclass(frozen=True)
class Stiffness:
    """k (N/mm) with its standard error, the offset (N) and R² of F = k·x + b on the loading branch."""

    k_N_per_mm: float
    stderr_N_per_mm: float
    offset_N: float
    r2: float
    samples: int


def fit_stiffness(force_N, displacement_mm) -> Stiffness:
    """Machine stiffness from a push test (PHYSICS.md §5.4): least squares F = k·x + b on the loading
    branch (the samples where |F| rises; unloading shows hysteresis and backlash, fitted apart if at all)."""
    f, x = np.asarray(force_N, float), np.asarray(displacement_mm, float)
    ok = np.isfinite(f) & np.isfinite(x)
    f, x = f[ok], x[ok]
    if len(f) < 3:
        raise MillpostError(f"stiffness fit needs at least 3 samples of force and displacement, got {len(f)}")
    mag = np.abs(f)
    loading = mag >= np.maximum.accumulate(mag)   # at a new maximum of |F|: the loading branch
    f, x = f[loading], x[loading]
    X = np.column_stack([x, np.ones_like(x)])
    beta, *_ = np.linalg.lstsq(X, f, rcond=None)
    r = f - X @ beta
    dof = max(len(f) - 2, 1)
    cov = float(r @ r) / dof * np.linalg.pinv(X.T @ X)
    ss = float(np.sum((f - f.mean()) ** 2))
    return Stiffness(float(abs(beta[0])), float(np.sqrt(cov[0, 0])), float(beta[1]),
                     1.0 - float(r @ r) / ss if ss > 0 else float("nan"), len(f))


def fit_idle_power(rpm, power_W, *, resolution_rpm: float = 50.0) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """No-load spindle power (W) per speed: the mean power at each speed level (speeds within
    resolution_rpm are one level), as the (idle_rpm, idle_power_W) points of a machine file; a mean under
    0 (a spindle with no measurable no-load loss, read through a sensor's noise) is 0."""
    n, p = np.asarray(rpm, float), np.asarray(power_W, float)
    ok = np.isfinite(n) & np.isfinite(p) & (n > 0)
    if not ok.any():
        raise MillpostError("no idle samples (spindle on, not cutting) with speed and power")
    levels = np.round(n[ok] / resolution_rpm) * resolution_rpm
    speeds = np.unique(levels)
    return tuple(float(s) for s in speeds), tuple(max(float(np.mean(p[ok][levels == s])), 0.0) for s in speeds)


def fit_spindle_current(torque_Nm, current_A) -> tuple[float, float]:
    """(K_t N·m/A, I₀ A) of I² = I₀² + (T/K_t)² by least squares in (T², 1) (machine.Spindle.current_A)."""
    t, i = np.asarray(torque_Nm, float), np.asarray(current_A, float)
    ok = np.isfinite(t) & np.isfinite(i)
    if ok.sum() < 3:
        raise MillpostError("spindle current fit needs at least 3 samples of torque and current")
    X = np.column_stack([t[ok] ** 2, np.ones(ok.sum())])
    (a, b), *_ = np.linalg.lstsq(X, i[ok] ** 2, rcond=None)
    if a <= 0:
        raise MillpostError("the spindle current does not rise with torque in this log: no K_t")
    return float(1.0 / np.sqrt(a)), float(np.sqrt(max(b, 0.0)))
