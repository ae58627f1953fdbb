"""What every candidate effect is: a parametric term with a physical meaning, the channels it acts on,
and a fit (scikit-learn style: `fit` returns self, learned values end in `_`).

An effect proposes one or more *variants* (a nonlinear setting such as a time constant on a grid, or the
sensor it acts on), each as extra model terms (channel → {parameter: column}) and/or a filter of whole
channels; `fit` refits the base model together with each variant on the training rows and keeps the
variant with the smallest weighted residual (`search`; an effect with one nonlinear scalar, a lag τ, an
exponent m, a compliance C, searches a grid and then by golden section between the best point's neighbours,
`refine`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ...forces import NotFittedError
from ..model import Design, Filter, Fit, Terms, design, solve
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
    bounded: ClassVar[tuple[str, ...]] = ()    # parameter name prefixes that physics bounds below by 0 in the fit
    slow: ClassVar[bool] = True   # the effect changes the signal over many rows (see search.compare)

    @property
    def physical(self) -> bool:
        """Whether the fitted parameters have the signs the physics requires (a wear that lowers forces,
        a negative compliance or mass is another effect in disguise, never this one)."""
        return self.applicable and all(self.params_[k] > 0 for k in self.positive)

    def variants(self, ctx: Context) -> Iterator[Variant]:
        raise NotImplementedError

    def unavailable(self, ctx: Context) -> str | None:
        """Why the effect cannot be seen in this log (said in discover's notes), or None."""
        return None

    def fit(self, ctx: Context) -> "Effect":
        self.reason_ = self.unavailable(ctx)
        return self.keep(ctx, None if self.reason_ else self.search(ctx))

    def search(self, ctx: Context) -> tuple | None:
        """The best of the variants by training χ² (see `evaluate`), or None when there is none."""
        best = None
        for v in self.variants(ctx):
            trial = self.evaluate(ctx, v)
            if best is None or trial[0] < best[0]:
                best = trial
        return best

    def joint_design(self, ctx: Context, v: Variant) -> Design:
        """The design of the base, the kept effects and variant v."""
        terms = [e.variant_.terms for e in ctx.kept] + [v.terms]
        filters = {k: f for e in ctx.kept for k, f in e.variant_.filters.items()} | v.filters
        lower = {name for e in [*ctx.kept, self] for t in ([e.variant_.terms] if e is not self else [v.terms])
                 for cols in t.values() for name in cols
                 if any(name.startswith(e.param(b)) for b in e.bounded)}
        return design(ctx.rows, terms, filters, frozenset(lower))

    def evaluate(self, ctx: Context, v: Variant) -> tuple[float, Variant, Fit]:
        """(training χ², variant, joint fit) of one variant refitted with the base and the kept effects
        (the design is not kept: on a long log it is the largest array)."""
        f = solve(self.joint_design(ctx, v), ctx.rows, ctx.train, ctx.sigma)
        return f.chi2, v, f

    def refine(self, ctx: Context, best: tuple, grid: np.ndarray, at, steps: int = 8) -> tuple:
        """Golden-section search of the training χ² over a scalar setting between the grid neighbours of
        the best grid point (`best` from `evaluate`, `at(value)` → Variant; on a log scale)."""
        key = next(iter(best[1].setting))
        k = int(np.argmin(np.abs(np.log(grid / best[1].setting[key]))))
        lo, hi = np.log(grid[max(k - 1, 0)]), np.log(grid[min(k + 1, len(grid) - 1)])
        g = (np.sqrt(5) - 1) / 2
        a, b = hi - g * (hi - lo), lo + g * (hi - lo)
        fa, fb = self.evaluate(ctx, at(float(np.exp(a)))), self.evaluate(ctx, at(float(np.exp(b))))
        for _ in range(steps):
            if fa[0] < fb[0]:
                hi, b, fb = b, a, fa
                a = hi - g * (hi - lo)
                fa = self.evaluate(ctx, at(float(np.exp(a))))
            else:
                lo, a, fa = a, b, fb
                b = lo + g * (hi - lo)
                fb = self.evaluate(ctx, at(float(np.exp(b))))
        return min((best, fa, fb), key=lambda x: x[0])

    def keep(self, ctx: Context, best: tuple | None) -> "Effect":
        """Store the best (χ², variant, fit) as the fitted state."""
        if best is None:
            self.variant_ = None
            return self
        _, v, f = best
        self.variant_, self.fit_ = v, f
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
        return self.fit_.predicted

    def param(self, key: str) -> str:
        return f"{self.name}:{key}"


def cutting_channels(ctx: Context) -> list[str]:
    return ctx.measured(CUTTING)

