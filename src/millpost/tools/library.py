"""Read cutters from the files people already have: millpost TOML, Fusion tool library JSON, FreeCAD
tool bits (.fctb). Everything becomes a `Tool`; refusals are ConfigErrors naming field, value and file.

Fusion (``{"data": [{"type": "flat end mill", "unit": "millimeters", "geometry": {...}}]}``) geometry keys:
DC cutting diameter, NOF flutes, LCF flute length, LB body length below the holder (= stickout), SFDM
shank diameter, RE corner radius, TA taper angle (half angle of a chamfer mill), tip-diameter, SIG point
angle of a drill (types "drill" and "spot drill"); number in post-process.number; BMC body material.
FreeCAD (``{"shape": "endmill.fcstd", "parameter": {...}}``): Diameter, CuttingEdgeHeight, ShankDiameter,
Flutes, FlatRadius (bull nose), CuttingEdgeAngle (included angle of chamfer/V bits), TipDiameter,
TipAngle (point angle of drill.fcstd); quantities are strings such as "6.000 mm". Neither format stores
a helix angle reliably; the Tool default (30°) applies unless the file gives one.
"""

from __future__ import annotations

import json
from dataclasses import fields
from pathlib import Path
from typing import Any

from ..config import Table, load_toml, quantity
from ..errors import ConfigError
from .cutter import Tool

FUSION_SHAPES = {"flat end mill": "flat", "ball end mill": "ball", "bull nose end mill": "bull",
                 "chamfer mill": "chamfer", "drill": "drill", "spot drill": "drill"}
FREECAD_SHAPES = {"endmill": "flat", "ballend": "ball", "bullnose": "bull", "chamfer": "chamfer", "v-bit": "chamfer",
                  "vbit": "chamfer", "drill": "drill"}
TOOL_MATERIALS = {"carbide": "carbide", "hss": "hss", "hsco": "hss", "high speed steel": "hss"}


def make_tool(values: dict[str, Any], *, file: str | None, prefix: str = "") -> Tool:
    """Build a Tool, re-raising its validation errors with the file and field path."""
    try:
        return Tool(**values)
    except ConfigError as exc:
        raise ConfigError(prefix + exc.field, exc.value, exc.rule, file=file) from None


def tool_from_table(t: Table) -> Tool:
    """A Tool from a TOML table whose keys are the Tool's field names (with units in the names)."""
    values: dict[str, Any] = {"diameter_mm": t.number("diameter_mm", gt=0)}
    for f in fields(Tool):
        if f.name == "diameter_mm" or not t.has(f.name):
            continue
        if f.name in ("flutes", "number"):
            values[f.name] = t.integer(f.name)
        elif f.name in ("shape", "material", "name"):
            values[f.name] = t.string(f.name)
        else:
            values[f.name] = t.number(f.name)
    t.done(tuple(f.name for f in fields(Tool)))
    return make_tool(values, file=t.file, prefix=t.name + "." if t.name else "")


def read_toml_tool(path: str | Path) -> Tool:
    p = Path(path)
    root = Table(load_toml(p), "", str(p))
    tool = tool_from_table(root.table("tool"))
    root.done()
    return tool


def _json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ConfigError("<file>", path.name, f"not valid JSON ({exc.msg} at line {exc.lineno})",
                          file=str(path)) from None


def read_fusion_library(path: str | Path) -> list[Tool]:
    """Milling cutters and drills of a Fusion tool library (holders, taps, probes and other types are
    skipped)."""
    p = Path(path)
    data = _json(p)
    entries = data.get("data") if isinstance(data, dict) else None
    if not isinstance(entries, list):
        raise ConfigError("data", type(data).__name__, "a Fusion tool library has a 'data' list", file=str(p))
    tools = []
    for i, entry in enumerate(entries):
        shape = FUSION_SHAPES.get(str(entry.get("type", "")).lower())
        if shape is None:
            continue
        field = f"data[{i}]"
        unit = entry.get("unit", "millimeters")
        if unit not in ("millimeters", "inches"):
            raise ConfigError(f"{field}.unit", unit, "must be millimeters or inches", file=str(p))
        scale = 25.4 if unit == "inches" else 1.0
        geo = entry.get("geometry", {})

        def length(key: str) -> float | None:
            if key not in geo:
                return None
            return quantity(geo[key], None, f"{field}.geometry.{key}", file=str(p)) * scale

        values: dict[str, Any] = {"diameter_mm": length("DC"), "shape": shape,
                                  "name": str(entry.get("description", ""))}
        if values["diameter_mm"] is None:
            raise ConfigError(f"{field}.geometry.DC", None, "is required", file=str(p))
        if "NOF" in geo:
            values["flutes"] = int(quantity(geo["NOF"], None, f"{field}.geometry.NOF", file=str(p)))
        for key, name in (("LCF", "flute_length_mm"), ("LB", "stickout_mm"), ("SFDM", "shank_diameter_mm"),
                          ("tip-diameter", "tip_diameter_mm")):
            v = length(key)
            if v is not None and (v > 0 or name == "tip_diameter_mm"):
                values[name] = v
        if shape == "bull":
            values["corner_radius_mm"] = length("RE")
        if shape == "chamfer" and "TA" in geo:
            values["tip_angle_deg"] = 2 * quantity(geo["TA"], None, f"{field}.geometry.TA", file=str(p))
        if shape == "drill":
            values.pop("tip_diameter_mm", None)
            if "SIG" in geo:
                values["tip_angle_deg"] = quantity(geo["SIG"], None, f"{field}.geometry.SIG", file=str(p))
        if values.get("flute_length_mm") and values.get("stickout_mm") and \
                values["flute_length_mm"] > values["stickout_mm"]:
            values["flute_length_mm"] = values["stickout_mm"]   # flutes partly inside the holder
        number = entry.get("post-process", {}).get("number")
        if isinstance(number, int):
            values["number"] = number
        material = TOOL_MATERIALS.get(str(entry.get("BMC", "carbide")).lower())
        if material:
            values["material"] = material
        tools.append(make_tool(values, file=str(p), prefix=field + "."))
    return tools


