"""Workpiece materials: cutting-force coefficients, surface-speed window and chip-load guidance.

Built-ins live in ``millpost/data/materials/<name>.toml`` with a source for every number; a user file
has the same layout (see any built-in). Load either with `Material.load(name_or_path)`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .config import Table, load_description
from .errors import ConfigError
from .registry import plugins


@dataclass(frozen=True)
class Strategy:
    """How a roughing strategy sets its cut. width: "range" (the material file's `<name>_ae_D` range),
    "full" (a slot: the tool's diameter) or "zero_normal_force" (computed from the force model: the width
    at which the mean force normal to the feed vanishes, `millpost.lowdeflection`); depth: the material
    file's key of the deepest cut (None: the flute length alone); climb: climb (down) milling, else
    conventional (up)."""

    width: str = "range"
    depth: str | None = None
    climb: bool = True


STRATEGY_KINDS: dict[str, Strategy] = {
    "adaptive": Strategy(), "slot": Strategy("full", "slot_ap_D"), "profile": Strategy(),
    "face": Strategy(depth="face_ap_D"), "low-deflection": Strategy("zero_normal_force", climb=False)}
STRATEGIES = tuple(STRATEGY_KINDS)


@dataclass(frozen=True)
class StrategyRules:
    """A machinist's rules for roughing with an end mill in this material, as fractions of the tool
    diameter D. Radial width ranges (lo, hi): adaptive clearing (constant light engagement, deep),
    profile (side milling a wall), face (a wide, shallow pass); slot_ap_D: deepest full-width slot (chips
    must leave a closed slot); face_ap_D: deepest facing pass. Entry: ramp_angle_deg (steepest helical
    or linear ramp), ramp_feed_ratio (ramp feed over the cutting feed), plunge_fz_ratio (axial feed per
    tooth of a plunge over the chip-load target: the whole end edge cuts, no chip thinning).
    low-deflection has no width rule here (its width is computed, `Strategy`); its entry follows these."""

    adaptive_ae_D: tuple[float, float] = (0.05, 0.2)
    profile_ae_D: tuple[float, float] = (0.1, 0.4)
    face_ae_D: tuple[float, float] = (0.6, 0.8)
    slot_ap_D: float = 1.0
    face_ap_D: float = 0.1
    ramp_angle_deg: float = 2.0
    ramp_feed_ratio: float = 0.5
    plunge_fz_ratio: float = 0.25
    source: str = "millpost defaults (no material-specific source)"

    def ae_range_D(self, strategy: str) -> tuple[float, float]:
        """Radial width range of a strategy (fractions of D); a slot is full width; a computed width
        (zero normal force) may lie anywhere up to D."""
        width = STRATEGY_KINDS[strategy].width
        if width == "range":
            return getattr(self, f"{strategy}_ae_D")
        return (1.0, 1.0) if width == "full" else (0.0, 1.0)

    def ap_max_D(self, strategy: str) -> float | None:
        """Deepest cut of a strategy (fraction of D), None where only the flute length bounds it."""
        key = STRATEGY_KINDS[strategy].depth
        return getattr(self, key) if key else None

    @classmethod
    def from_table(cls, t: Table) -> "StrategyRules":
        ranges = {}
        for name in ("adaptive_ae_D", "profile_ae_D", "face_ae_D"):
            lo, hi = t.numbers(name, gt=0, length=2)
            if not lo <= hi <= 1:
                raise t.fail(name, [lo, hi], "must be [low, high] with high <= 1 (fractions of D)")
            ranges[name] = (lo, hi)
        rules = cls(**ranges, slot_ap_D=t.number("slot_ap_D", gt=0), face_ap_D=t.number("face_ap_D", gt=0),
                    ramp_angle_deg=t.number("ramp_angle_deg", gt=0, le=45),
                    ramp_feed_ratio=t.number("ramp_feed_ratio", gt=0, le=1),
                    plunge_fz_ratio=t.number("plunge_fz_ratio", gt=0, le=1), source=t.string("source"))
        t.done()
        return rules


@dataclass(frozen=True)
class KienzleCoefficients:
    """k_c1.1 (N/mm², force per mm of chip width at h = 1 mm), m_c, and F_r/F_t, F_a/F_t ratios."""

    kc11_N_mm2: float
    mc: float
    radial_ratio: float
    axial_ratio: float
    source: str


@dataclass(frozen=True)
class MechanisticCoefficients:
    """Altintas' shearing (N/mm²) and edge (N/mm) coefficients."""

    Ktc_N_mm2: float
    Krc_N_mm2: float
    Kac_N_mm2: float
    Kte_N_per_mm: float
    Kre_N_per_mm: float
    Kae_N_per_mm: float
    source: str

    def values(self) -> tuple[float, ...]:
        return (self.Ktc_N_mm2, self.Krc_N_mm2, self.Kac_N_mm2, self.Kte_N_per_mm, self.Kre_N_per_mm,
                self.Kae_N_per_mm)


@dataclass(frozen=True)
class EndCuttingCoefficients:
    """Drilling/plunging: thrust_ratio c_f (normal over cutting force of an end edge) and the Shaw–Oxford
    drilling constant Kd_N_mm2 (K_d, for the chisel edge's feed-independent thrust)."""

    thrust_ratio: float
    Kd_N_mm2: float
    source: str


@dataclass(frozen=True)
class Material:
    """A workpiece material. Speeds m/min, chip loads mm per tooth, hardness HB (0 when not given).

    surface_speed_m_min: {"carbide": (lo, hi), "hss": (lo, hi)}. chip_load: diameters (mm) with the
    recommended f_z range at each (interpolated in between, clamped outside). min_chip_ratio: minimum
    chip thickness over the cutting-edge radius (below it the edge ploughs instead of cutting).
    min_chip_fz_ratio: for materials that burn or melt (wood, plastics), the minimum chip as a share of
    the table's smallest chip load for the tool's diameter (below it the edge scrapes dust, and the
    friction heat scorches wood or melts plastic); 0 where ploughing alone sets the minimum.
    strategies: roughing rules per strategy (optional table; defaults when absent, said in its source).
    end_cutting: drilling/plunging coefficients (None when the file has none: then no end load can be
    predicted and feeds of moves that cut with the tool's end are not raised; `forces.endcut.EndCut`).
    """

    name: str
    description: str
    kienzle: KienzleCoefficients
    mechanistic: MechanisticCoefficients | None
    surface_speed_m_min: dict[str, tuple[float, float]]
    speed_source: str
    chip_diameters_mm: tuple[float, ...]
    fz_min_mm: tuple[float, ...]
    fz_max_mm: tuple[float, ...]
    chip_source: str
    min_chip_ratio: float
    min_chip_source: str
    hardness_HB: float = 0.0
    strategies: StrategyRules = StrategyRules()
    end_cutting: EndCuttingCoefficients | None = None
    min_chip_fz_ratio: float = 0.0

    @classmethod
    def load(cls, name_or_path: str | Path) -> "Material":
        data, file = load_description("materials", name_or_path)
        return cls.from_dict(data, file=file)

    @classmethod
    def from_dict(cls, data: dict, *, file: str | None = None) -> "Material":
        t = Table(data, "", file)
        name = t.string("name")
        description = t.string("description", "")
        hardness = t.number("hardness_HB", 0.0, ge=0)
        k = t.table("kienzle")
        kienzle = KienzleCoefficients(k.number("kc11_N_mm2", gt=0), k.number("mc", ge=0, lt=1),
                                      k.number("radial_ratio", ge=0, le=2), k.number("axial_ratio", ge=0, le=2),
                                      k.string("source"))
        k.done()
        mech = None
        if t.has("mechanistic"):
            m = t.table("mechanistic")
            mech = MechanisticCoefficients(
                m.number("Ktc_N_mm2", gt=0), m.number("Krc_N_mm2", ge=0), m.number("Kac_N_mm2"),
                m.number("Kte_N_per_mm", ge=0), m.number("Kre_N_per_mm", ge=0), m.number("Kae_N_per_mm"),
                m.string("source"))
            m.done()
        s = t.table("surface_speed")
        speeds = {}
        for tool_mat in ("carbide", "hss"):
            lo, hi = s.numbers(f"{tool_mat}_m_min", gt=0, length=2)
            if lo > hi:
                raise s.fail(f"{tool_mat}_m_min", [lo, hi], "must be [low, high]")
            speeds[tool_mat] = (lo, hi)
        speed_source = s.string("source")
        s.done()
        c = t.table("chip_load")
        dia = c.numbers("diameter_mm", gt=0)
        fmin = c.numbers("fz_min_mm", gt=0, length=len(dia))
        fmax = c.numbers("fz_max_mm", gt=0, length=len(dia))
        if any(np.diff(dia) <= 0):
            raise c.fail("diameter_mm", list(dia), "must increase")
        if any(a > b for a, b in zip(fmin, fmax)):
            raise c.fail("fz_max_mm", list(fmax), "must be >= fz_min_mm at every diameter")
        chip_source = c.string("source")
        c.done()
        mc = t.table("min_chip")
        ratio = mc.number("ratio_to_edge_radius", gt=0, le=2)
        fz_ratio = mc.number("ratio_to_chip_load_min", 0.0, ge=0, le=1)
        mc_source = mc.string("source")
        mc.done()
        strategies = StrategyRules.from_table(t.table("strategies")) if t.has("strategies") else StrategyRules()
        end = None
        if t.has("end_cutting"):
            e = t.table("end_cutting")
            end = EndCuttingCoefficients(e.number("thrust_ratio", ge=0, le=3), e.number("Kd_N_mm2", ge=0),
                                         e.string("source"))
            e.done()
        t.done(("mechanistic", "strategies", "end_cutting"))
        return cls(name, description, kienzle, mech, speeds, speed_source, dia, fmin, fmax, chip_source,
                   ratio, mc_source, hardness, strategies, end, fz_ratio)

    # --- guidance -------------------------------------------------------------------------------
    def chip_load_mm(self, diameter_mm: float) -> tuple[float, float]:
        """Recommended (min, max) chip thickness per tooth for a tool diameter (mm): the table's rows
        interpolated; above its largest diameter, that row; below its smallest diameter D0, that row
        scaled by D / D0 (a small end mill's chip load falls in proportion to its diameter: the
        tool's section, and so its strength against the chip's force, shrinks with D)."""
        scale = min(1.0, diameter_mm / float(self.chip_diameters_mm[0]))
        return (scale * float(np.interp(diameter_mm, self.chip_diameters_mm, self.fz_min_mm)),
                scale * float(np.interp(diameter_mm, self.chip_diameters_mm, self.fz_max_mm)))

    def rpm_window(self, diameter_mm: float, tool_material: str = "carbide") -> tuple[float, float]:
        """Spindle speed window n = 1000 v_c / (π D) for the surface-speed window (rpm)."""
        lo, hi = self.surface_speed_m_min[tool_material]
        k = 1000.0 / (np.pi * diameter_mm)
        return lo * k, hi * k

    def min_chip_mm(self, edge_radius_mm: float, diameter_mm: float) -> float:
        """Minimum uncut chip thickness (mm) for a cutting-edge radius and a tool diameter (mm): the edge
        ploughs below min_chip_ratio · r_e; a material that burns or melts also needs
        min_chip_fz_ratio × the table's smallest chip load at that diameter."""
        return max(self.min_chip_ratio * edge_radius_mm, self.min_chip_fz_ratio * self.chip_load_mm(diameter_mm)[0])

    # --- force models ---------------------------------------------------------------------------
    def force_model(self, kind: str = "mechanistic", **settings):
        """The force model `kind` with this material's coefficients: any model registered in the
        ``millpost.force_models`` entry-point group (built-ins: mechanistic, kienzle), built by its
        ``from_material(material, **settings)``."""
        models = plugins("force_models")
        if kind not in models:
            raise ConfigError("model", kind, f"must be one of {', '.join(sorted(models))} (force models registered "
                                             "in the millpost.force_models entry-point group)")
        return models[kind].from_material(self, **settings)
