"""A job: the program and everything the physics needs about it, from a `job.toml`.

    program = "program.nc"            # required; paths are relative to the job file
    output = "program.millpost.nc"    # optional
    dialect = "fanuc"                 # optional (default: detected)
    material = "al6061"               # built-in name or TOML file
    machine = "benchtop-belt"         # built-in name or TOML file
    [stock]                           # box = [[xmin,ymin,zmin],[xmax,ymax,zmax]] (mm) or file = "x.stl|.step|.py"
    cell_mm = 0.05                    # optional
    [tools.1]                         # by tool number; Tool fields, or file = "t1.toml|.json|.fctb"
    [limits]                          # optional: deflection_mm, feed_max_mm_min,
                                      # tool_safety_factor, ds_mm, model ("mechanistic"|"kienzle")

A folder stands for the `job.toml` inside it.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

from .errors import ConfigError
from .machine import Machine
from .materials import Material
from .registry import plugins
from .gcode import ReaderOptions
from .tools import Tool
from .config import Table
from .tools.library import load_tool, tool_from_table

_LIMIT_KEYS = {"deflection_mm": 0.025, "feed_max_mm_min": None, "tool_safety_factor": None,
               "ds_mm": 0.1, "model": "mechanistic", "jerk_mm_s3": None}


@dataclass
class Job:
    """Everything `optimize` needs. Stock: a box (mm, program frame) or a solid's file."""

    path: Path
    program: Path
    output: Path
    material: Material
    machine: Machine
    tools: dict[int, Tool]
    stock_box: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    stock_file: Path | None = None
    cell_mm: float | None = None
    dialect: str | None = None
    limits: dict = field(default_factory=lambda: dict(_LIMIT_KEYS))

    def reader_options(self) -> ReaderOptions:
        """How to read the program: the job's dialect, and its tools' diameters for cutter compensation."""
        return ReaderOptions(dialect=self.dialect, tool_diameters_mm={n: t.diameter_mm for n, t in self.tools.items()})

    def stock(self):
        """Build the stock height field (mm, program frame)."""
        from . import stock
        if self.stock_file is not None:
            return stock.load(self.stock_file, self.cell_mm)
        return stock.box(*self.stock_box, self.cell_mm)


def load_job(path: str | Path) -> Job:
    """Read and validate a job file (or the job.toml in a folder). Errors name the field and the rule."""
    path = Path(path)
    if path.is_dir():
        path = path / "job.toml"
    if not path.exists():
        raise ConfigError("job", str(path), "no such job file (a job.toml, or a folder holding one)")
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("job", str(path), f"not valid TOML: {exc}", file=str(path)) from None
    base = path.parent
    f = str(path)

    def need(key: str) -> object:
        if key not in data:
            raise ConfigError(key, None, "is required", file=f)
        return data[key]

    unknown = set(data) - {"program", "output", "dialect", "material", "machine", "stock", "tools", "limits"}
    if unknown:
        raise ConfigError(sorted(unknown)[0], data[sorted(unknown)[0]], "unknown field", file=f)
    program = base / str(need("program"))
    if not program.exists():
        raise ConfigError("program", str(program), "file not found", file=f)
    output = base / data["output"] if "output" in data else program.with_name(
        f"{program.stem}.millpost{program.suffix}")
    material = Material.load(_resolve(base, str(need("material"))))
    machine = Machine.load(_resolve(base, str(need("machine"))))
    stock = need("stock")
    if not isinstance(stock, dict):
        raise ConfigError("stock", stock, "must be a table with box = [[...],[...]] or file = ...", file=f)
    box = file = None
    if ("box" in stock) == ("file" in stock):
        raise ConfigError("stock", stock, "give exactly one of box or file", file=f)
    if "box" in stock:
        b = stock["box"]
        ok = (isinstance(b, list) and len(b) == 2 and all(isinstance(r, list) and len(r) == 3 for r in b)
              and all(float(b[1][i]) > float(b[0][i]) for i in range(3)))
        if not ok:
            raise ConfigError("stock.box", b, "[[xmin, ymin, zmin], [xmax, ymax, zmax]] in mm with max > min", file=f)
        box = (tuple(map(float, b[0])), tuple(map(float, b[1])))
    else:
        file = base / stock["file"]
        if not file.exists():
            raise ConfigError("stock.file", str(file), "file not found", file=f)
    cell = stock.get("cell_mm")
    if cell is not None and not (isinstance(cell, (int, float)) and cell > 0):
        raise ConfigError("stock.cell_mm", cell, "must be a positive number (mm)", file=f)
    tools = {}
    for key, spec in dict(need("tools")).items():
        if not str(key).isdigit():
            raise ConfigError(f"tools.{key}", spec, "tool tables are named by tool number, e.g. [tools.1]", file=f)
        n = int(key)
        if not isinstance(spec, dict):
            raise ConfigError(f"tools.{key}", spec, "must be a table", file=f)
        if "file" in spec:
            tools[n] = replace(load_tool(base / spec["file"], number=n), number=n)
        else:
            tools[n] = replace(tool_from_table(Table(spec, f"tools.{key}", f)), number=n)
    limits = dict(_LIMIT_KEYS)
    for key, value in dict(data.get("limits", {})).items():
        if key not in _LIMIT_KEYS:
            raise ConfigError(f"limits.{key}", value, f"unknown limit; known: {', '.join(_LIMIT_KEYS)}", file=f)
        if key == "model":
            if value not in plugins("force_models"):
                raise ConfigError("limits.model", value, f"one of {', '.join(sorted(plugins('force_models')))}",
                                  file=f)
        elif not (isinstance(value, (int, float)) and value >= 0):
            raise ConfigError(f"limits.{key}", value, "must be a number >= 0", file=f)
        limits[key] = value
    return Job(path, program, output, material, machine, tools, box, file, cell, data.get("dialect"), limits)


def _resolve(base: Path, name: str) -> str | Path:
    """A built-in name stays a name; anything that looks like a file is taken relative to the job."""
    return base / name if name.endswith(".toml") or "/" in name else name
