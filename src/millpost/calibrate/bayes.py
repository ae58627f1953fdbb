"""What measurements say about coefficients that start from a catalogue: Gaussian prior, Gaussian noise.

Linear models (y = X θ + e, e ~ N(0, σ² I); θ ~ N(μ₀, diag(s₀²))): the posterior is Gaussian with

    Σ = (XᵀX/σ² + S₀⁻²)⁻¹,   μ = Σ (Xᵀy/σ² + S₀⁻² μ₀).

In prior-whitened coordinates z = S₀⁻¹(θ − μ₀) the data's information is A = S₀XᵀXS₀/σ²; an
eigen-direction of A with eigenvalue λ > 1 is one the data know better than the prior (its spread shrinks by √(1+λ)):
those are the identified combinations of coefficients, their number the rank, λ_max/λ_min over them the
condition. A coefficient whose posterior spread is more than half its prior spread is left at the prior:
it gets no standard error of its own. σ is estimated from the residuals when the data have at least
`MIN_DOF` degrees of freedom beyond the identified combinations, and taken as `NOISE_REL` of the
measured values' RMS otherwise (one cut: three means, six coefficients); rows from different sensors
(force components, power) get a σ each, so that one biased channel (a power with a wrong no-load
baseline) does not drown the others.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ..errors import MillpostError

NOISE_REL = 0.05    # noise of a mean over a whole cut, relative to the measured RMS, when it cannot be estimated
MIN_DOF = 3         # residual degrees of freedom needed to estimate the noise from the data
IDENTIFIED = 0.5    # posterior spread / prior spread below this: the data identify the coefficient


@dataclass
class Identifiability:
    """rank: combinations the data know better than the prior; condition: λ_max/λ_min over them;
    ratio: per coefficient, posterior over prior spread; combinations: the identified ones as
    {name: weight} (largest weight 1); noise: σ used per group of rows and whether it was estimated."""

    names: tuple[str, ...]
    rank: int
    condition: float
    ratio: np.ndarray
    combinations: list[dict[str, float]]
    noise: dict[str, float]
    noise_estimated: bool
    dof: float

    @property
    def identified(self) -> list[str]:
        return [n for n, r in zip(self.names, self.ratio) if r < IDENTIFIED]

    @property
    def at_prior(self) -> list[str]:
        return [n for n, r in zip(self.names, self.ratio) if r >= IDENTIFIED]

    def describe(self) -> str:
        combos = "; ".join(" + ".join(f"{w:.3g}·{n}" for n, w in c.items()) for c in self.combinations)
        text = (f"the data identify {self.rank} of {len(self.names)} combinations (condition {self.condition:.3g}): "
                f"{combos or 'none'}")
        if self.at_prior:
            text += (f"; not identified alone, so left near the prior: {', '.join(self.at_prior)} (more chip "
                     "thicknesses or engagements would separate them)")
        return text

    def as_dict(self) -> dict:
        return {"rank": self.rank, "condition": self.condition, "identified": self.identified,
                "at_prior": self.at_prior, "combinations": self.combinations,
                "posterior_over_prior_spread": dict(zip(self.names, np.round(self.ratio, 4).tolist())),
                "noise": self.noise, "noise_estimated": self.noise_estimated, "dof": self.dof}


@dataclass
class LinearPosterior:
    """Bayesian linear least squares (see the module's docstring). Learned: mean_, cov_, identifiability_."""

    names: tuple[str, ...]
    prior_mean: np.ndarray
    prior_sd: np.ndarray
    mean_: np.ndarray = field(init=False)
    cov_: np.ndarray = field(init=False)
    identifiability_: Identifiability = field(init=False)

    def fit(self, X: np.ndarray, y: np.ndarray, groups: np.ndarray | None = None) -> "LinearPosterior":
        """X (n, p), y (n,): the data; groups: a label per row (default one group), each group with its own
        noise σ (a sensor of its own: force components, power), estimated as the docstring says."""
        X, y = np.asarray(X, float), np.asarray(y, float)
        if len(y) == 0:
            raise MillpostError("no measured values to fit")
        groups = np.zeros(len(y), int) if groups is None else np.asarray(groups)
        labels = np.unique(groups)
        mu0 = np.asarray(self.prior_mean, float)
        s0 = np.asarray(self.prior_sd, float)
        flat = ~np.isfinite(s0)                       # no prior: the data alone (scaled by the columns)
        scale = np.where(flat, 1.0 / np.maximum(np.linalg.norm(X, axis=0), 1e-300), s0)
        mu0 = np.where(flat, 0.0, mu0)
        Xz = X * scale
        r0 = y - X @ mu0
        sigma = np.ones(len(y))
        for g in labels:
            on = groups == g
            sigma[on] = NOISE_REL * float(np.sqrt(np.mean(y[on] ** 2)) or 1.0)
        estimated = False
        for step in range(5):
            lam, V, mean_z, cov_z = _solve(Xz / sigma[:, None], r0 / sigma, flat)
            used = float(np.sum(lam / (1.0 + lam)) if not flat.any() else np.sum(lam > 0))
            dof = len(y) - used
            if dof < MIN_DOF or step == 4:
                break
            resid = r0 - Xz @ mean_z
            for g in labels:     # each group's share of the degrees of freedom, by its number of rows
                on = groups == g
                dof_g = on.sum() * dof / len(y)
                if dof_g >= 1:
                    sigma[on] = max(float(np.sqrt(resid[on] @ resid[on] / dof_g)), 1e-9 * sigma[on][0])
            estimated = True
        if flat.any() and np.sum(lam > 1e-9 * max(lam.max(), 1e-300)) < len(lam):
            raise MillpostError("the measurements do not determine every coefficient and no prior was given "
                                "(start from a material: --material)")
        self.mean_ = mu0 + scale * mean_z
        self.cov_ = cov_z * np.outer(scale, scale)
        ratio = np.where(flat, 0.0, np.sqrt(np.maximum(np.diag(cov_z), 0.0)))
        noise = {str(g): float(sigma[groups == g][0]) for g in labels}
        self.identifiability_ = identifiability(self.names, lam, V, scale, ratio, noise, estimated, dof)
        return self

    def sd(self) -> np.ndarray:
        """Posterior standard deviations (nan where the coefficient stays at its prior)."""
        sd = np.sqrt(np.maximum(np.diag(self.cov_), 0.0))
        return np.where(self.identifiability_.ratio < IDENTIFIED, sd, np.nan)


def _solve(Xw: np.ndarray, rw: np.ndarray, flat: np.ndarray):
    """For the noise-whitened problem (Xw, rw) in prior-whitened coordinates: eigenvalues (ascending) and
    vectors of the information, posterior mean and covariance of z."""
    A = Xw.T @ Xw
    lam, V = np.linalg.eigh(A)
    lam = np.maximum(lam, 0.0)
    cov = np.linalg.pinv(A + np.diag(np.where(flat, 0.0, 1.0)), hermitian=True)
    return lam, V, cov @ (Xw.T @ rw), cov


def map_fit(residuals, theta0: np.ndarray, prior_sd: np.ndarray, names: tuple[str, ...], n_data: int,
            bounds=(-np.inf, np.inf), noise: float | None = None) -> tuple[np.ndarray, np.ndarray, Identifiability]:
    """Maximum a posteriori of a nonlinear model with a Gaussian prior N(theta0, prior_sd²): residuals(θ)
    → (n_data,) model − data. Returns (θ, covariance, identifiability) of the Laplace approximation,
    the noise σ estimated from the residuals as in `LinearPosterior`."""
    s0 = np.asarray(prior_sd, float)
    sigma = noise if noise is not None else NOISE_REL
    estimated = False
    for _ in range(3):
        res = least_squares(lambda th: np.concatenate([residuals(th) / sigma, (th - theta0) / s0]), theta0,
                            bounds=bounds, method="trf", x_scale=s0)
        J = res.jac[:n_data] * s0              # whitened data Jacobian (σ included)
        lam = np.maximum(np.linalg.eigvalsh(J.T @ J), 0.0)
        dof = n_data - float(np.sum(lam / (1 + lam)))
        if noise is not None or dof < MIN_DOF:
            break
        r = residuals(res.x)
        new = max(float(np.sqrt(r @ r / dof)), 1e-9)
        if abs(new - sigma) <= 1e-3 * sigma:
            sigma, estimated = new, True
            break
        sigma, estimated = new, True
    J = res.jac[:n_data] * s0
    A = J.T @ J
    lam, V = np.linalg.eigh(A)
    lam = np.maximum(lam, 0.0)
    cov_z = np.linalg.inv(A + np.eye(len(s0)))
    ident = identifiability(names, lam, V, s0, np.sqrt(np.diag(cov_z)), {"log": sigma}, estimated, dof)
    return res.x, cov_z * np.outer(s0, s0), ident


def identifiability(names, lam: np.ndarray, V: np.ndarray, scale: np.ndarray, ratio: np.ndarray,
                    sigma: dict[str, float], estimated: bool, dof: float) -> Identifiability:
    """From the whitened information's eigenvalues lam (ascending) and vectors V, whitening scale per
    coefficient: the identified combinations (λ > 1, the functional vᵀz in the coefficients, largest weight
    1) and their condition."""
    strong = lam > 1.0
    combos = []
    for v in V[:, strong].T[::-1]:
        w = v / scale
        w = w / w[np.argmax(np.abs(w))]
        combos.append({n: round(float(c), 4) for n, c in zip(names, w) if abs(c) > 1e-3})
    cond = float(lam[strong].max() / lam[strong].min()) if strong.any() else float("nan")
    return Identifiability(tuple(names), int(strong.sum()), cond, ratio, combos, sigma, estimated, dof)
