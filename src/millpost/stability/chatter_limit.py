"""The chatter limit of a planned cut (`millpost recommend --frf`): its axial depth against the limiting
depth of the zero-order stability lobes (`lobes.zero_order_limit_mm`, Altintas & Budak 1995) at its speed
and radial immersion.

A straight flank cut of width ae with a tool of diameter D engages φ_st…φ_ex (`forces.immersion`: climb
π − φ_s…π, conventional 0…φ_s, cos φ_s = 1 − 2ae/D); the feed runs along the FRF's x (the machine's X:
a round tool's X and Y are the same). K_t and K_r are those of the optimize check
(`check.cutting_coefficients`: the material's mechanistic set or its Kienzle tangent). The load ratio is
ap / a_lim (≤ 1 stable; its inverse is the margin).

Every pair (ae, rpm) evaluated is cached: a search asks again and again for the same widths and speeds.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..forces import immersion
from ..materials import Material
from .check import limit_mm
from .frf import ToolTipFRF


@dataclass
class ChatterLimit:
    """ap ≤ a_lim(ae, rpm) for a tool (diameter_mm, flutes) with tip FRF `frf` in a material, milling
    climb or conventional."""

    frf: ToolTipFRF
    material: Material
    diameter_mm: float
    flutes: int
    climb: bool
    _cache: dict[tuple[float, float], float] = field(default_factory=dict, repr=False)

    def a_lim_mm(self, ae_mm, rpm) -> np.ndarray:
        """The limiting depth (mm; inf where no lobe reaches) per candidate (arrays of one shape)."""
        ae, n = np.broadcast_arrays(np.asarray(ae_mm, float), np.asarray(rpm, float))
        todo = sorted({(a, r) for a, r in zip(ae.ravel().tolist(), n.ravel().tolist())} - set(self._cache))
        for width in sorted({a for a, _ in todo}):
            speeds = np.array([r for a, r in todo if a == width])
            st, ex = immersion(width, self.diameter_mm, climb=self.climb)
            limit = limit_mm(self.frf, self.material, self.flutes, st, ex, speeds)
            self._cache.update(zip(((width, r) for r in speeds.tolist()), limit.tolist()))
        pairs = zip(ae.ravel().tolist(), n.ravel().tolist())
        return np.array([self._cache[pair] for pair in pairs]).reshape(ae.shape)

    def ratio(self, ae_mm, ap_mm, rpm) -> np.ndarray:
        """ap / a_lim per candidate (≤ 1: stable)."""
        return np.asarray(ap_mm, float) / self.a_lim_mm(ae_mm, rpm)
