"""The job report: its numbers against independent sums over the program, the page self-contained
(nothing fetched: it opens offline), and the CLI paths that write it."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from millpost.cli import main
from millpost.errors import MillpostError
from millpost.gcode import read_program
from millpost.report import collect, read_trace, render
from millpost.report.data import operation_times, operations_from_lines, sample_times_s
from millpost.report.figures import envelope
from millpost.toolpath import RAPID


def test_sample_times_closed_form():
    s = np.linspace(0.0, 100.0, 1001)
    assert sample_times_s(s, np.full_like(s, 600.0)).sum() == pytest.approx(10.0)  # 100 mm at 10 mm/s
    # a linear ramp v = v0 + k s: exact time ∫ ds / v = ln(v1/v0) / k; the trapezoid in 1/v converges
    v = 60.0 * (1.0 + 0.09 * s)
    assert sample_times_s(s, v).sum() == pytest.approx(np.log(10.0) / 0.09, rel=1e-4)
    f = np.full_like(s, 600.0)
    f[:500] = np.nan  # rapids: not counted
    assert sample_times_s(s, f).sum() == pytest.approx(50.0 / 10.0, rel=1e-9)


def test_envelope_keeps_every_extreme():
    rng = np.random.default_rng(3)
    x = np.arange(100_000.0)
    y = rng.normal(size=x.size)
    y[77_777] = 50.0
    ex, ey = envelope(x, y, 500)
    assert len(ex) <= 1000 and ey.max() == 50.0 and ey.min() == y.min()
    assert np.all(np.diff(ex) > 0)


def test_operations_follow_comments_and_tools():
    lines = np.array([1, 3, 5, 7, 9, 11])
    tools = np.array([1, 1, 1, 2, 2, 2])
    ops = operations_from_lines(lines, tools, [(2, "(face)"), (6, "(drill)")])
    assert [(o.name, o.tool, o.index.tolist()) for o in ops] == [
        ("T1", 1, [0]), ("(face)", 1, [1, 2]), ("(drill)", 2, [3, 4, 5])]


def test_report_numbers_and_self_contained(slotting_result):
    job, result = slotting_result
    data = collect(result.summary, result.trace, job)
    (row,) = operation_times(data)  # one operation, one tool
    tp = read_program(job.program).toolpath
    feed = tp.kind != RAPID
    # at the programmed F: the sum over the program's moves of length / F
    assert row["programmed_s"] == pytest.approx(float(np.sum(tp.lengths()[feed] / tp.feed_mm_min[feed] * 60)),
                                                rel=0.01)
    assert row["length_mm"] == pytest.approx(float(tp.lengths()[feed].sum()), rel=1e-3)
    # at the baseline F: per programmed F (plunges, slots, contour) the summary's constant feed
    base = result.summary["baseline_feed_mm_min"][1]
    assert len(base) == 3
    base_f = np.array([base[f] for f in tp.feed_mm_min[feed]])
    assert row["baseline_s"] == pytest.approx(float(np.sum(tp.lengths()[feed] / base_f * 60)), rel=0.01)
    assert 0 < row["optimized_s"] <= result.summary["cycle_time_after_s"]
    # the drive current bound (inertia + friction + the whole peak force on X and Y) is no lower than the
    # replay's current ratio (the cutting force along each axis): an upper bound, and a close one here
    current = float(np.nanmax(np.where(data.cutting, data.signals["current_ratio"], np.nan)))
    assert result.summary["limits"]["current"] - 1e-3 <= current <= 2 * result.summary["limits"]["current"] + 0.05
    page = render(data)
    assert len(re.findall(r"<svg data-figure=", page)) == 5
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:|//)""", page)  # nothing fetched: opens offline
    assert "<script" not in page
    # the final stock: cut down to the deepest Z programmed where the tool overlaps the stock (the slots'
    # floors, the side contour's step)
    (x0, y0, _), (x1, y1, _) = job.stock_box
    r = job.tools[1].radius_mm
    end = result.samples.xyz_mm[result.samples.kind != RAPID]
    inside = (end[:, 0] > x0 - r) & (end[:, 0] < x1 + r) & (end[:, 1] > y0 - r) & (end[:, 1] < y1 + r)
    z_cut = float(np.min(end[inside, 2]))
    assert np.nanmin(data.stock.top) == pytest.approx(z_cut, abs=0.05)


def test_cli_optimize_report_and_report_from_trace(tmp_path):
    from pathlib import Path
    job = Path(__file__).resolve().parents[1] / "sample_jobs" / "slotting"
    out, html_a, trace, summary = (tmp_path / n for n in ("o.nc", "a.html", "t.csv", "s.json"))
    assert main(["optimize", str(job), "-o", str(out), "--report", str(html_a), "--trace", str(trace),
                 "--json", str(summary)]) == 0
    html_b = tmp_path / "b.html"
    assert main(["report", str(trace), "--summary", str(summary), "--job", str(job), "-o", str(html_b)]) == 0
    a, b = html_a.read_text(), html_b.read_text()
    assert a.count("<svg data-figure=") == b.count("<svg data-figure=") == 5
    s = json.loads(summary.read_text())
    assert f"{s['cycle_time_after_s']:.1f} s optimized" in b
    html_c = tmp_path / "c.html"  # the trace alone: no stock, tools as operations
    assert main(["report", str(trace), "-o", str(html_c)]) == 0
    assert html_c.read_text().count("<svg data-figure=") == 4


def test_trace_must_be_an_optimize_trace(tmp_path):
    bad = tmp_path / "x.csv"
    bad.write_text("a,b\n1,2\n")
    with pytest.raises(MillpostError, match="not an optimize trace"):
        read_trace(bad)
