"""Tool beam against PHYSICS.md §4.3 oracles (F = 100 N, E = 600 GPa) and textbook beam identities."""

from __future__ import annotations

import math

import numpy as np
import pytest

from millpost.errors import MillpostError
from millpost.tools.beam import ToolBeam, default_safety_factor
from millpost.tools.cutter import Tool


def beam(stickout, flutes_len, d_shank, d_flute, *, E=600e3, strength=3000.0, sf=3.0) -> ToolBeam:
    return ToolBeam(stickout_mm=stickout, flute_length_mm=flutes_len, shank_diameter_mm=d_shank,
                    flute_diameter_mm=d_flute, E_MPa=E, strength_MPa=strength, safety_factor=sf)


def test_solid_cylinder_D1():
    b = beam(30, 30, 10, 10)
    assert b.deflection_mm(100) * 1000 == pytest.approx(3.056, abs=1e-3)
    assert b.stiffness_N_per_mm() / 1000 == pytest.approx(32.725, abs=1e-3)   # N/µm


def test_equivalent_diameter_all_along():
    assert beam(30, 30, 8, 8).deflection_mm(100) * 1000 == pytest.approx(7.460, abs=1e-3)


def test_two_segment_D2():
    # shank 10 mm (D 10) + flutes 20 mm (d_e 8), tip load
    assert beam(30, 20, 10, 8).deflection_mm(100) * 1000 == pytest.approx(4.361, abs=1e-3)


def test_load_at_mid_depth_and_tip_deflection():
    b = beam(30, 30, 10, 10)
    # load at a = 25 (a_p 10): δ(a) = F a³/3EI, δ(tip) = δ(a) + θ(a)(L − a), θ = F a²/2EI
    ei = 600e3 * math.pi * 10 ** 4 / 64
    assert b.deflection_mm(100, ap_mm=10) == pytest.approx(100 * 25 ** 3 / (3 * ei), rel=1e-12)
    tip = 100 * 25 ** 3 / (3 * ei) + 100 * 25 ** 2 / (2 * ei) * 5
    assert b.compliance_mm_per_N(10, at_tip=True) * 100 == pytest.approx(tip, rel=1e-12)


def test_bending_stress_and_allowable_force():
    # flute root with arm 20 mm and d_e 8: 39.79 MPa at 100 N; σ 3000 MPa, SF 3 → 2513.3 N
    b = beam(30, 20, 100, 8)   # a stiff wide shank makes the flute root the weakest section
    assert b.bending_stress_MPa(100) == pytest.approx(39.79, abs=0.01)
    assert b.breaking_force_N() == pytest.approx(2513.3, abs=0.1)


def test_torsion_equivalent_stress():
    b = beam(30, 20, 10, 8)
    tau = 16 * 2000.0 / (math.pi * 8 ** 3)       # 2 N·m in the flutes
    assert b.bending_stress_MPa(0.0, torque_Nm=2.0) == pytest.approx(tau / 0.577, rel=1e-12)


def test_tool_defaults_and_safety_factor():
    tool = Tool(diameter_mm=6, flutes=3, flute_length_mm=18, stickout_mm=24)
    b = ToolBeam.of(tool)
    assert b.E_MPa == 600e3 and b.flute_diameter_mm == pytest.approx(4.8)
    assert b.shank_length_mm == pytest.approx(6)
    assert default_safety_factor(tool) == 2.0
    small = dict(diameter_mm=2, shank_diameter_mm=6, stickout_mm=20)
    assert default_safety_factor(Tool(flute_length_mm=6, **small)) == 3.0
    assert default_safety_factor(Tool(flute_length_mm=10, **small)) == 3.75     # long reach
    hss = ToolBeam.of(Tool(diameter_mm=6, material="hss", flute_length_mm=18, stickout_mm=24))
    assert hss.deflection_mm(50) == pytest.approx(3 * b.deflection_mm(50), rel=1e-12)   # E 200 vs 600 GPa


def test_arrays_of_depths_for_the_scheduler():
    b = beam(30, 20, 10, 8)
    ap = np.array([0.0, 4.0, 10.0])
    np.testing.assert_allclose(b.compliance_mm_per_N(ap), [b.compliance_mm_per_N(float(a)) for a in ap], rtol=1e-15)
    np.testing.assert_allclose(b.breaking_force_N(ap), [b.breaking_force_N(float(a)) for a in ap], rtol=1e-15)
    assert b.load_arm_mm(100.0) == pytest.approx(20.0)      # a cut deeper than the flutes loads them all
    with pytest.raises(MillpostError, match="longer than the stickout"):
        beam(20, 30, 10, 8)
