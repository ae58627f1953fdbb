"""A job: the program and everything the physics needs about it, from a `job.toml`.

    program = "program.nc"            # required; paths are relative to the job file
    output = "program.millpost.nc"    # optional
    dialect = "fanuc"                 # optional (default: detected)
    material = "al6061"               # built-in name or TOML file
    machine = "benchtop-belt"         # built-in name or TOML file
    spindle_rpm = 18000               # optional: a spindle switched by hand turns at this speed (rpm)
                                      # where the program leaves it off (with --allow spindle-off;
                                      # without it: the program's S word in force)
    [stock]                           # box = [[xmin,ymin,zmin],[xmax,ymax,zmax]] (mm) or file = "x.stl|.step|.py";
                                      # optional where the program states its blank (Heidenhain BLK FORM)
    cell_mm = 0.05                    # optional
    [tools.1]                         # by tool number; Tool fields, or file = "t1.toml|.json|.fctb"
    [tools.1.frf]                     # optional: the tool tip's FRF in this holder on this machine, modes
                                      # x = [{fn_hz, zeta, k_N_per_mm}], y = [...] (default x) or
                                      # csv = "frf.csv" (`millpost.stability.job_frf`): chatter is checked
    [limits]                          # optional: settings.JobSettings (deflection_mm, feed_max_mm_min,
                                      # tool_safety_factor, ds_mm, model, jerk_mm_s3, lower, rpm, ...)
    [safety]                          # optional: allow = ["no-cut", ...] (see millpost.safety)

A folder stands for the `job.toml` inside it. Every number must be finite and inside its stated
range (`settings.RANGES`, stock sizes): a value outside is a slip, refused naming the file and the key.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

from .config import Table, is_number
from .errors import ConfigError, MillpostError
from .gcode import ReaderOptions, dialects
from .machine import Machine
from .materials import Material
from .settings import JobSettings
from .stability.frf import ToolTipFRF
from .stability.job_frf import frf_from_table
from .tools import Tool
from .tools.library import load_tool, tool_from_table

CELL_RANGE_MM = (1e-3, 10.0)
SPINDLE_RPM_RANGE = (1.0, 2e5)  # rpm: no milling spindle turns faster than 200 000 rpm
STOCK_SPAN_MM = 1e5  # no stock corner is 100 m from the work zero
_FIELDS = {"program", "output", "dialect", "material", "machine", "stock", "tools", "limits", "safety",
           "spindle_rpm"}

Box = tuple[tuple[float, float, float], tuple[float, float, float]]


@dataclass(frozen=True)
class Job:
    """Everything `optimize` needs, as read from a job file (frozen: a command that overrides a field makes
    a new Job with `dataclasses.replace`). Stock: a box (mm, program frame) or a solid's file."""

    path: Path
    program: Path
    output: Path
    material: Material
    machine: Machine
    tools: dict[int, Tool]
    stock_box: Box | None = None
    stock_file: Path | None = None
    cell_mm: float | None = None
    dialect: str | None = None
    settings: JobSettings = field(default_factory=JobSettings)  # the job file's [limits]
    allow: frozenset[str] = frozenset()  # safety gates the user overrides ([safety] allow)
    inputs: tuple[Path, ...] = ()  # every file the job reads (outputs must not replace one)
    spindle_rpm: float | None = None  # a spindle switched by hand: its speed (rpm) where the program has none
    frf: dict[int, ToolTipFRF] = field(default_factory=dict)  # tool number → its tip's FRF ([tools.N.frf])

    def reader_options(self) -> ReaderOptions:
        """How to read the program: the job's dialect, its tools' diameters for cutter compensation, and
        its only tool (when it describes one) loaded before any T word."""
        return ReaderOptions.for_tools({n: t.diameter_mm for n, t in self.tools.items()}, self.dialect)

    def stock(self):
        """Build the stock height field (mm, program frame)."""
        from . import stock
        if self.stock_file is not None:
            return stock.load(self.stock_file, self.cell_mm)
        return stock.box(*self.stock_box, self.cell_mm)


def load_job(path: str | Path) -> Job:
    """Read and validate a job file (or the job.toml in a folder). Errors name the field and the rule."""
    path, data = _read(Path(path))
    base, f = path.parent, str(path)
    unknown = set(data) - _FIELDS
    if unknown:
        raise ConfigError(sorted(unknown)[0], data[sorted(unknown)[0]], "unknown field", file=f)
    program = base / str(_need(data, "program", f))
    if not program.exists():
        raise ConfigError("program", str(program), "file not found", file=f)
    output = base / str(data["output"]) if "output" in data else program.with_name(
        f"{program.stem}.millpost{program.suffix}")
    material, machine, described = _material_machine(data, base, f)
    dialect = _dialect(data.get("dialect"), f)
    if "stock" in data:
        box, stock_file, cell = _stock(data["stock"], base, f)
    else:
        box, stock_file, cell = _program_blank(program, dialect, f), None, None
    tools, tool_files, frf = _tools(_table(_need(data, "tools", f), "tools", f), base, f)
    settings = JobSettings.from_table(_table(data.get("limits", {}), "limits", f), f)
    spindle_rpm = data.get("spindle_rpm")
    lo, hi = SPINDLE_RPM_RANGE
    if spindle_rpm is not None and not (is_number(spindle_rpm) and lo <= spindle_rpm <= hi):
        raise ConfigError("spindle_rpm", spindle_rpm, f"must be a number in [{lo:g}, {hi:g}] rpm", file=f)
    inputs = (path, program, *described, *([stock_file] if stock_file else []), *tool_files,
              *(csv for _, csv in frf.values() if csv is not None))
    return Job(path, program, output, material, machine, tools, box, stock_file, cell, dialect, settings,
               _allowed(data.get("safety", {}), f), inputs, None if spindle_rpm is None else float(spindle_rpm),
               {n: t for n, (t, _) in frf.items()})


