"""The report's figures as inline SVG (matplotlib, Agg-free SVG backend, imported here only).

Long programs have millions of samples: curves along the path are reduced to the minimum and maximum
of each of ~2000 buckets (every peak and dip survives) and span the first cut to the last; the top view
keeps one point per grid cell (its least feed), so no cut is dropped; point clouds are rasterised inside
the SVG. Views of the XY plane take the part's proportions at one scale, their colour bar alongside.
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass

import numpy as np

from .data import LABELS, TIGHT, ReportData, operation_times
from .lobes import ToolLobes

BUCKETS = 2000
POCKET_LABELS = 5  # stable pockets labelled with their speed on a lobe diagram
BINDING_COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
                   "#bcbd22", "#17becf"]


def _figure(width_in: float = 10.0, height_in: float = 3.6, rows: int = 1):
    from matplotlib.figure import Figure
    fig = Figure(figsize=(width_in, height_in * rows), layout="constrained")
    axes = [fig.add_subplot(rows, 1, k + 1) for k in range(rows)]
    return fig, axes


def svg(fig, name: str) -> str:
    """The figure as an inline <svg> element; ids salted with the figure's name so that several SVGs
    on one page never share an id, and the same data gives the same text."""
    import matplotlib
    buf = io.StringIO()
    with matplotlib.rc_context({"svg.hashsalt": name, "svg.fonttype": "path"}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    text = buf.getvalue()
    start = text.index("<svg")
    return re.sub(r"<svg ", f'<svg data-figure="{name}" role="img" ', text[start:], count=1)


def envelope(x: np.ndarray, y: np.ndarray, buckets: int = BUCKETS) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) reduced to the min and max of `buckets` runs of samples, in order (nan kept as gaps)."""
    n = len(x)
    if n <= 2 * buckets:
        return x, y
    edges = np.linspace(0, n, buckets + 1).astype(int)
    xs, ys = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        seg = y[a:b]
        if np.all(np.isnan(seg)):
            xs.append(x[a]), ys.append(np.nan)
            continue
        lo, hi = a + int(np.nanargmin(seg)), a + int(np.nanargmax(seg))
        for k in sorted({lo, hi}):
            xs.append(x[k]), ys.append(y[k])
    return np.asarray(xs), np.asarray(ys)


def cycle_times(data: ReportData) -> str:
    rows = operation_times(data)
    fig, (ax,) = _figure(height_in=max(2.2, 0.45 * len(rows) + 1.2))
    names = [f"{k + 1}. {r['operation']} (T{r['tool']})" for k, r in enumerate(rows)]
    y = np.arange(len(rows))
    for k, (key, colour) in enumerate((("programmed", "#7f7f7f"), ("baseline", "#ff7f0e"), ("optimized", "#1f77b4"))):
        ax.barh(y + (k - 1) * 0.27, [r[f"{key}_s"] for r in rows], height=0.27, color=colour, label=key)
    ax.set_yticks(y, names)
    ax.invert_yaxis()
    ax.set_xlabel("feed time (s)")
    ax.legend(loc="lower right")
    return svg(fig, "cycle-times")


def cut_span(data: ReportData) -> tuple[float, float]:
    """Path length s (mm) of the first and the last cutting sample (of the first and last sample when
    nothing cuts)."""
    s = data.trace["s_mm"][data.cutting] if data.cutting.any() else data.trace["s_mm"]
    return float(s[0]), float(s[-1])


def _along_path(ax, data: ReportData) -> None:
    """x from the first cut to the last (1 % margin) and a dotted line at each operation's start, numbered
    as in the cycle time table."""
    s0, s1 = cut_span(data)
    pad = 0.01 * max(s1 - s0, 1e-6)
    ax.set_xlim(s0 - pad, s1 + pad)
    if len(data.operations) < 2:
        return
    s, cut = data.trace["s_mm"], data.cutting
    for k, op in enumerate(data.operations):
        cutting = op.index[cut[op.index]]
        if len(cutting):
            ax.axvline(s[cutting[0]], color="#555555", lw=0.6, ls=":")
            ax.text(s[cutting[0]], 1.0, f" {k + 1}", transform=ax.get_xaxis_transform(), va="top", fontsize=8)


def binding_shares(s: np.ndarray, cut: np.ndarray, binding: np.ndarray, span: tuple[float, float],
                   buckets: int = 200) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Bucket centres along s (mm) and per limit the share of each bucket's cutting length it holds."""
    edges = np.linspace(*span, buckets + 1)
    ds = np.diff(s, prepend=s[0]) * cut
    total = np.histogram(s, edges, weights=ds)[0]
    shares = {}
    for name in sorted(set(binding[cut].tolist())):
        held = np.histogram(s, edges, weights=ds * (binding == name))[0]
        shares[name] = np.divide(held, total, out=np.zeros(buckets), where=total > 0)
    return 0.5 * (edges[:-1] + edges[1:]), shares


