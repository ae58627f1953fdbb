"""`millpost recommend` on the command line: JSON keys, CAM dialog formats, sweep and plot, refusals."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import millpost
from millpost.cli import main
from millpost.lowdeflection import zero_normal_force
from millpost.materials import Material
from millpost.tools.cutter import Tool


def test_recommend_cli(capsys, tmp_path):
    base = ["recommend", "--diameter", "6", "--flutes", "3", "--flute-length", "18", "--stickout", "25",
            "--material", "al6061", "--machine", "hobby-router", "--rpm", "20000", "--ap", "6"]
    assert main([*base, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("ap_mm", "ae_mm", "rpm", "fz_mm", "feed_mm_min", "mrr_mm3_min", "deflection_mm", "power_W", "binding"):
        assert key in out
    assert out["rpm"] == 20000 and out["ap_mm"] == 6
    assert main([*base, "--format", "freecad", "--json"]) == 0
    fc = json.loads(capsys.readouterr().out)
    assert fc["Step over"] == pytest.approx(100 * out["ae_mm"] / 6) and fc["Horizontal feed"] == out["feed_mm_min"]
    assert main([*base, "--format", "fusion"]) == 0
    assert "Optimal load" in capsys.readouterr().out
    png = tmp_path / "sweep.png"
    assert main([*base[:-4], "--sweep", "--plot", str(png)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("ap_mm,ae_mm,rpm") and len(lines) > 10
    assert png.stat().st_size > 1000
    assert main([*base, "--max-deflection", "1e-7"]) == 2
    assert "relax a limit" in capsys.readouterr().err
    assert main([*base[:-2], "--ap", "40"]) == 2
    assert "outside" in capsys.readouterr().err


def test_recommend_low_deflection_cli(capsys, tmp_path):
    """--strategy low-deflection: conventional milling at the width where the mean normal force vanishes,
    printed with the engagement and the mean-force deflection (JSON and table); a fixed --ae conflicts
    with it; a material whose model has no radial force has no such width and the refusal says so."""
    base = ["recommend", "--diameter", "6", "--flutes", "3", "--flute-length", "18", "--stickout", "25",
            "--material", "al6061", "--machine", "vmc-small", "--strategy", "low-deflection"]
    assert main([*base, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["climb"] is False and out["strategy"] == "low-deflection"
    tool = Tool(diameter_mm=6, flutes=3, flute_length_mm=18, stickout_mm=25)
    root = zero_normal_force(tool, Material.load("al6061").force_model(), fz_mm=out["fz_mm"], ap_mm=out["ap_mm"])
    assert out["ae_mm"] == pytest.approx(root.ae_mm, abs=1e-5)
    assert out["engagement_deg"] == pytest.approx(root.engagement_deg, abs=1e-3)
    assert abs(out["mean_deflection"]["tool_normal_mm"]) < 1e-9 < abs(out["mean_deflection"]["tool_feed_mm"])
    assert abs(out["F_avg_N"][1]) < 1e-6 * abs(out["F_avg_N"][0])
    assert main(base) == 0
    table = capsys.readouterr().out
    assert "conventional, engagement" in table and "where the mean force normal to the feed is zero" in table
    assert "toward the wall" in table
    assert main([*base, "--ae", "1"]) == 2
    assert "chooses the width" in capsys.readouterr().err
    text = (Path(millpost.__file__).parent / "data" / "materials" / "al6061.toml").read_text()
    text = text.replace("Krc_N_mm2 = 99", "Krc_N_mm2 = 0").replace("Kre_N_per_mm = 10", "Kre_N_per_mm = 0")
    (tmp_path / "norad.toml").write_text(text)
    no_radial = [str(tmp_path / "norad.toml") if a == "al6061" else a for a in base]
    assert main([*no_radial, "--json"]) == 2
    assert "no radial width" in capsys.readouterr().err
