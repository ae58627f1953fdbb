"""What the job report shows, gathered from an optimize result (its summary and per-sample trace) and,
when the job is at hand, from the job itself (operations from the program's comments, the load
limits per sample, the final stock, the stability lobes of the tools with a tip FRF: `report.lobes`).

The optimize trace holds per sample the programmed, scheduled and executed feeds (mm/min), where a
cut is too heavy at any feed, and the replay check's loads at the executed feed with their bounds
(`millpost.replay`: the forward model's signals): peak in-plane force against the tool's allowed
force, cutting power against the spindle's, deflection against `deflection_mm`, the largest chip
against the material's chip load, and the largest axis motor current over its drive's limit.
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
from ..operations import Operation, operations_from_lines, program_operations
from ..signals import Load, step_times_s
from .lobes import ToolLobes, tool_lobes, why_none

RAPID_FEED = np.nan  # the trace's programmed feed on rapids
TIGHT = 0.97  # a ratio this close to 1 counts as binding
STOCK_CELLS = 250_000  # the report's stock map resolution (cells)


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
    lobes: list[ToolLobes] = field(default_factory=list)  # per tool with an FRF that cuts
    lobes_note: str = ""  # why a job with a chatter check has no lobes here ("" otherwise)

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
    """Time (s) of the step ending at each sample at the given feeds (`signals.step_times_s`), 0 where
    either end has no feed (rapids in a programmed-feed column) or the step does not move."""
    v = np.nan_to_num(np.asarray(feed_mm_min, float), nan=0.0) / 60.0
    dt = step_times_s(s_mm, v)
    dt[1:][(v[1:] <= 0) | (v[:-1] <= 0)] = 0.0
    return dt


def operation_times(data: ReportData) -> list[dict]:
    """Per operation: cutting length (mm) and the feed time (s) at the programmed F, at the baseline F
    (the trace's: per tool and programmed feed one constant feed, capped on plunges and approaches, as
    the summary's baseline run) and as executed after optimizing (the controller model's speed along the
    path). Rapids are left out of all three."""
    tr = data.trace
    cut = data.cutting
    base_feed = tr.get("feed_baseline_mm_min", np.full(len(tr["s_mm"]), np.nan))  # older traces: none
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


def collect(summary: dict, trace: dict[str, np.ndarray], job=None, *, stock_map: bool = True) -> ReportData:
    """Everything the report shows. Without a job: per-tool operations and the trace's own columns."""
    trace = {k: np.asarray(v) for k, v in trace.items()}
    n = len(trace["s_mm"])
    data = ReportData(summary, trace, [], title=Path(summary.get("program", "job")).name)
    _trace_limits(data)
    data.lobes, data.lobes_note = tool_lobes(trace, job), why_none(trace, job)
    if job is None:
        data.operations = operations_from_lines(np.zeros(n, int), trace["tool"], [])
        data.binding = _binding(data, feed_cap=None)
        return data
    from ..gcode import read_program
    from ..limits import feed_cap_mm_s
    program = read_program(job.program, job.reader_options())
    samples = program.toolpath.resample(job.settings.ds_mm)
    if len(samples) != n:
        raise MillpostError(f"the trace has {n} samples but {job.program} resamples to {len(samples)}: "
                            "trace and job do not match")
    data.title = job.program.name
    data.operations = program_operations(program, samples)
    data.binding = _binding(data, feed_cap_mm_s(job) * 60.0)  # mm/min, as the trace
    if stock_map:
        data.stock = final_stock(job, samples)
    return data


# the loads the report plots against their bounds: (trace column of the load, of its bound; None: a ratio)
TRACE_LIMITS = {load.column: load.bound_column for load in Load.plotted()}


def _trace_limits(data: ReportData) -> None:
    """The loads and bounds per sample from the trace (the replay check's forward-model signals at the
    executed feed, written by optimize); a trace without them shows none."""
    tr = data.trace
    for key, bound in TRACE_LIMITS.items():
        if key in tr and (bound is None or bound in tr):
            data.signals[key] = tr[key]
            data.limits[key] = tr[bound] if bound is not None else np.ones(len(tr[key]))


LABELS = {load.column: load.label for load in Load.plotted()}


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
        if key.startswith("held_"):
            out[cut & (tr[key] > 0)] = f"{key[5:].replace('_', ' ')} (held by the feed policy)"
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
    top = np.where(stock.top > stock.z_floor, stock.z0 + stock.top.astype(float), np.nan)  # heights above z0
    return StockMap(top, (stock.x0, stock.x0 + stock.nx * stock.cell_mm, stock.y0, stock.y0 + stock.ny * stock.cell_mm))
