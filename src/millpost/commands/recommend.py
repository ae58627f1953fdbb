"""`millpost recommend`: roughing depth, width, spindle speed and feed for a tool, material and machine."""

from __future__ import annotations

import argparse
import sys
from dataclasses import asdict
from pathlib import Path

from ..errors import ConfigError
from ..files import atomic_path, json_text
from ..heuristics import Limits, Recommendation, recommend, sweep_ae
from ..machine import Machine
from ..materials import STRATEGIES, STRATEGY_KINDS, Material
from ..progress import Bars, stage
from ..registry import plugins
from ..safety import check_outputs
from ..stability.job_frf import frf_from_file
from .calc import add_tool_arguments, tool_from_args

HELP = """\
Heuristics (each limit is named in `binding` when it decides the answer):
  surface_speed / spindle_rpm  rpm within the material's surface-speed window for the tool material
                               (material file: Tungaloy/Amana/Machinery's Handbook tables) and the spindle range
  chip_load     max chip thickness on the material's target with radial chip thinning:
                fz = h_target · D / (2 sqrt(ae (D − ae))) for ae < D/2 (machinecalcs.com; PHYSICS.md §3.1)
  minimum chip  h_max ≥ ratio · edge radius, or the edge rubs (Cheng 2018; PHYSICS.md §3.4)
  deflection    tool deflection under the peak force ≤ --max-deflection (0.025 mm = Ingersoll's 0.001 in)
  breakage      peak force ≤ breaking force / safety factor (bending at holder and flute root; PHYSICS.md §4)
  spindle_power cutting power ≤ the spindle's power at that rpm (constant torque below base speed)
  axis_thrust   feed-direction force within what the X drive can push at that feed (motor, screw, bus voltage)
  machine_feed / feed_max / dynamic_range  feed ≤ the machine's, the user's, and the corner-to-open-pass
                dynamic range (the reference's 100 mm/s)
  max_depth / slot  ap at the flute length, ae at the full diameter
  chatter       with --frf FILE.toml (the tool tip's FRF, as `millpost tap fit --toml` writes it): ap ≤ a_lim,
                the zero-order stability lobes' limiting depth at the cut's speed and immersion (Altintas &
                Budak 1995; the material's K_t, K_r as optimize's chatter check; feed along the FRF's x).
                61 speeds over the window are searched; among cuts within 3 % of the best removal rate those
                at the highest lobe win (a_lim at their speed, counted up to 1.25 × their depth: a speed near a
                stable pocket's top, not on a lobe's flank), then the usual rule.
                The answer gives a_lim and the margin; when no depth searched is stable, which ap would be.
Strategy rules (--strategy, default adaptive; from the material file's [strategies] table, with sources):
  <strategy>_width_min/max  radial width within the strategy's range (adaptive clearing: light, e.g.
                0.15-0.2 D in aluminium; profile 0.1-0.4 D; face 0.67-0.83 D; slot: full width)
  <strategy>_depth_max  slot depth for chip evacuation (1 x D), facing depth (0.1 D)
  ramp / plunge feed  a full-width ramp at the material's ramp angle under the same limits and at most
                ramp_feed_ratio of the cutting feed; plunge: axial chip plunge_fz_ratio of the target,
                end-edge torque within the spindle's, never above the ramp feed
  low-deflection  conventional (up) milling at the width where the mean force normal to the feed is zero
                for this tool, force model and the cut's own feed (a robot-milling strategy: a slow, compliant
                structure follows the mean force, so the wall is not pushed in or out; Altintas' mean-force
                integrals: the radial force pushes off the wall, the tangential pulls in). Climb milling has
                no such width. ap, rpm, fz as for the others; mean_deflection gives the tool and machine
                deflection under the mean force, normal to the wall (≈ 0 here) and along the feed
  any           no strategy rules: the physics alone
Among cuts within 0.5 % of the best removal rate the fastest feed wins (fast, light passes over slow,
heavy ones). Units: mm, rpm, mm/min, mm³/min, N, W. --format fusion|freecad prints the values under the
names of those CAM dialogs (metric).

example:
  millpost recommend --diameter 6 --flutes 3 --material al6061 --machine vmc-small --strategy adaptive --format fusion"""

