"""The cutter as a cantilever beam clamped in the holder: deflection, bending stress, breaking force.

Two segments from the holder face: the shank (length stickout − flute length, diameter D_s) and the
fluted part (flute length, equivalent diameter d_e = 0.8·D; Kops & Vo, CIRP Annals 39(1) 1990, the same
for 2 and 4 flutes). The cutting force acts at mid-depth of cut, a = stickout − a_p/2 from the holder
(cactode/ammp). By the unit-load method (Euler–Bernoulli, E constant):

    δ(load point) = F ∫₀^a (a − x)² / (E I(x)) dx,     δ(tip) = F ∫₀^a (a − x)(L − x) / (E I(x)) dx

which for a tip load reduces to the two-segment formula of PHYSICS.md §4.1. Bending stress at a round
section a lever arm l from the load: σ = 32 F l / (π d³); checked at the holder (D_s, arm a) and at the
flute root (d_e, arm a − L_s, where the shank steps down to the flutes). Torsion τ = 16 T/(π d_e³) is
turned into an equivalent normal stress τ/0.577 (von Mises, as cactode/ammp does).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import MillpostError
from .cutter import Tool

# Young's modulus and bending (transverse rupture) strength, MPa.
# Carbide E 600 GPa: cactode/ammp models.py (580 GPa calculatorhub.com after Machinery's Handbook);
#   TRS of cemented carbide grades 2–4 GPa (PHYSICS.md §4.2 [†]); 3000 MPa is the middle.
# HSS E 200 GPa: PHYSICS.md §4.1; bending strength of hardened M2 ~3000 MPa is quoted in steel makers'
#   sheets [†], but HSS bends before it snaps, so 2000 MPa is used as the allowable base.
MATERIALS = {
    "carbide": {"E_MPa": 600e3, "strength_MPa": 3000.0},
    "hss": {"E_MPa": 200e3, "strength_MPa": 2000.0},
}
FLUTE_DIAMETER_RATIO = 0.8   # Kops & Vo 1990


def default_safety_factor(tool: Tool) -> float:
    """Safety factor on the bending strength, chosen from the geometry [engineering judgement, †]:
    2 for an ordinary end mill; ×1.5 below 3 mm diameter (runout and edge chipping are a larger share of
    the load and the strength scatters more); ×1.25 for a slender tool, flute length over 4·D or stickout
    over 4·shank diameter (vibration adds to the quasi-static load). Brittle carbide gets no credit for ductility, HSS the same factor."""
    sf = 2.0
    if tool.diameter_mm < 3.0:
        sf *= 1.5
    if tool.flute_len > 4.0 * tool.diameter_mm or tool.stickout > 4.0 * tool.shank_diameter:
        sf *= 1.25
    return sf


@dataclass(frozen=True)
class ToolBeam:
    """Beam model of one tool. Lengths mm, E and strength MPa, forces N."""

    stickout_mm: float
    flute_length_mm: float
    shank_diameter_mm: float
    flute_diameter_mm: float
    E_MPa: float
    strength_MPa: float
    safety_factor: float

    @classmethod
    def of(cls, tool: Tool, *, safety_factor: float | None = None, E_MPa: float | None = None,
           strength_MPa: float | None = None) -> "ToolBeam":
        props = MATERIALS[tool.material]
        flute_len = min(tool.flute_len, tool.stickout)
        return cls(stickout_mm=tool.stickout, flute_length_mm=flute_len, shank_diameter_mm=tool.shank_diameter,
                   flute_diameter_mm=FLUTE_DIAMETER_RATIO * tool.diameter_mm,
                   E_MPa=E_MPa or props["E_MPa"], strength_MPa=strength_MPa or props["strength_MPa"],
                   safety_factor=safety_factor or default_safety_factor(tool))

    @property
    def shank_length_mm(self) -> float:
        return self.stickout_mm - self.flute_length_mm

    def _segments(self) -> list[tuple[float, float, float]]:
        """(start, end, E·I) from the holder face, mm and N·mm²."""
        ei = lambda d: self.E_MPa * math.pi * d ** 4 / 64.0  # noqa: E731
        return [(0.0, self.shank_length_mm, ei(self.shank_diameter_mm)),
                (self.shank_length_mm, self.stickout_mm, ei(self.flute_diameter_mm))]

    def load_arm_mm(self, ap_mm: float = 0.0) -> float:
        """Distance from the holder to the resultant cutting force: stickout − a_p/2."""
        arm = self.stickout_mm - 0.5 * min(max(ap_mm, 0.0), self.flute_length_mm)
        if arm <= 0:
            raise MillpostError("the cut is above the holder face")
        return arm

    def compliance_mm_per_N(self, ap_mm: float = 0.0, *, at_tip: bool = False) -> float:
        """Lateral deflection per newton at the load point (or the tip) for a load at mid-depth of cut."""
        a = self.load_arm_mm(ap_mm)
        L = self.stickout_mm if at_tip else a
        total = 0.0
        for x0, x1, ei in self._segments():
            x1 = min(x1, a)
            if x1 <= x0:
                continue
            # ∫ (a − x)(L − x) dx, exact for a polynomial
            F = lambda x: a * L * x - (a + L) * x * x / 2 + x ** 3 / 3  # noqa: E731
            total += (F(x1) - F(x0)) / ei
        return total

    def stiffness_N_per_mm(self, ap_mm: float = 0.0) -> float:
        return 1.0 / self.compliance_mm_per_N(ap_mm)

    def deflection_mm(self, force_N: float, ap_mm: float = 0.0) -> float:
        """Deflection at the load point under a lateral force (N)."""
        return force_N * self.compliance_mm_per_N(ap_mm)

    def bending_stress_MPa(self, force_N: float, ap_mm: float = 0.0, torque_Nm: float = 0.0) -> float:
        """Largest of: bending at the holder, bending at the flute root, torsion in the flutes (equivalent)."""
        a = self.load_arm_mm(ap_mm)
        at_holder = 32.0 * force_N * a / (math.pi * self.shank_diameter_mm ** 3)
        at_root = 32.0 * force_N * max(a - self.shank_length_mm, 0.0) / (math.pi * self.flute_diameter_mm ** 3)
        torsion = 16.0 * torque_Nm * 1000.0 / (math.pi * self.flute_diameter_mm ** 3) / 0.577
        return max(at_holder, at_root, torsion)

    def breaking_force_N(self, ap_mm: float = 0.0) -> float:
        """Allowed lateral force: bending stress reaches strength / safety factor at the weakest section."""
        return (self.strength_MPa / self.safety_factor) / self.bending_stress_MPa(1.0, ap_mm)
