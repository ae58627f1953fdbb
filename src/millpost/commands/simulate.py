"""`millpost simulate JOB|PROGRAM`: step the tools through the stock along a G-code program and write
the per-sample engagement trace (CSV, or NPZ with every axial slice) and optionally the final stock
as STL. JOB is a job folder or job.toml (program, stock and tools from it, see docs/job-files.md); a bare
PROGRAM takes stock and tool from the flags."""

from __future__ import annotations

import argparse
from dataclasses import replace
import sys
import time
from pathlib import Path

import numpy as np

from ..errors import ConfigError, MillpostError
from ..files import atomic_path, json_text, write_csv
from ..progress import Bars
from ..safety import check_outputs
from . import add_allow_argument
from ..tools.cutter import SHAPES

TRACE_COLUMNS = ("sample", "s_mm", "x_mm", "y_mm", "z_mm", "move", "line", "kind", "tool", "feed_mm_min",
                 "volume_mm3", "area_mm2", "ap_mm", "ae_mm", "phi_st_deg", "phi_ex_deg", "engaged_deg", "descending")
TRACE_FORMATS = {"sample": "%d", "move": "%d", "line": "%d", "kind": "%d", "tool": "%d", "descending": "%d",
                 "s_mm": "%.4f", "x_mm": "%.4f", "y_mm": "%.4f", "z_mm": "%.4f", "ap_mm": "%.5g", "ae_mm": "%.5g",
                 "phi_st_deg": "%.4f", "phi_ex_deg": "%.4f", "engaged_deg": "%.4f"}


def register(subparsers) -> None:
    p = subparsers.add_parser("simulate", help="engagement of the tools along a program through the stock",
                              description=__doc__, epilog="example:\n  millpost simulate sample_jobs/slotting "
                                                          "--trace slotting.csv --stock-stl slotting.stl")
    p.add_argument("target", metavar="JOB|PROGRAM", help="job folder or job.toml, or a G-code file")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--stock-box", metavar="X0,Y0,Z0,X1,Y1,Z1", help="block stock corners (mm; PROGRAM only)")
    src.add_argument("--stock", metavar="FILE", help="stock solid: .stl, .step/.stp, or .py defining `stock` "
                                                     "(PROGRAM only)")
    p.add_argument("--cell", type=float, default=None, help="stock cell size in mm (default: the job's, else "
                                                            "0.025 where memory allows)")
    p.add_argument("--tool-diameter", type=float, help="cutter diameter (mm; PROGRAM only: one tool for all)")
    p.add_argument("--shape", default="flat", choices=SHAPES)
    p.add_argument("--corner-radius", type=float, default=0.0, help="bull nose corner radius (mm)")
    p.add_argument("--tip-angle", type=float, default=None,
                   help="chamfer/V included angle (default 90) or drill point angle (default 118), degrees")
    p.add_argument("--tip-diameter", type=float, default=0.0, help="chamfer flat tip diameter (mm)")
    p.add_argument("--flute-length", type=float, default=None, help="cutting length (mm)")
    p.add_argument("--step", type=float, default=None, help="sample spacing along the path (mm; default: the "
                                                            "job's ds_mm, else 0.1)")
    p.add_argument("--slices", type=int, default=8, help="axial slices per sample")
    p.add_argument("--trace", required=True, help="output trace: .csv (per sample) or .npz (all arrays)")
    p.add_argument("--stock-stl", help="write the final stock as STL")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    add_allow_argument(p)
    p.set_defaults(func=run)


def _box(text: str) -> tuple[list[float], list[float]]:
    try:
        v = [float(t) for t in text.split(",")]
    except ValueError:
        v = []
    if len(v) != 6:
        raise ConfigError("stock-box", text, "needs six numbers X0,Y0,Z0,X1,Y1,Z1 (mm)")
    return v[:3], v[3:]


def _inputs(args: argparse.Namespace):
    """(program path, stock, tools by number or one tool, step mm, dialect, gates allowed, input files)
    from a job or the flags. Outputs are checked before the stock is built."""
    from .. import stock as stk
    from ..job import load_job
    from ..tools import Tool

    target = Path(args.target)
    if target.is_dir() or target.suffix == ".toml":
        for flag in ("stock_box", "stock", "tool_diameter"):
            if getattr(args, flag) is not None:
                raise ConfigError(flag.replace("_", "-"), getattr(args, flag),
                                  "comes from the job file; give it only with a bare PROGRAM")
        job = load_job(target)
        check_outputs({"--trace": args.trace, "--stock-stl": args.stock_stl}, job.inputs)
        if args.cell is not None:
            job = replace(job, cell_mm=args.cell)
        step = args.step if args.step is not None else job.settings.ds_mm
        return job.program, job.stock(), dict(job.tools), step, job.dialect, job.allow
    if args.stock_box is None and args.stock is None:
        raise ConfigError("stock", None, "a bare PROGRAM needs --stock-box or --stock (or give a job)")
    if args.tool_diameter is None:
        raise ConfigError("tool-diameter", None, "a bare PROGRAM needs the tool (or give a job)")
    check_outputs({"--trace": args.trace, "--stock-stl": args.stock_stl},
                  [target] + ([Path(args.stock)] if args.stock else []))
    tool = Tool(args.tool_diameter, shape=args.shape, corner_radius_mm=args.corner_radius,
                tip_angle_deg=args.tip_angle, tip_diameter_mm=args.tip_diameter, flute_length_mm=args.flute_length)
    if args.stock_box:
        stock = stk.box(*_box(args.stock_box), args.cell)
    else:
        if not Path(args.stock).is_file():
            raise MillpostError(f"{args.stock}: no such stock file")
        stock = stk.load(args.stock, args.cell)
    return target, stock, tool, args.step if args.step is not None else 0.1, None, frozenset()


