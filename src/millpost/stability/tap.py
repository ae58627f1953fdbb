"""The tap test: the tool tip's modes from a hammer-and-accelerometer record, and the chatter frequency
(with the spindle speeds that avoid it) from a recording of a chattering cut.

Modal parameters (impact testing, Ewins "Modal Testing" ch. 3, ISO 7626-5; Schmitz & Smith "Machining
Dynamics" ch. 2): each hammer hit is cut out of the record (from a short pre-trigger on), the force kept
only around its pulse, and force and response both multiplied by the same exponential window
w(t) = exp(−t/τ). Since w·(h∗f) = (w·h)∗(w·f), the ratio of their spectra is exactly the FRF of the
windowed impulse response, whose every pole is moved left by 1/τ: ζ_w ω_w = ζ ω_n + 1/τ at the same damped
frequency ω_d. The H1 estimator averages over the hits, H = Σ F̄·A / Σ |F|² (the noise on the response
averages out), with the coherence γ² = |Σ F̄·A|² / (Σ|F|² Σ|A|²) saying how much of the response the force
explains. The window evaluates each transfer function at s = iω + 1/τ, so the windowed accelerance
(m/s² per N) becomes the windowed receptance (mm/N) by G = 1000·A / s² (velocity mm/s: V / s; without
the window this is the familiar −A/ω²).
A sum of modes G = Σ 1/(k (1 − r² + 2iζr)) plus residual terms R_U − R_L/f² (modes above and below the
band) is fitted to the complex receptance by least squares, started from peak picking (peak frequency,
half-power bandwidth ζ = Δf/2f_n, k = 1/(2ζ|G(f_n)|)); the window's damping is then taken out:
σ = ζ_w ω_w − 1/τ, ω_n = √(σ² + ω_d²), ζ = σ/ω_n, and k = k_w (ω_n/ω_w)² (the modal mass is unchanged).

Chatter frequency: the Welch spectrum of the recording with the spindle harmonics k·n/60 (they hold the
tooth-passing ones k·N·n/60, and runout's) removed; the strongest remaining local maximum is f_c, and the
cut chatters if it stands above the noise floor by more than the Welch estimate's χ² noise passes 1 time in
100 over the spectrum (`chatter_frequency`); with an even flute count, period-doubling chatter at
(k + ½)·N·n/60 is itself a spindle harmonic, found when it stands 20 dB above its neighbouring runout
harmonics (`flip_chatter`). The stable speeds
are those that put the tooth-passing frequency on f_c or a fraction of it, n_j = 60 f_c / (N j), j = 1, 2, …
(Tlusty's rule, Smith & Tlusty 1992 "Stabilizing chatter by automatic spindle speed regulation"; tap-test
apps call it the best speed): the teeth then meet the surface wave in phase. At the present speed
f_c / f_tooth = lobe + ε/2π: the lobe number and the phase ε (rad) between successive teeth' waves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import fft, optimize, signal, stats

from ..errors import MillpostError, ParseError
from ..measure.log import check_time, data_line, read_table
from .frf import DirectionFRF, Mode

RESPONSES = {"accel_m_s2": "acceleration (m/s²)", "vel_mm_s": "velocity (mm/s)", "disp_mm": "displacement (mm)"}
TAP_COLUMNS = {"t_s": "time (s)", "force_N": "hammer force (N)", **RESPONSES}
RECORDING_COLUMNS = {"t_s": "time (s)", "signal": "microphone or accelerometer signal (any unit)",
                     "spindle_rpm": "spindle speed (rpm)"}


# --- reading ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Record:
    """Evenly sampled columns read from a CSV file (`t_s` first); `header_line` locates rows for errors."""

    columns: dict[str, np.ndarray]
    path: str
    header_line: int

    @property
    def fs_hz(self) -> float:
        """Sampling rate (Hz)."""
        return 1.0 / float(np.median(np.diff(self.columns["t_s"])))

    def line(self, row: int) -> int:
        """The file line (1-based) of data row `row` (0-based)."""
        return data_line(Path(self.path).read_bytes(), self.header_line, row)

    def error(self, row: int, name: str, message: str, expected: str) -> ParseError:
        """A ParseError at row `row` of column `name`, naming the value."""
        col = list(self.columns).index(name) + 1
        return ParseError(message, file=self.path, line=self.line(row), column=col,
                          word=f"{name}={float(self.columns[name][row]):g}", expected=expected)


def _read(path, known: dict[str, str], required: tuple[str, ...]) -> Record:
    def check(name: str, *, file: str, line: int, column: int) -> None:
        if name not in known:
            raise ParseError(f"unknown column {name!r}", file=file, line=line, column=column, word=name,
                             expected=f"one of {', '.join(known)}")

    data = Path(path).read_bytes()
    columns, header_at = read_table(path, check, required=required, describe=known, data=data)
    rec = Record(columns, str(path), header_at)
    t = columns["t_s"]
    check_time(t, str(path), data, header_at)
    if len(t) < 16:
        raise ParseError(f"{len(t)} samples", file=str(path), line=header_at, column=1, word="t_s",
                         expected="at least 16 evenly spaced samples")
    dt = np.diff(t)
    bad = np.flatnonzero(np.abs(dt - np.median(dt)) > 0.01 * np.median(dt))
    if len(bad):
        raise rec.error(int(bad[0]) + 1, "t_s", "samples are not evenly spaced (a gap or a change of rate)",
                        f"t_s = {float(t[bad[0]] + np.median(dt)):g} s (one sample period after the row before)")
    for name in columns:
        nan = np.flatnonzero(~np.isfinite(columns[name]))
        if len(nan) and name != "spindle_rpm":
            raise rec.error(int(nan[0]), name, f"a missing value in {name}", f"a number ({known[name]})")
    return rec


def read_tap_log(path) -> Record:
    """A hammer-test log: CSV with t_s (s, evenly spaced), force_N (hammer force, N) and one response at the
    tool tip in the hammer's direction: accel_m_s2 (m/s²), vel_mm_s (mm/s) or disp_mm (mm); any number
    of hits. Errors are ParseErrors at file:line:column."""
    rec = _read(path, TAP_COLUMNS, ("t_s", "force_N"))
    given = [r for r in RESPONSES if r in rec.columns]
    if len(given) != 1:
        raise ParseError(f"{len(given) or 'no'} response columns{': ' + ', '.join(given) if given else ''}",
                         file=rec.path, line=rec.header_line, column=1, word=",".join(rec.columns),
                         expected=f"exactly one of {', '.join(RESPONSES)}")
    return rec


def read_recording(path) -> Record:
    """A recording of a cut: CSV with t_s (s, evenly spaced), signal (microphone or accelerometer, any unit)
    and optionally spindle_rpm (rpm)."""
    return _read(path, RECORDING_COLUMNS, ("t_s", "signal"))


# --- the measured FRF ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Hits:
    """The hammer hits found in a force record: window starts (sample index), the common window length
    and the pre-trigger (samples: the pulse crosses the threshold this far into its window), the
    threshold (N) and the hits left out (double hits) as notes."""

    starts: tuple[int, ...]
    length: int
    pretrigger: int
    threshold_N: float
    notes: tuple[str, ...] = ()


def find_hits(rec: Record, *, pretrigger_s: float = 1e-3, min_record_s: float = 0.05,
              max_record_s: float = 1.0) -> Hits:
    """Hits: runs of ≥ 2 samples of hammer force above max(20 % of the largest, 6σ of the noise) (runs closer
    than 10 samples are one pulse). A pulse within `min_record_s` of the next is a double hit (the hammer
    bounced, or two taps) and left out. Each window starts `pretrigger_s` before its pulse; all have the
    length of the shortest gap to the next pulse (or the record's end), at most `max_record_s`.
    A pulse with three or more samples at its peak value is clipped (the amplifier or the ADC saturated):
    refused, as a response held at one value is."""
    f = rec.columns["force_N"] - np.median(rec.columns["force_N"])
    noise = 1.4826 * float(np.median(np.abs(f - np.median(f))))
    peak = float(np.max(f))
    threshold = max(0.2 * peak, 6.0 * noise)
    runs = _runs(f > threshold, gap=10)
    if peak <= 6.0 * noise or not runs:
        raise ParseError("no hammer hit found", file=rec.path, line=rec.header_line, column=2, word="force_N",
                         expected=f"force pulses well above the noise (largest {peak:.3g} N, noise σ {noise:.3g} N)")
    fs = rec.fs_hz
    pre, shortest = max(int(round(pretrigger_s * fs)), 2), int(round(min_record_s * fs))
    kept, notes = [], []
    for i, (a, b) in enumerate(runs):
        _check_clipped(rec, "force_N", a, b)
        near = [r for r in (runs[i - 1] if i else None, runs[i + 1] if i + 1 < len(runs) else None)
                if r and abs(r[0] - a) < shortest]
        if near:
            if near[-1][0] > a:
                gap_ms = (near[-1][0] - a) / fs * 1e3
                notes.append(f"double hit at t = {rec.columns['t_s'][a]:.4g} s (a second pulse {gap_ms:.3g} ms "
                             "later) left out")
        elif a >= pre:
            kept.append(a - pre)
    if not kept:
        raise ParseError("no usable hammer hit (every hit is a double hit, or starts the record)", file=rec.path,
                         line=rec.line(runs[0][0]), column=2, word="force_N",
                         expected=f"single hits at least {min_record_s:g} s apart, after {pretrigger_s:g} s of record")
    ends = [r[0] - pre for r in runs[1:]] + [len(f)]
    length = min(min(e for e in ends if e > s) - s for s in kept)
    length = min(length, int(max_record_s * fs))
    if length < shortest:
        raise ParseError(f"the last hit leaves {length / fs:.3g} s of record", file=rec.path,
                         line=rec.line(kept[-1] + pre), column=2, word="force_N",
                         expected=f"at least {min_record_s:g} s of response after every hit")
    for s in kept:
        response = next(r for r in RESPONSES if r in rec.columns)
        _check_clipped(rec, response, s, s + length)
    return Hits(tuple(kept), length, pre, threshold, tuple(notes))


def _runs(above: np.ndarray, gap: int) -> list[tuple[int, int]]:
    """(start, end) of runs of ≥ 2 True samples, runs closer than `gap` samples merged."""
    edges = np.diff(np.r_[0, above.astype(np.int8), 0])
    runs = [(int(a), int(b)) for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)) if b - a >= 2]
    merged: list[tuple[int, int]] = []
    for a, b in runs:
        if merged and a - merged[-1][1] < gap:
            merged[-1] = (merged[-1][0], b)
        else:
            merged.append((a, b))
    return merged


def _check_clipped(rec: Record, name: str, a: int, b: int) -> None:
    x = rec.columns[name][a:b]
    k = int(np.argmax(np.abs(x)))
    top = abs(float(x[k]))
    if top > 0 and np.count_nonzero(np.abs(np.abs(x) - top) <= 1e-9 * top) >= 3:
        raise rec.error(a + k, name, f"{name} is clipped: three or more samples at its peak {float(x[k]):g}",
                        "a hit within the sensor's range (a softer tip, a lighter hit or a larger range)")


@dataclass(frozen=True)
class MeasuredFRF:
    """The H1 receptance (mm/N, of the exponentially windowed response) and its coherence per frequency
    (Hz, from the first bin above 0 to Nyquist), the window's time constant τ (s), the hits averaged, and
    the force spectrum (N/Hz, relative) whose fall-off bounds the hammer's useful band."""

    f_hz: np.ndarray
    receptance_mm_per_N: np.ndarray
    coherence: np.ndarray
    force_spectrum: np.ndarray
    tau_s: float
    hits: Hits


def measure_frf(rec: Record, *, end_value: float = 0.01, tau_s: float | None = None, **hit_options) -> MeasuredFRF:
    """H1 = Σ F̄ X / Σ |F|² over the hits: both channels less their pre-trigger mean, the force zeroed farther
    than the pulse's length (above the threshold) before or after it, both multiplied by exp(−t/τ), τ such
    that the window ends at `end_value`."""
    hits = find_hits(rec, **hit_options)
    fs, n = rec.fs_hz, hits.length
    response = next(r for r in RESPONSES if r in rec.columns)
    tau = tau_s or n / fs / math.log(1.0 / end_value)
    w = np.exp(-np.arange(n) / fs / tau)
    sff = sxx = 0.0
    sfx = 0.0j
    for s in hits.starts:
        f = rec.columns["force_N"][s:s + n].astype(float)
        x = rec.columns[response][s:s + n].astype(float)
        pre = hits.pretrigger
        f, x = f - f[:pre].mean(), x - x[:pre].mean()
        end = pre + int(np.argmax(f[pre:] < hits.threshold_N))
        f[:max(2 * pre - end - 2, 0)] = 0.0
        f[min(2 * end - pre + 2, n):] = 0.0
        F, X = fft.rfft(f * w), fft.rfft(x * w)
        sff, sxx, sfx = sff + np.abs(F) ** 2, sxx + np.abs(X) ** 2, sfx + np.conj(F) * X
    freq = fft.rfftfreq(n, 1.0 / fs)[1:]
    h = (sfx / sff)[1:]
    s = 2j * np.pi * freq + 1.0 / tau   # the window evaluates the transfer function at s = iω + 1/τ
    g = {"accel_m_s2": 1e3 * h / s**2, "vel_mm_s": h / s, "disp_mm": h}[response]
    coh = (np.abs(sfx) ** 2 / (sff * sxx))[1:]
    return MeasuredFRF(freq, g, coh, sff[1:] / sff[1:].max(), tau, hits)


# --- the modal fit ---------------------------------------------------------------------------------------
Z_PEAK = 3.0          # a candidate peak's prominence, in random errors ε|G| of the H1 estimate at its top
MAX_CANDIDATES = 10   # candidate peaks tried, most prominent first


class ModalFit:
    """Modes of one direction fitted to a tap log's receptance.

    Settings: n_modes (None: chosen by model selection, see `select_modes`), band_hz (lo, hi; None: where
    the hammer excites, from 5 bins up to where the force spectrum first falls 20 dB below its top, at most
    0.45·fs), min_coherence (bins below it are not fitted, with two or more hits), window_s (the exponential
    window's τ, s; None: first one that ends at 1 %, then τ = 2/σ for the slowest decay σ = ζω_n found:
    ζ's error for white response noise, ∝ √(1 + στ)·(1 + 1/(στ)), is least at στ = 2). Learned: measured_
    (MeasuredFRF), frf_ (DirectionFRF of the modes, window damping removed), modes_, residual_ (R_U mm/N,
    R_L mm·Hz²/N), r2_ (of the fit to the complex receptance), coherence_ (mean over the fitted bins),
    fit_band_hz_, notes_."""

    def __init__(self, n_modes: int | None = None, *, band_hz: tuple[float, float] | None = None,
                 min_coherence: float = 0.9, window_s: float | None = None) -> None:
        if n_modes is not None and n_modes < 1:
            raise MillpostError(f"n_modes = {n_modes}: at least one mode")
        if window_s is not None and not window_s > 0:
            raise MillpostError(f"window_s = {window_s}: the exponential window's time constant must be > 0 s")
        self.n_modes, self.band_hz, self.min_coherence, self.window_s = n_modes, band_hz, min_coherence, window_s

    def fit(self, rec: Record) -> "ModalFit":
        m = measure_frf(rec, tau_s=self.window_s)
        start = select_modes(m, self._usable(m, rec.fs_hz), self.n_modes, rec.path)
        sigma = min(_decay(w) for w in start) - 1.0 / m.tau_s
        if self.window_s is None and sigma > 0 and 2.0 / sigma < m.tau_s:
            start = [_shift_decay(w, sigma / 2.0 - 1.0 / m.tau_s) for w in start]   # the same poles, new window
            m = measure_frf(rec, tau_s=2.0 / sigma)
        use = self._usable(m, rec.fs_hz)
        self.measured_ = m
        lo = max(0.6 * min(p.fn_hz for p in start), m.f_hz[use][0])
        hi = min(1.4 * max(p.fn_hz for p in start), m.f_hz[use][-1])
        pts = use & (m.f_hz >= lo) & (m.f_hz <= hi)
        g = m.receptance_mm_per_N[pts]
        windowed, self.residual_ = _least_squares(m.f_hz[pts], g, _random_error(m)[pts], start)
        err = g - _model(m.f_hz[pts], _params(windowed), self.residual_)
        self.r2_ = 1.0 - float(np.sum(np.abs(err) ** 2) / np.sum(np.abs(g - g.mean()) ** 2))
        self.coherence_ = float(np.mean(m.coherence[pts]))
        self.fit_band_hz_ = (float(lo), float(hi))
        self.modes_ = tuple(sorted((_unwindow(w, m.tau_s, rec.path) for w in windowed), key=lambda x: x.fn_hz))
        self.frf_ = DirectionFRF(modes=self.modes_)
        self.notes_ = list(m.hits.notes) + ([] if len(m.hits.starts) > 1 else
                                            ["one hit: the coherence is 1 by construction, tap two or more times"])
        return self

    def _usable(self, m: MeasuredFRF, fs: float) -> np.ndarray:
        lo = 5 * m.f_hz[0]
        weak = np.flatnonzero((m.force_spectrum < 0.01) & (m.f_hz > lo))   # past the force pulse's first lobe
        lo, hi = self.band_hz or (lo, min(m.f_hz[weak[0] - 1] if len(weak) else m.f_hz[-1], 0.45 * fs))
        use = (m.f_hz >= lo) & (m.f_hz <= hi)
        if len(m.hits.starts) > 1:
            use &= m.coherence >= self.min_coherence
        if np.count_nonzero(use) < 10:
            raise MillpostError(f"fewer than 10 frequencies between {lo:.4g} and {hi:.4g} Hz with coherence ≥ "
                                f"{self.min_coherence:g}: the hits do not excite the tool tip consistently")
        return use

    def predict(self, f_hz) -> np.ndarray:
        """The fitted modes' receptance G(f) (mm/N, complex)."""
        if not hasattr(self, "frf_"):
            raise MillpostError("ModalFit: call fit() first")
        return self.frf_.receptance_mm_per_N(f_hz)


def select_modes(m: MeasuredFRF, use: np.ndarray, n_modes: int | None, path: str) -> list[Mode]:
    """The modes of the windowed receptance (start values of the final fit).

    With n_modes: the start values of the n_modes most prominent peaks of |G|. Without: a forward model
    selection over the usable bins. Candidates are the peaks of |G| whose prominence is at least Z_PEAK
    times the H1 estimate's random error ε|G| there, ε = √((1 − γ²)/(2 n γ²)) for n hits (Bendat &
    Piersol, "Random Data", §9.2); most prominent first, each is added to the modes kept so far and the
    lot fitted (`_least_squares`); it is kept if every fitted mode is its peak (`_makes_peak`: noise
    smoothed by the window looks like a mode with σ = 0, a broad shallow mode patches the baseline) and
    the Bayesian information criterion falls,

        BIC = n_eff ln(RSS / 2N) + p ln n_eff,   n_eff = 2N τ/T,

    RSS the weighted complex residual Σ|e/σ|² over N bins, p = 3 per mode + 2 residual terms, and n_eff
    the independent values: the window e^(−t/τ) smooths the spectrum of a record of length T over T/τ
    bins (the noise's equivalent duration is τ). The common scale of σ is estimated (ln RSS), since γ²
    from a few hits is biased upward."""
    f, a = m.f_hz, np.abs(m.receptance_mm_per_N)
    peaks, props = signal.find_peaks(a, prominence=0.0)
    eps = np.sqrt(np.clip(1 - m.coherence, 0, 1) / (2 * len(m.hits.starts) * m.coherence))
    clear = use[peaks] & (True if n_modes else props["prominences"] >= Z_PEAK * eps[peaks] * a[peaks])
    order = [i for i in np.argsort(props["prominences"])[::-1] if clear[i]]
    cands = [_half_power(f, a, peaks[i]) for i in order[:n_modes or MAX_CANDIDATES]]
    if len(cands) < (n_modes or 1):
        raise MillpostError(f"{path}: {len(cands)} resonance peaks stand out of the receptance's random error"
                            f"{f', {n_modes} modes asked for' if n_modes else ''}")
    if n_modes:
        return cands
    fu, g, err = f[use], m.receptance_mm_per_N[use], _random_error(m)[use]
    n_eff = 2 * len(fu) * min(1.0, m.tau_s * f[0])      # f[0] = 1/T
    best, peaks_kept, kept = math.inf, [], []
    for c in cands:
        try:
            fitted, residual = _least_squares(fu, g, err, kept + [c])
        except MillpostError:
            continue
        if not all(_makes_peak(w, p, m, a) for w, p in zip(fitted, peaks_kept + [c])):
            continue
        rss = float(np.sum(np.abs((g - _model(fu, _params(fitted), residual)) / err) ** 2))
        bic = n_eff * math.log(rss / (2 * len(fu))) + (3 * len(fitted) + 2) * math.log(n_eff)
        if bic < best:
            best, peaks_kept, kept = bic, peaks_kept + [c], fitted
    if not kept:
        raise MillpostError(f"{path}: no resonance peak of the receptance fits a mode that decays faster than "
                            f"the exponential window (τ = {m.tau_s:.3g} s): tap with a longer record")
    return kept


def _makes_peak(w: Mode, peak: Mode, m: MeasuredFRF, a: np.ndarray) -> bool:
    """Whether the fitted (windowed) mode w is the peak it started from: the peak lies within w's half-power
    band, w decays at least as fast as the window (windowed decay ≥ 2/τ), and w's own height 1/(2kζ) is at
    least half of |G| at its natural frequency (less: the flank of other modes, or noise)."""
    return (abs(w.fn_hz - peak.fn_hz) <= w.zeta * w.fn_hz and _decay(w) * m.tau_s >= 2.0
            and 1.0 / (2 * w.k_N_per_mm * w.zeta) >= 0.5 * float(np.interp(w.fn_hz, m.f_hz, a)))


def _half_power(f: np.ndarray, a: np.ndarray, p: int) -> Mode:
    """Start values from the peak of |G| at bin p: f_n there, ζ = Δf/2f_n from the half-power bandwidth Δf,
    k = 1/(2ζ|G(f_n)|)."""
    half = a[p] / math.sqrt(2)
    i = p
    while i > 0 and a[i] > half:
        i -= 1
    j = p
    while j < len(a) - 1 and a[j] > half:
        j += 1
    f1 = np.interp(half, [a[i], a[i + 1]], [f[i], f[i + 1]])
    f2 = np.interp(half, [a[j], a[j - 1]], [f[j], f[j - 1]])
    zeta = min(max((f2 - f1) / (2 * f[p]), 1e-3), 0.3)
    return Mode(float(f[p]), float(zeta), float(1.0 / (2 * zeta * a[p])))


def _random_error(m: MeasuredFRF) -> np.ndarray:
    """The error (mm/N) each real and imaginary part of the H1 receptance is weighted by: |G|·√((1 − γ²)/(γ² n))
    for n hits (√2 times Bendat & Piersol's ε, which a few hits' upward-biased γ² understates), at least
    1 % of |G|."""
    coh = m.coherence
    return np.abs(m.receptance_mm_per_N) * np.maximum(np.sqrt(np.clip(1 - coh, 0, 1) / (coh * len(m.hits.starts))),
                                                      0.01)


def _model(f: np.ndarray, modes, residual: tuple[float, float]) -> np.ndarray:
    """Σ 1/(k (1 − r² + 2iζr)) + R_U − R_L/f² (mm/N); modes as (f_n Hz, ζ, k N/mm)."""
    return sum(1.0 / (k * (1 - (f / fn) ** 2 + 2j * z * f / fn)) for fn, z, k in modes) + residual[0] - residual[1] / f**2


def _params(modes: list[Mode]) -> list[tuple[float, float, float]]:
    """(f_n Hz, ζ, k N/mm) of each mode, as `_model` takes them."""
    return [(m.fn_hz, m.zeta, m.k_N_per_mm) for m in modes]


def _least_squares(f: np.ndarray, g: np.ndarray, sigma: np.ndarray,
                   start: list[Mode]) -> tuple[list[Mode], tuple[float, float]]:
    """Modes (f_n, ζ, k as logarithms, so they stay positive) and the residuals R_U, R_L fitted to the
    complex receptance g (mm/N), real and imaginary parts, each bin weighted by 1/sigma (its error, mm/N)."""
    scale = float(np.max(np.abs(g)))
    x0 = np.r_[[v for m in start for v in (math.log(m.fn_hz), math.log(m.zeta), math.log(m.k_N_per_mm))], 0.0, 0.0]
    f_ref2 = float(np.min(f)) ** 2

    def unpack(x):
        modes = [(math.exp(x[3 * i]), math.exp(x[3 * i + 1]), math.exp(x[3 * i + 2])) for i in range(len(start))]
        return modes, (x[-2] * scale, x[-1] * scale * f_ref2)

    def resid(x):
        e = (_model(f, *unpack(x)) - g) / sigma
        return np.r_[e.real, e.imag]

    sol = optimize.least_squares(resid, x0, x_scale="jac", method="lm")
    modes, residual = unpack(sol.x)
    if any(not (0 < z < 1) for _, z, _ in modes):
        raise MillpostError("the modal fit found a mode with a damping ratio outside (0, 1): "
                            "fewer modes (--modes) or a narrower band (--band)")
    return [Mode(*m) for m in modes], (float(residual[0]), float(residual[1]))


def _decay(m: Mode) -> float:
    """The mode's decay rate σ = ζω_n (1/s)."""
    return 2 * math.pi * m.fn_hz * m.zeta


def _shift_decay(m: Mode, d_sigma: float) -> Mode:
    """The mode with its decay rate raised by d_sigma (1/s): same damped frequency, same modal mass (what an
    exponential window e^(−t/τ) does with d_sigma = 1/τ)."""
    w = 2 * math.pi * m.fn_hz
    sigma, wd = _decay(m) + d_sigma, w * math.sqrt(1 - m.zeta**2)
    wn = math.hypot(sigma, wd)
    return Mode(wn / (2 * math.pi), sigma / wn, m.k_N_per_mm * (wn / w) ** 2)


def _unwindow(m: Mode, tau_s: float, path: str) -> Mode:
    """The mode without the exponential window's damping: decay rate less 1/τ."""
    if _decay(m) <= 1.0 / tau_s:
        raise MillpostError(f"{path}: the mode at {m.fn_hz:.4g} Hz decays no faster than the exponential window "
                            f"(τ = {tau_s:.3g} s): its damping cannot be measured; tap with a longer record")
    return _shift_decay(m, -1.0 / tau_s)


# --- chatter ---------------------------------------------------------------------------------------------
FALSE_ALARM = 0.01   # probability that a stable cut's noise alone is called chatter
FLIP_RATIO = 100.0   # a spindle harmonic this far (power) above its neighbours' median is flip chatter (20 dB)


@dataclass(frozen=True)
class ChatterVerdict:
    """A cut's verdict: `chatter` when the strongest non-harmonic peak, at f_chatter_hz (Hz), stands above the
    noise floor by more than `threshold` (ratios of power densities; `peak_to_floor` is the peak's), or, with
    `period_doubling`, when a spindle harmonic at (k + ½)·f_t stands above its neighbouring runout harmonics
    by more than `threshold` (`flip_chatter`; `peak_to_floor` is then that ratio); the tooth-passing
    frequency f_t = N n/60 (Hz), the lobe number and phase ε (rad) with f_c/f_t = lobe + ε/2π, and the
    stable speeds (j, rpm) with n_j = 60 f_c/(N j) (none without chatter)."""

    chatter: bool
    f_chatter_hz: float
    peak_to_floor: float
    threshold: float
    rpm: float
    flutes: int
    f_tooth_hz: float
    lobe: int
    epsilon_rad: float
    speeds: tuple[tuple[int, float], ...] = field(default=())
    period_doubling: bool = False

    @property
    def notes(self) -> list[str]:
        """What the verdict cannot tell: with an even flute count flip chatter lies on a spindle harmonic."""
        if self.flutes % 2 or self.period_doubling:
            return []
        return [f"with {self.flutes} flutes (even) period-doubling chatter, at (k + ½)·{self.f_tooth_hz:.6g} Hz, "
                f"lies on a spindle harmonic: it is found only where it stands {10 * math.log10(FLIP_RATIO):.0f} dB "
                "above the neighbouring (runout) harmonics; weaker, it cannot be told from runout"]


def spectrum(rec: Record, resolution_hz: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Welch power spectral density (Hann, 50 % overlap) of the signal, segments of the power of two that
    gives at most `resolution_hz` between bins (the whole record when it is shorter): (f Hz, PSD, ν), ν
    the estimate's equivalent χ² degrees of freedom, 2K / (1 + 2ρ²(1 − 1/K)) for K segments whose
    overlapping windows correlate by ρ (1/6 for Hann; Percival & Walden, "Spectral Analysis for Physical
    Applications", §6.17)."""
    x = rec.columns["signal"] - np.mean(rec.columns["signal"])
    fs = rec.fs_hz
    nper = min(len(x), 2 ** math.ceil(math.log2(fs / resolution_hz)))
    f, p = signal.welch(x, fs, window="hann", nperseg=nper, detrend="constant")
    w, step = signal.get_window("hann", nper), nper // 2
    k = 1 + (len(x) - nper) // step
    rho = float(np.sum(w[:nper - step] * w[step:]) / np.sum(w**2))
    return f, p, 2 * k / (1 + 2 * rho**2 * (1 - 1 / k))


def chatter_frequency(f: np.ndarray, p: np.ndarray, dof: float, rpm: float, *, tolerance: float = 0.002
                      ) -> tuple[float, float, float, float]:
    """(f_c Hz, its peak / the noise floor, the threshold, its peak's density) from the spectrum (f Hz, PSD p,
    ν = dof; `spectrum`): f_c is the strongest local maximum of the spectrum
    that is not a spindle harmonic k·n/60 (within max(2 bins, `tolerance`·f) of one; k·n/60 includes the
    tooth-passing harmonics; a local maximum, so not a harmonic's leakage), refined by a parabola through
    the log power of the peak bin and its neighbours. The noise floor is the median of the non-harmonic
    bins within an octave of f_c. Noise alone makes each bin's estimate S·χ²_ν/ν: the threshold is the
    ratio whose chance of being passed by any of the M non-harmonic bins is FALSE_ALARM,
    χ²_ν quantile(1 − FALSE_ALARM/M) / χ²_ν median."""
    f_spindle = rpm / 60.0
    df = f[1] - f[0]
    k = np.maximum(np.round(f / f_spindle), 1)
    free = (np.abs(f - k * f_spindle) > np.maximum(2 * df, tolerance * f)) & (f > 0.5 * f_spindle)
    free[[0, -1]] = False
    peak = free & (p >= np.roll(p, 1)) & (p >= np.roll(p, -1))
    if not peak.any():
        raise MillpostError("no frequency of the recording lies between the spindle harmonics")
    i = int(np.argmax(np.where(peak, p, -np.inf)))
    y0, y1, y2 = np.log(p[i - 1:i + 2] + 1e-300)
    shift = 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2) if y0 - 2 * y1 + y2 < 0 else 0.0
    floor = float(np.median(p[free & (f >= f[i] / 2) & (f <= 2 * f[i])]))
    chi2 = stats.chi2(dof)
    threshold = float(chi2.isf(FALSE_ALARM / np.count_nonzero(free)) / chi2.median())
    return float(f[i] + shift * df), float(p[i] / floor), threshold, float(p[i])


def flip_chatter(f: np.ndarray, p: np.ndarray, rpm: float, flutes: int) -> tuple[float, float, float]:
    """(f Hz, its level / its neighbours', its density) of the strongest candidate for period-doubling (flip)
    chatter on a spindle harmonic: with an even flute count N flip chatter sits at (k + ½)·N·n/60, the
    spindle harmonic m = (2k + 1)·N/2, which the harmonic mask of `chatter_frequency` hides. Runout makes
    every spindle harmonic but not one towering over the others: each such m's level (the largest density
    within 2 bins) is compared with the median of the nearest harmonics that are not tooth-passing ones, two
    each side; an m with fewer below (the once-per-revolution 1×, where unbalance and runout dominate, and
    for N = 2 also 3×) is not examined. (nan, 0, 0) for an odd N (its flip chatter lies between harmonics)."""
    if flutes % 2:
        return math.nan, 0.0, 0.0
    f_spindle, df = rpm / 60.0, f[1] - f[0]
    top = int(f[-1] / f_spindle) - 1
    level = {m: float(p[np.abs(f - m * f_spindle) <= 2 * df].max()) for m in range(1, top + 1)}
    runout = [m for m in level if m % flutes]
    best = (math.nan, 0.0, 0.0)
    for m in range(flutes // 2, top + 1, flutes):
        near = [q for q in runout if q < m][-2:] + [q for q in runout if q > m][:2]
        ratio = level[m] / float(np.median([level[q] for q in near])) if len(near) == 4 else 0.0
        if ratio > best[1]:
            best = (m * f_spindle, ratio, level[m])
    return best


def stable_speeds(f_chatter_hz: float, flutes: int, *, rpm_min: float = 0.0, rpm_max: float = math.inf,
                  count: int = 5) -> tuple[tuple[int, float], ...]:
    """The `count` fastest speeds n_j = 60 f_c/(N j) (rpm), j = 1, 2, …, within [rpm_min, rpm_max]."""
    j = max(1, math.ceil(60.0 * f_chatter_hz / (flutes * rpm_max))) if math.isfinite(rpm_max) else 1
    out = []
    while len(out) < count:
        n = 60.0 * f_chatter_hz / (flutes * j)
        if n < rpm_min:
            break
        out.append((j, n))
        j += 1
    return tuple(out)


def analyse_chatter(rec: Record, rpm: float, flutes: int, *, rpm_min: float = 0.0, rpm_max: float = math.inf,
                    count: int = 5) -> ChatterVerdict:
    """Whether a recording at `rpm` with `flutes` teeth chatters, at what frequency, and the stable speeds."""
    for name, value, ok, rule in (("rpm", rpm, math.isfinite(rpm) and rpm > 0, "a spindle speed > 0"),
                                  ("flutes", flutes, flutes >= 1, "at least 1"),
                                  ("spindle min rpm", rpm_min, math.isfinite(rpm_min) and rpm_min >= 0, "≥ 0"),
                                  ("spindle max rpm", rpm_max, rpm_max > 0 and rpm_max >= rpm_min,
                                   f"> 0 and ≥ the spindle min ({rpm_min:g} rpm)"),
                                  ("stable speeds listed", count, count >= 1, "at least 1")):
        if not ok:
            raise MillpostError(f"{name} = {value:g}: expected {rule}")
    if flutes * rpm / 60.0 >= rec.fs_hz / 2:
        raise MillpostError(f"{rec.path}: the tooth-passing frequency at {rpm:g} rpm with {flutes} flutes, "
                            f"{flutes * rpm / 60.0:.6g} Hz, is not below the recording's Nyquist frequency "
                            f"{rec.fs_hz / 2:.6g} Hz: check the speed (rpm) or record faster")
    f, p, dof = spectrum(rec, rpm / 60.0 / 40.0)
    fc, ratio, threshold, power = chatter_frequency(f, p, dof, rpm)
    f_flip, flip_ratio, flip_power = flip_chatter(f, p, rpm, flutes)
    flip = flip_ratio > FLIP_RATIO and (ratio <= threshold or flip_power > power)
    if flip:
        fc, ratio, threshold = f_flip, flip_ratio, FLIP_RATIO
    ft = flutes * rpm / 60.0
    lobe = int(fc // ft)
    chatter = ratio > threshold
    return ChatterVerdict(chatter, fc, ratio, threshold, rpm, flutes, ft, lobe, 2 * math.pi * (fc / ft - lobe),
                          stable_speeds(fc, flutes, rpm_min=rpm_min, rpm_max=rpm_max, count=count) if chatter else (),
                          flip)
