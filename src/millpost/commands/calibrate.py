"""`millpost calibrate plan|fit`: calibration programs for a tool, material and machine, and fitted cutting
coefficients and machine constants from their logs or from a table of steady cuts."""

from __future__ import annotations

import argparse
import datetime
import json
import sys
from pathlib import Path

import numpy as np

from ..calibrate.coefficients import PRIOR_SPREAD, fit_cuts, material_dict
from ..calibrate.cuts import read_cuts
from ..calibrate.logfit import fit_log
from ..calibrate.machine_fit import fit_stiffness
from ..calibrate.plan import PlanRequest, make_plan
from ..config import dump_toml, load_description
from ..errors import ConfigError, MillpostError
from ..calibrate.descriptions import job_ref, machine_dict
from ..files import write_atomic
from ..gcode import dialects
from ..job import load_job
from ..machine import Machine
from ..materials import Material
from ..measure import read_log
from ..measure.alignment import TOLERANCE_MM
from .calc import add_tool_arguments, tool_from_args

EXAMPLE_PLAN = ("millpost calibrate plan --diameter 6 --flutes 3 --material al6061 --machine vmc-small "
                "--stock-box 0,0,-20,80,100,0 --rpm 8000 --fz 0.02,0.05,0.08 --ap 1 --idle-rpm 3000,8000 -o cal")
EXAMPLE_FIT = "millpost calibrate fit --log spindle.csv --plan cal --json fit.json -o al6061-mine.toml"

HELP_PLAN = """\
Writes into OUT: calibration.nc (the program, in --dialect), plan.csv (per planned line: kind idle/slot/
step/axis, the tool, ae, ap, fz, rpm, feed, start and end) and job.toml (program, material, machine, stock,
tool) for `calibrate fit --plan OUT` and for `optimize`. Run it on the machine while logging (a table
dynamometer, `millpost log` for the VFD, the controller's axis currents), then fit."""

