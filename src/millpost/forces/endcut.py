"""End cutting: thrust and torque of the edges at a tool's end when it moves down into material
(plunging, drilling, pecking, the bottom of a ramp), and the tool's allowances against them.

Each end edge is a turning tool whose edge makes the angle κ(r) with the tool axis (90° on a flat
end, σ/2 on a drill of point angle σ, falling to 0 towards the equator of a ball or corner radius).
An axial feed per tooth f (mm) cuts at radius r a chip of thickness h = f·sin κ and width
db = dr / sin κ, so b·h = f·dr whatever κ. Kienzle (k_c1.1 N/mm², m_c; Tschätsch, *Praxis der
Zerspantechnik*; the lip model of twist drills, Paucksch/Tschätsch): the cutting (tangential) force
per edge element is dF_c = k_c1.1·h^(1−m_c)·db = k_c1.1·f^(1−m_c)·sin κ^(−m_c)·dr, and with z edges,
w(r) the share of the circle at radius r that is in material (Engagement.end_engaged):

    torque  M = z·k_c1.1·f^(1−m_c)·∫ w(r)·r·sin κ^(−m_c) dr                          (N·mm)
    thrust  F = c_f·z·k_c1.1·f^(1−m_c)·∫ w(r)·sin κ^(1−m_c) dr  +  F_chisel·w(0)         (N)

A solid flat plunge gives M = k_c·f·z·R²/2 = k_c·f_rev·D²/8 and a twist drill M = 2·F_c·D/4 (each
lip's force at D/4), the closed forms of the drilling literature. The lip thrust is the normal force
on the edge, c_f·dF_c, projected on the axis (sin κ): c_f = 0.63 is ISCAR's drilling ratio
(F_ax ≈ 0.63·(D/2)·f·k_c·sin κ against the torque's F_c; ISCAR Rotating Tools 2017, "General –
Calculations"). The chisel edge of a drill extrudes rather than cuts (negative rake, no speed at the
centre); its thrust does not depend on the feed: the indentation term of Shaw & Oxford (1957) as
printed in Machinery's Handbook 31st ed. (Machining Power, SI Eq. (5), Table 7):
F_chisel = 0.007·K_d·D²·J, with the material's drilling constant K_d and J(c/d) from the chisel
length ratio (0.001 split point c/d = 0.03 … 0.030 standard c/d = 0.18 … 0.120 at 0.35).
Sharp tools (wear factors 1); no chip-packing torque (deep holes without pecks are not modelled).

f^(1−m_c) is concave, so for the feed scheduler its tangent at the programmed feed bounds every
load from above and is exact there (`linear_loads`), as for the Kienzle milling model.
"""

from __future__ import annotations

import math

import numpy as np

from ..engagement import Engagement
from ..errors import MillpostError
from ..tools.beam import MATERIALS, default_safety_factor
from ..tools.cutter import Tool
from .base import LinearLoads, rpm_array

# Machinery's Handbook 31st ed. Table 7 (Shaw–Oxford chisel factor J against c/d); J(0) = 0 (no chisel)
_CHISEL_CD = (0.0, 0.03, 0.18, 0.25, 0.35)
_CHISEL_J = (0.0, 0.001, 0.030, 0.065, 0.120)
# Euler buckling with the tip free to move sideways (an unguided point touching the work): K = 2
BUCKLING_K = 2.0
# Equivalent round sections of the fluted part (PHYSICS notes on drill sections, Prandtl stress function
# on a two-flute web section): a twist drill's least bending inertia is ≥ 0.20 of a solid bar's
# (d = 0.20^(1/4)·D = 0.67·D) and its torsional section ≥ that of a bar of 0.50·D; end mills use the
# Kops & Vo flute diameter 0.8·D of the beam model for both.
DRILL_BENDING_DIAMETER = 0.20 ** 0.25
DRILL_TORSION_DIAMETER = 0.50
MILL_DIAMETER = 0.8


def chisel_factor(chisel_ratio: float) -> float:
    """Shaw–Oxford J for a chisel length / diameter ratio c/d (linear between Table 7's rows)."""
    return float(np.interp(chisel_ratio, _CHISEL_CD, _CHISEL_J))


