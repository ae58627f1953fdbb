"""Tool readers: Fusion tool library JSON, FreeCAD .fctb, millpost TOML; bad files name the field."""

from __future__ import annotations

import json

import numpy as np
import pytest

from millpost.errors import ConfigError
from millpost.tools.library import load_tool, read_fctb, read_fusion_library

FUSION = {
    "data": [
        {"type": "holder", "description": "ER20"},
        {"type": "flat end mill", "unit": "millimeters", "description": "6mm 3FL", "BMC": "carbide",
         "geometry": {"DC": 6, "NOF": 3, "LCF": 18, "LB": 25, "OAL": 50, "SFDM": 6, "RE": 0, "HAND": True},
         "post-process": {"number": 3}},
        {"type": "bull nose end mill", "unit": "inches", "description": "1/4 bull", "BMC": "hss",
         "geometry": {"DC": 0.25, "NOF": 4, "LCF": 0.75, "LB": 1.0, "SFDM": 0.25, "RE": 0.03},
         "post-process": {"number": 7}},
        {"type": "chamfer mill", "unit": "millimeters", "geometry": {"DC": 10, "NOF": 2, "TA": 45, "tip-diameter": 1,
                                                                     "LCF": 5, "LB": 20}},
        {"type": "drill", "unit": "millimeters", "geometry": {"DC": 5, "NOF": 2, "SIG": 135, "LCF": 28, "LB": 40},
         "post-process": {"number": 9}},
        {"type": "tap right hand", "unit": "millimeters", "geometry": {"DC": 6}},
    ],
    "version": 16,
}


def test_fusion_library(tmp_path):
    p = tmp_path / "lib.json"
    p.write_text(json.dumps(FUSION))
    tools = read_fusion_library(p)
    assert [t.shape for t in tools] == ["flat", "bull", "chamfer", "drill"]
    flat, bull, chamfer, drill = tools
    assert (drill.tip_angle_deg, drill.chisel_ratio, drill.flutes, drill.number) == (135, 0.18, 2, 9)
    assert (flat.diameter_mm, flat.flutes, flat.flute_length_mm, flat.stickout_mm, flat.number) == (6, 3, 18, 25, 3)
    assert bull.diameter_mm == pytest.approx(6.35) and bull.corner_radius_mm == pytest.approx(0.762)
    assert bull.stickout_mm == pytest.approx(25.4) and bull.material == "hss"
    assert chamfer.tip_angle_deg == 90 and chamfer.tip_diameter_mm == 1
    assert load_tool(p, number=7) is not None and load_tool(p, number=7).flutes == 4
    assert load_tool(p).number == 3
    with pytest.raises(ConfigError, match="no milling cutter or drill numbered 99"):
        load_tool(p, number=99)


def test_fusion_bad_values(tmp_path):
    bad = json.loads(json.dumps(FUSION))
    bad["data"][1]["geometry"]["DC"] = -6
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(bad))
    with pytest.raises(ConfigError) as err:
        read_fusion_library(p)
    assert err.value.field == "data[1].diameter_mm" and err.value.file == str(p)
    p.write_text("{not json")
    with pytest.raises(ConfigError, match="not valid JSON"):
        read_fusion_library(p)


def test_freecad_tool_bits(tmp_path):
    end = {"version": 2, "name": "6mm Endmill", "shape": "endmill.fcstd", "attribute": {"Flutes": 2, "Material": "HSS"},
           "parameter": {"CuttingEdgeHeight": "20.000 mm", "Diameter": "6.000 mm", "Length": "50.000 mm",
                         "ShankDiameter": "0.25 in"}}
    p = tmp_path / "end.fctb"
    p.write_text(json.dumps(end))
    t = load_tool(p)
    assert (t.shape, t.diameter_mm, t.flutes, t.flute_length_mm, t.material) == ("flat", 6, 2, 20, "hss")
    assert t.shank_diameter_mm == pytest.approx(6.35)
    bull = {"shape": "bullnose.fcstd", "parameter": {"Diameter": "10 mm", "FlatRadius": "4 mm", "Flutes": 4}}
    vbit = {"shape": "v-bit.fcstd", "parameter": {"Diameter": "12 mm", "CuttingEdgeAngle": "60.000 °",
                                                  "TipDiameter": "0.2 mm"}}
    for name, data in (("bull.fctb", bull), ("v.fctb", vbit)):
        (tmp_path / name).write_text(json.dumps(data))
    assert read_fctb(tmp_path / "bull.fctb").corner_radius_mm == pytest.approx(1.0)
    v = read_fctb(tmp_path / "v.fctb")
    assert (v.shape, v.tip_angle_deg, v.tip_diameter_mm) == ("chamfer", 60, 0.2)
    drill = {"shape": "drill.fcstd", "parameter": {"Diameter": "6.8 mm", "Length": "70 mm", "TipAngle": "118.00 °"}}
    (tmp_path / "d.fctb").write_text(json.dumps(drill))
    d = read_fctb(tmp_path / "d.fctb")
    assert (d.shape, d.tip_angle_deg, d.diameter_mm) == ("drill", 118, 6.8)


def test_drill_shape_rules(tmp_path):
    p = tmp_path / "d.toml"
    p.write_text('[tool]\ndiameter_mm = 5\nshape = "drill"\n')
    d = load_tool(p)
    assert (d.tip_angle_deg, d.chisel_ratio) == (118, 0.18)   # a jobber drill's standard point
    assert d.height_at(2.5) == pytest.approx(2.5 / np.tan(np.radians(59)))  # the cone of the point
    p.write_text('[tool]\ndiameter_mm = 5\nshape = "drill"\nchisel_ratio = 0.5\n')
    with pytest.raises(ConfigError) as err:
        load_tool(p)
    assert err.value.field == "tool.chisel_ratio"
    p.write_text('[tool]\ndiameter_mm = 5\nshape = "drill"\ntip_diameter_mm = 1\n')
    with pytest.raises(ConfigError, match="no flat"):
        load_tool(p)


def test_freecad_wrong_units_and_shape(tmp_path):
    p = tmp_path / "x.fctb"
    p.write_text(json.dumps({"shape": "endmill.fcstd", "parameter": {"Diameter": "6 kg"}}))
    with pytest.raises(ConfigError) as err:
        read_fctb(p)
    assert err.value.field == "parameter.Diameter" and "not a length unit" in err.value.rule
    p.write_text(json.dumps({"shape": "thread-mill.fcstd", "parameter": {"Diameter": "6 mm"}}))
    with pytest.raises(ConfigError, match="supported"):
        read_fctb(p)


def test_toml_tool(tmp_path):
    p = tmp_path / "t.toml"
    p.write_text('[tool]\ndiameter_mm = "0.25 in"\nflutes = 3\nhelix_deg = 40\nstickout_mm = 30\n'
                 'flute_length_mm = 19\nshape = "flat"\n')
    t = load_tool(p)
    assert t.diameter_mm == pytest.approx(6.35) and t.helix_deg == 40
    p.write_text("[tool]\ndiameter_mm = 6\nflutes = 0\n")
    with pytest.raises(ConfigError) as err:
        load_tool(p)
    assert err.value.field == "tool.flutes" and err.value.file == str(p)
    p.write_text("[tool]\ndiameter_mm = 6\nflute_lenght_mm = 10\n")
    with pytest.raises(ConfigError, match="did you mean 'flute_length_mm'"):
        load_tool(p)
    with pytest.raises(ConfigError, match="expected a .toml"):
        load_tool(tmp_path.joinpath("x.txt").write_text("") or tmp_path / "x.txt")
