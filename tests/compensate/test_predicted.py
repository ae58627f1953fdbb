"""The predicted surface error in optimize's summary, trace and report (asked for with the trace): the
programmed state is what `compensate` reports before compensating, a faster feed bends the tool further,
and without the trace nothing changes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from millpost.compensate import compensate
from millpost.job import load_job
from millpost.optimize import optimize
from millpost.report import collect
from millpost.report.page import render

ROOT = Path(__file__).resolve().parents[2]


def test_programmed_state_is_compensates_before():
    """Same forward model, same programmed run: per operation the walls and floors as programmed equal
    compensate's errors before it moves any point (thin wall: 154.8 µm RMS on the walls, 109.8 µm over
    walls and floors)."""
    job = load_job(ROOT / "sample_jobs" / "thin_wall_finish")
    entry = optimize(job, progress=False, surface_error=True).summary["surface_error"]
    before = compensate(job).summary
    assert [op["programmed"] for op in entry["operations"]] == [op["before"] for op in before["operations"]]
    assert entry["rms_um"]["programmed"] == before["surface_error_before_um"]


@pytest.fixture(scope="module")
def slotting():
    job = load_job(ROOT / "sample_jobs" / "slotting")
    return job, optimize(job, progress=False, trace=True, surface_error=True), optimize(job, progress=False)


def test_faster_feed_bends_the_tool_further(slotting):
    """Where the optimized feed is faster than the programmed one, the chip and with it the force and the
    wall's undercut grow: every wall sample at ≥ 1.2× the programmed feed has a larger error."""
    _, r, _ = slotting
    t = r.trace
    prog, opt = t["surface_error_programmed_um"], t["surface_error_optimized_um"]
    faster = np.isfinite(prog) & (t["feed_executed_mm_min"] >= 1.2 * t["feed_programmed_mm_min"]) & (prog > 1.0)
    assert faster.sum() > 100
    assert np.all(opt[faster] > prog[faster])
    rms = r.summary["surface_error"]["rms_um"]
    assert rms["optimized"] > rms["programmed"] > 0


def test_without_the_trace_nothing_changes_and_the_report_shows_it(slotting):
    job, r, plain = slotting
    assert plain.text == r.text and "surface_error" not in plain.summary and not plain.trace
    page = render(collect(r.summary, r.trace, job, stock_map=False))
    assert "<h2>Predicted surface error</h2>" in page and page.count('data-figure="surface-error"') == 1
    for op in r.summary["surface_error"]["operations"]:
        row = op["programmed"]["wall"]["rms_um"], op["optimized"]["wall"]["rms_um"]
        assert f"<td>{row[0]:.1f}</td><td>{row[1]:.1f}</td>" in page