def _read(path: Path) -> tuple[Path, dict]:
    """The job file (`path`, or the job.toml in the folder `path`) and its TOML."""
    if path.is_dir():
        path = path / "job.toml"
    if not path.exists():
        raise ConfigError("job", str(path), "no such job file (a job.toml, or a folder holding one)")
    try:
        return path, tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("job", str(path), f"not valid TOML: {exc}", file=str(path)) from None


def _need(data: dict, key: str, f: str) -> object:
    """The job file's required field `key`."""
    if key not in data:
        raise ConfigError(key, None, "is required", file=f)
    return data[key]


def _material_machine(data: dict, base: Path, f: str) -> tuple[Material, Machine, list[Path]]:
    """The job's material and machine (built-in names or files) and the files among them."""
    described = [_resolve(base, str(_need(data, key, f))) for key in ("material", "machine")]
    try:
        material, machine = Material.load(described[0]), Machine.load(described[1])
    except ConfigError as exc:
        if exc.file:
            raise
        raise ConfigError(exc.field, exc.value, exc.rule, file=f) from None
    return material, machine, [d for d in described if isinstance(d, Path)]


def _stock(stock: object, base: Path, f: str) -> tuple[Box | None, Path | None, float | None]:
    """The [stock] table: (its box (mm), or its solid's file; the cell size (mm) or None)."""
    if not isinstance(stock, dict):
        raise ConfigError("stock", stock, "must be a table with box = [[...],[...]] or file = ...", file=f)
    box = file = None
    if ("box" in stock) == ("file" in stock):
        raise ConfigError("stock", stock, "give exactly one of box or file", file=f)
    if "box" in stock:
        b = stock["box"]
        ok = (isinstance(b, list) and len(b) == 2 and all(isinstance(r, list) and len(r) == 3 for r in b)
              and all(is_number(v) and abs(v) <= STOCK_SPAN_MM for r in b for v in r)
              and all(float(b[1][i]) > float(b[0][i]) for i in range(3)))
        if not ok:
            raise ConfigError("stock.box", b, "[[xmin, ymin, zmin], [xmax, ymax, zmax]] in mm with max > min, "
                              f"finite numbers within {STOCK_SPAN_MM:g} mm of the work zero", file=f)
        box = (tuple(map(float, b[0])), tuple(map(float, b[1])))
    else:
        file = base / str(stock["file"])
        if not file.is_file():
            raise ConfigError("stock.file", str(file), "file not found", file=f)
    cell = stock.get("cell_mm")
    if cell is not None and not (is_number(cell) and CELL_RANGE_MM[0] <= cell <= CELL_RANGE_MM[1]):
        raise ConfigError("stock.cell_mm", cell, f"must be a number in [{CELL_RANGE_MM[0]:g}, {CELL_RANGE_MM[1]:g}] mm",
                          file=f)
    return box, file, cell


def _program_blank(program: Path, dialect: str | None, f: str) -> Box:
    """The stock of a job with no [stock] table: the blank its program states (`Dialect.blank`, as a
    Heidenhain program's BLK FORM), a box in mm."""
    text = program.read_bytes().decode("utf-8", errors="replace")
    read = dialects.get(dialect) if dialect else dialects.detect(text)
    box = read.blank(text, str(program)) if read.blank is not None else None
    if box is None:
        raise ConfigError("stock", None, "is required: the program states no blank (as a Heidenhain BLK FORM) "
                          "to take as the stock", file=f)
    return box


def _tools(table: dict, base: Path, f: str
           ) -> tuple[dict[int, Tool], list[Path], dict[int, tuple[ToolTipFRF, Path | None]]]:
    """The [tools.N] tables: the tools by number, the tool files they name, and by number the tip FRFs
    the [tools.N.frf] tables give (with the measured table's file, if any)."""
    tools, files, frf = {}, [], {}
    for key, spec in table.items():
        if not str(key).isdigit():
            raise ConfigError(f"tools.{key}", spec, "tool tables are named by tool number (T word), e.g. [tools.1]; "
                              "for a program without T words, one table with any number is the tool loaded",
                              file=f)
        n = int(key)
        if not isinstance(spec, dict):
            raise ConfigError(f"tools.{key}", spec, "must be a table", file=f)
        if "frf" in spec:
            spec = dict(spec)
            frf[n] = frf_from_table(Table(spec.pop("frf"), f"tools.{key}.frf", f), base)
        try:
            if "file" in spec:
                files.append(base / str(spec["file"]))
                tools[n] = replace(load_tool(base / str(spec["file"]), number=n), number=n)
            else:
                tools[n] = replace(tool_from_table(Table(spec, f"tools.{key}", f)), number=n)
        except ConfigError as exc:
            if exc.file:
                raise
            raise ConfigError(f"tools.{key}.{exc.field}", exc.value, exc.rule, file=f) from None
    return tools, files, frf


def _dialect(dialect: object, f: str) -> str | None:
    """The job's dialect name (checked against `gcode.dialects`), or None: detected."""
    if dialect is None:
        return None
    try:
        if not isinstance(dialect, str):
            raise MillpostError("not a name")
        dialects.get(dialect)
    except MillpostError:
        raise ConfigError("dialect", dialect, f"one of {', '.join(dialects.names())} (haas = fanuc)",
                          file=f) from None
    return dialect


def _table(value: object, key: str, f: str) -> dict:
    """The job file's table `key` (its `value`)."""
    if not isinstance(value, dict):
        raise ConfigError(key, value, "must be a table", file=f)
    return value


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
