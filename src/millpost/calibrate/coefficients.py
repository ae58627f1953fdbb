"""Cutting coefficients from measured means of steady cuts, starting from a catalogue material.

The material's coefficients are a prior, each with a relative spread (`PRIOR_SPREAD`, 1σ); the
measurements update them (`bayes`):

- mechanistic: the mean forces and power are linear in (K_tc, K_rc, K_ac, K_te, K_re, K_ae) (`design`), so
  the posterior is exact. One chip thickness fixes, per direction, the cutting-plus-edge sum at that
  chip thickness and leaves the split at the prior (a slot at one feed: F̄_y/(N a) = K_tc f_z/4 + K_te/π);
  several chip thicknesses separate them. With no prior (spread inf) and data that determine all six,
  the result is ordinary least squares: on a slot series, the textbook average-force method (Altintas
  ch. 2).
- Kienzle: (log k_c1.1, m_c) by maximum a posteriori in log space on |F̄_xy| and power; one chip thickness
  fixes k_c1.1·h^(−m_c) and leaves m_c at the prior.

Signs are checked from the data before anything is fitted: each force channel must point the way the
prior says (a channel whose measured means run against the prediction is a sign or frame error: force on
the tool vs on the workpiece, an axis pointing the other way); a posterior that needs a negative
cutting or edge coefficient (K_tc, K_rc, K_te, K_re) is refused for the same reason.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..engagement import Engagement
from ..errors import MillpostError
from ..forces import COEF_NAMES, Kienzle, Measurements, Mechanistic
from ..forces.kienzle import log_problem
from ..forces.mechanistic import design
from ..materials import Material
from ..tools.cutter import Tool
from .bayes import IDENTIFIED, Identifiability, LinearPosterior, map_fit

PRIOR_SPREAD = 0.5        # relative 1σ of a catalogue coefficient (and of k_c1.1)
MC_PRIOR_SD = 0.1         # 1σ of the Kienzle exponent m_c
POSITIVE = ("Ktc", "Krc", "Kte", "Kre")   # physically > 0 in the model's frame
UNITS = {"Ktc": "N/mm²", "Krc": "N/mm²", "Kac": "N/mm²", "Kte": "N/mm", "Kre": "N/mm", "Kae": "N/mm",
         "kc11": "N/mm²", "mc": ""}


@dataclass
class Fit:
    """Fitted models, what the data identified, and residuals. residuals: {model: {"before"|"after":
    {"force_N": RMS, "power_W": RMS}}}; before = the base material's coefficients (absent without one).
    identifiability: per model (`bayes.Identifiability`); prior: per model, (mean, sd)."""

    rows: int
    source: str
    mechanistic: Mechanistic | None
    kienzle: Kienzle | None
    identifiability: dict[str, Identifiability] = field(default_factory=dict)
    prior: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    residuals: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def coefficients(self, model: str) -> dict[str, dict]:
        """{name: value, stderr (None for a coefficient left at the prior), prior, prior_sd, identified}."""
        m = self.mechanistic if model == "mechanistic" else self.kienzle
        names = COEF_NAMES if model == "mechanistic" else ("kc11", "mc")
        ident = self.identifiability[model]
        sd = np.sqrt(np.maximum(np.diag(m.coef_cov_), 0.0))
        mean0, sd0 = self.prior.get(model, (np.full(len(names), np.nan), np.full(len(names), np.inf)))
        return {n: {"value": float(v), "stderr": float(s) if r < IDENTIFIED else None,
                    "prior": float(p) if np.isfinite(p) else None,
                    "prior_sd": float(q) if np.isfinite(q) else None,
                    "identified": bool(r < IDENTIFIED)}
                for n, v, s, r, p, q in zip(names, m.coef_, sd, ident.ratio, mean0, sd0)}

    def as_dict(self) -> dict:
        out: dict = {"rows": self.rows, "source": self.source}
        for model in ("mechanistic", "kienzle"):
            if getattr(self, model) is not None:
                out[model] = self.coefficients(model)
                out[f"{model}_covariance"] = getattr(self, model).coef_cov_.tolist()
                out[f"{model}_identifiability"] = self.identifiability[model].as_dict()
        if self.kienzle is not None:
            out["kienzle_ratios"] = {"radial": self.kienzle.radial_ratio, "axial": self.kienzle.axial_ratio}
        after = self.residuals.get("mechanistic", {}).get("after", {})
        out["rms_N"] = after.get("force_N")
        out["rms_W"] = after.get("power_W")
        out["residuals"] = self.residuals
        out["notes"] = self.notes
        return out

    def table(self) -> str:
        """Coefficient, value, ± (or 'prior'), and the residuals before and after, as text."""
        lines = [f"{'coefficient':<12}{'value':>12}{'±':>10}"]
        for model in ("mechanistic", "kienzle"):
            if getattr(self, model) is None:
                continue
            for k, v in self.coefficients(model).items():
                se = f"{v['stderr']:>10.3g}" if v["stderr"] is not None else f"{'prior':>10}"
                lines.append(f"{k:<12}{v['value']:>12.5g}{se}  {UNITS[k]}")
        for model, res in self.residuals.items():
            for which in ("force_N", "power_W"):
                b, a = res.get("before", {}).get(which), res.get("after", {}).get(which)
                if a is not None:
                    before = f"{b:.4g}" if b is not None else "-"
                    lines.append(f"residual RMS {model} {which}: before {before}, after {a:.4g}")
        return "\n".join(lines)


def fit_cuts(cuts, base: Material | None = None, *, prior_spread: float = PRIOR_SPREAD) -> Fit:
    """Mechanistic and Kienzle coefficients from a table of steady cuts (`cuts.Cuts`; see `fit_models`)."""
    return fit_models(cuts.engagement(), cuts.measurements(), cuts.tools(), base, cuts.source,
                      prior_spread=prior_spread)


def fit_models(eng: Engagement, meas: Measurements, tools: list[Tool], base: Material | None = None,
               source: str = "", *, prior_spread: float = PRIOR_SPREAD) -> Fit:
    """Both force models' posteriors from measured means per sample (engagement, feed per tooth, speed,
    force on the tool in machine XYZ and/or cutting power), the base material as the prior (none: the data
    must determine every coefficient). prior_spread: relative 1σ of the prior (inf: no prior)."""
    fit = Fit(len(eng), source, None, None)
    prior_m = base.force_model("mechanistic") if base is not None else None
    if prior_m is not None:
        check_signs(prior_m, eng, meas, tools)
    mu0 = prior_m.coef_.astype(float) if prior_m is not None else np.zeros(6)
    sd0 = prior_sd(mu0, prior_spread) if prior_m is not None else np.full(6, np.inf)
    X, y, kind = design(eng, meas, tools)
    post = LinearPosterior(COEF_NAMES, mu0, sd0).fit(X, y, np.array(["fx", "fy", "fz", "power"])[kind])
    fit.mechanistic = Mechanistic.from_coefficients(*post.mean_)
    fit.mechanistic.coef_cov_ = post.cov_
    fit.identifiability["mechanistic"] = post.identifiability_
    fit.prior["mechanistic"] = (mu0 if prior_m is not None else np.full(6, np.nan), sd0)
    _refuse_negative(fit.mechanistic.coef_, post.identifiability_, source)
    fit.residuals["mechanistic"] = {"before": _residuals(prior_m, eng, meas, tools) if prior_m is not None else {},
                                    "after": _residuals(fit.mechanistic, eng, meas, tools)}
    if post.identifiability_.at_prior:
        fit.notes.append("mechanistic: " + post.identifiability_.describe())
    kz0 = base.force_model("kienzle") if base is not None else Kienzle()
    fit.kienzle, fit.identifiability["kienzle"], fit.prior["kienzle"] = _kienzle(kz0, eng, meas, tools, prior_spread)
    if fit.identifiability["kienzle"].at_prior:
        fit.notes.append("kienzle: " + fit.identifiability["kienzle"].describe())
    fit.residuals["kienzle"] = {"before": _residuals(kz0, eng, meas, tools) if hasattr(kz0, "coef_") else {},
                                "after": _residuals(fit.kienzle, eng, meas, tools)}
    return fit


def prior_sd(mean: np.ndarray, spread: float) -> np.ndarray:
    """1σ of the mechanistic prior: `spread` × the coefficient, or × half the tangential one of its kind
    where that is larger (a catalogue's small radial or axial value is no more certain in N/mm² than
    the others: an axial edge coefficient of 0.7 N/mm may well be 5)."""
    if not np.isfinite(spread):
        return np.full(6, np.inf)
    floor = 0.5 * np.abs(np.repeat(mean[[0, 3]], 3))
    return spread * np.maximum(np.abs(mean), floor)


def _kienzle(prior: Kienzle, eng: Engagement, meas: Measurements, tools: list[Tool], prior_spread: float):
    """(fitted Kienzle, identifiability, (prior mean, prior sd) of (k_c1.1, m_c))."""
    y, model_log = log_problem(eng, meas, tools, prior.radial_ratio, prior.axial_ratio)
    if len(y) == 0:
        raise MillpostError("the Kienzle fit needs positive measured |F_xy| or power")
    has_prior = hasattr(prior, "coef_") and np.isfinite(prior_spread)
    kc0, mc0 = (prior.coef_ if has_prior else (1000.0, 0.25))
    s0 = np.array([prior_spread, MC_PRIOR_SD]) if has_prior else np.array([1e3, 1e3])
    theta, cov_t, ident = map_fit(lambda th: model_log(th) - y, np.array([np.log(kc0), mc0]), s0,
                                  ("kc11", "mc"), len(y), bounds=([-np.inf, 0.0], [np.inf, 0.95]))
    ident.combinations = [{("ln kc11" if n == "kc11" else n): w for n, w in c.items()} for c in ident.combinations]
    if not has_prior and ident.rank < 2:
        raise MillpostError("the measurements do not determine both Kienzle coefficients and no prior was given "
                            "(start from a material: --material)")
    kz = Kienzle(radial_ratio=prior.radial_ratio, axial_ratio=prior.axial_ratio)
    kc11 = float(np.exp(theta[0]))
    J = np.diag([kc11, 1.0])                     # delta method: log k_c1.1 → k_c1.1
    kz.coef_, kz.coef_cov_ = np.array([kc11, theta[1]]), J @ cov_t @ J
    mean0 = np.array([kc0, mc0]) if has_prior else np.full(2, np.nan)
    sd0 = np.array([kc0 * prior_spread, MC_PRIOR_SD]) if has_prior else np.full(2, np.inf)
    return kz, ident, (mean0, sd0)


def check_signs(prior: Mechanistic, eng: Engagement, meas: Measurements, tools: list[Tool]) -> None:
    """Refuse force channels whose measured means run against the prior's prediction (a sign or frame
    error): per machine axis, the projection Σ measured·predicted over the cuts must be positive where the
    prediction is not negligible (over 10 % of the largest channel's RMS)."""
    if meas.force_N is None:
        return
    pred, _ = _predict(prior, eng, meas, tools)
    got = np.asarray(meas.force_N, float)
    rms = np.sqrt(np.nanmean(pred * pred, axis=0))
    for k, axis in enumerate("xyz"):
        ok = np.isfinite(got[:, k])
        if not ok.any() or rms[k] < 0.1 * rms.max():
            continue
        slope = float(got[ok, k] @ pred[ok, k] / (pred[ok, k] @ pred[ok, k]))
        if slope < 0:
            raise MillpostError(
                f"the measured {axis} forces run against the model (measured/predicted {slope:.2f}): a sign or frame "
                f"error. A log holds the force on the workpiece (f{axis}_N, what a table dynamometer reads: −the "
                f"force on the tool) along machine +{axis.upper()}; a table of cuts the force on the tool, x along "
                "the feed, y to its left, z up the tool axis. Flip the channel or the axis and fit again")


def _refuse_negative(coef: np.ndarray, ident: Identifiability, source: str) -> None:
    bad = [(n, v) for n, v in zip(COEF_NAMES, coef) if n in POSITIVE and v <= 0]
    if bad:
        raise MillpostError(
            f"{source or 'the cuts'}: the data need {', '.join(f'{n} = {v:.4g}' for n, v in bad)} (must be > 0): "
            "a sign or frame error in the forces (on the tool vs on the workpiece, an axis the other way), a "
            "cut whose engagement is not the one assumed, or a load the model lacks. Nothing is fitted; "
            f"{ident.describe()}")


def _predict(model, eng: Engagement, meas: Measurements, tools: list[Tool]) -> tuple[np.ndarray, np.ndarray]:
    """(force on the tool (N, 3) machine XYZ, cutting power (N,) W) of `model` at the measured conditions."""
    n = len(eng)
    force, power = np.zeros((n, 3)), np.zeros(n)
    fz = np.broadcast_to(np.asarray(meas.fz_mm, float), (n,))
    rpm = np.broadcast_to(np.asarray(meas.rpm, float), (n,))
    groups: dict[Tool, list[int]] = {}
    for i, t in enumerate(tools):
        groups.setdefault(t, []).append(i)
    for t, idx in groups.items():
        loads = model.predict(eng.select(np.array(idx)), fz[idx], rpm[idx], t, peaks=False)
        force[idx], power[idx] = loads.force_N, loads.power_W
    return force, power


def _residuals(model, eng: Engagement, meas: Measurements, tools: list[Tool]) -> dict[str, float]:
    """RMS of measured − predicted: force components (N, machine XYZ) and power (W)."""
    force, power = _predict(model, eng, meas, tools)
    out = {}
    if meas.force_N is not None:
        d = (np.asarray(meas.force_N) - force)[np.isfinite(meas.force_N)]
        out["force_N"] = float(np.sqrt(np.mean(d * d)))
    if meas.power_W is not None:
        d = (np.asarray(meas.power_W) - power)[np.isfinite(meas.power_W)]
        out["power_W"] = float(np.sqrt(np.mean(d * d)))
    return out


def material_dict(data: dict, fit: Fit, provenance: str) -> dict:
    """`data` (a material description) with the fitted [mechanistic] and [kienzle] tables; their source
    says which coefficients the data identified (± 1 posterior s.d.) and which stayed at the prior."""
    data = dict(data)
    d = fit.as_dict()

    def spread(model: str) -> str:
        coefs = d[model]
        fitted = ", ".join(f"{n} ± {v['stderr']:.3g}" for n, v in coefs.items() if v["stderr"] is not None)
        prior = ", ".join(n for n, v in coefs.items() if v["stderr"] is None)
        return f"fitted {fitted or 'nothing alone'}" + (f"; at the prior: {prior}" if prior else "")

    if fit.mechanistic is not None:
        k = fit.mechanistic.coef_
        rms = d.get("rms_N")
        data["mechanistic"] = {
            "Ktc_N_mm2": float(k[0]), "Krc_N_mm2": float(k[1]), "Kac_N_mm2": float(k[2]),
            "Kte_N_per_mm": float(k[3]), "Kre_N_per_mm": float(k[4]), "Kae_N_per_mm": float(k[5]),
            "source": f"{provenance}; mechanistic posterior ({spread('mechanistic')})" +
            (f"; residual RMS {rms:.4g} N" if rms is not None else "") +
            (f"; {d['rms_W']:.4g} W" if d.get("rms_W") is not None else "")}
    if fit.kienzle is not None:
        kc, mc = fit.kienzle.coef_
        data["kienzle"] = {"kc11_N_mm2": float(kc), "mc": float(mc), "radial_ratio": fit.kienzle.radial_ratio,
                           "axial_ratio": fit.kienzle.axial_ratio,
                           "source": f"{provenance}; Kienzle posterior ({spread('kienzle')}); force ratios kept "
                                     "from the base"}
    return data
