"""Alignment of a measurement log to the program it recorded: for every log row, the program time τ (the
forward model's time base, `millpost.signals`) at which the tool was where the row says.

- With logged positions (x_mm, y_mm, z_mm): by place (`path_match`): each row is matched to a place on the
  predicted path, monotone along it; τ is the model's time at that place. Where the tool stands still (a
  dwell, a feed hold, a pause), τ runs linearly in log time between the places before and after. The
  log's own path speed (ds/dt of the matched arc length over its own clock) comes with it, so a feed
  override or another planner's accelerations are seen, not assumed. Every row's distance from its place
  is a residual: rows farther than `tolerance_mm` are not used, and a log with more than
  `MAX_OFF_FRACTION` of such rows between its first and last matched row is refused (`MisalignedLog`,
  naming the worst rows): it is not the log of this program in this frame.
- Without positions: one time offset by cross-correlation (`xcorr`), τ = t − offset.

The residuals say how well the prediction matches after alignment: the RMS of logged − predicted for each
channel, and the RMS distance of logged positions from the path.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import MillpostError
from ..signals import Signals
from . import path_match, xcorr
from .log import Log

CHANNELS = ("fx_N", "fy_N", "fz_N", "spindle_power_W", "spindle_current_A", "ix_A", "iy_A", "iz_A")
POSITIONS = ("x_mm", "y_mm", "z_mm")
TOLERANCE_MM = 0.3          # default: a row farther than this from the path is off it
MAX_OFF_FRACTION = 0.01     # more off-path rows than this (between the first and last on it): refused
STILL_MM_S = 0.5            # below this log path speed the tool stands still
SPEED_WINDOW_S = 0.01       # half-width of the window of the log's path speed (≥ 1 row)


class MisalignedLog(MillpostError):
    """The log's positions do not lie on the program's path: nothing may be fitted from it."""


@dataclass
class Alignment:
    """Per log row: tau_s, the program time (s, nan outside the program); residual_mm, the distance of the
    logged position from the path there (nan without positions); speed_mm_s, the path speed the log
    shows (nan without positions); on_path, rows inside the program within the tolerance. method:
    "position" or "xcorr"; offset_s: median log time − program time; correlation: xcorr's normalised
    peak (nan by position)."""

    method: str
    tau_s: np.ndarray
    on_path: np.ndarray
    residual_mm: np.ndarray
    speed_mm_s: np.ndarray
    offset_s: float
    correlation: float
    channels: list[str]
    tolerance_mm: float = TOLERANCE_MM
    place: np.ndarray | None = None     # per row, the fractional path-sample index matched (by position)
    residual_rms: dict[str, float] = field(default_factory=dict)
    position_rms_mm: float = float("nan")
    notes: list[str] = field(default_factory=list)

    def samples(self, signals: Signals) -> np.ndarray:
        """Per log row, the index of the path sample nearest in program time (−1 off the path)."""
        tau = np.where(self.on_path, self.tau_s, signals.t_s[0])
        j = np.clip(np.searchsorted(signals.t_s, tau), 1, len(signals) - 1)
        j = np.where(np.abs(signals.t_s[j - 1] - tau) < np.abs(signals.t_s[j] - tau), j - 1, j)
        return np.where(self.on_path, j, -1)

    def summary(self) -> dict:
        r = self.residual_mm[np.isfinite(self.residual_mm)]
        return {"method": self.method, "offset_s": round(self.offset_s, 6),
                "correlation": None if np.isnan(self.correlation) else round(self.correlation, 4),
                "rows_on_path": int(self.on_path.sum()), "rows": len(self.tau_s), "channels": self.channels,
                "tolerance_mm": self.tolerance_mm,
                "position_rms_mm": None if np.isnan(self.position_rms_mm) else round(self.position_rms_mm, 4),
                "position_max_mm": round(float(r.max()), 4) if len(r) else None,
                "residual_rms": {k: round(v, 4) for k, v in self.residual_rms.items()}, "notes": self.notes}


def align(log: Log, signals: Signals, *, tolerance_mm: float = TOLERANCE_MM, channels: tuple[str, ...] | None = None,
          max_offset_s: float | None = None) -> Alignment:
    """Align `log` to the prediction `signals` (see the module's docstring); refuses a log whose positions
    are off the path (`MisalignedLog`). channels, max_offset_s: for the cross-correlation without
    positions (restrict the channels; search |offset| ≤ this)."""
    pred = signals.log_columns()
    use = [c for c in (channels or CHANNELS) if log.has(c) and c in pred and np.isfinite(pred[c]).sum() > 1
           and np.nanstd(pred[c]) > 0]
    if len(log) < 4:
        raise MillpostError(f"{log.path}: too few samples to align ({len(log)})")
    if all(log.has(c) for c in POSITIONS) and np.isfinite(np.column_stack([log[c] for c in POSITIONS])).all(1).any():
        result = _by_position(log, signals, tolerance_mm)
        result.channels = use
    else:
        if not use:
            raise MillpostError(f"{log.path}: the log has neither positions (x_mm, y_mm, z_mm) nor a varying channel "
                                f"shared with the prediction (has {', '.join(log.columns)}; usable: "
                                f"{', '.join(CHANNELS)})")
        off, corr = xcorr.offset(log, signals, pred, use, max_offset_s)
        tau = log.t_s - off
        inside = (tau >= signals.t_s[0]) & (tau <= signals.t_s[-1])
        nan = np.full(len(log), np.nan)
        result = Alignment("xcorr", np.where(inside, tau, np.nan), inside, nan, nan.copy(), off, corr, use)
    _residuals(result, log, signals, pred)
    return result


def _by_position(log: Log, signals: Signals, tolerance_mm: float) -> Alignment:
    t = log.t_s
    xyz = np.column_stack([log[c] for c in POSITIONS])
    v_max = 2.0 * float(np.max(signals.speed_mm_s)) + 1.0   # a feed override up to 200 %
    f, dist = path_match.match(xyz, t, signals.xyz_mm, signals.s_mm, v_max, 2.0 + 3.0 * tolerance_mm)
    k = np.arange(len(signals))
    matched = np.isfinite(f)
    s = np.interp(f, k, signals.s_mm)
    tau = np.interp(f, k, signals.t_s)
    speed = _speed(t, s)
    still = matched & ~(speed > STILL_MM_S)
    moving = np.flatnonzero(matched & ~still)
    if len(moving) >= 2:   # standing still: program time runs between the places before and after
        inner = still & (np.arange(len(t)) > moving[0]) & (np.arange(len(t)) < moving[-1])
        tau[inner] = np.interp(t[inner], t[moving], tau[moving])
    near = matched & (dist <= tolerance_mm)
    on = np.flatnonzero(near)
    result = Alignment("position", np.where(near, tau, np.nan), near, dist, speed,
                       float(np.median(t[near] - tau[near])) if len(on) else float("nan"), float("nan"), [],
                       tolerance_mm, np.where(near, f, np.nan))
    span = np.zeros(len(t), bool)
    if len(on):
        span[on[0]:on[-1] + 1] = True
    off = span & ~near
    if len(on) < 10 or off.sum() > MAX_OFF_FRACTION * max(span.sum(), 1):
        raise MisalignedLog(_refusal(log, signals, f, dist, span, tolerance_mm))
    outside = matched & ~span
    if outside.any():
        result.notes.append(f"{int(outside.sum())} rows before or after the program's path (farther than "
                            f"{tolerance_mm:g} mm from it) are left out")
    if off.any():
        result.notes.append(f"{int(off.sum())} rows farther than {tolerance_mm:g} mm from the path are left out")
    return result


def _speed(t: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Path speed (mm/s) per row: the matched arc length's slope over ±SPEED_WINDOW_S of the log's clock."""
    return rate(t, s)


def rate(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Per row, (y(i + w) − y(i − w)) / (t(i + w) − t(i − w)): the rate of y over the log's own clock, w
    rows ≈ SPEED_WINDOW_S (at least 1; clipped at the ends)."""
    n = len(t)
    if n < 2:
        return np.zeros(n)
    dt = float(np.median(np.diff(t)))
    w = max(1, int(round(SPEED_WINDOW_S / dt))) if dt > 0 else 1
    i = np.arange(n)
    a, b = np.maximum(i - w, 0), np.minimum(i + w, n - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(t[b] > t[a], (y[b] - y[a]) / (t[b] - t[a]), 0.0)


def _refusal(log: Log, signals: Signals, f: np.ndarray, dist: np.ndarray, span: np.ndarray, tol: float) -> str:
    worst = np.argsort(np.where(np.isfinite(dist), -dist, 0.0))[:5]
    k = np.clip(np.rint(np.nan_to_num(f)).astype(int), 0, len(signals) - 1)
    rows = "; ".join(
        f"row {i + 1} (t_s {log.t_s[i]:.3f}): logged ({log['x_mm'][i]:.3f}, {log['y_mm'][i]:.3f}, "
        f"{log['z_mm'][i]:.3f}) is {dist[i]:.3f} mm from the path (nearest: line {int(signals.line[k[i]])} at "
        f"({signals.xyz_mm[k[i], 0]:.3f}, {signals.xyz_mm[k[i], 1]:.3f}, {signals.xyz_mm[k[i], 2]:.3f}))"
        for i in worst)
    n_off = int(np.sum(dist > tol))
    return (f"{log.path}: the logged positions do not lie on the program's path: {n_off} of {len(dist)} rows are "
            f"farther than {tol:g} mm from it (median {float(np.nanmedian(dist)):.3f} mm). Is it the log of this "
            f"program, in its frame (x_mm, y_mm, z_mm in program coordinates: work offset and tool length applied, "
            f"mm)? Worst rows: {rows}. Nothing is fitted from a log that does not fit its program")


def _residuals(result: Alignment, log: Log, signals: Signals, pred: dict[str, np.ndarray]) -> None:
    tau = result.tau_s[result.on_path]
    for c in result.channels:
        d = log[c][result.on_path] - np.interp(tau, signals.t_s, pred[c])
        d = d[np.isfinite(d)]
        result.residual_rms[c] = float(np.sqrt(np.mean(d * d))) if len(d) else float("nan")
    r = result.residual_mm[result.on_path]
    r = r[np.isfinite(r)]
    if len(r):
        result.position_rms_mm = float(np.sqrt(np.mean(r * r)))
