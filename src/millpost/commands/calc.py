"""`millpost calc`: feeds-and-speeds calculator on millpost's force, beam and machine models."""

from __future__ import annotations

import argparse
import math

from ..files import json_text
from ..errors import ConfigError
from ..cut import evaluate_cut
from ..forces import Kienzle, Mechanistic
from ..forces.mechanistic import COEF_NAMES
from ..machine import Machine
from ..materials import Material
from ..registry import plugins
from ..tools.cutter import Tool
from ..tools.library import load_tool

HELP = """\
Units: lengths mm, feed per tooth mm, feed mm/min, speed rpm, forces N, torque N·m, power W,
removal rate mm³/min. The cut is a straight pass along +X beside a wall, width ae (ae ≥ D is a slot),
depth ap; --climb (default) keeps the material on the right of the travel (down milling with an M3
spindle), --conventional on the left. Forces are those on the tool in machine X, Y, Z; F_z is the
axial force +F_a of Altintas' convention (which way it points depends on the helix hand, so take
its magnitude). F_avg_N is the mean over a tooth period, F_peak_N the largest in-plane
|F| over a revolution (helix included). deflection_mm is the tool's lateral deflection under F_peak at
mid-depth (two-segment cantilever, fluted diameter 0.8·D); break_ratio = F_peak over the tool's
allowed lateral force (bending strength / safety factor). With --machine, machine_deflection_mm is
F_peak over the softer X/Y axis stiffness (in series with the tool) and spindle_power_ratio the cutting
power over the spindle's power at that speed. Coefficients: --coeffs Ktc,Krc,Kac (N/mm²) and
Kte,Kre,Kae (N/mm) for the mechanistic model; --kienzle kc11 (N/mm²), mc [, radial=F_r/F_t,
axial=F_a/F_t].

example:
  millpost calc --diameter 6 --flutes 3 --material al6061 --machine vmc-small --ae 1.2 --ap 6 --rpm 12000 --feed 2000"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("calc", help="cutting forces, power and tool deflection for one cut",
                       description="Predict the loads of one cut from a tool, a material and cutting parameters.",
                       epilog=HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_tool_arguments(p)
    add_material_arguments(p)
    p.add_argument("--machine", metavar="NAME|FILE", help="machine (adds its axis compliance and spindle limits)")
    cut = p.add_argument_group("cut")
    cut.add_argument("--ae", type=float, required=True, metavar="MM", help="radial width of cut (mm)")
    cut.add_argument("--ap", type=float, required=True, metavar="MM", help="axial depth of cut (mm)")
    cut.add_argument("--rpm", type=float, required=True, help="spindle speed (rpm)")
    feed = cut.add_mutually_exclusive_group(required=True)
    feed.add_argument("--fz", type=float, metavar="MM", help="feed per tooth (mm)")
    feed.add_argument("--feed", type=float, metavar="MM_MIN", help="feed rate (mm/min)")
    side = cut.add_mutually_exclusive_group()
    side.add_argument("--climb", dest="climb", action="store_true", default=True, help="down milling (default)")
    side.add_argument("--conventional", dest="climb", action="store_false", help="up milling")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run)


# --- shared with `millpost recommend` ----------------------------------------------------------
def add_tool_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("tool (a file, or flags)")
    g.add_argument("--tool", metavar="FILE", help="tool file: .toml, FreeCAD .fctb or Fusion library .json")
    g.add_argument("--tool-number", type=int, help="tool number in a Fusion library")
    g.add_argument("--diameter", type=float, metavar="MM", help="cutting diameter (mm)")
    g.add_argument("--flutes", type=int, default=2, help="number of flutes (default 2)")
    g.add_argument("--helix", type=float, default=30.0, metavar="DEG", help="helix angle (deg, default 30)")
    g.add_argument("--corner-radius", type=float, default=0.0, metavar="MM",
                   help="corner radius (mm); D/2 makes a ball end mill")
    g.add_argument("--stickout", type=float, metavar="MM", help="holder face to tip (mm)")
    g.add_argument("--flute-length", type=float, metavar="MM", help="cutting length (mm)")
    g.add_argument("--shank", type=float, metavar="MM", help="shank diameter (mm)")
    g.add_argument("--tool-material", choices=("carbide", "hss"), default="carbide")
    g.add_argument("--safety-factor", type=float, help="on the tool's bending strength (default: by geometry)")


def add_material_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("material (a name or file, or coefficients)")
    m = g.add_mutually_exclusive_group(required=True)
    m.add_argument("--material", metavar="NAME|FILE", help="built-in material name or material .toml")
    m.add_argument("--coeffs", metavar="Ktc=..,Krc=..,Kac=..,Kte=..,Kre=..,Kae=..",
                   help="mechanistic coefficients (N/mm², N/mm)")
    m.add_argument("--kienzle", metavar="kc11=..,mc=..", help="Kienzle kc1.1 (N/mm²) and mc")
    g.add_argument("--model", choices=sorted(plugins("force_models")), help="force model for --material "
                   "(default mechanistic; --coeffs and --kienzle imply theirs)")


def tool_from_args(args: argparse.Namespace) -> Tool:
    if args.tool:
        return load_tool(args.tool, number=args.tool_number)
    if args.diameter is None:
        raise ConfigError("--diameter", None, "give --tool FILE or --diameter MM")
    d, rc = args.diameter, args.corner_radius
    shape = "flat" if rc <= 0 else ("ball" if math.isclose(rc, d / 2) else "bull")
    return Tool(diameter_mm=d, flutes=args.flutes, helix_deg=args.helix, shape=shape,
                corner_radius_mm=rc if shape == "bull" else 0.0, stickout_mm=args.stickout,
                flute_length_mm=args.flute_length, shank_diameter_mm=args.shank, material=args.tool_material)


def _pairs(text: str, flag: str) -> dict[str, float]:
    out = {}
    for part in text.split(","):
        key, sep, value = part.partition("=")
        try:
            out[key.strip()] = float(value)
        except ValueError:
            raise ConfigError(flag, part, "expected name=number pairs separated by commas") from None
        if not sep:
            raise ConfigError(flag, part, "expected name=number")
    return out


def model_from_args(args: argparse.Namespace) -> tuple[Mechanistic | Kienzle, Material | None]:
    """The force model (and the material, when named) chosen on the command line."""
    if args.coeffs:
        k = _pairs(args.coeffs, "--coeffs")
        missing = [n for n in COEF_NAMES if n not in k]
        unknown = [n for n in k if n not in COEF_NAMES]
        if missing or unknown:
            raise ConfigError("--coeffs", args.coeffs, f"needs exactly {', '.join(COEF_NAMES)}")
        return Mechanistic.from_coefficients(**k), None
    if args.kienzle:
        k = _pairs(args.kienzle, "--kienzle")
        if set(k) - {"kc11", "mc", "radial", "axial"} or not {"kc11", "mc"} <= set(k):
            raise ConfigError("--kienzle", args.kienzle, "needs kc11 and mc (optional radial, axial)")
        ratios = {f"{n}_ratio": k[n] for n in ("radial", "axial") if n in k}
        return Kienzle.from_coefficients(k["kc11"], k["mc"], **ratios), None
    material = Material.load(args.material)
    return material.force_model(args.model or "mechanistic"), material


def run(args: argparse.Namespace) -> int:
    tool = tool_from_args(args)
    model, _ = model_from_args(args)
    machine = Machine.load(args.machine) if args.machine else None
    fz = args.fz if args.fz is not None else args.feed / (tool.flutes * args.rpm)
    res = evaluate_cut(tool, model, ae_mm=args.ae, ap_mm=args.ap, rpm=args.rpm, fz_mm=fz, climb=args.climb,
                       machine=machine, safety_factor=args.safety_factor)
    out = {"model": model.name, **res.__dict__, "F_avg_N": list(res.F_avg_N)}
    if args.json:
        print(json_text(out))
    else:
        for key, value in out.items():
            if value is None:
                continue
            if isinstance(value, list):
                value = "[" + ", ".join(f"{v:.4g}" for v in value) + "]"
            elif isinstance(value, float):
                value = f"{value:.6g}"
            print(f"{key:>22}  {value}")
    return 0
