"""Held-out scoring and greedy selection of candidate effects.

Split: the rows are cut into consecutive time blocks of about BLOCK_S; every third block is held out, the rest fit
(neighbouring rows share disturbances, so a random row split would leak). Every model (the refitted
base, each candidate) is fitted on the fitting blocks only and judged on the held-out ones.

Criterion: a candidate against the current model is kept when (1) it is significant: the held-out
F-test F = ((S_before − S_after)/k) / (S_after/(m − k)) on the held-out residuals averaged over
sub-blocks of MEAN_S (averaging makes neighbouring rows' correlated noise one observation; every channel
divided by its residual scale σ_c under the base model, so N and W weigh alike; F is free of the noise
level; an effect that lives above that bandwidth, `Effect.slow` false (runout: once per revolution,
which sub-block means average away), is tested on the held-out rows themselves), k the candidate's
parameters, m the sub-block means, has p < ALPHA / (number of candidates) (Bonferroni); (2) it is
material: the held-out gap of the channels it acts on (the same sub-block means: white noise and the
tooth-passing ripple a logger aliases average away, what is left is what the model misses) falls by at
least MIN_GAIN (a real base model never matches a machine exactly; a few % of structured mismatch is
significant on a long log but is not an effect worth naming); (3) its parameters have the signs
physics requires (`Effect.physical`); (4) no channel's held-out gap grows by more than WORSE. The best
kept candidate is added and the search repeats once for a second effect; no effect is named when none
passes.

Confounding: when another candidate passes too (drift in time and a load that grows with time explain
the same residual), the two are compared on the held-out blocks where their predictions differ most
(`disagreement`); if the data cannot tell them apart there, the selection records them as ambiguous,
and discover says "ambiguous: A or B" with that evidence instead of naming A alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from ..errors import MillpostError
from ..registry import plugins
from .effects.base import Context, Effect
from .model import Fit, design, residual_scale, solve
from .rows import COEFS, Rows

BLOCK_S = 1.5        # time block length (s), between MIN_BLOCKS and MAX_BLOCKS blocks in all
MIN_BLOCKS, MAX_BLOCKS = 30, 600
HELD_OUT_EVERY = 3
MEAN_S = 0.5        # residual means over sub-blocks this long (s) for the F-test
ALPHA = 0.01
MIN_GAIN = 0.25
MAX_EFFECTS = 2
WORSE = 0.05         # an effect may not grow any channel's held-out gap by more than this
AMBIGUOUS_P = 0.01   # two passing candidates not told apart at this level on their disagreeing blocks


def split(t_s: np.ndarray, use: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(train mask, block number per row: −1 for fitting rows, k ≥ 0 for the k-th held-out block); rows
    not in `use` are in neither."""
    t = np.asarray(t_s, float)
    blocks = int(np.clip((t[-1] - t[0]) / BLOCK_S, MIN_BLOCKS, MAX_BLOCKS))
    edges = np.linspace(t[0], t[-1], blocks + 1)
    b = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, blocks - 1)
    held = b % HELD_OUT_EVERY == 1
    use = np.ones(len(t), bool) if use is None else use
    return ~held & use, np.where(held & use, b // HELD_OUT_EVERY, -1)


def candidates(names: list[str] | None = None) -> dict[str, type[Effect]]:
    """The registered effects (the ``millpost.effects`` entry points; millpost's own are declared there
    too), optionally only `names`."""
    found = plugins("effects")
    if not found:
        raise MillpostError("no candidate effects are registered (entry-point group millpost.effects is empty): "
                            "reinstall millpost (pip install -e .) so that its package metadata declares them")
    if names is None:
        return dict(found)
    unknown = [n for n in names if n not in found]
    if unknown:
        raise MillpostError(f"unknown effect {', '.join(unknown)}; known: {', '.join(sorted(found))}")
    return {n: found[n] for n in names}


def held_out_rms(rows: Rows, pred: dict[str, np.ndarray], held: np.ndarray) -> dict[str, float]:
    out = {}
    for c, p in pred.items():
        r = (rows.measured[c] - p)[held]
        r = r[np.isfinite(r)]
        out[c] = float(np.sqrt(np.mean(r * r))) if len(r) else float("nan")
    return out


def compare(rows: Rows, sigma: dict[str, float], block: np.ndarray, before: dict, after: dict,
            k: int, channels: list[str], mean_s: float = MEAN_S) -> tuple[float, float]:
    """(gain, p) of a candidate with k parameters acting on `channels`: the relative fall of the held-out
    weighted squared error on those channels, and the p-value (all channels) of the held-out F-test on
    residual means over sub-blocks of mean_s (see the module's docstring; 0: on the rows themselves)."""
    held = block >= 0
    sub = np.full(len(rows), -1)
    sub[held] = (np.floor((rows.t_s[held] - rows.t_s[0]) / mean_s).astype(np.int64) if mean_s > 0
                 else np.arange(int(held.sum())))
    nb = int(sub.max()) + 1
    s_before = s_after = 0.0
    m = 0
    for c in before:
        y = rows.measured[c]
        ok = held & np.isfinite(y)
        cnt = np.bincount(sub[ok], minlength=nb)
        use = cnt > 0
        means = [np.bincount(sub[ok], weights=(y - p)[ok], minlength=nb)[use] / cnt[use] for p in (before[c], after[c])]
        s_before += float(np.sum(cnt[use] * means[0] ** 2)) / sigma[c] ** 2
        s_after += float(np.sum(cnt[use] * means[1] ** 2)) / sigma[c] ** 2
        m += int(use.sum())
    gap = held_out_gap(rows, block, before, after, channels, mean_s)
    rb, ra = (sum(v[i] / sigma[c] ** 2 for c, v in gap.items()) for i in (0, 1))
    gain = (rb - ra) / rb if rb > 0 else 0.0
    if m <= k or s_after <= 0:
        return gain, 1.0
    F = ((s_before - s_after) / k) / (s_after / (m - k))
    return gain, float(stats.f.sf(F, k, m - k)) if F > 0 else 1.0


def held_out_gap(rows: Rows, block: np.ndarray, before: dict, after: dict, channels, mean_s: float = MEAN_S
                 ) -> dict[str, tuple[float, float]]:
    """Per channel, (before, after): the held-out squared gap between measured and predicted, over the
    residual means of sub-blocks of mean_s (white noise and the tooth-passing ripple a logger aliases
    average away; what is left is what a model misses), weighted by the rows in each; mean_s 0: the rows
    themselves."""
    held = block >= 0
    sub = np.full(len(rows), -1)
    sub[held] = (np.floor((rows.t_s[held] - rows.t_s[0]) / mean_s).astype(np.int64) if mean_s > 0
                 else np.arange(int(held.sum())))
    nb = int(sub.max()) + 1
    out = {}
    for c in channels:
        y = rows.measured[c]
        ok = held & np.isfinite(y)
        cnt = np.bincount(sub[ok], minlength=nb)
        use = cnt > 0
        gaps = []
        for p in (before[c], after[c]):
            m = np.bincount(sub[ok], weights=(y - p)[ok], minlength=nb)[use] / cnt[use]
            gaps.append(float(np.sum(cnt[use] * m * m)))
        out[c] = (gaps[0], gaps[1])
    return out


@dataclass
class Selection:
    """The refitted base model, the effects kept (in order), every candidate's score per round, and the
    held-out split."""

    base: Fit
    sigma: dict[str, float]
    train: np.ndarray
    block: np.ndarray
    coef: dict[str, float]
    effects: list[Effect] = field(default_factory=list)
    scores: list[dict[str, dict]] = field(default_factory=list)
    steps: list[tuple[dict, dict]] = field(default_factory=list)   # (before, after) predictions per kept effect
    ambiguous: list[dict] = field(default_factory=list)   # kept effect and a rival the data cannot tell apart

    def predict_before(self) -> dict[str, np.ndarray]:
        return self.base.predicted

    def predict_after(self) -> dict[str, np.ndarray]:
        return self.effects[-1].predict() if self.effects else self.predict_before()


def fit_base(rows: Rows, train: np.ndarray) -> tuple[Fit, dict[str, float]]:
    """The base model refitted on the training rows; σ per channel from a first pass, then refitted."""
    d = design(rows)
    sigma = residual_scale(d, rows, train)
    f = solve(d, rows, train, sigma)
    sigma = residual_scale(d, rows, train, f)
    return solve(d, rows, train, sigma), sigma


def select(rows: Rows, nominal: dict[str, float], effects: dict[str, type[Effect]] | None = None, *,
           max_effects: int = MAX_EFFECTS, alpha: float = ALPHA, min_gain: float = MIN_GAIN) -> Selection:
    """Refit the base, then greedily add the significant effect that removes most held-out error.
    nominal: the job material's cutting coefficients (used where the log does not inform them)."""
    effects = candidates() if effects is None else effects
    train, block = split(rows.t_s, rows.use)
    base, sigma = fit_base(rows, train)
    coef = {n: base.params().get(n, nominal.get(n, 0.0)) for n in COEFS}
    sel = Selection(base, sigma, train, block, coef)
    current = sel.predict_before()
    level = alpha / max(len(effects), 1)
    for _ in range(max_effects):
        ctx = Context(rows, train, sigma, coef, list(sel.effects))
        round_scores: dict[str, dict] = {}
        passed: list[tuple] = []
        for name, cls in effects.items():
            if any(e.name == name for e in sel.effects):
                continue
            e = cls().fit(ctx)
            if not e.applicable:
                round_scores[name] = {"applicable": False, "reason": e.reason_}
                continue
            after = e.predict()
            k = len([n for n in e.fit_.names if n.startswith(name + ":")]) + len(e.variant_.setting)
            mean_s = MEAN_S if e.slow else 0.0
            gain, p = compare(rows, sigma, block, current, after, max(k, 1), e.channels_, mean_s)
            worse = worsened(rows, block, current, after, mean_s)
            ok = p < level and gain >= min_gain and e.physical and not worse
            round_scores[name] = {"applicable": True, "gain": gain, "p": p, "physical": e.physical,
                                  "worsens": worse, "significant": ok}
            if ok:
                passed.append((gain, e, after, mean_s))
        sel.scores.append(round_scores)
        if not passed:
            break
        passed.sort(key=lambda x: -x[0])
        best = passed[0]
        for other in passed[1:]:
            verdict = disagreement(rows, block, current, best[2], other[2], best[1].channels_, best[3])
            if verdict["p"] >= AMBIGUOUS_P:
                sel.ambiguous.append({"effects": [best[1].name, other[1].name], **verdict})
        sel.steps.append((current, best[2]))
        sel.effects.append(best[1])
        current = best[2]
    return sel


def worsened(rows: Rows, block: np.ndarray, before: dict, after: dict, mean_s: float) -> dict[str, float]:
    """The channels whose held-out gap (`held_out_gap`) grows by more than WORSE and by more than white
    noise could (three standard deviations of a noise-only gap over m sub-blocks, σ²·√(2m), σ² from
    successive differences of the held-out residual, which cancel what varies slowly), with the growth:
    an effect that helps one channel by hurting another is a compromise of the fit, not a found effect."""
    gap = held_out_gap(rows, block, before, after, list(before), mean_s)
    held = block >= 0
    m = max(len(np.unique(np.floor((rows.t_s[held] - rows.t_s[0]) / mean_s))) if mean_s > 0 else int(held.sum()), 1)
    out = {}
    for c, (b, a) in gap.items():
        r = (rows.measured[c] - before[c])[held]
        r = r[np.isfinite(r)]
        noise = float(np.mean(np.diff(r) ** 2) / 2) if len(r) > 1 else 0.0
        if b > 0 and a > (1 + WORSE) * b and a - b > 3 * noise * np.sqrt(2 * m):
            out[c] = round(a / b - 1, 4)
    return out


def disagreement(rows: Rows, block: np.ndarray, before: dict, a: dict, b: dict, channels, mean_s: float) -> dict:
    """Whether two candidates that both explain the held-out gap can be told apart: on the held-out blocks
    where their predictions differ most (the upper half by the squared difference), the per-block
    squared gaps of A and B are compared by a paired Wilcoxon signed-rank test. p: the test's two-sided
    p-value (large: the data cannot tell A from B); better: the share of those blocks where A fits better."""
    held = block >= 0
    diff = np.zeros(int(block.max()) + 1)
    gap_a, gap_b = np.zeros_like(diff), np.zeros_like(diff)
    for c in channels:
        y = rows.measured[c]
        ok = held & np.isfinite(y)
        s = sigma_of(y[ok] - before[c][ok])
        diff += np.bincount(block[ok], weights=((a[c] - b[c])[ok] / s) ** 2, minlength=len(diff))
        for g, p in ((gap_a, a), (gap_b, b)):
            g += _block_gap(rows.t_s[ok], block[ok], (y - p[c])[ok] / s, mean_s, len(diff))
    top = diff >= np.median(diff[diff > 0]) if (diff > 0).any() else diff > 0
    if top.sum() < 6 or np.allclose(gap_a[top], gap_b[top]):
        return {"p": 1.0, "blocks": int(top.sum()), "better": 0.5}
    p = float(stats.wilcoxon(gap_a[top], gap_b[top]).pvalue)
    return {"p": p, "blocks": int(top.sum()), "better": float(np.mean(gap_a[top] < gap_b[top]))}


def sigma_of(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(r * r))) or 1.0


def _block_gap(t: np.ndarray, blk: np.ndarray, r: np.ndarray, mean_s: float, n: int) -> np.ndarray:
    """Per held-out block, Σ count·mean² of the residual over its sub-blocks of mean_s (0: Σ r²)."""
    if mean_s <= 0:
        return np.bincount(blk, weights=r * r, minlength=n)
    sub = np.floor((t - t[0]) / mean_s).astype(np.int64)
    key = blk * (int(sub.max()) + 1) + sub
    uk, inv = np.unique(key, return_inverse=True)
    cnt = np.bincount(inv)
    m = np.bincount(inv, weights=r) / cnt
    return np.bincount(uk // (int(sub.max()) + 1), weights=cnt * m * m, minlength=n)