KEYS = ("ap_mm", "ae_mm", "rpm", "fz_mm", "feed_mm_min", "mrr_mm3_min", "deflection_mm", "power_W")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("recommend", help="roughing ae, ap, rpm and feed from chip-thinning and tool-beam heuristics",
                       description="Choose roughing depth, width, spindle speed and feed for CAM.",
                       epilog=HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_tool_arguments(p)
    p.add_argument("--material", required=True, metavar="NAME|FILE", help="built-in material or material .toml")
    p.add_argument("--machine", required=True, metavar="NAME|FILE", help="built-in machine or machine .toml")
    p.add_argument("--model", choices=sorted(plugins("force_models")), default="mechanistic", help="force model")
    p.add_argument("--strategy", choices=(*STRATEGIES, "any"), default="adaptive",
                   help="roughing strategy whose rules the cut keeps (default adaptive; low-deflection: zero "
                        "mean normal force; any: physics only)")
    lim = p.add_argument_group("limits")
    lim.add_argument("--max-deflection", type=float, default=0.025, metavar="MM", help="tool deflection (mm)")
    lim.add_argument("--feed-min", type=float, default=0.0, metavar="MM_MIN", help="slowest traversal rate")
    lim.add_argument("--feed-max", type=float, metavar="MM_MIN", help="fastest traversal rate (default: machine)")
    lim.add_argument("--dynamic-range", type=float, default=100.0, metavar="MM_S",
                     help="largest feed change between corners and open passes (mm/s, default 100)")
    lim.add_argument("--chip-load", type=float, metavar="MM", help="target max chip thickness (default: material)")
    lim.add_argument("--frf", metavar="FILE.toml", help="the tool tip's FRF ([tools.N.frf], as `millpost tap fit "
                     "--toml` writes it): keep the cut stable (chatter limit)")
    lim.add_argument("--frf-tool", type=int, metavar="N", help="with --frf: the tool table N (default: the only one)")
    fix = p.add_argument_group("fix a variable (the others are chosen)")
    fix.add_argument("--ae", type=float, metavar="MM")
    fix.add_argument("--ap", type=float, metavar="MM")
    fix.add_argument("--rpm", type=float)
    p.add_argument("--format", choices=("table", "fusion", "freecad"), default="table")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument("--sweep", action="store_true", help="best cut at each ae: MRR against ae (CSV, or JSON)")
    p.add_argument("--plot", metavar="FILE.png", help="with --sweep: write MRR against ae as a PNG")
    p.set_defaults(func=run)


def limits_from_args(args: argparse.Namespace) -> Limits:
    if args.frf_tool is not None and not args.frf:
        raise ConfigError("--frf-tool", args.frf_tool, "needs --frf FILE.toml (the file whose tool table it picks)")
    frf = frf_from_file(args.frf, args.frf_tool)[1] if args.frf else None
    return Limits(max_deflection_mm=args.max_deflection, safety_factor=args.safety_factor,
                  feed_min_mm_min=args.feed_min, feed_max_mm_min=args.feed_max,
                  dynamic_range_mm_s=args.dynamic_range, chip_load_mm=args.chip_load, frf=frf)


def as_dict(rec: Recommendation) -> dict:
    d = asdict(rec)
    if rec.a_lim_mm is None:  # no FRF: no chatter entries
        del d["a_lim_mm"]
    else:
        d["chatter_margin"] = rec.a_lim_mm / rec.ap_mm
    d["F_avg_N"] = list(rec.F_avg_N)
    d["binding"] = list(rec.binding)
    return d


def cam_values(rec: Recommendation, fmt: str, diameter_mm: float) -> dict[str, tuple[float, str]]:
    """The recommendation under the field names of a CAM dialog (metric units)."""
    if fmt == "fusion":
        return {"Spindle speed": (rec.rpm, "rpm"), "Surface speed": (rec.vc_m_min, "m/min"),
                "Cutting feedrate": (rec.feed_mm_min, "mm/min"), "Feed per tooth": (rec.fz_mm, "mm"),
                "Ramp feedrate": (rec.ramp_feed_mm_min, "mm/min"), "Plunge feedrate": (rec.plunge_feed_mm_min, "mm/min"),
                "Maximum roughing stepdown": (rec.ap_mm, "mm"), "Optimal load": (rec.ae_mm, "mm"),
                "Maximum stepover": (rec.ae_mm, "mm")}
    return {"Spindle speed": (rec.rpm, "rpm"), "Horizontal feed": (rec.feed_mm_min, "mm/min"),
            "Vertical feed": (rec.plunge_feed_mm_min, "mm/min"), "Step down": (rec.ap_mm, "mm"),
            "Step over": (100.0 * rec.ae_mm / diameter_mm, "%")}


def _write_plot(path: str, recs: list[Recommendation], chosen: Recommendation, title: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot([r.ae_mm for r in recs], [r.mrr_mm3_min / 1000 for r in recs], "o-", label="best cut at this ae")
    ax.plot([chosen.ae_mm], [chosen.mrr_mm3_min / 1000], "r*", ms=14, label="recommended")
    for r in recs:
        ax.annotate(",".join(r.binding), (r.ae_mm, r.mrr_mm3_min / 1000), fontsize=6, rotation=30)
    ax.set_xlabel("radial width ae (mm)")
    ax.set_ylabel("removal rate (cm³/min)")
    ax.set_title(title)
    ax.legend()
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png", dpi=120, bbox_inches="tight")
    finally:
        plt.close(fig)


def run(args: argparse.Namespace) -> int:
    if args.plot:
        check_outputs({"--plot": args.plot}, [p for p in (args.tool, args.material, args.machine)
                                              if p and Path(p).is_file()])
    tool = tool_from_args(args)
    material, machine = Material.load(args.material), Machine.load(args.machine)
    limits = limits_from_args(args)
    if args.plot and not args.sweep:
        raise ConfigError("plot", args.plot, "needs --sweep (the plot is removal rate against ae over the sweep)")
    strategy = None if args.strategy == "any" else args.strategy
    with Bars() as bars:
        with stage(bars, "search"):
            rec = recommend(tool, material, machine, limits, model=args.model, ae_mm=args.ae, ap_mm=args.ap,
                            rpm=args.rpm, strategy=strategy)
        recs = sweep_ae(tool, material, machine, limits, model=args.model, strategy=strategy,
                        progress=bars) if args.sweep else []
    if args.sweep:
        if args.plot:
            _write_plot(args.plot, recs, rec, f"D{tool.diameter_mm:g} {tool.flutes}FL, {material.name}, {machine.name}")
        if args.json:
            print(json_text([as_dict(r) for r in recs]))
        else:
            print(",".join(KEYS) + ",binding")
            for r in recs:
                print(",".join(f"{getattr(r, k):.6g}" for k in KEYS) + "," + " ".join(r.binding))
        return 0
    if args.format != "table":
        values = cam_values(rec, args.format, tool.diameter_mm)
        if args.json:
            print(json_text({k: v for k, (v, _) in values.items()}))
        else:
            for name, (value, unit) in values.items():
                print(f"{name:>26}  {value:.6g} {unit}")
        return 0
    if args.json:
        print(json_text(as_dict(rec)))
        return 0
    out = sys.stdout
    for key in ("ap_mm", "ae_mm", "rpm", "vc_m_min", "fz_mm", "h_max_mm", "chip_target_mm", "feed_mm_min",
                "ramp_feed_mm_min", "plunge_feed_mm_min", "mrr_mm3_min", "F_peak_N", "deflection_mm", "break_ratio", "torque_Nm", "power_W"):
        out.write(f"{key:>18}  {getattr(rec, key):.6g}\n")
    out.write(f"{'binding':>18}  {', '.join(rec.binding) or 'none'}\n")
    if rec.a_lim_mm is not None:
        out.write(f"{'chatter':>18}  a_lim {rec.a_lim_mm:.4g} mm at {rec.rpm:.0f} rpm and this immersion (zero-order "
                  f"lobes): margin a_lim/ap {rec.a_lim_mm / rec.ap_mm:.3g}\n")
    m = rec.mean_deflection
    out.write(f"{'milling':>18}  {'climb' if rec.climb else 'conventional'}, engagement {rec.engagement_deg:.4g}°\n")
    out.write(f"{'mean deflection':>18}  tool {m.tool_normal_mm:+.5f} mm toward the wall, {m.tool_feed_mm:+.5f} mm "
              f"along the feed; machine {m.machine_normal_mm:+.5f}, {m.machine_feed_mm:+.5f} mm\n")
    if rec.strategy:
        r, d = material.strategies, tool.diameter_mm
        lo, hi = r.ae_range_D(rec.strategy)
        depth = f", ap ≤ {r.ap_max_D(rec.strategy):g} D" if r.ap_max_D(rec.strategy) is not None else ""
        width = (f"ae {rec.ae_mm / d:.4g} D where the mean force normal to the feed is zero"
                 if STRATEGY_KINDS[rec.strategy].width == "zero_normal_force"
                 else f"ae {lo:g}–{hi:g} D ({lo * d:.3g}–{hi * d:.3g} mm)")
        out.write(f"{'strategy':>18}  {rec.strategy}: {width}{depth}; "
                  f"ramp ≤ {r.ramp_angle_deg:g}° at ≤ {r.ramp_feed_ratio:g} × feed; plunge f_z ≤ "
                  f"{r.plunge_fz_ratio:g} × chip target (sources: {material.name} material file)\n")
    if rec.ramp_feed_mm_min == 0:
        out.write(f"{'note':>18}  no full-width {material.strategies.ramp_angle_deg:g}° ramp keeps the limits: "
                  "ramp shallower or pre-drill\n")
    out.write(f"{'limit ratios':>18}  " + ", ".join(f"{k} {v:.2f}" for k, v in sorted(rec.ratios.items())) + "\n")
    return 0
