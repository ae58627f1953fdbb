"""Roughing recommendations: every limit holds when `millpost calc` re-evaluates the answer; the answer is
near the best of a brute-force grid; chip thinning follows its formula; typical cases look right."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from millpost.cli import main
from millpost.forces import given_cut
from millpost.heuristics import Limits, recommend
from millpost.machine import Machine
from millpost.materials import Material
from millpost.tools.beam import ToolBeam
from millpost.tools.cutter import Tool


def tool_flags(t: Tool) -> list[str]:
    return ["--diameter", str(t.diameter_mm), "--flutes", str(t.flutes), "--helix", str(t.helix_deg),
            "--flute-length", str(t.flute_length_mm), "--stickout", str(t.stickout_mm),
            "--shank", str(t.shank_diameter)]


def _cases(seed: int = 4, n: int = 4) -> list[tuple[Tool, str, str]]:
    """A seeded draw of (tool, material, machine) over the built-in materials and machines."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        d = float(rng.choice([3.0, 6.0, 8.0, 10.0, 12.0]))
        flute = round(d * float(rng.uniform(1.5, 3.0)), 1)
        tool = Tool(diameter_mm=d, flutes=int(rng.integers(2, 5)), helix_deg=float(rng.choice([30.0, 40.0])),
                    flute_length_mm=flute, stickout_mm=round(flute + d * float(rng.uniform(0.5, 2.0)), 1),
                    shank_diameter_mm=max(d, 6.0))
        out.append((tool, str(rng.choice(["al6061", "al7075", "steel1045", "ss304", "ti6al4v", "brass", "pom",
                                          "mdf", "plywood"])),
                    str(rng.choice(["benchtop-belt", "hobby-router", "vmc-small"]))))
    return out


CASES = _cases()


