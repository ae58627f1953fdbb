"""Time offset of a log without positions against the prediction, by cross-correlation.

Every channel the log shares with the prediction (forces, spindle power/current, axis currents) is put
on a uniform grid (the mean of the rows nearest each grid point), standardised (zero mean, unit variance;
lost intervals count as the mean), and the correlations with the prediction are summed; the lag of the
peak, refined by a parabola through it, gives the offset o with  log(t) ≈ predicted(t − o). A long log is
correlated first on a coarse grid (at most `COARSE_POINTS`, FFT over all lags), then at its own sample
interval over the lags near the coarse peak. One offset holds only when the machine ran the program on the
model's time base; a log with positions is matched by place instead (`path_match`).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import correlate

from ..errors import MillpostError
from ..signals import Signals
from .log import Log

COARSE_POINTS = 1 << 18             # the first correlation runs on at most this many grid points
FINE_POINTS = 1 << 18               # the second on a window of the program this long (at the log's interval)


def offset(log: Log, signals: Signals, pred: dict, use: list[str], max_offset_s: float | None
           ) -> tuple[float, float]:
    """(offset s, normalised correlation peak) of `log` against the prediction over channels `use`."""
    t = log.t_s
    if len(t) < 4:
        raise MillpostError(f"{log.path}: too few samples to align ({len(t)})")
    dt = float(np.median(np.diff(t)))
    if not dt > 0:
        raise MillpostError(f"{log.path}: t_s does not advance")
    factor = max(1, int(np.ceil((t[-1] - t[0]) / dt / COARSE_POINTS)))
    off, score, energy = _correlate(log, signals, pred, use, dt * factor, max_offset_s)
    if factor > 1:   # fine: the log's own interval, lags within two coarse steps of the coarse peak
        off, score, energy = _correlate(log, signals, pred, use, dt, max_offset_s, around=(off, 2 * factor))
    return off, score / energy if energy > 0 else 0.0


def _correlate(log: Log, signals: Signals, pred: dict, use: list[str], dt: float, max_offset_s: float | None,
               around: tuple[float, int] | None = None) -> tuple[float, float, float]:
    """(offset, peak score, normalising energy) of the summed correlation of standardised channels on a
    grid of step dt (block means of the log, the prediction interpolated). around = (offset, k): only
    the lags within k steps of that offset, by direct dot products; otherwise all lags by FFT."""
    t = log.t_s
    t0 = float(t[0])
    n_log = int(np.floor((t[-1] - t0) / dt)) + 1
    n_pred = int(np.floor(signals.t_s[-1] / dt)) + 1
    grid_pred = dt * np.arange(n_pred)
    cell = np.minimum(np.rint((t - t0) / dt).astype(np.int64), n_log - 1)   # the grid point nearest each row
    lost = _in_gaps(t0 + dt * np.arange(n_log), log)
    count = np.bincount(cell, minlength=n_log)
    lost |= count == 0
    if around is None:
        lags = np.arange(-(n_pred - 1), n_log)
    else:
        centre = (around[0] - t0) / dt
        lags = np.arange(int(np.floor(centre)) - around[1], int(np.ceil(centre)) + around[1] + 1)
    predicted = lambda c: _standardise(np.interp(grid_pred, signals.t_s, pred[c]), None)  # noqa: E731
    j0, j1 = 0, n_pred
    if around is not None and n_pred > FINE_POINTS:
        # the window of the program whose prediction changes most (edges fix the time best)
        g = np.zeros(n_pred - 1)
        for c in use:
            g += np.diff(predicted(c)) ** 2
        sums = np.concatenate([[0.0], np.cumsum(g)])
        j0 = int(np.argmax(sums[FINE_POINTS - 1:] - sums[:len(sums) - FINE_POINTS + 1]))
        j1 = j0 + FINE_POINTS
    score = np.zeros(len(lags))
    energy = 0.0
    for c in use:
        a = _standardise(np.bincount(cell, weights=_fill(log[c]), minlength=n_log) / np.maximum(count, 1), lost)
        b = predicted(c)
        if around is None:
            score += correlate(a, b, mode="full", method="fft")
            energy += float(np.sqrt(np.sum(a * a) * np.sum(b * b)))
            continue
        for i, lag in enumerate(lags):   # Σ_j a[j + lag] b[j] over the window's overlap
            lo, hi = max(j0, -lag), min(j1, n_log - lag)
            if hi > lo:
                score[i] += float(np.dot(a[lo + lag:hi + lag], b[lo:hi]))
        lo, hi = max(j0, -lags[0]), min(j1, n_log - lags[-1])
        energy += float(np.sqrt(np.sum(a[lo:hi] ** 2) * np.sum(b[lo:hi] ** 2))) if hi > lo else 0.0
    offsets = t0 + lags * dt
    if max_offset_s is not None:
        score = np.where(np.abs(offsets) <= max_offset_s, score, -np.inf)
    k = int(np.argmax(score))
    frac = 0.0
    if 0 < k < len(score) - 1 and np.isfinite(score[k - 1]) and np.isfinite(score[k + 1]):
        y0, y1, y2 = score[k - 1], score[k], score[k + 1]
        den = y0 - 2 * y1 + y2
        frac = 0.5 * (y0 - y2) / den if den < 0 else 0.0
    return float(offsets[k] + frac * dt), float(score[k]), energy


def _fill(v: np.ndarray) -> np.ndarray:
    """nan → the column's mean (missing values carry no correlation)."""
    ok = np.isfinite(v)
    return v if ok.all() else np.where(ok, v, np.mean(v[ok]) if ok.any() else 0.0)


def _standardise(v: np.ndarray, lost: np.ndarray | None) -> np.ndarray:
    v = v - (v[~lost].mean() if lost is not None and (~lost).any() else v.mean())
    if lost is not None:
        v[lost] = 0.0
    s = v.std()
    return v / s if s > 0 else v


def _in_gaps(grid: np.ndarray, log: Log) -> np.ndarray:
    lost = np.zeros(len(grid), bool)
    for g in log.gaps:
        lost[np.searchsorted(grid, g.t_start_s):np.searchsorted(grid, g.t_end_s, side="right")] = True
    return lost