HELP_FIT = """\
--cuts CUTS.csv: one row per steady cut, columns diameter_mm,flutes,helix_deg,ae_mm,ap_mm,fz_mm,rpm
[,climb] and any of fx_N,fy_N,fz_N (mean force on the tool, cut along +X, as `calc` prints) and
spindle_power_W (cutting power). --log LOG --plan DIR: a log (docs/logs.md: log format) of the program of
`calibrate plan`, aligned to it; fits what the log holds (forces and/or spindle power: cutting
coefficients; spindle power in the idle dwells: no-load power; spindle current: its K_t; ix_A/iy_A/iz_A:
axis mass and friction). --stiffness LOG --axis x: stiffness from force (f<axis>_N) vs displacement
(<axis>_mm) of a push test. -o writes the base material with the fitted coefficients, --machine-out the
base machine with the fitted constants; both with the fit's provenance in `source`."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("calibrate", help="calibration programs, and coefficients fitted from measurements",
                       description=__doc__, epilog=f"example:\n  {EXAMPLE_PLAN}\n  {EXAMPLE_FIT}")
    s = p.add_subparsers(dest="calibrate_command", required=True, metavar="plan|fit")
    plan = s.add_parser("plan", help="write a calibration program and its plan", description=HELP_PLAN,
                        epilog=f"example:\n  {EXAMPLE_PLAN}", formatter_class=argparse.RawDescriptionHelpFormatter)
    add_tool_arguments(plan)
    plan.add_argument("--material", required=True, metavar="NAME|FILE", help="material (predicts the loads)")
    plan.add_argument("--machine", required=True, metavar="NAME|FILE", help="machine (spindle, axes)")
    plan.add_argument("--stock-box", required=True, metavar="X0,Y0,Z0,X1,Y1,Z1", help="stock block corners (mm)")
    plan.add_argument("--rpm", type=float, required=True, help="spindle speed of the cuts (rpm)")
    plan.add_argument("--fz", default="", metavar="MM,...", help="slot series feeds per tooth (mm)")
    plan.add_argument("--ap", default="", metavar="MM,...", help="slot series depths (mm)")
    plan.add_argument("--step-fz", type=float, metavar="MM", help="stepped passes' feed per tooth (default: the "
                                                                   "material's mid chip load)")
    plan.add_argument("--margin", type=float, default=0.8, help="stepped passes stop before this fraction of a "
                                                                "predicted limit (default 0.8)")
    plan.add_argument("--deflection", type=float, default=0.025, metavar="MM", help="tool deflection limit (mm)")
    plan.add_argument("--idle-rpm", default="", metavar="RPM,...", help="spindle speeds to run in the air (no-load)")
    plan.add_argument("--no-steps", action="store_true", help="no stepped engagement")
    plan.add_argument("--no-axis-test", action="store_true", help="no axis strokes")
    plan.add_argument("--dialect", default="linuxcnc", choices=dialects.names(), help="controller dialect")
    plan.add_argument("-o", "--output", required=True, metavar="DIR", help="folder to write into")
    plan.set_defaults(func=run_plan)

    fit = s.add_parser("fit", help="fit coefficients from a log or a table of steady cuts", description=HELP_FIT,
                       epilog=f"example:\n  {EXAMPLE_FIT}", formatter_class=argparse.RawDescriptionHelpFormatter)
    src = fit.add_mutually_exclusive_group(required=True)
    src.add_argument("--cuts", metavar="CUTS.csv", help="table of steady cuts")
    src.add_argument("--log", metavar="LOG", help="log (CSV/NPZ) of a calibration program (with --plan)")
    src.add_argument("--stiffness", metavar="LOG", help="push-test log: force vs displacement (with --axis)")
    fit.add_argument("--plan", metavar="DIR|JOB", help="the folder `calibrate plan` wrote, or any job (its steady "
                                                        "cuts are fitted)")
    fit.add_argument("--axis", choices=("x", "y", "z"), help="axis of the push test")
    fit.add_argument("--material", metavar="NAME|FILE", help="base material (default: the plan's job's)")
    fit.add_argument("--machine", metavar="NAME|FILE", help="base machine (default: the plan's job's)")
    fit.add_argument("--prior-spread", type=float, default=PRIOR_SPREAD, metavar="FRACTION",
                     help=f"relative 1σ of the base material's coefficients, the prior the measurements update "
                          f"(default {PRIOR_SPREAD}; inf: no prior, the data alone must determine every coefficient)")
    fit.add_argument("--position-tolerance", type=float, default=TOLERANCE_MM, metavar="MM",
                     help=f"log rows farther than this from the program's path are off it; a log with more than "
                          f"1 %% of such rows is refused (default {TOLERANCE_MM} mm)")
    fit.add_argument("--json", metavar="OUT", help="write the results as JSON ('-' for stdout)")
    fit.add_argument("-o", "--output", metavar="MATERIAL.toml", help="write the fitted material")
    fit.add_argument("--machine-out", metavar="MACHINE.toml", help="write the fitted machine")
    fit.set_defaults(func=run_fit)


def _numbers(text: str, what: str) -> tuple[float, ...]:
    try:
        values = tuple(float(t) for t in text.split(",") if t.strip())
    except ValueError:
        raise ConfigError(what, text, "comma-separated numbers") from None
    if any(v <= 0 for v in values):
        raise ConfigError(what, text, "numbers > 0")
    return values


def run_plan(args: argparse.Namespace) -> int:
    tool = tool_from_args(args)
    material, machine = Material.load(args.material), Machine.load(args.machine)
    box = _box(args.stock_box)
    request = PlanRequest(stock=box, rpm=args.rpm, slot_fz_mm=_numbers(args.fz, "fz"),
                          slot_ap_mm=_numbers(args.ap, "ap"),
                          step_fz_mm=args.step_fz, steps=not args.no_steps, margin=args.margin,
                          deflection_mm=args.deflection, axis_test=not args.no_axis_test,
                          idle_rpm=_numbers(args.idle_rpm, "idle-rpm"))
    plan = make_plan(tool, material, machine, request, dialect=args.dialect)
    ref = lambda a: str(Path(a).resolve()) if Path(a).suffix == ".toml" else a  # noqa: E731
    folder = plan.write(args.output, tool, ref(args.material), ref(args.machine), box)
    kinds = {k: sum(m.kind == k for m in plan.moves) for k in ("idle", "slot", "step", "axis")}
    for note in plan.notes:
        print(f"millpost: note: {note}", file=sys.stderr)
    print(f"millpost: wrote {folder}/calibration.nc ({plan.dialect}), plan.csv ("
          + ", ".join(f"{n} {k}" for k, n in kinds.items() if n) + "), job.toml", file=sys.stderr)
    return 0


def _box(text: str):
    try:
        v = [float(t) for t in text.split(",")]
    except ValueError:
        v = []
    if len(v) != 6 or not all(v[i + 3] > v[i] for i in range(3)):
        raise ConfigError("stock-box", text, "six numbers X0,Y0,Z0,X1,Y1,Z1 (mm) with max > min")
    return (tuple(v[:3]), tuple(v[3:]))


def run_fit(args: argparse.Namespace) -> int:
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    result: dict = {}
    if args.stiffness:
        return _fit_stiffness(args, stamp)
    if args.cuts:
        base = Material.load(args.material) if args.material else None
        fit = fit_cuts(read_cuts(args.cuts), base, prior_spread=args.prior_spread)
        source = args.cuts
        machine_updates: dict = {}
    else:
        if not args.plan:
            raise MillpostError("--log needs --plan DIR|JOB (the folder `calibrate plan` wrote, or a job)")
        job = load_job(args.plan)
        base = Material.load(args.material) if args.material else job.material
        lf = fit_log(args.plan, read_log(args.log), base, prior_spread=args.prior_spread,
                     tolerance_mm=args.position_tolerance)
        fit, source = lf.cutting, args.log
        result["alignment"] = lf.alignment.summary()
        result["notes"] = lf.notes
        machine = Machine.load(args.machine) if args.machine else job.machine
        machine_updates = {"spindle": dict(lf.idle)} if lf.idle else {}
        axes_out = {}
        for name, drive in lf.axes.items():
            consts = drive.axis_constants(machine.axes[name])
            axes_out[name] = {"r2": drive.r2_, "coef_A": dict(zip(drive.terms, drive.coef_.tolist())),
                              "intercept_A": drive.intercept_, **consts}
            machine_updates.setdefault("axes", {})[name] = {k: v for k, v in consts.items() if v > 0}
            result["notes"] += [f"axis {name}: fitted {k} = {v:.4g} is not positive; the base machine's value is kept"
                                for k, v in consts.items() if v <= 0]
        result["axes"] = axes_out
        result["spindle"] = lf.idle
    provenance = f"fitted by millpost calibrate fit from {source} on {stamp}"
    if fit is not None:
        notes = result.get("notes", [])
        result.update(fit.as_dict())
        result["notes"] = notes + result["notes"]
        print(fit.table())
    for name, a in result.get("axes", {}).items():
        print(f"axis {name}: " + ", ".join(f"{k} {v:.4g}" for k, v in a.items() if isinstance(v, float) and k != "r2")
              + f" (R² {a['r2']:.4f})")
    if result.get("spindle"):
        print("spindle: " + ", ".join(f"{k} {v}" for k, v in result["spindle"].items()))
    for note in result.get("notes", []):
        print(f"millpost: note: {note}", file=sys.stderr)
    files = []  # (path, text): every output checked before any is written (a refusal writes nothing)
    if args.output:
        if fit is None:
            raise MillpostError("no cutting coefficients were fitted: nothing to write to " + args.output)
        base_ref = args.material or (job_ref(args.plan, "material") if args.log else None)
        if base_ref is None:
            raise MillpostError("-o needs --material (the base material whose other data the file keeps)")
        data, _ = load_description("materials", base_ref)
        out = material_dict(data, fit, provenance)
        Material.from_dict(out)  # refuse to write what optimize would not read
        files.append((args.output, dump_toml(out)))
    if args.machine_out:
        if not machine_updates:
            raise MillpostError("no machine constants were fitted: nothing to write to " + args.machine_out)
        files.append((args.machine_out, dump_toml(machine_dict(args.machine or job_ref(args.plan, "machine"),
                                                                machine_updates, provenance))))
    _write_json(args.json, result)
    for path, text in files:
        write_atomic(path, text)
        print(f"millpost: wrote {path}", file=sys.stderr)
    return 0


def _fit_stiffness(args, stamp: str) -> int:
    if not args.axis:
        raise MillpostError("--stiffness needs --axis x|y|z")
    log = read_log(args.stiffness)
    f, x = f"f{args.axis}_N", f"{args.axis}_mm"
    for c in (f, x):
        if not log.has(c):
            raise MillpostError(f"{args.stiffness}: the push test needs columns {f} and {x}")
    st = fit_stiffness(log[f], log[x])
    print(f"stiffness {args.axis}: {st.k_N_per_mm:.5g} ± {st.stderr_N_per_mm:.3g} N/mm (R² {st.r2:.4f}, "
          f"{st.samples} loading samples)")
    _write_json(args.json, {"stiffness": {"axis": args.axis, "k_N_per_mm": st.k_N_per_mm,
                                          "stderr_N_per_mm": st.stderr_N_per_mm, "r2": st.r2,
                                          "samples": st.samples}})
    if args.machine_out:
        if not args.machine:
            raise MillpostError("--machine-out needs --machine (the base machine)")
        updates = {"axes": {args.axis: {"stiffness_N_per_mm": st.k_N_per_mm}}}
        provenance = f"fitted by millpost calibrate fit from {args.stiffness} on {stamp}"
        write_atomic(args.machine_out, dump_toml(machine_dict(args.machine, updates, provenance)))
        print(f"millpost: wrote {args.machine_out}", file=sys.stderr)
    return 0


def _write_json(where: str | None, result: dict) -> None:
    if not where:
        return
    text = json.dumps(result, indent=2, default=lambda o: o.tolist() if isinstance(o, np.ndarray) else float(o))
    if where == "-":
        print(text)
    else:
        write_atomic(where, text + "\n")
