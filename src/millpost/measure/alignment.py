"""Alignment of a measurement log to the program it recorded: the time offset between the log's clock
and the controller model's time base (`millpost.signals`), never trusting timestamps alone.

1. Cross-correlation: every channel the log shares with the prediction (forces, spindle power/current,
   axis currents, positions) is put on a uniform grid (the mean of the rows nearest each grid point),
   standardised (zero mean, unit variance; lost intervals count as the mean), and the correlations with
   the prediction are summed; the lag of the peak, refined by a parabola through it, gives the offset
   o with  log(t) ≈ predicted(t − o). A long log is correlated first on a coarse grid (at most 2¹⁸
   points, FFT over all lags), then at its own sample interval over the lags near the coarse peak.
2. Position projection (when the log has x_mm, y_mm, z_mm): each logged point is projected onto the
   predicted path near the time the first estimate expects it (nearest neighbour in (x, y, z, λ·t),
   then onto the segment to the next sample), which gives the program time at which the tool was
   there; the median of logged time − program time over moving samples is the refined offset.

The residuals say how well the prediction matches after alignment: the RMS of logged − predicted for
each channel, and the RMS distance of logged positions from the predicted ones.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.signal import correlate

from ..errors import MillpostError
from ..signals import Signals
from .log import Log

CHANNELS = ("fx_N", "fy_N", "fz_N", "spindle_power_W", "spindle_current_A", "ix_A", "iy_A", "iz_A",
            "x_mm", "y_mm", "z_mm")
POSITION_TIME_SCALE_MM_PER_S = 1.0  # λ: 1 s apart in program time weighs like 1 mm apart in space
COARSE_POINTS = 1 << 18             # the first correlation runs on at most this many grid points
FINE_POINTS = 1 << 18               # the second on a window of the program this long (at the log's interval)
POSITION_ROWS = 200_000             # logged positions projected for the refinement (evenly spread)


@dataclass
class Alignment:
    """offset_s: log time = program time + offset. residual_rms: per channel, logged − predicted after
    alignment (channel units); position_rms_mm: logged vs predicted position (nan without positions);
    method: "xcorr" or "xcorr+position"; correlation: normalised peak of the summed correlation (1 = the
    log is the prediction up to scale)."""

    offset_s: float
    method: str
    correlation: float
    channels: list[str]
    residual_rms: dict[str, float] = field(default_factory=dict)
    position_rms_mm: float = float("nan")
    xcorr_offset_s: float = float("nan")

    def program_time(self, t_log_s) -> np.ndarray:
        """Program time (s, the signals' time base) of log times."""
        return np.asarray(t_log_s, float) - self.offset_s

    def nearest_samples(self, t_log_s, signals: Signals) -> np.ndarray:
        """For log times, the index of the path sample nearest in program time (−1 outside the program)."""
        tau = self.program_time(t_log_s)
        j = np.clip(np.searchsorted(signals.t_s, tau), 1, len(signals) - 1)
        j = np.where(np.abs(signals.t_s[j - 1] - tau) < np.abs(signals.t_s[j] - tau), j - 1, j)
        return np.where((tau >= signals.t_s[0]) & (tau <= signals.t_s[-1]), j, -1)

    def summary(self) -> dict:
        return {"offset_s": round(self.offset_s, 6), "method": self.method, "correlation": round(self.correlation, 4),
                "channels": self.channels, "position_rms_mm": None if np.isnan(self.position_rms_mm) else
                round(self.position_rms_mm, 4), "residual_rms": {k: round(v, 4) for k, v in self.residual_rms.items()}}


def align(log: Log, signals: Signals, *, channels: tuple[str, ...] | None = None,
          max_offset_s: float | None = None) -> Alignment:
    """Find the offset of `log` against the prediction `signals` (see the module's docstring).
    channels: restrict the cross-correlation to these columns; max_offset_s: search |offset| ≤ this."""
    pred = signals.log_columns()
    wanted = channels or CHANNELS
    use = [c for c in wanted if log.has(c) and c in pred and np.nanstd(pred[c]) > 0]
    if not use:
        raise MillpostError(f"{log.path}: the log shares no varying channel with the prediction "
                            f"(has {', '.join(log.columns)}; usable: {', '.join(CHANNELS)})")
    t = log.t_s
    if len(t) < 4:
        raise MillpostError(f"{log.path}: too few samples to align ({len(t)})")
    dt = float(np.median(np.diff(t)))
    if not dt > 0:
        raise MillpostError(f"{log.path}: t_s does not advance")
    # coarse: block means on a grid of at most COARSE_POINTS, FFT correlation over all lags
    factor = max(1, int(np.ceil((t[-1] - t[0]) / dt / COARSE_POINTS)))
    coarse = _correlate(log, signals, pred, use, dt * factor, max_offset_s)
    offset_c, score_c, energy = coarse
    offset, score = offset_c, score_c
    if factor > 1:   # fine: the log's own interval, lags within two coarse steps of the coarse peak
        offset, score, energy = _correlate(log, signals, pred, use, dt, max_offset_s,
                                           around=(offset_c, 2 * factor))
    result = Alignment(offset, "xcorr", score / energy if energy > 0 else 0.0, use, xcorr_offset_s=offset)
    if all(log.has(c) for c in ("x_mm", "y_mm", "z_mm")):
        refined = _project(log, signals, offset)
        if refined is not None:
            result.offset_s, result.method = refined, "xcorr+position"
    _residuals(result, log, signals, pred)
    return result


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


def _project(log: Log, signals: Signals, offset: float) -> float | None:
    """Refined offset from logged positions projected on the predicted path near the expected time."""
    from scipy.spatial import cKDTree

    lam = POSITION_TIME_SCALE_MM_PER_S
    moving = signals.speed_mm_s > 0.05 * max(float(np.max(signals.speed_mm_s)), 1e-9)
    if moving.sum() < 2:
        return None
    pts = np.column_stack([signals.xyz_mm, lam * signals.t_s])
    tree = cKDTree(pts)
    pick = np.unique(np.linspace(0, len(log) - 1, min(len(log), POSITION_ROWS)).astype(np.int64))
    xyz = np.column_stack([log["x_mm"][pick], log["y_mm"][pick], log["z_mm"][pick]])
    t_log = log.t_s[pick]
    tau_guess = t_log - offset
    inside = (tau_guess >= signals.t_s[0]) & (tau_guess <= signals.t_s[-1]) & np.isfinite(xyz).all(1)
    if inside.sum() < 2:
        return None
    q = np.column_stack([xyz[inside], lam * tau_guess[inside]])
    _, j = tree.query(q, workers=-1)
    # onto the segment from j to its neighbour (the side the point lies on)
    n = len(signals)
    j = np.clip(j, 0, n - 2)
    p0, p1 = signals.xyz_mm[j], signals.xyz_mm[j + 1]
    seg = p1 - p0
    L2 = np.einsum("ij,ij->i", seg, seg)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(L2 > 0, np.einsum("ij,ij->i", xyz[inside] - p0, seg) / L2, 0.0)
    back = (u < 0) & (j > 0)
    jb = np.where(back, j - 1, j)
    p0, p1 = signals.xyz_mm[jb], signals.xyz_mm[jb + 1]
    seg = p1 - p0
    L2 = np.einsum("ij,ij->i", seg, seg)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.clip(np.where(L2 > 0, np.einsum("ij,ij->i", xyz[inside] - p0, seg) / L2, 0.0), 0.0, 1.0)
    tau = signals.t_s[jb] + u * (signals.t_s[jb + 1] - signals.t_s[jb])
    ok = moving[jb] & moving[jb + 1] & (L2 > 0)
    if ok.sum() < 2:
        return None
    return float(np.median(t_log[inside][ok] - tau[ok]))


def _residuals(result: Alignment, log: Log, signals: Signals, pred: dict[str, np.ndarray]) -> None:
    tau = result.program_time(log.t_s)
    inside = (tau >= signals.t_s[0]) & (tau <= signals.t_s[-1])
    for c in result.channels:
        d = log[c][inside] - np.interp(tau[inside], signals.t_s, pred[c])
        d = d[np.isfinite(d)]
        result.residual_rms[c] = float(np.sqrt(np.mean(d * d))) if len(d) else float("nan")
    if all(log.has(c) for c in ("x_mm", "y_mm", "z_mm")) and inside.any():
        d2 = sum((log[c][inside] - np.interp(tau[inside], signals.t_s, pred[c])) ** 2 for c in ("x_mm", "y_mm", "z_mm"))
        d2 = d2[np.isfinite(d2)]
        result.position_rms_mm = float(np.sqrt(np.mean(d2))) if len(d2) else float("nan")