def feed_along_path(data: ReportData) -> str:
    """Programmed and executed feed over the whole cutting length (min/max envelopes: every dip drawn);
    below, the limit holding the feed as stacked shares, so that no limit hides another."""
    from matplotlib.figure import Figure
    tr, cut = data.trace, data.cutting
    s = tr["s_mm"]
    fig = Figure(figsize=(10.0, 5.0), layout="constrained")
    ax, below = fig.subplots(2, 1, sharex=True, height_ratios=[3, 1])
    for key, colour, label in (("feed_programmed_mm_min", "#7f7f7f", "programmed"),
                               ("feed_executed_mm_min", "#1f77b4", "optimized (executed)")):
        ax.plot(*envelope(s, np.where(cut, tr[key], np.nan)), color=colour, lw=0.8, label=label,
                gid=f"feed-{label.split()[0]}")
    ax.set_ylabel("feed (mm/min)")
    _along_path(ax, data)
    binding = data.binding if data.binding is not None else np.where(cut, "optimized", "")
    x, shares = binding_shares(s, cut, binding, cut_span(data))
    below.stackplot(x, list(shares.values()), labels=list(shares), step="mid",
                    colors=[BINDING_COLOURS[k % len(BINDING_COLOURS)] for k in range(len(shares))])
    below.set_ylim(0, 1)
    below.set_ylabel("held by")
    below.set_xlabel("path length s (mm)")
    fig.legend(loc="outside right upper", fontsize=8)
    return svg(fig, "feed-along-path")


def loads_vs_limits(data: ReportData) -> str:
    tr = data.trace
    s = tr["s_mm"]
    keys = [k for k in LABELS if k in tr or k in data.signals]
    ratios = data.summary.get("limits", {})
    fig, axes = _figure(height_in=2.6, rows=len(keys) + 1)
    for ax, key in zip(axes, keys):
        value = data.signals.get(key, tr.get(key))
        ax.plot(*envelope(s, np.where(data.cutting, value, np.nan)), lw=0.8, label=LABELS[key])
        if key in data.limits:
            ax.plot(*envelope(s, np.where(data.cutting, data.limits[key], np.nan)), color="#d62728", lw=1.0,
                    label="limit")
            top = 1.3 * max(np.nanmax(np.where(data.cutting, value, np.nan), initial=0.0), 1e-9)
            ax.set_ylim(0, top)  # a far-off limit would flatten the signal: say where it is instead
            lowest = np.nanmin(np.where(data.cutting, data.limits[key], np.nan), initial=np.inf)
            if lowest > top:
                ax.text(0.01, 0.9, f"limit ≥ {lowest:.3g}: off the scale", transform=ax.transAxes, fontsize=8,
                        color="#d62728")
        unit = key.rsplit("_", 1)[1]
        ax.set_ylabel(f"{LABELS[key]} ({'of limit' if unit == 'ratio' else unit})")
        ax.legend(loc="upper right", fontsize=8)
        _along_path(ax, data)
    axes[-2].set_xlabel("path length s (mm)") if keys else None
    ax = axes[-1]
    names = sorted(ratios)
    ax.bar(names, [ratios[k] for k in names], color=["#d62728" if ratios[k] >= TIGHT else "#1f77b4" for k in names])
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_ylabel("largest value / limit")
    ax.tick_params(axis="x", labelrotation=30)
    return svg(fig, "loads-vs-limits")


PLAN_BOX_IN = (8.6, 6.0)  # the largest XY view (width, height), inches
PLAN_ASPECT = (0.4, 5.0)  # the view's width / height kept within these: a part beyond is padded
# margins (inches): tick labels and axis label left and below, colour bar thickness and its labels
LEFT, RIGHT, TOP, BELOW, BAR, BAR_TEXT, GAP = 0.9, 0.3, 0.4, 0.6, 0.2, 0.8, 0.2


