"""A job: the program and everything the physics needs about it, from a `job.toml`.

    program = "program.nc"            # required; paths are relative to the job file
    output = "program.millpost.nc"    # optional
    dialect = "fanuc"                 # optional (default: detected)
    material = "al6061"               # built-in name or TOML file
    machine = "benchtop-belt"         # built-in name or TOML file
    spindle_rpm = 18000               # optional: a spindle switched by hand turns at this speed (rpm)
                                      # where the program leaves it off (with --allow spindle-off;
                                      # without it: the program's S word in force)
    [stock]                           # box = [[xmin,ymin,zmin],[xmax,ymax,zmax]] (mm) or file = "x.stl|.step|.py"
    cell_mm = 0.05                    # optional
    [tools.1]                         # by tool number; Tool fields, or file = "t1.toml|.json|.fctb"
    [limits]                          # optional: deflection_mm, feed_max_mm_min,
                                      # tool_safety_factor, ds_mm, model ("mechanistic"|"kienzle"),
                                      # plunge_feed_max_mm_min (cap on the feed of moves going down
                                      # into material: plunges, drilling, ramps),
                                      # plunge_raise_max (those moves at most this × their
                                      # programmed feed, 2),
                                      # lower ("hard"|"all"), feed_step (relative, 0.05),
                                      # solver ("auto"|"clarabel": Clarabel on every segment),
                                      # rpm ("programmed"|"optimize": choose S per operation),
                                      # air_clearance_mm (3: feed moves that cut nothing within it
                                      # of the stock keep their programmed feed),
                                      # trust_cut_space (false: a move going down below the stock's
                                      # top keeps the plunge rules where the program cut before),
                                      # air_feed_max_mm_min (cap on feed moves through cut space
                                      # below the stock's top; default the machine's maximum),
                                      # slower_max (1.25: refuse an optimized program slower than
                                      # this × the programmed one, unless --allow slower)
    [safety]                          # optional: allow = ["no-cut", ...] (see millpost.safety)

A folder stands for the `job.toml` inside it. Every number must be finite and inside its stated
range (`LIMIT_RANGES`, stock sizes): a value outside is a slip, refused naming the file and the key.
"""

from __future__ import annotations

import math
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

_LIMIT_KEYS = {"deflection_mm": None, "feed_max_mm_min": None, "tool_safety_factor": None,
               "ds_mm": 0.1, "model": "mechanistic", "jerk_mm_s3": None, "plunge_feed_max_mm_min": None,
               "plunge_raise_max": 2.0, "lower": "hard", "feed_step": 0.05, "solver": "auto", "rpm": "programmed",
               "air_clearance_mm": 3.0, "trust_cut_space": False, "air_feed_max_mm_min": None, "slower_max": 1.25}
_CHOICES = {"lower": ("hard", "all"), "solver": ("auto", "clarabel"), "rpm": ("programmed", "optimize")}
# the stated range of each numeric limit, both ends included: outside it a value is a slip (a unit or
# a digit wrong), not a wish. ds_mm below 1 µm or above 5 mm cannot resolve a cut; a deflection
# budget of 5 mm or a feed of 1000 m/min is no limit at all.
LIMIT_RANGES = {"deflection_mm": (1e-4, 5.0), "feed_max_mm_min": (1.0, 1e6), "tool_safety_factor": (1.0, 100.0),
                "ds_mm": (1e-3, 5.0), "jerk_mm_s3": (1.0, 1e9), "plunge_feed_max_mm_min": (1.0, 1e6),
                "plunge_raise_max": (1.0, 100.0), "air_clearance_mm": (0.0, 100.0), "air_feed_max_mm_min": (1.0, 1e6),
                "slower_max": (1.0, 100.0)}
