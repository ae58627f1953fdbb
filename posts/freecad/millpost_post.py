"""millpost post-processor for the FreeCAD CAM (Path) workbench.

FreeCAD finds posts named ``<name>_post.py`` on its post search path, so this file appears as the
processor ``millpost``. It posts G-code with FreeCAD's own LinuxCNC post, then hands the program to
``millpost optimize`` through a job.toml (stock box or STEP, tools from the Job's tool controllers)
and returns the optimised program. When millpost is missing or fails, the unoptimised program is
kept and the reason is printed to the report view: the user's output is never lost.

Arguments (Job → Output → Arguments), ours first, every other one goes to the LinuxCNC post:
  --material NAME      millpost material (built-in name or TOML file); default al6061
  --machine NAME       millpost machine (built-in name or TOML file); default benchtop-belt
  --millpost PATH      millpost executable; default: `millpost` on PATH
  --timeout S          seconds millpost may run; default 600
  --no-optimize        post with LinuxCNC only (no job, no millpost)

FreeCAD API relied on (read from FreeCAD's sources, FreeCAD/FreeCAD on GitHub):
  * post module contract: module-level ``TOOLTIP``, ``TOOLTIP_ARGS`` and
    ``export(objectslist, filename, argstring)`` returning the G-code text; FreeCAD 1.0's
    ``Path/Post/Processor.py`` (``WrapperPost.export``) calls it once per output section with
    ``filename="-"`` and writes the returned text itself; 0.2x called it with the real file name.
  * ``Path/Post/scripts/linuxcnc_post.py`` (1.0) and ``PathScripts/post/linuxcnc_post.py`` (0.2x):
    ``export(objectslist, filename, argstring)`` returns the text and writes ``filename`` unless it
    is ``"-"``; unknown arguments make it return None (argparse ``parse_args``), hence we strip ours.
    In the 1.1 development tree it became a class ``Linuxcnc(PostProcessor)`` with ``export()``
    returning ``[(section name, gcode)]``; handled below.
  * ``PathScripts.PathUtils.findParentJob(obj)`` finds the Job of an operation.
  * ``Job.Stock.Shape`` (Part shape; ``BoundBox.XMin..ZMax`` in mm, ``Volume``, ``exportStep``).
  * ``ToolController.ToolNumber`` and ``.Tool``; tool bits (``Path/Tool/Bit.py``) carry
    ``ShapeName`` (1.0+: endmill, ballend, bullnose, chamfer, v-bit, drill, ...) or legacy
    ``BitShape`` ("endmill.fcstd"), and Quantity properties ``Diameter``, ``CuttingEdgeHeight``,
    ``Length``, ``Flutes``, ``CornerRadius``/``FlatRadius``; pre-0.19 tools had ``ToolType`` and
    float ``Diameter``/``CornerRadius``/``CuttingEdgeHeight``.

Everything above ``export`` is plain Python so it can be tested without FreeCAD.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import shlex
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Any, Callable, Iterable, NamedTuple, Optional, Sequence

TOOLTIP = """millpost: post with FreeCAD's LinuxCNC post, then let `millpost optimize` reschedule the
feeds from cutting physics (stock, tools, material, machine). Falls back to the plain LinuxCNC
program when millpost is not installed or refuses the job."""

DEFAULT_MATERIAL = "al6061"
DEFAULT_MACHINE = "benchtop-belt"
BOX_VOLUME_TOLERANCE = 1e-6  # relative: a stock whose volume fills its bounding box is a box

_parser = argparse.ArgumentParser(prog="millpost", add_help=False)
_parser.add_argument("--material", default=DEFAULT_MATERIAL, help=f"millpost material (default {DEFAULT_MATERIAL})")
_parser.add_argument("--machine", default=DEFAULT_MACHINE, help=f"millpost machine (default {DEFAULT_MACHINE})")
_parser.add_argument("--millpost", default="millpost", help="millpost executable (default: millpost on PATH)")
_parser.add_argument("--timeout", type=float, default=600.0, help="seconds millpost may run (default 600)")
_parser.add_argument("--no-optimize", action="store_true", help="post with LinuxCNC only, do not run millpost")

TOOLTIP_ARGS = _parser.format_help() + "\nAll other arguments are passed to the LinuxCNC post.\n"


# NamedTuple, not dataclass: FreeCAD 1.0 executes posts with importlib without registering them in
# sys.modules, where @dataclass fails on string annotations (Python 3.11 dataclasses._is_type).
class Options(NamedTuple):
    """Our arguments; `passthrough` is the argument string left for the LinuxCNC post."""

    material: str
    machine: str
    millpost: str
    timeout_s: float
    optimize: bool
    passthrough: str


class ToolSpec(NamedTuple):
    """One [tools.N] table of job.toml; lengths in mm, None when FreeCAD does not know it."""

    number: int
    diameter_mm: float
    shape: str
    flutes: Optional[int] = None
    corner_radius_mm: Optional[float] = None
    flute_length_mm: Optional[float] = None
    stickout_mm: Optional[float] = None


def parse_args(argstring: str | None) -> Options:
    """Split the Job's PostProcessorArgs into our options and the LinuxCNC post's arguments.

    Raises ValueError on a malformed value of one of our options (FreeCAD shows the message).
    """
    words = shlex.split(argstring or "")
    try:
        ns, rest = _parser.parse_known_args(words)
    except SystemExit as exc:  # argparse exits on a bad value; turn it into a message
        raise ValueError(f"millpost post: bad arguments {argstring!r}") from exc
    if not (ns.timeout > 0):
        raise ValueError(f"millpost post: --timeout must be > 0 s, got {ns.timeout}")
    return Options(ns.material, ns.machine, ns.millpost, ns.timeout, not ns.no_optimize, shlex.join(rest))


# --- tools -----------------------------------------------------------------------------------------

# FreeCAD shape names (ShapeName, legacy BitShape file stem, pre-0.19 ToolType) → job.toml shape.
_SHAPES = {
    "endmill": "flat", "flat": "flat", "squareendmill": "flat", "flatendmill": "flat",
    "ballend": "ball", "ballendmill": "ball", "ball": "ball",
    "bullnose": "bull", "bullnosemill": "bull", "torus": "bull",
    "chamfer": "chamfer", "chamfermill": "chamfer", "v-bit": "chamfer", "vbit": "chamfer",
}


def _mm(value: Any) -> float | None:
    """A FreeCAD length (Quantity with .Value in mm, or a plain number in mm) as float mm."""
    if value is None:
        return None
    value = getattr(value, "Value", value)
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


def shape_of(bit: Any) -> str | None:
    """millpost shape of a FreeCAD tool bit, or None for shapes millpost does not model (drills, ...)."""
    for attr in ("ShapeName", "BitShape", "ShapeType", "ToolType"):
        name = getattr(bit, attr, None)
        if name:
            key = Path(str(name)).stem.lower().replace("_", "").replace(" ", "")
            if key in _SHAPES:
                return _SHAPES[key]
    return None


def tool_spec(number: int, bit: Any) -> ToolSpec:
    """Read a ToolController's Tool into a ToolSpec.

    Raises ValueError when the diameter is missing or the shape is one millpost cannot model.
    Bull-nose corner radius: ``CornerRadius`` when present, else D/2 − ``FlatRadius``. Stick-out:
    FreeCAD records the overall tool ``Length``, not the length out of the holder; it is used as
    the stick-out, which over-estimates deflection (conservative feeds).
    """
    diameter = _mm(getattr(bit, "Diameter", None))
    if diameter is None or diameter <= 0:
        raise ValueError(f"T{number}: tool has no positive Diameter")
    shape = shape_of(bit)
    if shape is None:
        name = getattr(bit, "ShapeName", None) or getattr(bit, "BitShape", None) or getattr(bit, "ToolType", "?")
        raise ValueError(f"T{number}: tool shape {name!r} is not one millpost models (flat, ball, bull, chamfer)")
    flutes = getattr(bit, "Flutes", None)
    flutes = int(flutes) if isinstance(flutes, (int, float)) and flutes >= 1 else None
    corner = None
    if shape == "ball":
        corner = diameter / 2
    elif shape == "bull":
        corner = _mm(getattr(bit, "CornerRadius", None))
        if corner is None and _mm(getattr(bit, "FlatRadius", None)) is not None:
            corner = diameter / 2 - _mm(bit.FlatRadius)
    elif shape == "flat":
        corner = 0.0
    return ToolSpec(number, diameter, shape, flutes, corner,
                    _mm(getattr(bit, "CuttingEdgeHeight", None)), _mm(getattr(bit, "Length", None)))


# --- stock -----------------------------------------------------------------------------------------

def stock_box(bound_box: Any) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """((xmin, ymin, zmin), (xmax, ymax, zmax)) in mm from a FreeCAD BoundBox."""
    lo = (float(bound_box.XMin), float(bound_box.YMin), float(bound_box.ZMin))
    hi = (float(bound_box.XMax), float(bound_box.YMax), float(bound_box.ZMax))
    if not all(h > l for l, h in zip(lo, hi)):
        raise ValueError(f"stock bounding box {lo}..{hi} is empty")
    return lo, hi


def is_box(volume_mm3: float, box: tuple[Sequence[float], Sequence[float]]) -> bool:
    """True when a solid of this volume fills its axis-aligned bounding box (then the box is exact)."""
    lo, hi = box
    box_volume = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2])
    return abs(box_volume - volume_mm3) <= BOX_VOLUME_TOLERANCE * box_volume


# --- job.toml --------------------------------------------------------------------------------------

def _toml_str(text: str) -> str:
    return json.dumps(str(text))  # a JSON string is a valid TOML basic string


def _toml_num(x: float) -> str:
    return repr(float(x))


def job_toml(stock: tuple[Sequence[float], Sequence[float]] | str, tools: Iterable[ToolSpec], program: str,
             material: str, machine: str, output: str | None = None) -> str:
    """The job.toml text of the job format (docs/job-files.md) (paths relative to the job file, lengths in mm).

    `stock` is a box ((xmin, ymin, zmin), (xmax, ymax, zmax)) or the name of a stock file.
    """
    lines = ["# written by the millpost FreeCAD post", f"program = {_toml_str(program)}"]
    if output is not None:
        lines.append(f"output = {_toml_str(output)}")
    lines += ['dialect = "linuxcnc"', f"material = {_toml_str(material)}", f"machine = {_toml_str(machine)}",
              "", "[stock]"]
    if isinstance(stock, str):
        lines.append(f"file = {_toml_str(stock)}")
    else:
        lo, hi = stock
        lines.append(f"box = [[{', '.join(map(_toml_num, lo))}], [{', '.join(map(_toml_num, hi))}]]")
    for t in sorted(tools, key=lambda t: t.number):
        lines += ["", f"[tools.{t.number}]", f"diameter_mm = {_toml_num(t.diameter_mm)}",
                  f"shape = {_toml_str(t.shape)}"]
        if t.flutes is not None:
            lines.append(f"flutes = {t.flutes}")
        for key in ("corner_radius_mm", "flute_length_mm", "stickout_mm"):
            value = getattr(t, key)
            if value is not None:
                lines.append(f"{key} = {_toml_num(value)}")
    return "\n".join(lines) + "\n"


# --- running millpost ------------------------------------------------------------------------------

def run_millpost(executable: str, job_path: Path, out_path: Path, timeout_s: float) -> tuple[bool, str]:
    """Run `millpost optimize JOB -o OUT`. Returns (ok, message); never raises for a failed run."""
    exe = shutil.which(executable) or (executable if os.path.isfile(executable) else None)
    if exe is None:
        return False, f"millpost executable {executable!r} not found (install millpost or pass --millpost PATH)"
    cmd = [exe, "optimize", str(job_path), "-o", str(out_path)]
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return False, f"millpost took longer than {timeout_s:g} s and was stopped"
    except OSError as exc:
        return False, f"could not run {exe}: {exc}"
    report = (done.stdout + done.stderr).strip()
    if done.returncode != 0:
        return False, f"millpost exited with {done.returncode}: {report or 'no message'}"
    return True, report


def optimize(gcode: str, out_path: Path, stock: tuple | None, stock_writer: Callable[[Path], None] | None,
             tools: Sequence[ToolSpec], options: Options) -> tuple[str, bool, str]:
    """Post `gcode` to `out_path` and let millpost optimise it in place.

    Writes OUT (the plain program, so it is never missing), OUT-stem.posted.EXT (millpost's input),
    OUT-stem.job.toml and, when `stock` is None, OUT-stem.stock.step via `stock_writer(path)`; then
    runs `millpost optimize JOB -o OUT` (millpost writes atomically: OUT is the plain program until
    it succeeds). Returns (final G-code, optimised?, message for the user).
    """
    folder, stem, suffix = out_path.parent, out_path.stem, out_path.suffix
    folder.mkdir(parents=True, exist_ok=True)
    out_path.write_text(gcode)
    program = folder / f"{stem}.posted{suffix}"
    program.write_text(gcode)
    if stock is None:
        stock_file = folder / f"{stem}.stock.step"
        stock_writer(stock_file)
        stock = stock_file.name
    job = folder / f"{stem}.job.toml"
    job.write_text(job_toml(stock, tools, program.name, options.material, options.machine, out_path.name))
    ok, message = run_millpost(options.millpost, job, out_path, options.timeout_s)
    if not ok:
        out_path.write_text(gcode)
        return gcode, False, f"millpost: kept the unoptimised program ({message}); job in {job}"
    note = f"millpost: optimised {out_path} from {job}" + (f"\n{message}" if message else "")
    return out_path.read_text(), True, note


# --- FreeCAD side ----------------------------------------------------------------------------------

def _fresh(module: Any) -> Any:
    """A new copy of a post module, executed from its file. FreeCAD's module posts keep their options
    in module globals that ``export`` sets from the arguments and never resets (after one ``--inches``
    post every later one in the session would be G20), so each post gets a module of its own."""
    path = getattr(module, "__file__", None)
    if not path:
        return module
    spec = importlib.util.spec_from_file_location(module.__name__, path)
    fresh = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fresh)
    return fresh


def _linuxcnc_gcode(objectslist: list, argstring: str) -> str:
    """G-code of `objectslist` from FreeCAD's LinuxCNC post (1.0 module, 0.2x module or 1.1 class),
    loaded afresh for this post."""
    try:
        from Path.Post.scripts import linuxcnc_post  # FreeCAD 1.x
    except ImportError:
        from PathScripts.post import linuxcnc_post  # FreeCAD 0.19 – 0.21
    linuxcnc_post = _fresh(linuxcnc_post)
    if hasattr(linuxcnc_post, "export"):
        gcode = linuxcnc_post.export(objectslist, "-", argstring)
        if gcode is None:
            raise ValueError(f"the LinuxCNC post refused the arguments {argstring!r} (see its --help)")
        return gcode
    # 1.1 development tree: class post; it posts the whole Job (all sections) at once.
    post = linuxcnc_post.Linuxcnc(_find_job(objectslist))
    return "".join(g for _, g in post.export() if g)


def _find_job(objectslist: list) -> Any:
    from PathScripts import PathUtils

    for obj in objectslist:
        if hasattr(obj, "InList"):
            job = PathUtils.findParentJob(obj)
            if job is not None:
                return job
    raise ValueError("no Job found for the posted objects")


def _tool_controllers(objectslist: list) -> list:
    """Tool controllers posted in this section: the ones listed and those of the listed operations."""
    seen, out = set(), []
    for obj in objectslist:
        for tc in (obj, getattr(obj, "ToolController", None)):
            if tc is not None and hasattr(tc, "ToolNumber") and hasattr(tc, "Tool") and id(tc) not in seen:
                seen.add(id(tc))
                out.append(tc)
    return out


def export(objectslist, filename, argstring):
    """FreeCAD post entry point: returns the G-code text (and writes `filename` unless it is "-")."""
    import FreeCAD

    console = FreeCAD.Console
    options = parse_args(argstring)
    gcode = _linuxcnc_gcode(objectslist, options.passthrough)
    to_file = bool(filename) and filename != "-"
    if not options.optimize:
        if to_file:
            Path(filename).write_text(gcode)
        return gcode
    try:
        job = _find_job(objectslist)
        tools = {}
        for tc in _tool_controllers(objectslist):
            number = int(tc.ToolNumber)
            try:
                tools.setdefault(number, tool_spec(number, tc.Tool))
            except ValueError as exc:
                console.PrintWarning(f"millpost: {exc}\n")
        shape = job.Stock.Shape
        box = stock_box(shape.BoundBox)
        exact_box = is_box(float(shape.Volume), box)
        # FreeCAD 0.2x names the output file; 1.0 writes the returned text itself, so the job goes
        # to a folder of its own.
        out = Path(filename) if to_file else Path(tempfile.mkdtemp(prefix="millpost-")) / "program.ngc"
        final, optimised, message = optimize(gcode, out, box if exact_box else None,
                                             None if exact_box else (lambda p: shape.exportStep(str(p))),
                                             list(tools.values()), options)
        (console.PrintMessage if optimised else console.PrintWarning)(message + "\n")
        return final
    except Exception as exc:  # never lose the user's program to a millpost-side problem
        console.PrintWarning(f"millpost: kept the unoptimised program ({exc})\n")
        if to_file:
            Path(filename).write_text(gcode)
        return gcode