def radial_weights(tool: Tool, bins: int, mc: float, sub: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """(W_M, W_F): per radial bin j of `bins` equal bins over [0, R], ∫ r·sin κ^(−m_c) dr (mm²) and
    ∫ sin κ^(1−m_c) dr (mm), by the midpoint rule on `sub` points per bin (exact on flat and cone ends)."""
    R = tool.radius_mm
    edges = np.linspace(0.0, R, bins + 1)
    u = (np.arange(sub) + 0.5) / sub
    r = edges[:-1, None] + u[None, :] * (R / bins)
    s = np.maximum(tool.end_sin_kappa(r), 1e-3)   # the equator of a ball (κ → 0) carries no axial chip
    dr = R / bins / sub
    return (r * s ** (-mc)).sum(1) * dr, (s ** (1.0 - mc)).sum(1) * dr


def _descent(engagement: Engagement) -> np.ndarray:
    """−dz/ds per sample; 0 for engagements given as flank cuts (no end data)."""
    return engagement.descent if engagement.descent is not None else np.zeros(len(engagement))


def end_chip_factor(engagement: Engagement, tool: Tool) -> np.ndarray:
    """Per sample the largest end chip per unit feed per tooth, descent·max sin κ over the engaged bins
    (the axial chip is h = f_z·descent·sin κ); 0 where the end does not cut."""
    w = engagement.end_engaged
    if w is None:
        return np.zeros(len(engagement))
    J = w.shape[1]
    mid = (np.arange(J) + 0.5) * tool.radius_mm / J
    s = np.where(w > 0, tool.end_sin_kappa(mid)[None, :], 0.0).max(axis=1)
    return _descent(engagement) * s


def entry_chip_factor(engagement: Engagement, tool: Tool, plunge_fz_ratio: float, chip: np.ndarray) -> np.ndarray:
    """Per sample the end's chip per unit feed per tooth as the chip-load limit sees it (0 where the end
    does not cut). A milling cutter entering along its axis with its end enclosed (material all round
    at every radius that cuts: a plunge, ramp or helical entry; chips leave only up the flutes) takes
    `plunge_fz_ratio` of the chip load (the material's entry rule, e.g. Kyocera's −50 % for ramps and
    plunges, FANAR's 25–50 %) on its axial feed per tooth f_z·descent, with no chip-thinning credit
    for a ball or pointed end: its centre cuts at no speed and crushes the axial feed whatever κ.
    Elsewhere (an end cutting part of the circle: a ball going down a slope, a plunge over a hole;
    and a drill, whose lips are made for it) the axial chip f_z·descent·sin κ, `chip` (`end_chip_factor`)."""
    if tool.shape == "drill" or engagement.end_engaged is None:
        return chip
    w = engagement.end_engaged
    enclosed = np.where(w > 0, w, np.inf).min(axis=1) > 0.5
    return np.where(enclosed & (chip > 0), _descent(engagement) / plunge_fz_ratio, chip)


def thrust_limit_N(tool: Tool, safety_factor: float | None = None) -> float:
    """Allowed thrust (N): Euler buckling of the stickout L with an unguided tip, F_cr = π²·E·I/(K·L)²,
    K = 2, I = π·d⁴/64 of the fluted section over the whole stickout (a lower bound), divided by the
    safety factor (the beam model's default for the tool)."""
    d = (DRILL_BENDING_DIAMETER if tool.shape == "drill" else MILL_DIAMETER) * tool.diameter_mm
    E = MATERIALS[tool.material]["E_MPa"]
    f_cr = math.pi ** 2 * E * (math.pi * d ** 4 / 64.0) / (BUCKLING_K * tool.stickout) ** 2
    return f_cr / (safety_factor or default_safety_factor(tool))


def torque_limit_Nm(tool: Tool, safety_factor: float | None = None) -> float:
    """Allowed spindle torque on the tool (N·m): shear τ = 16·M/(π·d³) of the fluted section up to
    0.577 × the tool material's strength (von Mises, as the beam model) / safety factor; d = 0.5·D for a
    twist drill, 0.8·D for an end mill."""
    d = (DRILL_TORSION_DIAMETER if tool.shape == "drill" else MILL_DIAMETER) * tool.diameter_mm
    tau = 0.577 * MATERIALS[tool.material]["strength_MPa"] / (safety_factor or default_safety_factor(tool))
    return tau * math.pi * d ** 3 / 16.0 / 1000.0


class EndCut:
    """Thrust and torque of a tool's end edges (module docstring). Coefficients: kc11 (N/mm²), mc
    (Kienzle, the material's), thrust_ratio c_f, Kd_N_mm2 (Shaw–Oxford drilling constant K_d)."""

    name = "endcut"

    def __init__(self, kc11: float, mc: float, thrust_ratio: float, Kd_N_mm2: float) -> None:
        if not (kc11 > 0 and 0 <= mc < 1 and thrust_ratio >= 0 and Kd_N_mm2 >= 0):
            raise MillpostError(f"end cutting needs kc1.1 > 0, 0 <= mc < 1, thrust ratio >= 0 and K_d >= 0, got "
                                f"{kc11}, {mc}, {thrust_ratio}, {Kd_N_mm2}")
        self.kc11, self.mc, self.thrust_ratio, self.Kd = kc11, mc, thrust_ratio, Kd_N_mm2

    @classmethod
    def from_material(cls, material) -> "EndCut | None":
        """The material's Kienzle k_c1.1, m_c on the end edges with its [end_cutting] thrust ratio and K_d;
        None when the material has no end-cutting data."""
        if material.end_cutting is None:
            return None
        e = material.end_cutting
        return cls(material.kienzle.kc11_N_mm2, material.kienzle.mc, e.thrust_ratio, e.Kd_N_mm2)

    def power_law(self, engagement: Engagement, tool: Tool) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """(Q_F (N,), Q_M (N,), C (N,), p) with thrust = Q_F·f^p + C (N) and torque = Q_M·f^p (N·mm) for an
        axial feed per tooth f (mm): the module docstring's integrals over the engaged bins. An engagement
        given as flank cuts (no end_engaged: `Engagement.uniform`, `given_cut`) has no end loads."""
        w = engagement.end_engaged
        if w is None:
            zero = np.zeros(len(engagement))
            return zero, zero, zero, 1.0 - self.mc
        W_M, W_F = radial_weights(tool, w.shape[1], self.mc)
        k = tool.flutes * self.kc11
        chisel = 0.007 * self.Kd * tool.diameter_mm ** 2 * chisel_factor(tool.chisel_ratio)
        cutting = _descent(engagement) > 0
        return (np.where(cutting, self.thrust_ratio * k * (w @ W_F), 0.0), np.where(cutting, k * (w @ W_M), 0.0),
                np.where(cutting, chisel * w[:, 0], 0.0), 1.0 - self.mc)

    def predict(self, engagement: Engagement, fz_mm, tool: Tool) -> tuple[np.ndarray, np.ndarray]:
        """(thrust N, torque N·m) per sample at feed per tooth fz_mm along the path (the end's axial feed
        per tooth is fz·descent)."""
        QF, QM, C, p = self.power_law(engagement, tool)
        f = np.broadcast_to(np.asarray(fz_mm, float), (len(engagement),)) * _descent(engagement)
        fp = np.power(np.maximum(f, 0.0), p)
        return QF * fp + C, QM * fp / 1000.0

    def linear_loads(self, engagement: Engagement, tool: Tool, rpm, feed_ref_mm_min) -> LinearLoads:
        """Thrust (+Z on the tool: the work pushes the tool up; a vertical tool) and torque as affine
        functions of the path feed (mm/s; `LinearLoads.per_minute`): the tangent at feed_ref (the F word,
        mm/min, scalar or (N,), > 0) of f^p, f = v·descent/(z·n) for v in mm/min, which bounds it from
        above for every v ≥ 0."""
        n = len(engagement)
        rpm_n = rpm_array(rpm, n)
        per_feed = _descent(engagement) / (tool.flutes * rpm_n)        # f per mm/min of path feed
        v0 = np.broadcast_to(np.asarray(feed_ref_mm_min, float), (n,))
        if np.any(v0 <= 0):
            raise MillpostError("the reference feed must be > 0")
        QF, QM, C, p = self.power_law(engagement, tool)
        f0 = np.maximum(v0 * per_feed, 1e-12)
        slope = p * f0 ** (p - 1) * per_feed
        icpt = (1 - p) * f0 ** p
        slope, icpt = np.where(per_feed > 0, slope, 0.0), np.where(per_feed > 0, icpt, 0.0)
        omega = 2 * np.pi * rpm_n / 60.0
        force_a, force_b = np.zeros((n, 3)), np.zeros((n, 3))
        force_a[:, 2], force_b[:, 2] = QF * slope, QF * icpt + C
        T_a, T_b = QM * slope / 1000.0, QM * icpt / 1000.0
        zero = np.zeros(n)
        return LinearLoads.per_minute(force_a=force_a, force_b=force_b, peak_a=zero, peak_b=zero, torque_a=T_a,
                                      torque_b=T_b, power_a=T_a * omega, power_b=T_b * omega, exact=False,
                                      feed_ref_mm_min=v0.copy())
