"""The tool tip's frequency response (receptance, mm/N) in the machine's X and Y directions.

A direction's response is either a sum of modes, each a mass-spring-damper seen at the tool tip,

    G(ω) = Σ_i 1 / (k_i (1 − r_i² + 2 i ζ_i r_i)),   r_i = ω / ω_n,i

(k_i the modal stiffness N/mm, ζ_i the damping ratio, f_n,i = ω_n,i / 2π in Hz), or a measured table of
frequency (Hz) against the complex receptance, interpolated linearly between its rows. Cross terms
(X force → Y motion) are neglected, as in the zero-order and semi-discretisation stability methods.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

G_MIN_MM_PER_N = 1e-7  # a tool tip's largest |G| is above this (1 / 10 N/nm, a static stiffness none reaches)


@dataclass(frozen=True)
class Mode:
    """One vibration mode at the tool tip: natural frequency fn_hz (Hz), damping ratio zeta (–), modal
    stiffness k_N_per_mm (N/mm)."""

    fn_hz: float
    zeta: float
    k_N_per_mm: float

    def __post_init__(self) -> None:
        for name, value, rule in (("fn_hz", self.fn_hz, self.fn_hz > 0), ("zeta", self.zeta, 0 < self.zeta < 1),
                                  ("k_N_per_mm", self.k_N_per_mm, self.k_N_per_mm > 0)):
            if not (math.isfinite(value) and rule):
                raise ConfigError(name, value, "fn_hz and k_N_per_mm must be > 0, zeta in (0, 1)")

    def receptance_mm_per_N(self, f_hz) -> np.ndarray:
        """G(f) = 1 / (k (1 − r² + 2iζr)), r = f / f_n (mm/N, complex)."""
        r = np.asarray(f_hz, float) / self.fn_hz
        return 1.0 / (self.k_N_per_mm * (1.0 - r**2 + 2j * self.zeta * r))


@dataclass(frozen=True)
class DirectionFRF:
    """The receptance of one direction: modes, or a measured table (f_hz ascending, receptance mm/N)."""

    modes: tuple[Mode, ...] = ()
    f_hz: np.ndarray | None = None
    measured_mm_per_N: np.ndarray | None = None

    def __post_init__(self) -> None:
        if bool(self.modes) == (self.f_hz is not None):
            raise ConfigError("frf", "modes and table", "give either modes or a measured table, one of them")
        if self.f_hz is not None:
            f = np.asarray(self.f_hz, float)
            if f.ndim != 1 or len(f) < 2 or np.any(np.diff(f) <= 0) or f[0] < 0:
                raise ConfigError("frf f_hz", "table", "at least two frequencies, ascending, ≥ 0 Hz")
            if np.shape(self.measured_mm_per_N) != f.shape:
                raise ConfigError("frf receptance", "table", "one complex receptance per frequency")

    def receptance_mm_per_N(self, f_hz) -> np.ndarray:
        """G(f), mm/N complex; a measured table is interpolated (real and imaginary parts) and refused
        outside its frequency range."""
        f = np.asarray(f_hz, float)
        if self.modes:
            return sum(m.receptance_mm_per_N(f) for m in self.modes)
        lo, hi = self.f_hz[0], self.f_hz[-1]
        if np.any((f < lo) | (f > hi)):
            raise ConfigError("frf", f"{float(np.min(f)):.6g}–{float(np.max(f)):.6g} Hz",
                              f"the measured FRF covers {lo:.6g}–{hi:.6g} Hz only")
        g = np.asarray(self.measured_mm_per_N)
        return np.interp(f, self.f_hz, g.real) + 1j * np.interp(f, self.f_hz, g.imag)

    @property
    def doubts(self) -> list[str]:
        """What makes a measured table suspect: its largest |G| at an end of its band (the resonance, where
        chatter lives, may lie outside it), or |G| below `G_MIN_MM_PER_N` everywhere (stiffer than any tool
        tip: a table in m/N, 1000 times too small). None for modes."""
        if self.f_hz is None:
            return []
        g = np.abs(np.asarray(self.measured_mm_per_N))
        k, out = int(np.argmax(g)), []
        if k in (0, len(g) - 1):
            out.append(f"its largest |G| ({g[k]:.3g} mm/N) is at the end of its band, {self.f_hz[k]:g} Hz: the "
                       "resonance may lie outside the table, and chatter near it is not seen")
        if g[k] < G_MIN_MM_PER_N:
            out.append(f"|G| ≤ {g[k]:.3g} mm/N everywhere, stiffer than any tool tip: a receptance in m/N? (the "
                       "table is read in mm/N: 1 m/N = 1000 mm/N)")
        return out

    @property
    def band_hz(self) -> tuple[float, float]:
        """The frequencies where chatter is sought: a measured table's range, or 0 to three times the
        highest mode (each mode's response peak lies near its f_n)."""
        if self.modes:
            return 0.0, 3.0 * max(m.fn_hz for m in self.modes)
        return float(self.f_hz[0]), float(self.f_hz[-1])


@dataclass(frozen=True)
class ToolTipFRF:
    """The tool tip's receptance in machine X and Y (mm/N)."""

    x: DirectionFRF
    y: DirectionFRF

    def oriented(self, along_y: bool) -> "ToolTipFRF":
        """The receptance in the feed frame (x along the feed): X and Y swapped where the feed runs along
        machine Y."""
        return ToolTipFRF(self.y, self.x) if along_y else self

    @classmethod
    def symmetric(cls, *modes: Mode) -> "ToolTipFRF":
        """The same modes in X and Y (a tool's own bending modes: round, so symmetric)."""
        d = DirectionFRF(modes=tuple(modes))
        return cls(d, d)
