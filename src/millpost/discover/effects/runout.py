"""runout: a cutter whose flutes sit at different radii (its axis off the spindle's by ρ, and/or each flute
ground to its own radius) cuts a different chip with each flute: flute j's chip is f_z·sin φ + δ_j with
δ_j = r_j − r_(j−1) (r_j its radius; Σ δ_j = 0). Over a revolution of N flutes the chip change is a
staircase δ(θ) that holds δ_j while flute j is in the cut, periodic once per revolution: its content is
at the spindle harmonics k = 1 … N−1 (the N-th is the tooth-passing frequency, where a zero-sum δ has
none). The shearing share of every cutting channel (proportional to the chip) changes by δ(θ)/f_z:
ΔF_c = F_shear,c(K̂)/f_z · Σ_k (a_k·cos kθ + b_k·sin kθ), θ = ∫Ω dt the spindle angle.

The logged speed holds the angle only within a stretch at one speed: between cuts the spindle changes
speed through ramps a speed column does not resolve to a fraction of a turn, so each cut has its own
angle origin, and its own a_k, b_k (parameters `a<k>_cut<g>_mm`, `b<k>_cut<g>_mm`; still linear). A
logged row is the mean of the signal over its sample interval (an integrating or anti-aliased
acquisition): each column is cos kθ, sin kθ averaged over the row's Ω·Δt.

What is reported: runout_mm, the amplitude of the per-flute chip offsets √(2·mean_j δ_j²) (2ρ·sin(π/N)
for a pure axis offset ρ), and for N ≥ 3 eccentricity_mm, the axis offset ρ that the once-per-revolution
part of the radii amounts to; both from each cut's harmonics (staircase: harmonic k's amplitude is
2·|Δ_k|/N·sinc(πk/N), |Δ_k| the k-th DFT magnitude of δ_j over N, |Δ_(N−k)| = |Δ_k|; Parseval gives
mean_j δ_j²), combined over the cuts by inverse variance, with their standard errors (linearised from the fit's covariance).

It shows only when the log samples the revolution: a harmonic is fitted in a cut when the log has at
least ROWS_PER_PERIOD rows per period of it (below 80 % of the Nyquist frequency); when not even the
first harmonic at the log's fastest spindle speed qualifies, the effect is not applicable and says so.
Channels: forces and spindle power."""

from __future__ import annotations

import numpy as np

from .base import Context, Effect, Variant, cutting_channels

ROWS_PER_PERIOD = 2.5
MIN_TRAIN_ROWS = 50    # a cut's own angle origin needs training rows of its own


class Runout(Effect):
    name = "runout"
    channels = ("fx_N", "fy_N", "fz_N", "spindle_power_W")
    meaning = "per-flute chip change from cutter runout (spindle harmonics 1 … N−1)"
    slow = False

    def unavailable(self, ctx: Context) -> str | None:
        rows = ctx.rows
        rpm = float(rows.features["rpm"].max()) if len(rows) else 0.0
        if not cutting_channels(ctx) or rpm <= 0 or rows.cuts is None:
            return "no cutting channel or no spindle speed in the log"
        rate = 1.0 / rows.dt_s
        need = ROWS_PER_PERIOD * rpm / 60.0
        if rate < need:
            return (f"the log's {rate:.4g} Hz cannot show once-per-revolution content ({rpm:.0f} rpm is "
                    f"{rpm / 60:.4g} Hz; {ROWS_PER_PERIOD} rows per revolution need ≥ {need:.4g} Hz)")
        return None

    def variants(self, ctx: Context):
        rows = ctx.rows
        omega = 2 * np.pi * rows.features["rpm"] / 60.0
        step = omega * np.gradient(rows.t_s)             # spindle angle over each row's interval (rad)
        angle = np.cumsum(step)
        fz = rows.features["fz_mm"]
        per_chip = np.where(fz > 0, 1.0 / np.where(fz > 0, fz, 1.0), 0.0)
        shear = {c: ctx.cutting(c, slice(0, 3)) * per_chip for c in cutting_channels(ctx)}
        flutes = flutes_per_row(rows)
        rate = 1.0 / rows.dt_s
        cols: dict[str, np.ndarray] = {}
        self.cuts_ = []
        for g, on in enumerate(cuts(shear, rows.features["rpm"]), start=1):
            n = int(flutes[on].max())
            if (ctx.train & on).sum() < MIN_TRAIN_ROWS or n < 2:
                continue
            fastest = float(omega[on].max()) / (2 * np.pi)
            harmonics = [k for k in range(1, n) if ROWS_PER_PERIOD * k * fastest <= rate]
            if not harmonics:
                continue
            self.cuts_.append((g, n, harmonics))
            for k in harmonics:
                cos, sin = row_means(k, angle[on], step[on])
                cols[f"a{k}_cut{g}_mm"], cols[f"b{k}_cut{g}_mm"] = np.zeros(len(rows)), np.zeros(len(rows))
                cols[f"a{k}_cut{g}_mm"][on], cols[f"b{k}_cut{g}_mm"][on] = cos, sin
        if cols:
            yield Variant({}, {c: {self.param(k): s * v for k, v in cols.items()} for c, s in shear.items()})

    def fit(self, ctx: Context) -> "Runout":
        super().fit(ctx)
        if not self.applicable and self.reason_ is None:
            self.reason_ = f"no cut has both {MIN_TRAIN_ROWS} training rows and {ROWS_PER_PERIOD} log rows per revolution"
        if self.applicable:
            names = self.fit_.names
            beta, cov = self.fit_.beta, self.fit_.cov
            for key, per_cut in (("runout_mm", offsets), ("eccentricity_mm", eccentricity)):
                est = []
                for g, n, harmonics in self.cuts_:
                    at = [names.index(self.param(f"{ab}{k}_cut{g}_mm")) for k in harmonics for ab in "ab"]
                    value, grad = per_cut(beta[at], n, harmonics)
                    if value is not None:
                        est.append((value, float(grad @ cov[np.ix_(at, at)] @ grad)))
                if est:
                    v, var = np.array(est).T
                    w = 1.0 / np.maximum(var, 1e-300)
                    self.params_[key] = float(np.sum(w * v) / np.sum(w))
                    self.stderr_[key] = float(np.sqrt(1.0 / np.sum(w)))
        return self


