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
from millpost.report import collect, figures, read_trace, render
from millpost.operations import operations_from_lines
from millpost.report.data import ReportData, StockMap, operation_times, sample_times_s
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
    # cycle times, feed, loads, top view, final stock and the predicted surface error (the slots' walls)
    assert len(re.findall(r"<svg data-figure=", page)) == 6 and "surface_error" in result.summary
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
    job = Path(__file__).resolve().parents[2] / "sample_jobs" / "slotting"
    out, html_a, trace, summary = (tmp_path / n for n in ("o.nc", "a.html", "t.csv", "s.json"))
    assert main(["optimize", str(job), "-o", str(out), "--report", str(html_a), "--trace", str(trace),
                 "--json", str(summary)]) == 0
    html_b = tmp_path / "b.html"
    assert main(["report", str(trace), "--summary", str(summary), "--job", str(job), "-o", str(html_b)]) == 0
    a, b = html_a.read_text(), html_b.read_text()
    # the five figures and the predicted surface error, from the trace CSV too
    assert a.count("<svg data-figure=") == b.count("<svg data-figure=") == 6
    assert b.count('data-figure="surface-error"') == 1
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


def zigzag_report(width_mm: float, height_mm: float, n: int = 200_000) -> tuple[ReportData, np.ndarray]:
    """A raster over width × height mm (rapids before it and between its two operations, tools 1 and 2)
    with its report data, and the samples where the optimized feed dips for one sample only. Limits hold
    the feed: chip load on every 10th cutting sample, axis rates on one stretch, ramps elsewhere."""
    t = np.linspace(0.0, 40.0, n)
    row = np.minimum(t.astype(int), 39)
    x = np.where(row % 2 == 0, t - row, 1.0 - (t - row)) * width_mm
    y = row / 39 * height_mm
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
    programmed = np.full(n, 1000.0)
    programmed[: n // 50] = programmed[n // 2: n // 2 + n // 100] = np.nan  # rapids
    executed = 2000.0 + 300.0 * np.sin(s / 7.0)
    cut = np.isfinite(programmed)
    dips = np.flatnonzero(cut)[np.linspace(10, cut.sum() - 10, 40).astype(int)]
    executed[dips] = 150.0 + np.arange(40)
    binding = np.where(cut, "ramps and corners (controller)", "").astype(object)
    binding[np.flatnonzero(cut)[::10]] = "chip load"
    binding[n // 5: n // 5 + n // 20] = "axis rates or current"
    tool = np.where(np.arange(n) < n // 2, 1, 2)
    trace = {"s_mm": s, "x": x, "y": y, "z": np.zeros(n), "tool": tool, "feed_programmed_mm_min": programmed,
             "feed_executed_mm_min": executed}
    ops = operations_from_lines(np.zeros(n, int), tool, [])
    return ReportData({}, trace, ops, binding=binding, title="zigzag"), dips


@pytest.fixture
def drawn(monkeypatch) -> dict:
    """The figures the page builder draws, by name (the page gets no SVG)."""
    figs = {}

    def keep(fig, name: str) -> str:
        figs[name] = fig
        return ""
    monkeypatch.setattr(figures, "svg", keep)
    return figs


def _series(ax, prefix: str) -> tuple[np.ndarray, np.ndarray]:
    """The finite points of every curve and point cloud on `ax` whose label starts with `prefix`."""
    xy = [line.get_xydata() for line in ax.lines if line.get_label().startswith(prefix)]
    xy += [np.asarray(c.get_offsets()) for c in ax.collections if c.get_label().startswith(prefix)]
    xy = np.concatenate(xy)
    ok = np.isfinite(xy).all(axis=1)
    return xy[ok, 0], xy[ok, 1]


def _area(collection) -> float:
    """The area (data units) a filled collection covers (shoelace over its closed paths)."""
    total = 0.0
    for path in collection.get_paths():
        x, y = path.vertices.T
        total += 0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1)))
    return total


def test_feed_along_path_shows_the_whole_job(drawn):
    data, dips = zigzag_report(200.0, 20.0)
    render(data)
    fig = drawn["feed-along-path"]
    ax = fig.axes[0]
    tr, cut = data.trace, data.cutting
    s, v = tr["s_mm"], tr["feed_executed_mm_min"]
    s0, s1 = s[cut][0], s[cut][-1]
    xs, ys = _series(ax, "optimized")
    assert xs.min() <= s0 + 0.01 * (s1 - s0) and xs.max() >= s1 - 0.01 * (s1 - s0)  # the whole cutting length
    lo, hi = ax.get_xlim()
    assert lo <= s0 and hi >= s1 and hi - lo <= 1.05 * (s1 - s0)
    assert xs.size <= 10_000  # reduced, but every one-sample dip drawn
    assert set(zip(s[dips].tolist(), v[dips].tolist())) <= set(zip(xs.tolist(), ys.tolist()))
    # every operation's start marked
    starts = {float(s[op.index[cut[op.index]][0]]) for op in data.operations}
    assert starts <= {float(line.get_xdata()[0]) for line in ax.lines}
    # below: each limit's share of the cutting length, none drawn over another
    ds = np.diff(s, prepend=s[0])
    shares = fig.axes[1]
    for name in ("ramps and corners (controller)", "chip load", "axis rates or current"):
        (band,) = [c for c in shares.collections if c.get_label() == name]
        share = ds[cut & (data.binding == name)].sum() / ds[cut].sum()
        assert _area(band) / (s1 - s0) == pytest.approx(share, abs=0.02), name


@pytest.mark.parametrize("name", ["top-view", "stock-map"])
@pytest.mark.parametrize("size", [(200.0, 20.0), (20.0, 200.0), (80.0, 80.0), (3000.0, 10.0)])
def test_plan_views_show_the_part_at_a_readable_size(drawn, name, size):
    width, height = size
    data, _ = zigzag_report(width, height, n=20_000)
    data.stock = StockMap(np.zeros((40, 40)), (0.0, width, 0.0, height))
    render(data)
    fig = drawn[name]
    fig.draw_without_rendering()
    fw, fh = fig.get_size_inches()
    ax, bar = fig.axes[:2]
    box, cbox = ax.get_position(), bar.get_position()
    w, h = box.width * fw, box.height * fh
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert (x1 - x0) / w == pytest.approx((y1 - y0) / h, rel=0.02)  # X and Y at one scale
    assert x0 <= 0 and x1 >= width and y0 <= 0 and y1 >= height  # the whole part ...
    assert max(width / (x1 - x0), height / (y1 - y0)) >= 0.85  # ... filling the view along its long side
    assert w * h >= 0.35 * fw * fh and min(w, h) >= 1.5 and max(w, h) >= 5.5  # inches: not a strip
    cw, ch = cbox.width * fw, cbox.height * fh
    length, side = (cw, w) if cw > ch else (ch, h)
    assert length == pytest.approx(side, rel=0.05)  # the colour bar as long as the view beside it


def test_top_view_draws_every_cut(drawn):
    data, dips = zigzag_report(200.0, 20.0)
    render(data)
    ax = drawn["top-view"].axes[0]
    (cloud,) = [c for c in ax.collections if c.get_array() is not None]
    xy, feed = np.asarray(cloud.get_offsets()), np.asarray(cloud.get_array())
    assert len(xy) <= 200_000
    tr = data.trace
    for k in dips:  # each one-sample dip drawn where it is, with its feed (a thinned cloud misses most)
        near = np.hypot(xy[:, 0] - tr["x"][k], xy[:, 1] - tr["y"][k]) < 0.5
        assert tr["feed_executed_mm_min"][k] in feed[near], k