def plan_view(extent: tuple[float, float, float, float]):
    """A figure for the XY extent (x0, x1, y0, y1) mm at one scale on X and Y, in a view with the part's
    proportions (within PLAN_ASPECT) as large as PLAN_BOX_IN allows, and a colour bar as long as the
    view's long side: under a wide view, beside a tall one. Returns (figure, axes, colour bar axes)."""
    from matplotlib.figure import Figure
    x0, x1, y0, y1 = extent
    wmax, hmax = PLAN_BOX_IN
    r = float(np.clip(max(x1 - x0, 1e-6) / max(y1 - y0, 1e-6), *PLAN_ASPECT))
    wide = r > (wmax + RIGHT - GAP - BAR - BAR_TEXT) / hmax  # a bar beside it would make the figure wider
    w = min(wmax, hmax * r)
    h = w / r
    if wide:
        fw, fh = LEFT + w + RIGHT, TOP + h + BELOW + BAR + BAR_TEXT
        view, bar = (LEFT, BAR_TEXT + BAR + BELOW, w, h), (LEFT, BAR_TEXT, w, BAR)
    else:
        fw, fh = LEFT + w + GAP + BAR + BAR_TEXT, TOP + h + BELOW
        view, bar = (LEFT, BELOW, w, h), (LEFT + w + GAP, BELOW, BAR, h)
    fig = Figure(figsize=(fw, fh))
    ax, cax = (fig.add_axes((a / fw, b / fh, c / fw, d / fh)) for a, b, c, d in (view, bar))
    scale = max((x1 - x0) / w, (y1 - y0) / h)  # mm per inch; the short side padded to the view
    xc, yc = (x0 + x1) / 2, (y0 + y1) / 2
    ax.set_xlim(xc - scale * w / 2, xc + scale * w / 2)
    ax.set_ylim(yc - scale * h / 2, yc + scale * h / 2)
    ax.set_aspect("equal")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    return fig, ax, cax


def _colour_bar(fig, mappable, cax, label: str) -> None:
    wide = cax.get_position().width > cax.get_position().height
    fig.colorbar(mappable, cax=cax, orientation="horizontal" if wide else "vertical", label=label)


