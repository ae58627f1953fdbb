"""What the job report shows, gathered from an optimize result (its summary and per-sample trace) and,
when the job is at hand, from the job itself (operations from the program's comments, the load
limits per sample, the final stock).

The optimize trace holds per sample the programmed, scheduled and executed feeds (mm/min), the peak
in-plane force (N) and spindle power (W) at the executed feed, and where a cut is too heavy at any
feed. Derived here from the job: an upper bound of the drive current (see `_current_ratio`), the
maximum chip thickness of a flat flank (see `_derive_limits`)
against the material's chip load, the tool's allowed force (beam: strength / safety factor at the
weakest section, load at mid-depth of cut), the spindle's power at the sample's speed, and the
deflection (tool compliance at the tip + the softer X/Y axis) × peak force against `deflection_mm`.
The binding limit per sample is the trace's `binding` column when it has one; otherwise the one of
those ratios (or the feed cap, or the controller's ramps) that holds the feed, found within 3 %.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import MillpostError

RAPID_FEED = np.nan  # the trace's programmed feed on rapids
TIGHT = 0.97  # a ratio this close to 1 counts as binding
STOCK_CELLS = 250_000  # the report's stock map resolution (cells)


@dataclass
class Operation:
    """A run of the program under one tool and one CAM comment (the operation's name as posted)."""

    name: str
    tool: int
    index: np.ndarray  # sample indices


@dataclass
class StockMap:
    """Final top of material (mm) per cell over [x0, x1] × [y0, y1] (mm); nan where cut through."""

    top: np.ndarray
    extent: tuple[float, float, float, float]


@dataclass
class ReportData:
    summary: dict
    trace: dict[str, np.ndarray]
    operations: list[Operation]
    limits: dict[str, np.ndarray] = field(default_factory=dict)  # per-sample bound of a signal
    signals: dict[str, np.ndarray] = field(default_factory=dict)  # derived signals (deflection_mm, chip_mm)
    binding: np.ndarray | None = None  # str per sample ("" off the cut)
    stock: StockMap | None = None
    title: str = ""

    @property
    def cutting(self) -> np.ndarray:
        return np.isfinite(self.trace["feed_programmed_mm_min"])


def read_trace(path: str | Path) -> dict[str, np.ndarray]:
    """An optimize trace CSV (`optimize --trace`) as columns by name."""
    path = Path(path)
    with open(path) as fh:
        header = fh.readline().strip().split(",")
    if "feed_programmed_mm_min" not in header or "s_mm" not in header:
        raise MillpostError(f"{path}:1: not an optimize trace (expected columns s_mm, feed_programmed_mm_min, "
                            f"...; got {','.join(header[:4])}...)")
    table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if table.shape[1] != len(header):
        raise MillpostError(f"{path}: {table.shape[1]} columns per row but {len(header)} in the header")
    return {name: table[:, k] for k, name in enumerate(header)}


def sample_times_s(s_mm: np.ndarray, feed_mm_min: np.ndarray) -> np.ndarray:
    """Time (s) of the step ending at each sample at the given feeds: 2·Δs / (v₀ + v₁), 0 where the
    step does not move or either end has no feed (rapids in a programmed-feed column)."""
    v = np.nan_to_num(np.asarray(feed_mm_min, float), nan=0.0) / 60.0
    dt = np.zeros(len(s_mm))
    if len(s_mm) > 1:
        ds = np.diff(s_mm)
        both = (v[1:] > 0) & (v[:-1] > 0) & (ds > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            dt[1:] = np.where(both, 2 * ds / (v[1:] + v[:-1]), 0.0)
    return dt


def operation_times(data: ReportData) -> list[dict]:
    """Per operation: cutting length (mm) and the feed time (s) at the programmed F, at the baseline F
    (per tool one constant feed, as in the summary) and as executed after optimizing (the controller
    model's speed along the path). Rapids are left out of all three."""
    tr = data.trace
    cut = data.cutting
    base = data.summary.get("baseline_feed_mm_min", {})
    base_feed = np.array([base.get(str(int(t)), base.get(int(t), math.nan)) for t in tr["tool"]], float)
    columns = {"programmed": np.where(cut, tr["feed_programmed_mm_min"], np.nan),
               "baseline": np.where(cut, base_feed, np.nan),
               "optimized": np.where(cut, tr["feed_executed_mm_min"], np.nan)}
    times = {k: sample_times_s(tr["s_mm"], v) for k, v in columns.items()}
    ds = np.concatenate([[0.0], np.diff(tr["s_mm"])])
    rows = []
    for op in data.operations:
        i = op.index[cut[op.index]]
        rows.append({"operation": op.name, "tool": op.tool, "length_mm": float(ds[i].sum()),
                     **{f"{k}_s": float(t[i].sum()) for k, t in times.items()}})
    return rows


def operations_from_lines(lines: np.ndarray, tools: np.ndarray, comments: list[tuple[int, str]]) -> list[Operation]:
    """Operations by source line: a sample belongs to the last comment at or before its line (the
    operation name a CAM post writes before each operation) and to its tool."""
    comment_lines = np.array([c[0] for c in comments], int)
    texts = [c[1] for c in comments]
    at = np.searchsorted(comment_lines, lines, side="right") - 1 if len(comment_lines) else np.full(len(lines), -1)
    ops: dict[tuple[int, int], list[int]] = {}
    for k, key in enumerate(zip(at.tolist(), tools.astype(int).tolist())):
        ops.setdefault(key, []).append(k)
    out = []
    for (c, tool), idx in sorted(ops.items(), key=lambda kv: kv[1][0]):
        if tool < 0:
            continue
        out.append(Operation(texts[c].strip() if c >= 0 else f"T{tool}", tool, np.asarray(idx)))
    return out


def collect(summary: dict, trace: dict[str, np.ndarray], job=None, *, stock_map: bool = True) -> ReportData:
    """Everything the report shows. Without a job: per-tool operations and the trace's own columns."""
    trace = {k: np.asarray(v) for k, v in trace.items()}
    n = len(trace["s_mm"])
    data = ReportData(summary, trace, [], title=Path(summary.get("program", "job")).name)
    if job is None:
        data.operations = operations_from_lines(np.zeros(n, int), trace["tool"], [])
        data.binding = _binding(data, feed_cap=None)
        return data
    from ..gcode import read_program
    program = read_program(job.program, job.reader_options())
    samples = program.toolpath.resample(float(job.limits["ds_mm"]))
    if len(samples) != n:
        raise MillpostError(f"the trace has {n} samples but {job.program} resamples to {len(samples)}: "
                            "trace and job do not match")
    comments = [(e.line, str(e.value)) for e in program.events if e.kind == "comment"]
    data.title = job.program.name
    data.operations = operations_from_lines(samples.line, samples.tool, comments)
    _derive_limits(data, job, samples)
    feed_cap = job.machine.feed_max_mm_min
    if job.limits.get("feed_max_mm_min"):
        feed_cap = min(feed_cap, float(job.limits["feed_max_mm_min"]))
    data.binding = _binding(data, feed_cap)
    if stock_map:
        data.stock = final_stock(job, samples)
    return data


def _derive_limits(data: ReportData, job, samples) -> None:
    from ..tools.beam import ToolBeam
    tr, m = data.trace, job.machine
    n = len(tr["s_mm"])
    force_lim, compliance = np.full(n, np.nan), np.full(n, np.nan)
    rpm = np.clip(samples.rpm, m.spindle.rpm_min, m.spindle.rpm_max)
    k_xy = min(m.axes["x"].stiffness_N_per_mm, m.axes["y"].stiffness_N_per_mm)
    for number, tool in job.tools.items():
        idx = np.flatnonzero(samples.tool == number)
        if not len(idx):
            continue
        beam = ToolBeam.of(tool, safety_factor=job.limits["tool_safety_factor"] or None)
        force_lim[idx] = beam.breaking_force_N(tr["ap_mm"][idx])
        compliance[idx] = beam.compliance_mm_per_N(tr["ap_mm"][idx], at_tip=True) + 1.0 / k_xy
    data.limits["peak_force_N"] = force_lim
    data.limits["power_W"] = np.where(samples.rpm > 0, m.spindle.power_available_W(rpm), np.nan)
    data.signals["deflection_mm"] = tr["peak_force_N"] * compliance
    data.limits["deflection_mm"] = np.full(n, float(job.limits["deflection_mm"]))
    # chip thickness h_max = f_z·sin φ_max with sin φ_max = 2·√(a_e/D·(1 − a_e/D)) below half immersion
    # (1 above): the flank edge of a flat tool (an upper bound of h on ball and bull noses)
    chip, chip_lim = np.full(n, np.nan), np.full(n, np.nan)
    for number, tool in job.tools.items():
        idx = np.flatnonzero((samples.tool == number) & (samples.rpm > 0))
        d = np.clip(tr["ae_mm"][idx] / tool.diameter_mm, 0.0, 1.0)
        sin_max = np.where(d >= 0.5, 1.0, 2 * np.sqrt(d * (1 - d)))
        chip[idx] = tr["feed_executed_mm_min"][idx] / (tool.flutes * rpm[idx]) * sin_max
        chip_lim[idx] = job.material.chip_load_mm(tool.diameter_mm)[1]
    data.signals["chip_mm"], data.limits["chip_mm"] = chip, chip_lim
    data.signals["current_ratio"] = _current_ratio(job, samples, tr)
    data.limits["current_ratio"] = np.ones(n)


def _current_ratio(job, samples, tr: dict) -> np.ndarray:
    """Largest axis current over its drive limit per sample at the executed feed: inertia (path tangent
    and curvature, a = v dv/ds along the path) and friction, plus on X and Y the cutting share bounded
    by the whole peak in-plane force (the trace has no force direction): an upper bound."""
    v = np.nan_to_num(tr["feed_executed_mm_min"], nan=0.0) / 60.0
    ds = np.gradient(samples.s_mm)
    a_path = v * np.gradient(v) / np.where(ds > 0, ds, 1.0)
    worst = np.zeros(len(v))
    for k, name in enumerate("xyz"):
        axis = job.machine.axes[name]
        d = axis.demand(samples.tangent[:, k] * v, samples.tangent[:, k] * a_path + samples.curvature[:, k] * v ** 2)
        cut = tr["peak_force_N"] * axis.rho_m_per_rad / (axis.efficiency * axis.motor.kt_Nm_per_A) if k < 2 else 0.0
        worst = np.maximum(worst, (np.abs(d.current_A) + cut) / axis.motor.current_limit_A)
    return worst


LABELS = {"peak_force_N": "cutting force", "power_W": "power", "deflection_mm": "deflection", "chip_mm": "chip load",
          "current_ratio": "drive current"}


def _binding(data: ReportData, feed_cap: float | None) -> np.ndarray:
    """The limit that holds the feed per sample (see the module docstring); "" off the cut."""
    tr = data.trace
    n = len(tr["s_mm"])
    if "binding" in tr and tr["binding"].dtype.kind in "US":
        return tr["binding"]
    out = np.full(n, "", dtype=object)
    cut = data.cutting
    out[cut] = "axis rates or current"  # what is left: axis velocity, acceleration, drive current
    sched, execd = tr["feed_schedule_mm_min"], tr["feed_executed_mm_min"]
    out[cut & (execd < TIGHT * np.nan_to_num(sched, nan=np.inf))] = "ramps and corners (controller)"
    if feed_cap is not None:
        out[cut & (sched >= TIGHT * feed_cap)] = "feed cap"
    best = np.zeros(n)
    for key, bound in data.limits.items():
        value = data.signals.get(key, tr.get(key))
        if value is None:
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.nan_to_num(value / bound, nan=0.0)
        hit = cut & (r >= TIGHT) & (r > best)
        out[hit], best[hit] = LABELS[key], r[hit]
    for key in tr:
        if key.startswith("unavoidable_"):
            out[cut & (tr[key] > 0)] = f"{key[12:].replace('_', ' ')} (cut too heavy: held)"
    return out


def final_stock(job, samples) -> StockMap | None:
    """The stock after the program, cut again by the engagement simulation on a grid of about
    `STOCK_CELLS` cells (a picture, not the optimizer's grid)."""
    from .. import engagement
    cell = job.cell_mm or 0.05
    if job.stock_box is not None:
        (x0, y0, _), (x1, y1, _) = job.stock_box
        cell = max(cell, math.sqrt((x1 - x0) * (y1 - y0) / STOCK_CELLS))
    stock = dataclasses.replace(job, cell_mm=cell).stock()
    try:
        engagement.simulate(stock, dict(job.tools), samples, slices=1, ring_samples=8, progress=False)
    except MillpostError:
        return None  # the coarse grid found material the optimizer's did not: no map rather than a wrong one
    top = np.where(stock.top > stock.z_floor, stock.top, np.nan).astype(float)
    return StockMap(top, (stock.x0, stock.x0 + stock.nx * stock.cell_mm, stock.y0, stock.y0 + stock.ny * stock.cell_mm))
