"""recommend like a machinist: on a grid of tools, materials, machines and strategies the answer keeps
the material file's published rules for its strategy (radial width range, slot and facing depth), enters
slower than it cuts (ramp and plunge), keeps the plunge's end-edge torque within the spindle's, and names
the rules that bind."""

from __future__ import annotations

import json

import numpy as np
import pytest

from millpost.cli import main
from millpost.errors import MillpostError
from millpost.heuristics import recommend
from millpost.machine import Machine
from millpost.materials import STRATEGIES, Material
from millpost.tools.cutter import Tool


def _grid(seed: int = 15, n: int = 14):
    rng = np.random.default_rng(seed)
    cases = []
    for k in range(n):
        d = float(rng.choice([3.0, 6.0, 10.0]))
        tool = Tool(diameter_mm=d, flutes=int(rng.integers(2, 5)), flute_length_mm=3 * d, stickout_mm=4 * d)
        material = str(rng.choice(["al6061", "al7075", "steel1045", "ss304", "ti6al4v", "brass", "pom", "mdf"]))
        machine = str(rng.choice(["vmc-small", "hobby-router", "benchtop-belt"]))
        cases.append((tool, material, machine, STRATEGIES[k % len(STRATEGIES)]))
    return cases


@pytest.mark.parametrize("tool, material, machine, strategy", _grid())
def test_rules_of_the_strategy_hold(tool, material, machine, strategy):
    mat, mach = Material.load(material), Machine.load(machine)
    try:
        rec = recommend(tool, mat, mach, strategy=strategy)
    except MillpostError as exc:  # a machine that cannot do it must say so, not bend the rules
        assert "relax a limit" in str(exc)
        return
    rules, d = mat.strategies, tool.diameter_mm
    lo, hi = rules.ae_range_D(strategy)
    assert lo * d * (1 - 1e-9) <= rec.ae_mm <= hi * d * (1 + 1e-9)
    if rules.ap_max_D(strategy) is not None:
        assert rec.ap_mm <= rules.ap_max_D(strategy) * d * (1 + 1e-9)
    assert rec.ap_mm <= tool.flute_length_mm
    # entry moves slower than the cut: ramp at most its ratio of the feed, plunge at most the ramp
    assert rec.ramp_feed_mm_min <= rules.ramp_feed_ratio * rec.feed_mm_min * (1 + 1e-9)
    assert rec.plunge_feed_mm_min <= rec.ramp_feed_mm_min * (1 + 1e-9)
    assert rec.plunge_feed_mm_min < rec.feed_mm_min
    # the plunge's end-edge torque (Kienzle, bottom edges as a 180° drill) within the spindle's
    h = rec.plunge_feed_mm_min / (tool.flutes * rec.rpm)
    if h > 0:
        k = mat.kienzle
        torque_Nm = tool.flutes * k.kc11_N_mm2 * h ** (1 - k.mc) * (d / 2) ** 2 / 2 / 1000
        assert torque_Nm <= float(mach.spindle.torque_Nm(rec.rpm)) * (1 + 1e-6)
        assert h <= rules.plunge_fz_ratio * rec.chip_target_mm * (1 + 1e-9)
    # a rule at its bound is named
    if rec.ae_mm >= hi * d * (1 - 1e-6) and lo < hi:
        assert f"{strategy}_width_max" in rec.binding


def test_6mm_6061_vmc_small_adaptive(capsys):
    """The issue's case: 6 mm 3-flute end mill in 6061 on vmc-small. Before: a full-width 18 mm slot at
    2250 mm/min, plunging at the cutting feed."""
    args = ["recommend", "--diameter", "6", "--flutes", "3", "--flute-length", "18", "--stickout", "25",
            "--material", "al6061", "--machine", "vmc-small", "--strategy", "adaptive", "--json"]
    assert main(args) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["ae_mm"] <= 0.2 * 6 * (1 + 1e-9)
    assert rec["plunge_feed_mm_min"] < rec["feed_mm_min"] and rec["ramp_feed_mm_min"] < rec["feed_mm_min"]
    assert "adaptive_width_max" in rec["binding"]
    assert main([*args[:-1], "--format", "fusion", "--json"]) == 0
    fusion = json.loads(capsys.readouterr().out)
    assert fusion["Optimal load"] <= 1.2 and fusion["Plunge feedrate"] < fusion["Cutting feedrate"]
    assert main([*args[:-2], "slot", "--json"]) == 0
    slot = json.loads(capsys.readouterr().out)
    assert slot["ae_mm"] == 6 and slot["ap_mm"] <= 6 * (1 + 1e-9)  # 1 x D: the chips must leave the slot


def test_fixed_width_outside_the_strategy_is_refused():
    mat, mach = Material.load("al6061"), Machine.load("vmc-small")
    with pytest.raises(MillpostError, match="outside adaptive's range"):
        recommend(Tool(diameter_mm=6, flutes=3, flute_length_mm=18, stickout_mm=25), mat, mach, ae_mm=3.0,
                  strategy="adaptive")