def read_fctb(path: str | Path) -> Tool:
    """A FreeCAD tool bit (.fctb JSON)."""
    p = Path(path)
    data = _json(p)
    if not isinstance(data, dict) or not isinstance(data.get("parameter"), dict):
        raise ConfigError("parameter", None, "a FreeCAD tool bit has a 'parameter' table", file=str(p))
    shape_file = str(data.get("shape", "endmill.fcstd"))
    shape = FREECAD_SHAPES.get(shape_file.rsplit(".", 1)[0].lower())
    if shape is None:
        raise ConfigError("shape", shape_file, f"supported: {', '.join(sorted(FREECAD_SHAPES))}", file=str(p))
    par, attr = data["parameter"], data.get("attribute", {}) or {}

    def q(key: str, suffix: str | None) -> float | None:
        if key not in par:
            return None
        return quantity(par[key], suffix, f"parameter.{key}", file=str(p))

    values: dict[str, Any] = {"diameter_mm": q("Diameter", "mm"), "shape": shape, "name": str(data.get("name", ""))}
    if values["diameter_mm"] is None:
        raise ConfigError("parameter.Diameter", None, "is required", file=str(p))
    for key, name in (("CuttingEdgeHeight", "flute_length_mm"), ("ShankDiameter", "shank_diameter_mm")):
        v = q(key, "mm")
        if v:
            values[name] = v
    flutes = par.get("Flutes", attr.get("Flutes"))
    if flutes is not None:
        values["flutes"] = int(quantity(flutes, None, "parameter.Flutes", file=str(p)))
    helix = q("HelixAngle", "deg")
    if helix is not None:
        values["helix_deg"] = helix
    if shape == "bull":
        flat = q("FlatRadius", "mm")
        if flat is None:
            raise ConfigError("parameter.FlatRadius", None, "a bull nose bit needs FlatRadius", file=str(p))
        values["corner_radius_mm"] = values["diameter_mm"] / 2 - flat
    if shape == "chamfer":
        angle = q("CuttingEdgeAngle", "deg")
        if angle is not None:
            values["tip_angle_deg"] = angle
        tip = q("TipDiameter", "mm")
        if tip is None and q("FlatRadius", "mm") is not None:
            tip = 2 * q("FlatRadius", "mm")
        if tip is not None:
            values["tip_diameter_mm"] = tip
    if shape == "drill":
        angle = q("TipAngle", "deg")
        if angle is not None:
            values["tip_angle_deg"] = angle
    material = TOOL_MATERIALS.get(str(attr.get("Material", "carbide")).lower())
    if material:
        values["material"] = material
    return make_tool(values, file=str(p), prefix="parameter.")


def load_tool(path: str | Path, *, number: int | None = None) -> Tool:
    """A tool from a .toml, .fctb or Fusion .json file; `number` picks one from a Fusion library
    (default: the first milling cutter or drill)."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError("tool", str(p), "file not found")
    suffix = p.suffix.lower()
    if suffix == ".toml":
        return read_toml_tool(p)
    if suffix == ".fctb":
        return read_fctb(p)
    if suffix == ".json":
        tools = read_fusion_library(p)
        if number is not None:
            tools = [t for t in tools if t.number == number]
        if not tools:
            what = f"no milling cutter or drill numbered {number}" if number is not None else \
                "no milling cutter or drill"
            raise ConfigError("tool", str(p), what, file=str(p))
        return tools[0]
    raise ConfigError("tool", str(p), "expected a .toml, .fctb or Fusion .json file")
