"""The report's figures as inline SVG (matplotlib, Agg-free SVG backend, imported here only).

Long programs have millions of samples: curves along the path are reduced to the minimum and maximum
of each of ~2000 buckets (every peak survives), dense point clouds are rasterised inside the SVG.
"""

from __future__ import annotations

import io
import re

import numpy as np

from .data import LABELS, TIGHT, ReportData, operation_times

BUCKETS = 2000
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


def _thin(n: int, buckets: int = 4 * BUCKETS) -> np.ndarray:
    return np.arange(n) if n <= buckets else np.linspace(0, n - 1, buckets).astype(int)


def cycle_times(data: ReportData) -> str:
    rows = operation_times(data)
    fig, (ax,) = _figure(height_in=max(2.2, 0.45 * len(rows) + 1.2))
    names = [f"{r['operation']} (T{r['tool']})" for r in rows]
    y = np.arange(len(rows))
    for k, (key, colour) in enumerate((("programmed", "#7f7f7f"), ("baseline", "#ff7f0e"), ("optimized", "#1f77b4"))):
        ax.barh(y + (k - 1) * 0.27, [r[f"{key}_s"] for r in rows], height=0.27, color=colour, label=key)
    ax.set_yticks(y, names)
    ax.invert_yaxis()
    ax.set_xlabel("feed time (s)")
    ax.legend(loc="lower right")
    return svg(fig, "cycle-times")


def feed_along_path(data: ReportData) -> str:
    tr, cut = data.trace, data.cutting
    s = tr["s_mm"]
    fig, (ax,) = _figure(height_in=4.0)
    ax.plot(*envelope(s, np.where(cut, tr["feed_programmed_mm_min"], np.nan)), color="#7f7f7f", lw=0.8,
            label="programmed")
    idx = np.flatnonzero(cut)
    keep = idx[_thin(len(idx))]
    labels = data.binding[keep] if data.binding is not None else np.full(len(keep), "optimized", dtype=object)
    for k, name in enumerate(sorted(set(labels.tolist()))):
        sel = keep[labels == name]
        ax.scatter(s[sel], tr["feed_executed_mm_min"][sel], s=2, color=BINDING_COLOURS[k % len(BINDING_COLOURS)],
                   label=f"optimized: {name}", rasterized=True)
    ax.set_xlabel("path length s (mm)")
    ax.set_ylabel("feed (mm/min)")
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, markerscale=4)
    return svg(fig, "feed-along-path")


def loads_vs_limits(data: ReportData) -> str:
    tr = data.trace
    s = tr["s_mm"]
    keys = [k for k in ("peak_force_N", "power_W", "deflection_mm", "chip_mm", "current_ratio") if k in tr or k in data.signals]
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
    axes[-2].set_xlabel("path length s (mm)") if keys else None
    ax = axes[-1]
    names = sorted(ratios)
    ax.bar(names, [ratios[k] for k in names], color=["#d62728" if ratios[k] >= TIGHT else "#1f77b4" for k in names])
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_ylabel("largest value / limit")
    ax.tick_params(axis="x", labelrotation=30)
    return svg(fig, "loads-vs-limits")



def top_view(data: ReportData) -> str:
    tr, cut = data.trace, data.cutting
    fig, (ax,) = _figure(width_in=8.0, height_in=6.0)
    idx = np.flatnonzero(cut)
    keep = idx[_thin(len(idx), 40_000)]
    pts = ax.scatter(tr["x"][keep], tr["y"][keep], c=tr["feed_executed_mm_min"][keep], s=3, cmap="viridis",
                     rasterized=True)
    fig.colorbar(pts, ax=ax, label="optimized feed (mm/min)")
    slower = idx[tr["feed_executed_mm_min"][idx] < 0.9 * tr["feed_programmed_mm_min"][idx]]
    slower = slower[_thin(len(slower), 4000)]
    ax.scatter(tr["x"][slower], tr["y"][slower], s=10, marker="x", color="#d62728", lw=0.6,
               label="slower than programmed (< 90 %)", rasterized=True)
    ax.set_aspect("equal")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    ax.legend(loc="upper left", bbox_to_anchor=(0, -0.1), fontsize=8)
    return svg(fig, "top-view")


def stock_map(data: ReportData) -> str:
    st = data.stock
    fig, (ax,) = _figure(width_in=8.0, height_in=6.0)
    im = ax.imshow(st.top, origin="lower", extent=st.extent, cmap="viridis", interpolation="nearest", rasterized=True)
    ax.set_facecolor("#f0f0f0")
    fig.colorbar(im, ax=ax, label="top of material Z (mm); grey: cut through")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    return svg(fig, "stock-map")