def write_trace(path: str, samples, eng) -> None:
    """Per-sample trace. CSV: one row per sample with the outermost arc over all slices (degrees);
    NPZ: every Engagement array (per slice too) plus the sample positions."""
    if path.endswith(".npz"):
        arrays = {k: v for k, v in vars(eng).items() if isinstance(v, np.ndarray)}
        arrays.update(s_mm=samples.s_mm, xyz_mm=samples.xyz_mm, kind=samples.kind, tool=samples.tool,
                      feed_mm_min=samples.feed_mm_s * 60.0)

        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
        return
    with np.errstate(all="ignore"):
        st = np.degrees(np.nanmin(np.where(np.isnan(eng.phi_st), np.inf, eng.phi_st), axis=1))
        ex = np.degrees(np.nanmax(np.where(np.isnan(eng.phi_ex), -np.inf, eng.phi_ex), axis=1))
    none = ~np.isfinite(st)
    st[none], ex[none] = np.nan, np.nan
    engaged = np.degrees(eng.arc_rad.max(axis=1))
    columns = dict(zip(TRACE_COLUMNS, [
        np.arange(len(samples)), samples.s_mm, *samples.xyz_mm.T, eng.move, eng.line, samples.kind, samples.tool,
        samples.feed_mm_s * 60.0, eng.volume_mm3, eng.area_mm2, eng.ap_mm, eng.ae_mm, st, ex, engaged,
        eng.descending.astype(int)]))
    write_csv(path, columns, TRACE_FORMATS)


def run(args: argparse.Namespace) -> int:
    from ..engagement import engage
    from ..gcode import ReaderOptions, read_program
    from ..settings import RANGES

    lo, hi = RANGES["ds_mm"]
    if args.step is not None and not lo <= args.step <= hi:
        raise ConfigError("step", args.step, f"must be in [{lo:g}, {hi:g}] mm")
    if not 1 <= args.slices <= 64:
        raise ConfigError("slices", args.slices, "must be in 1..64")
    t0 = time.perf_counter()
    program_path, stock, tools, step, dialect, allow = _inputs(args)
    diameters = {n: t.diameter_mm for n, t in tools.items()} if isinstance(tools, dict) else {}  # for G41/G42
    program = read_program(program_path, ReaderOptions.for_tools(diameters, dialect))
    v0 = stock.volume_mm3()
    with Bars() as bars:
        samples, eng, notes = engage(program, stock, tools, step, allow | set(args.allow), stage="simulate",
                                     slices=args.slices, progress=bars)
    write_trace(args.trace, samples, eng)
    if args.stock_stl:
        stock.export_stl(args.stock_stl)
    cutting = eng.volume_mm3 > 0
    summary = {
        "program": str(program_path), "samples": len(samples), "cell_mm": stock.cell_mm,
        "removed_mm3": round(v0 - stock.volume_mm3(), 4),
        "cutting_samples": int(cutting.sum()),
        "max_ap_mm": round(float(eng.ap_mm.max(initial=0.0)), 4),
        "max_ae_mm": round(float(eng.ae_mm.max(initial=0.0)), 4),
        "max_area_mm2": round(float(eng.area_mm2.max(initial=0.0)), 4),
        "trace": args.trace, "stock_stl": args.stock_stl, "seconds": round(time.perf_counter() - t0, 2),
        "notes": program.notes + notes,
    }
    if args.json:
        print(json_text(summary))
    else:
        print(f"{summary['samples']} samples ({summary['cutting_samples']} cutting) at {stock.cell_mm * 1000:g} µm: "
              f"removed {summary['removed_mm3']:.1f} mm³, max ap {summary['max_ap_mm']:.3f} mm, "
              f"max ae {summary['max_ae_mm']:.3f} mm; trace {args.trace} ({summary['seconds']} s)")
        for note in program.notes + notes:
            print(f"note: {note}", file=sys.stderr)
    return 0
