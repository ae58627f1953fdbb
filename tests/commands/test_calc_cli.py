"""`millpost calc` end to end against PHYSICS.md oracles."""

from __future__ import annotations

import json
import math

import pytest

from millpost.cli import main
from millpost.tools.beam import ToolBeam
from millpost.tools.cutter import Tool

AL7075 = "Ktc=767.01,Krc=168.8,Kac=222,Kte=27.7,Kre=26.6,Kae=0.7"
TOOL19 = ["--diameter", "19.05", "--flutes", "4", "--helix", "30"]


def calc(capsys, *argv: str) -> dict:
    assert main(["calc", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_slot_oracles(capsys):
    out = calc(capsys, *TOOL19, "--coeffs", AL7075, "--ae", "19.05", "--ap", "5", "--rpm", "6000", "--fz", "0.1")
    assert out["F_avg_N"] == pytest.approx([-253.741, 559.849, 148.330], abs=1e-3)
    assert out["torque_Nm"] == pytest.approx(7.2894, abs=1e-4)
    assert out["power_W"] == pytest.approx(4580.1, abs=0.1)
    assert out["F_peak_N"] == pytest.approx(663.20, rel=1e-3)
    assert out["mrr_mm3_min"] == pytest.approx(228.6e3, rel=1e-4)        # 228.6 cm³/min
    assert out["feed_mm_min"] == pytest.approx(2400)
    assert out["h_max_mm"] == pytest.approx(0.1) and out["h_mean_mm"] == pytest.approx(0.2 / math.pi)
    assert out["chip_thinning_factor"] == 1.0


@pytest.mark.parametrize("side, want", [("--climb", [83.375, 391.460]), ("--conventional", [-337.116, 168.389])])
def test_half_immersion_oracles(capsys, side, want):
    out = calc(capsys, *TOOL19, "--coeffs", AL7075, "--ae", "9.525", "--ap", "5", "--rpm", "6000", "--fz", "0.1", side)
    assert out["F_avg_N"][:2] == pytest.approx(want, abs=1e-3)


def test_chip_thinning_and_feed_flag(capsys):
    args = ["--diameter", "10", "--flutes", "3", "--material", "al6061", "--ae", "1", "--ap", "8", "--rpm", "10000"]
    a = calc(capsys, *args, "--fz", "0.05")
    b = calc(capsys, *args, "--feed", "1500")
    assert a["chip_thinning_factor"] == pytest.approx(1.6667, abs=1e-4)    # C1
    assert a["h_max_mm"] == pytest.approx(0.05 * 0.6)
    assert a["h_mean_mm"] == pytest.approx(0.05 * 0.2 / math.acos(0.8))    # K1 form
    assert b == a


def test_kienzle_slot_exact_mean_K3(capsys):
    out = calc(capsys, "--diameter", "10", "--flutes", "4", "--helix", "0", "--kienzle", "kc11=1500,mc=0.22",
               "--ae", "10", "--ap", "5", "--rpm", "3000", "--fz", "0.1")
    assert out["model"] == "kienzle"
    assert out["torque_Nm"] * 1000 / 5 == pytest.approx(1703.42, abs=0.01)


def test_deflection_break_ratio_and_machine(capsys):
    args = ["--diameter", "6", "--flutes", "3", "--stickout", "24", "--flute-length", "15", "--material", "al7075",
            "--ae", "3", "--ap", "6", "--rpm", "12000", "--fz", "0.05"]
    out = calc(capsys, *args)
    beam = ToolBeam.of(Tool(diameter_mm=6, flutes=3, stickout_mm=24, flute_length_mm=15))
    assert out["deflection_mm"] == pytest.approx(beam.deflection_mm(out["F_peak_N"], 6), rel=1e-12)
    assert out["break_ratio"] == pytest.approx(out["F_peak_N"] / beam.breaking_force_N(6), rel=1e-12)
    sf4 = calc(capsys, *args, "--safety-factor", "4")
    assert sf4["break_ratio"] == pytest.approx(out["break_ratio"] * 4 / beam.safety_factor, rel=1e-12)
    with_machine = calc(capsys, *args, "--machine", "benchtop-belt")
    assert with_machine["deflection_mm"] == out["deflection_mm"]
    assert with_machine["machine_deflection_mm"] == pytest.approx(out["F_peak_N"] / 400, rel=1e-12)
    # 300 W spindle, constant torque to 24000 rpm: 150 W available at 12000 rpm
    assert with_machine["spindle_power_ratio"] == pytest.approx(out["power_W"] / 150, rel=1e-9)


def test_material_kienzle_model_and_tool_file(capsys, tmp_path):
    p = tmp_path / "t.toml"
    p.write_text("[tool]\ndiameter_mm = 8\nflutes = 2\n")
    out = calc(capsys, "--tool", str(p), "--material", "pom", "--model", "kienzle", "--ae", "4", "--ap", "4",
               "--rpm", "15000", "--fz", "0.1")
    assert out["model"] == "kienzle" and out["power_W"] > 0


@pytest.mark.parametrize("argv, message", [
    (["--material", "al6061"], "--diameter"),
    (["--diameter", "6", "--coeffs", "Ktc=1"], "--coeffs"),
    (["--diameter", "6", "--kienzle", "kc11=abc"], "--kienzle"),
    (["--diameter", "6", "--material", "unobtainium"], "unknown material"),
    (["--diameter", "-6", "--material", "al6061"], "diameter_mm"),
])
def test_bad_inputs_exit_2_with_a_message(capsys, argv, message):
    code = main(["calc", *argv, "--ae", "1", "--ap", "1", "--rpm", "10000", "--fz", "0.05"])
    assert code == 2
    assert message in capsys.readouterr().err
