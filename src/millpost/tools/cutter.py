"""Cutter geometry: a rotationally symmetric tool described by its radial profile r(z).

z is measured up the tool axis from the tip (mm). Shapes: flat end mill, ball end mill, bull nose
(corner radius), chamfer/V-bit (included angle), twist drill (point angle σ, a cone r = z·tan(σ/2),
and a chisel edge of length c = chisel_ratio·D at its centre). The profile is what the engagement model
sweeps through the stock; flutes, helix and stickout feed the force and beam models.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

SHAPES = ("flat", "ball", "bull", "chamfer", "drill")
CONE_SHAPES = ("chamfer", "drill")  # profiles that are a cone from the tip (a drill: no flat)
DRILL_POINT_DEG = 118.0     # the common jobber-drill point angle
DRILL_CHISEL_RATIO = 0.18   # c/d of a standard (unthinned) point, Machinery's Handbook 31st ed. Table 7


@dataclass(frozen=True)
class Tool:
    """A milling cutter. Lengths in mm, angles in degrees (as on a tool's data sheet).

    shape: one of flat, ball, bull, chamfer, drill. corner_radius_mm: bull nose only (ball: D/2 implied).
    tip_angle_deg: included angle of a chamfer/V tool (default 90) or a drill's point angle σ (default
    118); tip_diameter_mm the flat of a chamfer tool. chisel_ratio: chisel-edge length over diameter c/d
    of a drill (0.18 standard point, 0.03 split or thinned point; Machinery's Handbook Table 7), 0 for
    milling cutters (their gashed centre is taken as cutting).
    helix_deg: flute helix angle. flute_length_mm: cutting length. stickout_mm: holder face to tip.
    shank_diameter_mm: defaults to the cutting diameter. material: "carbide" or "hss".
    edge_radius_mm: cutting-edge hone radius (sets the minimum chip thickness).
    """

    diameter_mm: float
    flutes: int = 2
    shape: str = "flat"
    corner_radius_mm: float = 0.0
    tip_angle_deg: float | None = None
    tip_diameter_mm: float = 0.0
    chisel_ratio: float | None = None
    helix_deg: float = 30.0
    flute_length_mm: float | None = None
    stickout_mm: float | None = None
    shank_diameter_mm: float | None = None
    material: str = "carbide"
    edge_radius_mm: float = 0.005
    number: int | None = None
    name: str = ""

    def __post_init__(self) -> None:
        def need(ok: bool, field: str, rule: str) -> None:
            if not ok:
                raise ConfigError(field, getattr(self, field), rule)

        need(math.isfinite(self.diameter_mm) and self.diameter_mm > 0, "diameter_mm", "must be > 0 mm")
        need(isinstance(self.flutes, int) and 1 <= self.flutes <= 20, "flutes", "must be an integer 1..20")
        need(self.shape in SHAPES, "shape", f"must be one of {', '.join(SHAPES)}")
        drill = self.shape == "drill"
        if self.tip_angle_deg is None:
            object.__setattr__(self, "tip_angle_deg", DRILL_POINT_DEG if drill else 90.0)
        if self.chisel_ratio is None:
            object.__setattr__(self, "chisel_ratio", DRILL_CHISEL_RATIO if drill else 0.0)
        need(0 <= self.chisel_ratio <= 0.35, "chisel_ratio", "must be in [0, 0.35] (chisel length / diameter)")
        need(0 <= self.helix_deg < 80, "helix_deg", "must be in [0, 80) degrees")
        need(self.material in ("carbide", "hss"), "material", "must be 'carbide' or 'hss'")
        need(self.edge_radius_mm >= 0, "edge_radius_mm", "must be >= 0 mm")
        if self.shape == "bull":
            need(0 < self.corner_radius_mm <= self.radius_mm, "corner_radius_mm",
                 "a bull nose needs 0 < corner radius <= D/2")
        if self.shape in CONE_SHAPES:
            need(0 < self.tip_angle_deg < 180, "tip_angle_deg", "must be in (0, 180) degrees")
            need(0 <= self.tip_diameter_mm < self.diameter_mm, "tip_diameter_mm", "must be in [0, D)")
        if drill:
            need(self.tip_diameter_mm == 0, "tip_diameter_mm", "a drill's point has no flat (give 0)")
        for f in ("flute_length_mm", "stickout_mm", "shank_diameter_mm"):
            v = getattr(self, f)
            need(v is None or (math.isfinite(v) and v > 0), f, "must be > 0 mm when given")
        if self.flute_length_mm is not None and self.stickout_mm is not None:
            need(self.flute_length_mm <= self.stickout_mm, "flute_length_mm", "must not exceed the stickout")

    @property
    def radius_mm(self) -> float:
        return 0.5 * self.diameter_mm

    @property
    def flute_len(self) -> float:
        """Cutting length (mm); 3·D when not given (a common stub-to-regular end mill)."""
        return self.flute_length_mm if self.flute_length_mm is not None else 3.0 * self.diameter_mm

    @property
    def stickout(self) -> float:
        """Holder face to tip (mm); flute length + 0.5·D when not given."""
        return self.stickout_mm if self.stickout_mm is not None else self.flute_len + 0.5 * self.diameter_mm

    @property
    def shank_diameter(self) -> float:
        return self.shank_diameter_mm if self.shank_diameter_mm is not None else self.diameter_mm

    @property
    def corner_radius(self) -> float:
        """Effective corner radius: D/2 for a ball, the given value for a bull, 0 otherwise."""
        return {"ball": self.radius_mm, "bull": self.corner_radius_mm}.get(self.shape, 0.0)

    @property
    def profile_height_mm(self) -> float:
        """Height above the tip where the profile reaches the full radius."""
        if self.shape in CONE_SHAPES:
            half = math.radians(0.5 * self.tip_angle_deg)
            return (self.radius_mm - 0.5 * self.tip_diameter_mm) / math.tan(half)
        return self.corner_radius

    def radius_at(self, z_mm: np.ndarray | float) -> np.ndarray:
        """Cutting radius r(z) at height z above the tip (mm); 0 below the tip, R above the profile."""
        z = np.asarray(z_mm, dtype=float)
        R = self.radius_mm
        if self.shape in ("ball", "bull"):
            rc = self.corner_radius
            dz = np.clip(rc - z, 0.0, rc)
            r = (R - rc) + np.sqrt(np.maximum(rc * rc - dz * dz, 0.0))
        elif self.shape in CONE_SHAPES:
            half = math.radians(0.5 * self.tip_angle_deg)
            r = np.minimum(0.5 * self.tip_diameter_mm + z * math.tan(half), R)
        else:
            r = np.full_like(z, R)
        return np.where(z < 0, 0.0, r)

    def height_at(self, r_mm: np.ndarray | float) -> np.ndarray:
        """Inverse profile: height above the tip of the cutting surface at radius r (mm); inf beyond R."""
        r = np.asarray(r_mm, dtype=float)
        R = self.radius_mm
        if self.shape in ("ball", "bull"):
            rc = self.corner_radius
            x = np.clip(r - (R - rc), 0.0, None)
            h = rc - np.sqrt(np.maximum(rc * rc - np.minimum(x, rc) ** 2, 0.0))
        elif self.shape in CONE_SHAPES:
            half = math.radians(0.5 * self.tip_angle_deg)
            h = np.maximum(r - 0.5 * self.tip_diameter_mm, 0.0) / math.tan(half)
        else:
            h = np.zeros_like(r)
        return np.where(r > R, np.inf, h)

    def end_sin_kappa(self, r_mm: np.ndarray | float) -> np.ndarray:
        """sin κ of the end's cutting edge at radius r (mm): κ is the angle between the edge and the tool
        axis, sin κ = 1/√(1 + (dz/dr)²) of the profile (1 on a flat end, sin(σ/2) on a cone, √(1 − x²/r_ε²)
        on a corner radius at x = r − (R − r_ε) from its centre, 1 on a chamfer tool's flat tip). An axial
        feed f cuts a chip h = f·sin κ."""
        r = np.asarray(r_mm, float)
        if self.shape in CONE_SHAPES:
            return np.where(r < 0.5 * self.tip_diameter_mm, 1.0, math.sin(math.radians(0.5 * self.tip_angle_deg)))
        rc = self.corner_radius
        if rc > 0:
            x = np.clip(r - (self.radius_mm - rc), 0.0, rc)
            return np.sqrt(np.maximum(1.0 - (x / rc) ** 2, 0.0))
        return np.ones_like(r)