CELL_RANGE_MM = (1e-3, 10.0)
SPINDLE_RPM_RANGE = (1.0, 2e5)  # rpm: no milling spindle turns faster than 200 000 rpm
STOCK_SPAN_MM = 1e5  # no stock corner is 100 m from the work zero


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
    allow: frozenset[str] = frozenset()  # safety gates the user overrides ([safety] allow)
    inputs: tuple[Path, ...] = ()  # every file the job reads (outputs must not replace one)
    spindle_rpm: float | None = None  # a spindle switched by hand: its speed (rpm) where the program has none

    def reader_options(self) -> ReaderOptions:
        """How to read the program: the job's dialect, its tools' diameters for cutter compensation, and
        its only tool (when it describes one) loaded before any T word."""
        return ReaderOptions.for_tools({n: t.diameter_mm for n, t in self.tools.items()}, self.dialect)

    def feed_key_mm_s(self, key: str) -> float | None:
        """A feed key of [limits] (`..._mm_min`, as the job file writes it) in mm/s; None where unset."""
        value = self.limits[key]
        return None if value is None else float(value) / 60.0

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

    unknown = set(data) - {"program", "output", "dialect", "material", "machine", "stock", "tools", "limits",
                           "safety", "spindle_rpm"}
    if unknown:
        raise ConfigError(sorted(unknown)[0], data[sorted(unknown)[0]], "unknown field", file=f)
    program = base / str(need("program"))
    if not program.exists():
        raise ConfigError("program", str(program), "file not found", file=f)
    output = base / str(data["output"]) if "output" in data else program.with_name(
        f"{program.stem}.millpost{program.suffix}")
    inputs = [path, program]
    described = []
    for key in ("material", "machine"):
        where = _resolve(base, str(need(key)))
        if isinstance(where, Path):
            inputs.append(where)
        described.append(where)
    try:
        material, machine = Material.load(described[0]), Machine.load(described[1])
    except ConfigError as exc:
        if exc.file:
            raise
        raise ConfigError(exc.field, exc.value, exc.rule, file=f) from None
    stock = need("stock")
    if not isinstance(stock, dict):
        raise ConfigError("stock", stock, "must be a table with box = [[...],[...]] or file = ...", file=f)
    box = file = None
    if ("box" in stock) == ("file" in stock):
        raise ConfigError("stock", stock, "give exactly one of box or file", file=f)
    if "box" in stock:
        b = stock["box"]
        ok = (isinstance(b, list) and len(b) == 2 and all(isinstance(r, list) and len(r) == 3 for r in b)
              and all(_number(v) and abs(v) <= STOCK_SPAN_MM for r in b for v in r)
              and all(float(b[1][i]) > float(b[0][i]) for i in range(3)))
        if not ok:
            raise ConfigError("stock.box", b, "[[xmin, ymin, zmin], [xmax, ymax, zmax]] in mm with max > min, "
                              f"finite numbers within {STOCK_SPAN_MM:g} mm of the work zero", file=f)
        box = (tuple(map(float, b[0])), tuple(map(float, b[1])))
    else:
        file = base / str(stock["file"])
        if not file.is_file():
            raise ConfigError("stock.file", str(file), "file not found", file=f)
        inputs.append(file)
    cell = stock.get("cell_mm")
    if cell is not None and not (_number(cell) and CELL_RANGE_MM[0] <= cell <= CELL_RANGE_MM[1]):
        raise ConfigError("stock.cell_mm", cell, f"must be a number in [{CELL_RANGE_MM[0]:g}, {CELL_RANGE_MM[1]:g}] mm",
                          file=f)
    tools = {}
    for key, spec in _table(need("tools"), "tools", f).items():
        if not str(key).isdigit():
            raise ConfigError(f"tools.{key}", spec, "tool tables are named by tool number (T word), e.g. [tools.1]; "
                              "for a program without T words, one table with any number is the tool loaded",
                              file=f)
        n = int(key)
        if not isinstance(spec, dict):
            raise ConfigError(f"tools.{key}", spec, "must be a table", file=f)
        try:
            if "file" in spec:
                inputs.append(base / str(spec["file"]))
                tools[n] = replace(load_tool(base / str(spec["file"]), number=n), number=n)
            else:
                tools[n] = replace(tool_from_table(Table(spec, f"tools.{key}", f)), number=n)
        except ConfigError as exc:
            if exc.file:
                raise
            raise ConfigError(f"tools.{key}.{exc.field}", exc.value, exc.rule, file=f) from None
    limits = dict(_LIMIT_KEYS)
    for key, value in _table(data.get("limits", {}), "limits", f).items():
        if key not in _LIMIT_KEYS:
            raise ConfigError(f"limits.{key}", value, f"unknown limit; known: {', '.join(_LIMIT_KEYS)}", file=f)
        if key == "model":
            if value not in plugins("force_models"):
                raise ConfigError("limits.model", value, f"one of {', '.join(sorted(plugins('force_models')))}",
                                  file=f)
        elif key in _CHOICES:
            if value not in _CHOICES[key]:
                raise ConfigError(f"limits.{key}", value, " or ".join(_CHOICES[key]), file=f)
        elif key == "trust_cut_space":
            if not isinstance(value, bool):
                raise ConfigError("limits.trust_cut_space", value, "must be true or false", file=f)
        elif key == "feed_step":
            if not (_number(value) and 0 <= value <= 1):
                raise ConfigError("limits.feed_step", value, "must be a number in [0, 1] (relative)", file=f)
        else:
            lo, hi = LIMIT_RANGES[key]
            if not (_number(value) and lo <= value <= hi):
                raise ConfigError(f"limits.{key}", value, f"must be a number in [{lo:g}, {hi:g}]", file=f)
        limits[key] = value
    spindle_rpm = data.get("spindle_rpm")
    lo, hi = SPINDLE_RPM_RANGE
    if spindle_rpm is not None and not (_number(spindle_rpm) and lo <= spindle_rpm <= hi):
        raise ConfigError("spindle_rpm", spindle_rpm, f"must be a number in [{lo:g}, {hi:g}] rpm", file=f)
    dialect = data.get("dialect")
    if dialect is not None:
        from .errors import MillpostError
        from .gcode import dialects
        try:
            if not isinstance(dialect, str):
                raise MillpostError("not a name")
            dialects.get(dialect)
        except MillpostError:
            raise ConfigError("dialect", dialect, f"one of {', '.join(dialects.names())} (haas = fanuc)",
                              file=f) from None
    return Job(path, program, output, material, machine, tools, box, file, cell, dialect, limits,
               _allowed(data.get("safety", {}), f), tuple(inputs),
               None if spindle_rpm is None else float(spindle_rpm))


def _table(value: object, key: str, f: str) -> dict:
    if not isinstance(value, dict):
        raise ConfigError(key, value, "must be a table", file=f)
    return value


def _number(value: object) -> bool:
    """A finite int or float (TOML's nan, inf and booleans are not numbers here)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _allowed(table: object, f: str) -> frozenset[str]:
    """The gates named in [safety] allow = [...] (names checked against `millpost.safety.GATES`)."""
    from .safety import GATES

    if not isinstance(table, dict) or set(table) - {"allow"}:
        raise ConfigError("safety", table, "must be a table holding only allow = [gate names]", file=f)
    names = table.get("allow", [])
    if not isinstance(names, list):
        raise ConfigError("safety.allow", names, "must be a list of gate names", file=f)
    for name in names:
        if name not in GATES or not GATES[name].overridable:
            raise ConfigError("safety.allow", name, "unknown gate; these may be overridden: "
                              + ", ".join(g for g in GATES if GATES[g].overridable), file=f)
    return frozenset(names)


def _resolve(base: Path, name: str) -> str | Path:
    """A built-in name stays a name; anything that looks like a file is taken relative to the job."""
    return base / name if name.endswith(".toml") or "/" in name else name
