"""What every candidate effect is: a parametric term with a physical meaning, the channels it acts on,
and a fit (scikit-learn style: `fit` returns self, learned values end in `_`).

An effect proposes one or more *variants* (a nonlinear setting such as a time constant on a grid, or the
sensor it acts on), each as extra model terms (channel → {parameter: column}) and/or a filter of whole
channels; `fit` refits the base model together with each variant on the training rows and keeps the
variant with the smallest weighted residual.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ...forces import NotFittedError
from ..model import Filter, Terms, design, solve
from ..rows import COEFS, CUTTING, Rows


@dataclass
class Context:
    """What an effect fits against: the rows, the training mask, the channel weights σ, the cutting
    coefficients K̂ (the base refit's where the log informs them, the job material's otherwise) and the
    effects already kept (fitted again with each candidate)."""

    rows: Rows
    train: np.ndarray
    sigma: dict[str, float]
    coef: dict[str, float]
    kept: list["Effect"] = field(default_factory=list)

    def cutting(self, channel: str, part: slice = slice(None)) -> np.ndarray:
        """The cutting share of a channel (N or W) at K̂: all of it, or part=slice(0, 3) the shearing
        share, slice(3, 6) the edge share."""
        k = np.array([self.coef[n] for n in COEFS])[part]
        return self.rows.cut[channel][:, part] @ k

    def force_xy_N(self) -> np.ndarray:
        """In-plane cutting force magnitude (N) at K̂."""
        return np.hypot(self.cutting("fx_N"), self.cutting("fy_N"))

    def measured(self, channels) -> list[str]:
        return [c for c in channels if c in self.rows.measured]


@dataclass
class Variant:
    setting: dict[str, float]
    terms: Terms
    filters: dict[str, Filter] = field(default_factory=dict)


class Effect:
    """Base of the candidate effects. Subclasses set `name`, `channels`, `units` (parameter → unit) and
    implement `variants`. Learned: fit_ (the joint fit), params_ and stderr_ (the effect's own parameters
    and nonlinear settings), channels_ (measured channels it acts on), variant_."""

    name: ClassVar[str]
    channels: ClassVar[tuple[str, ...]]
    meaning: ClassVar[str] = ""
    positive: ClassVar[tuple[str, ...]] = ()   # parameters that physics requires > 0

    @property
    def physical(self) -> bool:
        """Whether the fitted parameters have the signs the physics requires (a wear that lowers forces,
        a negative compliance or mass is another effect in disguise, never this one)."""
        return self.applicable and all(self.params_[k] > 0 for k in self.positive)

    def variants(self, ctx: Context) -> Iterator[Variant]:
        raise NotImplementedError

    def fit(self, ctx: Context) -> "Effect":
        best = None
        for v in self.variants(ctx):
            terms = [e.variant_.terms for e in ctx.kept] + [v.terms]
            filters = {k: f for e in ctx.kept for k, f in e.variant_.filters.items()} | v.filters
            d = design(ctx.rows, terms, filters)
            f = solve(d, ctx.rows, ctx.train, ctx.sigma)
            pred = f.predict(d)
            chi2 = sum(float(np.nansum((ctx.rows.measured[c] - pred[c])[ctx.train] ** 2)) / ctx.sigma[c] ** 2
                       for c in d.X)
            if best is None or chi2 < best[0]:
                best = (chi2, v, f, d)
        if best is None:
            self.variant_ = None
            return self
        _, v, f, d = best
        self.variant_, self.fit_, self.design_ = v, f, d
        own = [n for n in f.names if n.startswith(self.name + ":")]
        p, s = f.params(), f.stderr()
        self.params_ = {**v.setting, **{n.split(":", 1)[1]: p[n] for n in own}}
        self.stderr_ = {**{k: float("nan") for k in v.setting}, **{n.split(":", 1)[1]: s[n] for n in own}}
        self.channels_ = sorted(set(v.terms) | set(v.filters), key=list(ctx.rows.measured).index)
        return self

    @property
    def applicable(self) -> bool:
        """Whether `fit` found any variant (an effect may not apply to a log: no fast enough rate, no
        channel it acts on)."""
        if not hasattr(self, "variant_"):
            raise NotFittedError(f"{self.name}: call fit() first")
        return self.variant_ is not None

    def predict(self) -> dict[str, np.ndarray]:
        """The joint model's prediction with this effect on the rows it was fitted on."""
        if not self.applicable:
            raise NotFittedError(f"{self.name}: not applicable to this log")
        return self.fit_.predict(self.design_)

    def param(self, key: str) -> str:
        return f"{self.name}:{key}"


def cutting_channels(ctx: Context) -> list[str]:
    return ctx.measured(CUTTING)

