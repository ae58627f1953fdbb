"""One straight cut and all its loads: the API under `millpost calc` and the roughing heuristics
(`millpost recommend`). A pass along +X beside a wall, width ae (≥ D: a slot), depth ap, climb or
conventional; forces on the tool in machine X, Y, Z (N), torque N·m, power W, removal rate mm³/min."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import MillpostError
from .forces import Kienzle, Mechanistic, chip_thinning_factor, given_cut, immersion, max_chip_mm, mean_chip_mm
from .machine import Machine
from .tools.beam import ToolBeam
from .tools.cutter import Tool


@dataclass(frozen=True)
class CutResult:
    """Loads of one cut; units in the names."""

    fz_mm: float
    feed_mm_min: float
    rpm: float
    vc_m_min: float
    h_max_mm: float
    h_mean_mm: float
    chip_thinning_factor: float
    F_avg_N: tuple[float, float, float]
    F_peak_N: float
    torque_Nm: float
    power_W: float
    mrr_mm3_min: float
    deflection_mm: float
    break_ratio: float
    machine_deflection_mm: float | None
    spindle_power_ratio: float | None


def evaluate_cut(tool: Tool, model: Mechanistic | Kienzle, *, ae_mm: float, ap_mm: float, rpm: float,
                 fz_mm: float, climb: bool = True, machine: Machine | None = None,
                 safety_factor: float | None = None) -> CutResult:
    """All loads of one straight cut (the module docstring)."""
    if rpm <= 0 or fz_mm <= 0:
        raise MillpostError("rpm and feed per tooth must be > 0")
    eng = given_cut(tool, ae_mm, ap_mm, climb=climb)
    loads = model.predict(eng, fz_mm, rpm, tool)
    ae = min(ae_mm, tool.diameter_mm)
    feed = fz_mm * tool.flutes * rpm
    beam = ToolBeam.of(tool, safety_factor=safety_factor)
    f_peak = float(loads.peak_force_xy_N[0])
    machine_defl = spindle_ratio = None
    if machine is not None:
        machine_defl = f_peak * machine.lateral_compliance_mm_per_N
        avail = float(machine.spindle.power_available_W(rpm))
        spindle_ratio = float(loads.power_W[0]) / avail if avail > 0 else math.inf
    return CutResult(
        fz_mm=fz_mm, feed_mm_min=feed, rpm=rpm, vc_m_min=math.pi * tool.diameter_mm * rpm / 1000.0,
        h_max_mm=max_chip_mm(fz_mm, ae, tool.diameter_mm),
        h_mean_mm=float(mean_chip_mm(fz_mm, *immersion(ae, tool.diameter_mm))),
        chip_thinning_factor=chip_thinning_factor(ae, tool.diameter_mm),
        F_avg_N=tuple(float(v) for v in loads.force_N[0]), F_peak_N=f_peak, torque_Nm=float(loads.torque_Nm[0]),
        power_W=float(loads.power_W[0]), mrr_mm3_min=float(eng.area_mm2[0]) * feed,
        deflection_mm=beam.deflection_mm(f_peak, ap_mm), break_ratio=f_peak / beam.breaking_force_N(ap_mm),
        machine_deflection_mm=machine_defl, spindle_power_ratio=spindle_ratio)
