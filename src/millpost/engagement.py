"""Cutter engagement per path sample: what the force model needs to know about the cut.

Conventions (Altintas): x = feed direction, y = in-plane normal to the left of x, z = tool axis.
Immersion angle φ is measured clockwise from +y (the cutter turns clockwise seen from the spindle),
so a tooth enters at φ_st and leaves at φ_ex; up-milling starts at 0, down-milling ends at π, a full
slot spans [0, π]. The tool is cut into K axial slices; each slice carries its own engaged arc.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Engagement:
    """Per sample (N) and axial slice (K). Lengths mm, angles rad, volumes mm³.

    phi_st, phi_ex: (N, K) outermost engaged immersion interval of the slice (nan when the slice
        does not cut). dz_mm: (N, K) axial thickness of the slice's engaged part (0 when not cutting).
    z_mm: (N, K) slice mid-height above the tool tip. r_mm: (N, K) cutting radius of the slice.
    kappa: (N, K) axial immersion angle of the edge (π/2 on a cylindrical flank; < π/2 on a ball or
        corner radius), so chip thickness is h = f_z·sin φ·sin κ.
    feed_dir: (N, 3) unit feed direction (the x of the convention) in machine coordinates.
    ap_mm, ae_mm: (N,) axial depth and radial width of cut. volume_mm3: (N,) material removed on the
    step ending at the sample; area_mm2 = volume / step length (the cross-section the feed sweeps).
    """

    phi_st: np.ndarray
    phi_ex: np.ndarray
    dz_mm: np.ndarray
    z_mm: np.ndarray
    r_mm: np.ndarray
    kappa: np.ndarray
    feed_dir: np.ndarray
    ap_mm: np.ndarray
    ae_mm: np.ndarray
    volume_mm3: np.ndarray
    area_mm2: np.ndarray

    def __len__(self) -> int:
        return len(self.ap_mm)

    @classmethod
    def uniform(cls, phi_st, phi_ex, ap_mm: float, radius_mm: float, *, slices: int = 1,
                kappa: float = np.pi / 2, feed_dir=(1.0, 0.0, 0.0)) -> "Engagement":
        """A flank cut with the same arc on every slice: N samples from arrays phi_st, phi_ex.

        Used by `millpost calc`, by heuristics and in tests, where the cut is given, not simulated.
        ae follows from the arc for a cylindrical flank: ae = R·(cos φ_st − cos φ_ex).
        """
        phi_st = np.atleast_1d(np.asarray(phi_st, float))
        phi_ex = np.atleast_1d(np.asarray(phi_ex, float))
        n = len(phi_st)
        dz = ap_mm / slices
        full = lambda v: np.full((n, slices), v, float)  # noqa: E731
        ae = radius_mm * (np.cos(phi_st) - np.cos(phi_ex))
        area = ae * ap_mm
        return cls(
            phi_st=np.repeat(phi_st[:, None], slices, 1), phi_ex=np.repeat(phi_ex[:, None], slices, 1),
            dz_mm=full(dz), z_mm=np.tile((np.arange(slices) + 0.5) * dz, (n, 1)), r_mm=full(radius_mm),
            kappa=full(kappa), feed_dir=np.tile(np.asarray(feed_dir, float), (n, 1)),
            ap_mm=np.full(n, ap_mm), ae_mm=ae, volume_mm3=np.full(n, np.nan), area_mm2=area)