@pytest.mark.parametrize("tool, material, machine", CASES)
def test_calc_confirms_every_limit(capsys, tool, material, machine):
    mat, mach = Material.load(material), Machine.load(machine)
    rec = recommend(tool, mat, mach)
    assert main(["calc", *tool_flags(tool), "--material", material, "--machine", machine, "--ae", repr(rec.ae_mm),
                 "--ap", repr(rec.ap_mm), "--rpm", repr(rec.rpm), "--fz", repr(rec.fz_mm), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["deflection_mm"] <= 0.025 * (1 + 1e-9)
    assert out["break_ratio"] <= 1 + 1e-9
    assert out["spindle_power_ratio"] <= 1 + 1e-9
    assert out["feed_mm_min"] <= min(mach.feed_max_mm_min, 6000.0) * (1 + 1e-9)   # machine, 100 mm/s range
    assert out["h_max_mm"] >= mat.min_chip_mm(tool.edge_radius_mm, tool.diameter_mm)
    assert out["h_max_mm"] <= np.mean(mat.chip_load_mm(tool.diameter_mm)) * (1 + 1e-9)
    lo, hi = mat.rpm_window(tool.diameter_mm)
    assert max(lo, mach.spindle.rpm_min) * (1 - 1e-9) <= out["rpm"] <= min(hi, mach.spindle.rpm_max) * (1 + 1e-9) \
        or out["rpm"] in (mach.spindle.rpm_min, mach.spindle.rpm_max)
    thrust = mach.axes["x"].max_thrust_N(out["feed_mm_min"] / 60)
    assert abs(out["F_avg_N"][0]) <= thrust
    assert out["mrr_mm3_min"] == pytest.approx(rec.mrr_mm3_min, rel=1e-9)


def test_near_the_best_of_a_brute_force_grid():
    """Brute force over (ae, ap, rpm, fz) with the limits checked directly (model, beam, spindle, feed)."""
    tool = Tool(diameter_mm=6, flutes=3, flute_length_mm=8, stickout_mm=20)
    mat, mach = Material.load("al7075"), Machine.load("benchtop-belt")
    rec = recommend(tool, mat, mach)
    model = mat.force_model()
    beam = ToolBeam.of(tool)
    lo, hi = mat.rpm_window(6)
    rpms = np.linspace(max(lo, mach.spindle.rpm_min), min(hi, mach.spindle.rpm_max), 4)
    target = np.mean(mat.chip_load_mm(6))
    best = 0.0
    for ae in np.linspace(0.12, 6, 25):
        for ap in np.linspace(0.3, 8, 22):
            rctf = 1 / (2 * math.sqrt(ae / 6 - (ae / 6) ** 2)) if ae < 3 else 1.0
            fz = np.linspace(0.002, target * rctf, 30)
            n = np.repeat(rpms, len(fz))
            f = np.tile(fz, len(rpms))
            eng = given_cut(tool, np.full(len(f), ae), np.full(len(f), ap))
            loads = model.predict(eng, f, n, tool)
            feed = f * 3 * n
            ok = (loads.peak_force_xy_N * beam.compliance_mm_per_N(ap) <= 0.025)
            ok &= loads.peak_force_xy_N <= beam.breaking_force_N(ap)
            ok &= loads.power_W <= mach.spindle.power_available_W(n)
            ok &= feed <= min(mach.feed_max_mm_min, 6000)
            ok &= np.abs(loads.force_N[:, 0]) <= mach.axes["x"].max_thrust_N(feed / 60)
            ok &= f / rctf >= mat.min_chip_mm(tool.edge_radius_mm, tool.diameter_mm)
            if ok.any():
                best = max(best, float(np.max(eng.area_mm2[0] * feed[ok])))
    assert rec.mrr_mm3_min >= 0.98 * best, (rec.mrr_mm3_min, best)


def test_chip_thinning_feed_per_tooth():
    # shallow cuts on a strong machine at 8000 rpm (so the feed stays under the 100 mm/s dynamic range):
    # only the chip load binds, so f_z = h_target × RCTF exactly
    tool = Tool(diameter_mm=10, flutes=3, flute_length_mm=25, stickout_mm=35)
    mat, mach = Material.load("al6061"), Machine.load("vmc-small")
    target = np.mean(mat.chip_load_mm(10))
    for ae_over_d, rctf in ((0.1, 1.6667), (0.25, 1.1547), (0.05, 2.2942), (0.5, 1.0)):
        rec = recommend(tool, mat, mach, ae_mm=ae_over_d * 10, ap_mm=0.5, rpm=8000)
        assert "chip_load" in rec.binding
        assert rec.fz_mm == pytest.approx(target * rctf, rel=1e-4)
    # when another limit binds first the output says which, and the chip stays below target
    deep = recommend(tool, mat, mach, ae_mm=1.0, ap_mm=25, rpm=8000, limits=Limits(max_deflection_mm=0.005))
    assert "deflection" in deep.binding and "chip_load" not in deep.binding
    assert deep.fz_mm < target * 1.6667


def test_small_tool_in_titanium():
    # A 2 mm end mill in Ti-6Al-4V on a rigid VMC: titanium wants low surface speed (≤ 60 m/min → ≤ 9549
    # rpm at 2 mm) and the thin tool, not the 5.5 kW spindle, limits the cut. The answer a machinist
    # recognises is high-efficiency milling: most of the flute length deep, a small stepover (≤ 20 % of D;
    # the 2 mm tool's chip load is the table's 7 mm row scaled by 2/7, so little thinning is needed) with
    # the chip-thinned feed, the tool working near its strength, the spindle idling (a few % of power),
    # and a removal rate far below the same tool in aluminium.
    tool = Tool(diameter_mm=2, flutes=2, flute_length_mm=6, stickout_mm=15, shank_diameter_mm=4)
    mach = Machine.load("vmc-small")
    rec = recommend(tool, Material.load("ti6al4v"), mach)
    assert rec.rpm <= 1000 * 60 / (math.pi * 2) * (1 + 1e-9)
    assert rec.ap_mm >= 0.8 * 6 and rec.ae_mm <= 0.2 * 2
    assert rec.fz_mm > rec.h_max_mm                       # chip thinning in use
    assert max(rec.break_ratio, rec.deflection_mm / 0.025) >= 0.9
    assert rec.power_W < 0.05 * mach.spindle.power_W
    alu = recommend(tool, Material.load("al6061"), mach)
    assert rec.mrr_mm3_min < 0.2 * alu.mrr_mm3_min


def test_big_tool_on_a_weak_machine():
    # A 12 mm end mill in 1045 steel on a 300 W belt-driven benchtop mill: the spindle's power runs out
    # first, so the answer is a light cut (a small fraction of the tool's cross-section) run fast,
    # never a full-width slot; the tool itself is loafing (break ratio far below 1).
    tool = Tool(diameter_mm=12, flutes=4, flute_length_mm=30, stickout_mm=45)
    rec = recommend(tool, Material.load("steel1045"), Machine.load("benchtop-belt"))
    assert "spindle_power" in rec.binding
    assert rec.ae_mm * rec.ap_mm < 0.1 * 12 * 12
    assert rec.break_ratio < 0.2


def test_plastic_on_a_router():
    # A 6 mm two-flute cutter in acetal on a 2.2 kW router: plastic is soft, so the cut goes deep (most of
    # the flute) at high spindle speed, with thick chips allowed; the limit is the tool bending or the
    # machine's feed, not the spindle's power.
    tool = Tool(diameter_mm=6, flutes=2, flute_length_mm=22, stickout_mm=30)
    mach = Machine.load("hobby-router")
    rec = recommend(tool, Material.load("pom"), mach)
    assert rec.rpm >= 15000
    assert rec.ap_mm >= 2 * 6
    assert rec.power_W < mach.spindle.power_available_W(rec.rpm)
    assert {"deflection", "machine_feed", "chip_load", "dynamic_range"} & set(rec.binding)


def test_user_limits_are_kept_and_reported(capsys):
    # a stricter safety factor and a tighter deflection limit: calc with the same flags agrees
    tool = Tool(diameter_mm=2, flutes=2, flute_length_mm=6, stickout_mm=15, shank_diameter_mm=4)
    limits = Limits(safety_factor=8.0, max_deflection_mm=0.01, feed_max_mm_min=1500)
    rec = recommend(tool, Material.load("steel1045"), Machine.load("vmc-small"), limits)
    assert rec.feed_mm_min <= 1500 * (1 + 1e-9)
    assert main(["calc", *tool_flags(tool), "--material", "steel1045", "--safety-factor", "8", "--ae",
                 repr(rec.ae_mm), "--ap", repr(rec.ap_mm), "--rpm", repr(rec.rpm), "--fz", repr(rec.fz_mm),
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["break_ratio"] <= 1 + 1e-9 and out["deflection_mm"] <= 0.01 * (1 + 1e-9)
    assert set(rec.binding) & {"breakage", "deflection", "feed_max", "chip_load"}