@dataclass
class Grid:
    """Square cells of `cell` mm from (x0, y0), `shape` (rows along Y, columns along X)."""

    x0: float
    y0: float
    cell: float
    shape: tuple[int, int]

    @classmethod
    def around(cls, x: np.ndarray, y: np.ndarray, cells: int, finest: float) -> Grid:
        """About `cells` cells along the longer side of the points' extent (2 % margin), none under `finest`."""
        pad = max(0.02 * max(np.ptp(x), np.ptp(y)), 0.5)
        cell = max((max(np.ptp(x), np.ptp(y)) + 2 * pad) / cells, finest)
        shape = (int((np.ptp(y) + 2 * pad) // cell) + 1, int((np.ptp(x) + 2 * pad) // cell) + 1)
        return cls(float(x.min() - pad), float(y.min() - pad), cell, shape)

    @property
    def extent(self) -> tuple[float, float, float, float]:
        return self.x0, self.x0 + self.shape[1] * self.cell, self.y0, self.y0 + self.shape[0] * self.cell

    def least(self, x: np.ndarray, y: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The least v of the points in each cell, nan in a cell none falls in."""
        ny, nx = self.shape
        ix = np.clip(((x - self.x0) / self.cell).astype(int), 0, nx - 1)
        iy = np.clip(((y - self.y0) / self.cell).astype(int), 0, ny - 1)
        order = np.argsort(-v, kind="stable")  # written largest first: the least stays
        grid = np.full(nx * ny, np.nan)
        grid[(iy * nx + ix)[order]] = v[order]
        return grid.reshape(self.shape)

    def centres(self, iy: np.ndarray, ix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.x0 + (ix + 0.5) * self.cell, self.y0 + (iy + 0.5) * self.cell


def top_view(data: ReportData) -> str:
    """Every cutting sample, one point per cell of a grid of ~800 cells along the part's long side (at
    least one sample step each) coloured by the least optimized feed in it; crosses on cells where the
    feed is under 90 % of the programmed one."""
    tr = data.trace
    pick = data.cutting if data.cutting.any() else np.ones(len(tr["s_mm"]), bool)
    x, y, feed = tr["x"][pick], tr["y"][pick], tr["feed_executed_mm_min"][pick]
    step = np.diff(tr["s_mm"])
    grid = Grid.around(x, y, 800, float(np.median(step[step > 0])) if (step > 0).any() else 0.0)
    fig, ax, cax = plan_view(grid.extent)
    least = grid.least(x, y, feed)
    iy, ix = np.nonzero(np.isfinite(least))
    order = np.argsort(-least[iy, ix], kind="stable")  # the slowest drawn last, on top
    pts = ax.scatter(*grid.centres(iy[order], ix[order]), c=least[iy, ix][order], s=3, cmap="viridis",
                     rasterized=True)
    _colour_bar(fig, pts, cax, "least optimized feed (mm/min)")
    iy, ix = np.nonzero(grid.least(x, y, feed / tr["feed_programmed_mm_min"][pick]) < 0.9)
    keep = slice(None, None, max(1, len(ix) // 4000))
    ax.scatter(*grid.centres(iy[keep], ix[keep]), s=10, marker="x", color="#d62728", lw=0.6,
               label="slower than programmed (< 90 %)", rasterized=True)
    ax.legend(loc="lower left", bbox_to_anchor=(0, 1), fontsize=8, frameon=False)
    return svg(fig, "top-view")


def stock_map(data: ReportData) -> str:
    from matplotlib import colormaps
    st = data.stock
    fig, ax, cax = plan_view(st.extent)
    im = ax.imshow(st.top, origin="lower", extent=st.extent, cmap=colormaps["viridis"].with_extremes(bad="#c8c8c8"),
                   interpolation="nearest", rasterized=True)  # grey cut through, white beyond the stock
    _colour_bar(fig, im, cax, "top of material Z (mm); grey: cut through")
    return svg(fig, "stock-map")


def stability_lobes(lobes: ToolLobes) -> str:
    """One tool's lobe diagram: a_lim (mm) against spindle speed (rpm) per immersion (the most cut first, its
    stable pockets marked, the `POCKET_LABELS` fastest labelled in rpm), and the program's (rpm, ap) points, those over their limit in red."""
    fig, (ax,) = _figure(height_in=3.8)
    for k, c in enumerate(lobes.curves):
        colour = ("#1f77b4", "#9467bd", "#8c564b")[k % 3]
        feed = ", feed along Y" if c.along_y else ""
        ax.plot(c.rpm, c.a_lim_mm, color=colour, lw=1.1 if k == 0 else 0.8, gid=f"lobe-{k}",
                label=f"a_lim, φ {c.phi_st_deg:g}–{c.phi_ex_deg:g}°{feed} ({c.samples} samples)")
        ax.plot([p.rpm for p in c.pockets], [p.depth_mm for p in c.pockets], "v", color=colour, ms=5)
        for p in c.pockets[:POCKET_LABELS] if k == 0 else ():  # the fastest: the widest, deepest pockets
            ax.annotate(f"{p.rpm:.0f}", (p.rpm, p.depth_mm), textcoords="offset points", xytext=(0, 9),
                        ha="center", fontsize=7, color=colour)
    for sel, style, colour, name in ((~lobes.points_over, "o", "#2ca02c", "stable"),
                                     (lobes.points_over, "X", "#d62728", "above a_lim (chatter)")):
        if sel.any():
            ax.plot(lobes.points_rpm[sel], lobes.points_ap_mm[sel], style, color=colour, ms=7,
                    gid=f"cuts-{name.split()[0]}", label=f"program's cuts, {name}")
    finite = np.concatenate([c.a_lim_mm[np.isfinite(c.a_lim_mm)] for c in lobes.curves] + [lobes.points_ap_mm])
    ax.set_ylim(0, 1.15 * max(float(np.percentile(finite, 98)), float(lobes.points_ap_mm.max()), 1e-6))
    ax.set_xlim(lobes.curves[0].rpm[0], lobes.curves[0].rpm[-1])
    ax.set_xlabel("spindle speed (rpm)")
    ax.set_ylabel("axial depth (mm)")
    ax.set_title(f"T{lobes.tool} ({lobes.flutes} flutes): zero-order stability lobes", fontsize=10)
    ax.legend(loc="upper left", fontsize=8)
    return svg(fig, f"lobes-T{lobes.tool}")


def surface_error_map(x: np.ndarray, y: np.ndarray, errors_um: dict[str, np.ndarray]) -> str:
    """Top view of the predicted surface error along the finished walls and floors, one panel per state
    (e.g. programmed, compensated): each wall or floor sample at its programmed XY (mm), coloured by its
    error (µm; + material left, − overcut) on one diverging scale symmetric about 0; samples that finish
    no surface (nan) are left out."""
    finite = [e[np.isfinite(e)] for e in errors_um.values()]
    top = max((float(np.abs(e).max()) for e in finite if len(e)), default=1.0) or 1.0
    fig, axes = _figure(10.0, 2.6, rows=len(errors_um))
    for ax, (name, err) in zip(axes, errors_um.items()):
        ok = np.isfinite(err)
        pts = ax.scatter(x[ok], y[ok], c=err[ok], s=4, cmap="RdBu_r", vmin=-top, vmax=top, rasterized=True)
        rms = float(np.sqrt(np.mean(err[ok] ** 2))) if ok.any() else 0.0
        ax.set_title(f"{name}: RMS {rms:.1f} µm, largest {float(np.abs(err[ok]).max(initial=0.0)):.1f} µm",
                     fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("X (mm)")
        ax.set_ylabel("Y (mm)")
        fig.colorbar(pts, ax=ax, label="surface error (µm)")
    return svg(fig, "surface-error")