def cuts(shear: dict[str, np.ndarray], rpm: np.ndarray) -> list[np.ndarray]:
    """Masks of the cuts: runs of consecutive cutting rows at one spindle speed."""
    cutting = np.any([s != 0 for s in shear.values()], axis=0)
    start = cutting & ~np.concatenate([[False], cutting[:-1] & (rpm[1:] == rpm[:-1])])
    label = np.cumsum(start) * cutting
    return [label == g for g in range(1, int(label.max()) + 1)]


def flutes_per_row(rows) -> np.ndarray:
    """The cutting tool's flute count per row (0 where no cutting sample is behind the row)."""
    s = np.where(rows.cuts.sample[:, 0] >= 0, rows.cuts.sample[:, 0], rows.cuts.sample[:, 1])
    return np.where(s >= 0, rows.cuts.flutes[np.maximum(s, 0)], 0).astype(int)


def row_means(k: int, angle: np.ndarray, step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos kθ and sin kθ averaged over each row's interval, θ from angle − step/2 to angle + step/2."""
    lo, hi = angle - step / 2, angle + step / 2
    d = np.where(step > 0, k * step, 1.0)
    cos = np.where(step > 0, (np.sin(k * hi) - np.sin(k * lo)) / d, np.cos(k * angle))
    sin = np.where(step > 0, (np.cos(k * lo) - np.cos(k * hi)) / d, np.sin(k * angle))
    return cos, sin


def offsets(ab: np.ndarray, n: int, harmonics: list[int]) -> tuple[float | None, np.ndarray]:
    """Amplitude √(2·mean_j δ_j²) of the per-flute chip offsets from one cut's harmonics (a_k, b_k pairs
    in `ab`), and its gradient. Parseval: mean_j δ_j² = Σ_(r=1…N−1) |Δ_r/N|², harmonic k giving
    |Δ_k/N|² = (a_k² + b_k²) / (4·sinc²(πk/N)); δ_j real, so |Δ_(N−k)| = |Δ_k| and a harmonic not fitted
    (above the log's reach) is known from its mirror (the pair's fitted ones averaged). None when some
    pair {k, N−k} has neither fitted."""
    e = np.repeat([1.0 / (4 * np.sinc(k / n) ** 2) for k in harmonics], 2)
    weight = np.zeros(len(harmonics))
    for r in range(1, n):
        pair = [i for i, k in enumerate(harmonics) if k in (r, n - r)]
        if not pair:
            return None, np.zeros_like(ab)
        weight[pair] += 1.0 / len(pair)
    scale = e * np.repeat(weight, 2)
    amp = float(np.sqrt(2 * np.sum(scale * ab ** 2)))
    return amp, (2 * scale * ab / amp if amp > 0 else np.zeros_like(ab))


def eccentricity(ab: np.ndarray, n: int, harmonics: list[int]) -> tuple[float | None, np.ndarray]:
    """The axis offset ρ of the radii's once-per-revolution part, from the first harmonic: |Δ_1|/N =
    A_1 / (2·sinc(π/N)) = ρ·sin(π/N) (r_j = ρ·cos(ψ − 2πj/N) gives δ_j of amplitude 2ρ·sin(π/N)). None for
    two flutes (only ρ·cos ψ shows) or when the first harmonic is not fitted."""
    if n < 3 or harmonics[0] != 1:
        return None, np.zeros_like(ab)
    c = 1.0 / (2 * np.sinc(1.0 / n) * np.sin(np.pi / n))
    a1 = float(np.hypot(ab[0], ab[1]))
    grad = np.zeros_like(ab)
    if a1 > 0:
        grad[:2] = c * ab[:2] / a1
    return c * a1, grad
