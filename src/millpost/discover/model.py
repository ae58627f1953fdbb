"""One linear model over all measured channels: the base terms of `rows` plus the terms of any effects,
fitted jointly by weighted least squares (each channel weighted by 1/σ², σ its residual scale, so that
newtons and watts are comparable), with the parameter covariance.

A term is a column of one channel under a parameter name; a name that appears in several channels is one
parameter shared by them (the cutting coefficients; an effect's physical constant). The cutting
coefficients, and effect parameters physics bounds (a drag, a friction), are bounded below by 0
(`nonnegative`). An effect may also
filter a channel's whole prediction (a sensor lag): a linear filter of a linear model is the same model
on filtered columns, so it stays linear.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import lsq_linear

from ..errors import MillpostError
from .rows import COEFS, CUTTING, Rows

Terms = dict[str, dict[str, np.ndarray]]          # channel → {parameter: column}
Filter = Callable[[np.ndarray], np.ndarray]        # applied along rows to every column of a channel


@dataclass
class Design:
    names: list[str]
    X: dict[str, np.ndarray]        # channel → (n, P)
    fixed: dict[str, np.ndarray]    # channel → (n,) term with no parameter
    lower: frozenset[str] = frozenset()   # parameters besides the cutting coefficients bounded below by 0


def design(rows: Rows, terms: list[Terms] = (), filters: dict[str, Filter] | None = None,
           lower: frozenset[str] = frozenset()) -> Design:
    """The stacked design: base columns, then each effect's (cutting coefficients with no column in the
    measured channels are left out: the log says nothing about them); `lower`: effect parameters that
    physics bounds below by 0 (a drag, a friction)."""
    filters = filters or {}
    cols: dict[str, dict[str, np.ndarray]] = {c: {} for c in rows.channels}
    fixed = {c: rows.fixed.get(c, np.zeros(len(rows))).astype(float) for c in rows.channels}
    for c in rows.channels:
        if c in CUTTING:
            for k, name in enumerate(COEFS):
                col = rows.cut[c][:, k]
                if col.any():
                    cols[c][name] = col
        for name, col in rows.columns.get(c, {}).items():
            cols[c][f"{c}:{name}"] = col
    for t in terms:
        for c, named in t.items():
            if c in cols:
                for name, col in named.items():
                    cols[c][name] = cols[c].get(name, 0.0) + col
    names: list[str] = []
    for c in cols:
        names += [k for k in cols[c] if k not in names]
    X = {}
    for c in cols:
        m = np.zeros((len(names), len(rows)))     # column-major: each column written contiguously
        for k, col in cols[c].items():
            m[names.index(k)] = col
        m = m.T
        if c in filters:
            m = filters[c](m)
            fixed[c] = filters[c](fixed[c][:, None])[:, 0]
        X[c] = m
    return Design(names, X, fixed, frozenset(lower))


@dataclass
class Fit:
    """beta: parameters by name; cov: their covariance; sigma: per-channel residual scale used as weight;
    predicted: the prediction on the design it was fitted on (channel → (n,)); chi2: its weighted sum of
    squared training residuals."""

    names: list[str]
    beta: np.ndarray
    cov: np.ndarray
    sigma: dict[str, float]
    predicted: dict[str, np.ndarray] = field(default_factory=dict)
    chi2: float = float("nan")

    def params(self) -> dict[str, float]:
        return dict(zip(self.names, self.beta.tolist()))

    def stderr(self) -> dict[str, float]:
        return dict(zip(self.names, np.sqrt(np.maximum(np.diag(self.cov), 0.0)).tolist()))

    def predict(self, d: Design) -> dict[str, np.ndarray]:
        b = np.array([self.params().get(n, 0.0) for n in d.names])
        return {c: d.X[c] @ b + d.fixed[c] for c in d.X}


def solve(d: Design, rows: Rows, train: np.ndarray, sigma: dict[str, float]) -> Fit:
    """Weighted least squares on the `train` rows (each channel's residuals divided by its σ)."""
    P = len(d.names)
    A = np.zeros((P, P))
    b = np.zeros(P)
    dof = -P
    for c, X in d.X.items():
        y = rows.measured[c] - d.fixed[c]
        ok = train & np.isfinite(y)
        w = 1.0 / sigma[c] ** 2
        Xo = X[ok]
        A += w * Xo.T @ Xo
        b += w * Xo.T @ y[ok]
        dof += int(ok.sum())
    if dof <= 0:
        raise MillpostError(f"too few log rows ({dof + P}) for {P} parameters")
    scale = np.sqrt(np.maximum(np.diag(A), 1e-300))
    As, bs = A / np.outer(scale, scale), b / scale
    free = np.ones(P, bool)
    x = np.linalg.pinv(As, rcond=1e-10) @ bs
    coef = np.array([n in COEFS or n in d.lower for n in d.names])
    if (x[coef] < 0).any():
        x = nonnegative(As, bs, coef)
        free = ~coef | (x > 0)
    inv = np.zeros((P, P))
    inv[np.ix_(free, free)] = np.linalg.pinv(As[np.ix_(free, free)], rcond=1e-10)
    fit = Fit(list(d.names), x / scale, np.zeros((P, P)), dict(sigma))
    fit.predicted = fit.predict(d)
    fit.chi2 = sum(float(np.nansum(((rows.measured[c] - fit.predicted[c])[train]) ** 2)) / sigma[c] ** 2
                   for c in d.X)
    fit.cov = fit.chi2 / dof * inv / np.outer(scale, scale)
    return fit


def nonnegative(A: np.ndarray, b: np.ndarray, lower: np.ndarray) -> np.ndarray:
    """argmin xᵀAx − 2bᵀx with x ≥ 0 where `lower` (the cutting coefficients: a negative K_rc or K_te is a
    mismatch of the model absorbed by a coefficient, not a material's property), free elsewhere: the
    bounded least squares ‖Mx − c‖² with A = MᵀM, Mᵀc = b (M from A's eigendecomposition)."""
    s, V = np.linalg.eigh(A)
    keep = s > 1e-10 * s.max()
    M = np.sqrt(s[keep])[:, None] * V[:, keep].T
    c = (V[:, keep].T @ b) / np.sqrt(s[keep])
    return lsq_linear(M, c, bounds=(np.where(lower, 0.0, -np.inf), np.inf), method="bvls").x


def residual_scale(d: Design, rows: Rows, train: np.ndarray, fit: Fit | None = None) -> dict[str, float]:
    """Per channel σ: the RMS training residual of `fit` (or the measured values' spread without one)."""
    pred = fit.predicted if fit is not None else None
    out = {}
    for c in d.X:
        y = rows.measured[c][train]
        r = y - pred[c][train] if pred is not None else y - np.nanmean(y)
        s = float(np.sqrt(np.nanmean(r * r)))
        out[c] = s if s > 0 else 1.0
    return out
