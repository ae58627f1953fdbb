"""`recommend --frf`: the chatter limit among the heuristics' limits.

A 6 mm 3-flute end mill slotting Al 6061 on the benchtop mill (rpm window ~18600–24000) with a flexible tip,
one mode f_n 2200 Hz, ζ 0.03, k 2500 N/mm (the sample job chatter_slot's mode, a third as stiff): the
recommendation without the FRF (ap 0.68 mm at 24000 rpm) is above the zero-order limit there, computed
here by `zero_order_limit_mm` on its own (immersion φ_s = arccos(1 − 2ae/D), climb π − φ_s…π; K_t, K_r the
material's mechanistic K_tc, K_rc/K_tc); with the FRF it is below it, at a speed between the two lobe
minima around a stable pocket (`stable_pockets` of the same curve), near the pocket's speed."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from millpost.cli import main
from millpost.forces.mechanistic import Mechanistic
from millpost.materials import Material
from millpost.stability.frf import Mode, ToolTipFRF
from millpost.stability.lobes import stable_pockets, zero_order_limit_mm

FLEX = ToolTipFRF.symmetric(Mode(2200.0, 0.03, 2500.0))
ARGS = ["recommend", "--diameter", "6", "--flutes", "3", "--material", "al6061", "--machine", "benchtop-belt",
        "--json"]


def a_lim(ae_mm: float, rpm) -> np.ndarray:
    ktc, krc = Mechanistic.from_material(Material.load("al6061")).coef_[:2]
    phi_s = math.acos(1 - 2 * min(ae_mm / 6.0, 1.0))
    return zero_order_limit_mm(FLEX, kt_N_per_mm2=float(ktc), kr=float(krc / ktc), flutes=3,
                               phi_st_rad=math.pi - phi_s, phi_ex_rad=math.pi, rpm=np.atleast_1d(rpm))


def run(capsys, *extra: str) -> dict:
    assert main([*ARGS, *extra]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.fixture
def frf_file(tmp_path):
    path = tmp_path / "frf.toml"  # as `millpost tap fit --toml` writes it
    path.write_text("# fitted by millpost tap fit from tap-x.csv\n[tools.1.frf]\n"
                    "x = [{fn_hz = 2200, zeta = 0.03, k_N_per_mm = 2500}]\n")
    return path


def test_frf_makes_the_slot_stable_in_a_pocket(capsys, frf_file):
    free = run(capsys, "--strategy", "slot")
    assert free["ap_mm"] > 1.5 * a_lim(free["ae_mm"], free["rpm"])[0]  # chatters: 0.68 mm over ~0.34 mm
    rec = run(capsys, "--strategy", "slot", "--frf", str(frf_file))
    limit = a_lim(rec["ae_mm"], rec["rpm"])[0]
    assert rec["a_lim_mm"] == pytest.approx(limit, rel=1e-9) and rec["ap_mm"] <= limit
    assert rec["ratios"]["chatter"] == pytest.approx(rec["ap_mm"] / limit, rel=1e-9)
    assert rec["chatter_margin"] == pytest.approx(limit / rec["ap_mm"], rel=1e-9)
    n = np.linspace(15000, 30000, 3001)
    curve = a_lim(rec["ae_mm"], n)
    pocket = min(stable_pockets(n, curve), key=lambda p: abs(p.rpm - rec["rpm"]))
    minima = n[1:-1][(curve[1:-1] < curve[:-2]) & (curve[1:-1] <= curve[2:])]
    assert minima[minima < pocket.rpm].max() < rec["rpm"] < minima[minima > pocket.rpm].min()
    assert abs(rec["rpm"] - pocket.rpm) < 0.03 * pocket.rpm  # pocket near 21975 rpm
    assert rec["mrr_mm3_min"] < free["mrr_mm3_min"]


def test_chatter_binds_when_it_decides(capsys, frf_file):
    """A fixed speed on a lobe's flank: the depth is the stable one, and `chatter` is named in binding."""
    rec = run(capsys, "--strategy", "slot", "--frf", str(frf_file), "--rpm", "24000")
    assert rec["ap_mm"] == pytest.approx(a_lim(6.0, 24000.0)[0], rel=1e-9) and "chatter" in rec["binding"]


def refused(capsys, *extra: str) -> str:
    assert main([*ARGS, *extra]) != 0
    return capsys.readouterr().err


def test_no_stable_cut_says_which_depth_would_be(capsys, frf_file):
    err = refused(capsys, "--strategy", "slot", "--frf", str(frf_file), "--ap", "2")
    deepest = float(re.search(r"ap ≤ ([0-9.]+) mm would be stable", err).group(1))
    n = np.linspace(18000, 24000, 601)  # the slot's highest lobe in the window: the pocket near 21970 rpm
    assert "no stable cut" in err and a_lim(6.0, n).max() * 0.995 < deepest <= a_lim(6.0, n).max()


def test_frf_file_refusals(tmp_path, capsys):
    two = tmp_path / "two.toml"
    two.write_text("[tools.1.frf]\nx = [{fn_hz = 2200, zeta = 0.03, k_N_per_mm = 2500}]\n"
                   "[tools.2.frf]\nx = [{fn_hz = 900, zeta = 0.02, k_N_per_mm = 9000}]\n")
    assert re.search("two.toml.*more than one tool has an FRF.*--frf-tool", refused(capsys, "--frf", str(two)))
    assert re.search(r"tools.3.frf.*not in the file \(tools with an FRF: \[1, 2\]\)",
                     refused(capsys, "--frf", str(two), "--frf-tool", "3"))
    bad = tmp_path / "bad.toml"
    bad.write_text("[tools.1.frf]\nx = [{fn_hz = 2200, zeta = 1.5, k_N_per_mm = 2500}]\n")
    assert re.search(r"bad.toml.*tools.1.frf.x\[0\].zeta", refused(capsys, "--frf", str(bad)))
    assert "--frf-tool = 2: needs --frf" in refused(capsys, "--frf-tool", "2")


# recorded from main at 2442c09 (before --frf), benchtop-belt, D6 3F, al6061: the answer without an FRF
MAIN = {"adaptive": ((2.663597436565523, 1.1332862665350971, 24000.0, 5912.627396126714),
                     ["chip_load", "spindle_power", "spindle_rpm"]),
        "slot": ((0.6818672724341901, 6.0, 24000.0, 4628.571428571428), ["chip_load", "slot", "spindle_rpm"]),
        "any": ((0.8161696653162155, 5.230440520784958, 24000.0, 4628.571428571428),
                ["chip_load", "spindle_power", "spindle_rpm"])}


@pytest.mark.parametrize("strategy", sorted(MAIN))
def test_without_frf_unchanged(capsys, strategy):
    rec = run(capsys, "--strategy", strategy)
    values, binding = MAIN[strategy]
    assert (rec["ap_mm"], rec["ae_mm"], rec["rpm"], rec["feed_mm_min"]) == pytest.approx(values, rel=1e-12)
    assert rec["binding"] == binding and "a_lim_mm" not in rec and "chatter" not in rec["ratios"]
