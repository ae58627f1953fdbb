"""Zero-normal-force engagement (`millpost.lowdeflection`, `recommend --strategy low-deflection`): the root
against Altintas' closed form and against the time-domain model, how edge forces move it, and the
deflection of the recommended cut against half immersion and slotting."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from millpost.cut import evaluate_cut
from millpost.errors import MillpostError
from millpost.forces import Kienzle, Mechanistic, given_cut
from millpost.forces.base import chip_thinning_factor, clipped_arcs
from millpost.forces.timedomain import simulate
from millpost.heuristics import recommend
from millpost.lowdeflection import zero_normal_force
from millpost.machine import Machine
from millpost.materials import Material
from millpost.tools.beam import ToolBeam
from millpost.tools.cutter import Tool

TOOL = Tool(diameter_mm=6, flutes=3, flute_length_mm=18, stickout_mm=25)


def _bisect(g, lo: float, hi: float) -> float:
    """Plain bisection to machine precision (independent of the code's Brent solver)."""
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if np.sign(g(mid)) == np.sign(g(lo)) else (lo, mid)
    return 0.5 * (lo + hi)


@pytest.mark.parametrize("kr, flutes, helix", [(0.157, 3, 30.0), (0.3, 2, 0.0), (0.8, 4, 45.0), (1.4, 3, 35.0)])
def test_root_matches_the_closed_form_without_edge_forces(kr, flutes, helix):
    """Altintas' mean feed-normal force over one tooth period (Y. Altintas, Manufacturing Automation, 2nd ed.,
    Cambridge 2012, ch. 2, mean milling forces: the elemental forces dF_t = K_tc a h dφ, dF_r = K_rc a h dφ,
    h = c sin φ, projected on y and averaged over the pitch 2π/N), edge coefficients neglected, N teeth,
    depth a, feed per tooth c:

        F̄_y = (N a c / 8π) [K_tc (2φ − sin 2φ) + K_rc cos 2φ] from φ_st to φ_ex.

    Conventional (up) milling of width ae engages φ_st = 0, φ_ex = φ_s = arccos(1 − 2 ae/D), so

        F̄_y = (N a c / 8π) [K_tc (2φ_s − sin 2φ_s) − K_rc (1 − cos 2φ_s)],

    zero where 2φ_s − sin 2φ_s = K_r (1 − cos 2φ_s), K_r = K_rc/K_tc: independent of N, a, c and the helix.
    Near 0 the left side is 4φ³/3 and the right 2K_r φ², so the bracket is negative (the radial force pushes
    the tool off the wall); at φ = π it is 2π > 0 (the tangential force pulls it in): one root, found here by
    bisection and compared with the code's root on its own model within 1e-6 rad."""
    tool = Tool(diameter_mm=10, flutes=flutes, helix_deg=helix, flute_length_mm=20, stickout_mm=35)
    ktc = 700.0
    model = Mechanistic.from_coefficients(ktc, kr * ktc, 200.0, 0.0, 0.0, 0.0)
    phi = _bisect(lambda p: 2 * p - math.sin(2 * p) - kr * (1 - math.cos(2 * p)), 1e-3, math.pi)
    for fz, ap in ((0.02, 3.0), (0.2, 12.0)):
        root = zero_normal_force(tool, model, fz_mm=fz, ap_mm=ap)
        assert math.radians(root.engagement_deg) == pytest.approx(phi, abs=1e-6)
        assert root.ae_mm == pytest.approx(5.0 * (1 - math.cos(phi)), abs=1e-6)
        assert not root.climb and abs(root.F_normal_N) < 1e-9 * abs(root.F_feed_N)
        # the feed-direction force left: F̄_x = (N a c/8π)[K_tc cos 2φ − K_rc (2φ − sin 2φ)] from 0 to φ_s
        fx = flutes * ap * fz / (8 * math.pi) * ktc * (math.cos(2 * phi) - 1 - kr * (2 * phi - math.sin(2 * phi)))
        assert root.F_feed_N == pytest.approx(fx, rel=1e-6)
    if kr < math.pi / 2:   # the bracket at φ = π/2 is K_tc π − 2 K_rc > 0: the root is below half immersion
        assert phi < math.pi / 2


def test_kienzle_root_matches_its_integral():
    """Kienzle (F_t = k_c b h^p, F_r = ρ F_t, p = 1 − m_c, h = f_z sin φ):
    F̄_y ∝ ∫₀^φs (dF_t sin φ − dF_r cos φ) = ∫₀^φs sin^(p+1) φ dφ − ρ sin^(p+1) φ_s / (p + 1), zero at a width
    independent of f_z (every term ∝ f_z^p). Root of that quadrature by bisection against the code's, within
    1e-6 rad."""
    mc, rho = 0.25, 0.3
    model = Kienzle.from_coefficients(800.0, mc, radial_ratio=rho, axial_ratio=0.3)
    p = 1 - mc

    def g(s):
        return quad(lambda f: math.sin(f) ** (p + 1), 0, s, epsabs=1e-14)[0] - rho * math.sin(s) ** (p + 1) / (p + 1)

    phi = _bisect(g, 1e-6, math.pi / 2)
    for fz in (0.01, 0.3):
        root = zero_normal_force(TOOL, model, fz_mm=fz, ap_mm=6.0)
        assert math.radians(root.engagement_deg) == pytest.approx(phi, abs=1e-6)


def _timedomain_normal(tool, coef, fz, ap, ae, steps_per_rev=20000):
    """Mean F_y (N) over a revolution from the time-domain model: the cutter turned in 2π/20000 steps, every
    disk's elemental force summed (no closed-form integral)."""
    eng = given_cut(tool, ae, ap, climb=False)
    st, ex, b = clipped_arcs(eng)
    _, mean = simulate(st, ex, b, eng.z_mm, eng.dz_mm, eng.r_mm, eng.kappa, kc=coef[:3], ke=coef[3:], p=1.0,
                       flutes=tool.flutes, helix_deg=tool.helix_deg, radius_mm=tool.radius_mm, fz_mm=fz,
                       steps_per_rev=steps_per_rev)
    return float(mean[0, 1])


@pytest.mark.parametrize("tool", [TOOL, Tool(diameter_mm=8, flutes=2, shape="bull", corner_radius_mm=1.0,
                                             flute_length_mm=20, stickout_mm=30)])
def test_root_matches_the_time_domain_model(tool):
    """The width at which the time-domain mean normal force crosses zero (Brent on the simulated mean, al6061's
    published coefficients with their edge terms) agrees with the closed-form root within 0.1 %; a bull-nose
    tool (slices with their own radius and axial immersion) as well as a flat one."""
    mat = Material.load("al6061")
    coef = np.array(mat.mechanistic.values())
    model = mat.force_model("mechanistic")
    for fz in (0.03, 0.15):
        root = zero_normal_force(tool, model, fz_mm=fz, ap_mm=4.0)
        ae_td = brentq(lambda a: _timedomain_normal(tool, coef, fz, 4.0, a), 0.3 * root.ae_mm, 2.0 * root.ae_mm,
                       xtol=1e-9)
        assert ae_td == pytest.approx(root.ae_mm, rel=1e-3)   # measured: ≤ 2.6e-5


def test_edge_forces_move_the_root_toward_their_own():
    """With edge forces the conventional normal force adds (N a/2π)[K_te (1 − cos φ_s) − K_re sin φ_s], negative
    below tan(φ_s/2) = K_re/K_te and positive above: its own root φ_e = 2 atan(K_re/K_te). The shearing bracket
    (∝ f_z) has its root φ_0 from the closed form; the sum, negative below both and positive above both, has
    its root between them, and the edge share grows as the chip thins (∝ 1/f_z). In al6061 (K_re/K_te = 10/13,
    φ_e = 75.1°, K_rc/K_tc = 0.157, φ_0 = 13.6°) the edges therefore move the root to wider cuts, the more so
    the smaller f_z; f_z → 0 gives φ_e and f_z → ∞ gives φ_0."""
    mat = Material.load("al6061")
    k = mat.mechanistic
    kr = k.Krc_N_mm2 / k.Ktc_N_mm2
    phi0 = _bisect(lambda p: 2 * p - math.sin(2 * p) - kr * (1 - math.cos(2 * p)), 1e-3, math.pi)
    phie = 2 * math.atan(k.Kre_N_per_mm / k.Kte_N_per_mm)
    model = mat.force_model("mechanistic")
    angles = [math.radians(zero_normal_force(TOOL, model, fz_mm=fz, ap_mm=6.0).engagement_deg)
              for fz in (1e-7, 0.01, 0.05, 0.2, 1e4)]
    assert angles[0] == pytest.approx(phie, abs=1e-4) and angles[-1] == pytest.approx(phi0, abs=1e-4)
    assert all(phi0 < a < phie for a in angles[1:-1])
    assert angles == sorted(angles, reverse=True)


def test_climb_and_a_model_without_radial_force_have_no_root():
    """Climb milling: F̄_y = (N a c/8π)[K_tc(2φ_s − sin 2φ_s) + K_rc(1 − cos 2φ_s)]
    + (N a/2π)[K_te(1 − cos φ_s) + K_re sin φ_s] > 0 at every width (the tool is pushed off the wall); conventional milling with
    K_rc = K_re = 0 has only the tangential pull. Both are refused with the reason."""
    model = Material.load("al6061").force_model("mechanistic")
    with pytest.raises(MillpostError, match="climb milling pushes the tool off the wall"):
        zero_normal_force(TOOL, model, fz_mm=0.05, ap_mm=6.0, climb=True)
    tangential = Mechanistic.from_coefficients(700.0, 0.0, 100.0, 20.0, 0.0, 5.0)
    with pytest.raises(MillpostError, match="no radial width .* conventional"):
        zero_normal_force(TOOL, tangential, fz_mm=0.05, ap_mm=6.0)


@pytest.mark.parametrize("material, model", [("al6061", "mechanistic"), ("al7075", "mechanistic"),
                                             ("steel1045", "kienzle")])
def test_recommended_cut_barely_deflects_normal_to_the_wall(material, model):
    """The recommendation is a root at its own feed (the width and feed settle together), and its mean normal
    force, hence the tool's and the machine's deflection toward the wall, is ≤ 1 % of that of a half-immersion
    climb cut and of a slot at the same f_z, a_p and speed (tool: beam compliance at mid-depth × mean F_y;
    machine: F_y over the Y axis' stiffness)."""
    mat, mach = Material.load(material), Machine.load("vmc-small")
    rec = recommend(TOOL, mat, mach, model=model, strategy="low-deflection")
    assert not rec.climb and rec.strategy == "low-deflection"
    again = zero_normal_force(TOOL, mat.force_model(model), fz_mm=rec.fz_mm, ap_mm=rec.ap_mm)
    assert again.ae_mm == pytest.approx(rec.ae_mm, abs=1e-5 * TOOL.diameter_mm)
    compliance = float(ToolBeam.of(TOOL).compliance_mm_per_N(rec.ap_mm))
    for ae in (TOOL.diameter_mm / 2, TOOL.diameter_mm):
        other = evaluate_cut(TOOL, mat.force_model(model), ae_mm=ae, ap_mm=rec.ap_mm, rpm=rec.rpm, fz_mm=rec.fz_mm)
        normal_N = abs(other.F_avg_N[1])
        assert abs(rec.mean_deflection.tool_normal_mm) <= 0.01 * compliance * normal_N
        assert abs(rec.mean_deflection.machine_normal_mm) <= 0.01 * normal_N / mach.axes["y"].stiffness_N_per_mm
    assert rec.mean_deflection.tool_feed_mm == pytest.approx(compliance * rec.F_avg_N[0], rel=1e-12)
    assert rec.mean_deflection.machine_feed_mm == pytest.approx(rec.F_avg_N[0] / mach.axes["x"].stiffness_N_per_mm)
    assert rec.binding   # the feed is still the largest any limit allows


def test_a_fixed_width_is_refused():
    with pytest.raises(MillpostError, match="chooses the width"):
        recommend(TOOL, Material.load("al6061"), Machine.load("vmc-small"), ae_mm=1.0, strategy="low-deflection")


def _assert_root_or_refusal(tool, material, machine, **fixed):
    """The recommendation's width is a root of the mean normal force at its own feed (|F_y| ≤ 1e-6 |F_x|
    from an independent `evaluate_cut` of the answer) within every limit (each load ratio ≤ 1), or the
    refusal names the limit; never a search that did not settle."""
    mat, mach = Material.load(material), Machine.load(machine)
    try:
        rec = recommend(tool, mat, mach, strategy="low-deflection", **fixed)
    except MillpostError as exc:
        assert "no feasible feed at the width" in str(exc) and ("allows f_z" in str(exc) or "bound" in str(exc))
        return None
    cut = evaluate_cut(tool, mat.force_model(), ae_mm=rec.ae_mm, ap_mm=rec.ap_mm, rpm=rec.rpm, fz_mm=rec.fz_mm,
                       climb=False)
    assert not rec.climb and abs(cut.F_avg_N[1]) <= 1e-6 * abs(cut.F_avg_N[0])
    assert max(rec.ratios.values()) <= 1 + 1e-6, rec.ratios
    return rec


@pytest.mark.parametrize("machine, diameter, material", list(itertools.product(
    ("hobby-router", "benchtop-belt", "vmc-small"), (3, 6, 10), ("al6061", "steel1045", "mdf"))))
def test_every_built_in_machine_diameter_and_material(machine, diameter, material):
    """The reviewer's grid (3 flutes): a root within every limit, or a refusal naming the limit."""
    _assert_root_or_refusal(Tool(diameter_mm=diameter, flutes=3), material, machine)


def test_the_reviewers_examples_recommend():
    """hobby-router, D6 al6061 (the root cycled 0.8455 <-> 0.9225 mm as the outer search flipped the speed)
    and D10 al6061 (the widths past the root had no feed at the full depth: spindle power) both give a cut,
    and fixing the answer's depth and speed gives the same width (the width solve alone, no outer search)."""
    for d in (6, 10):
        tool = Tool(diameter_mm=d, flutes=3)
        rec = _assert_root_or_refusal(tool, "al6061", "hobby-router")
        assert rec is not None
        again = recommend(tool, Material.load("al6061"), Machine.load("hobby-router"), strategy="low-deflection",
                          ap_mm=rec.ap_mm, rpm=rec.rpm)
        assert again.ae_mm == pytest.approx(rec.ae_mm, abs=1e-7 * d) and again.fz_mm == pytest.approx(rec.fz_mm)


def test_a_refusal_names_the_feed_cap_against_the_minimum_chip():
    """MDF, D6 on the hobby router: Kienzle's root does not depend on f_z (see above), so the width is fixed by
    the model; there the minimum chip h_min needs f_z ≥ h_min · RCTF(ae) (radial chip thinning,
    RCTF = D / (2 sqrt(ae (D − ae)))), while the 3000 mm/min machine feed at the slowest speed of the window
    allows f_z ≤ 3000 / (z n_min): checked here from those formulas, then the refusal must name both."""
    tool, mat, mach = Tool(diameter_mm=6, flutes=3), Material.load("mdf"), Machine.load("hobby-router")
    ae = zero_normal_force(tool, mat.force_model(), fz_mm=0.1, ap_mm=1.0).ae_mm
    n_min = mat.rpm_window(6, tool.material)[0]
    h_min = mat.min_chip_mm(tool.edge_radius_mm, 6)
    assert 3000 / (3 * n_min) < h_min * chip_thinning_factor(ae, 6)
    with pytest.raises(MillpostError, match=r"machine_feed allows f_z ≤ .* minimum chip needs ≥"):
        recommend(tool, mat, mach, strategy="low-deflection")
