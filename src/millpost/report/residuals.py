"""The discover report: per measured channel, the held-out residual (measured − model) over time with
the refitted base model and with the named effects, on one self-contained HTML page."""

from __future__ import annotations

import html

import numpy as np

from ..files import write_atomic
from .figures import _figure, envelope, svg
from .page import STYLE, _table


def residual_figure(t_s: np.ndarray, measured: dict, before: dict, after: dict, held: np.ndarray) -> str:
    """One panel per channel: residual before (grey) and after (blue) on the held-out rows (min/max
    envelope of ~2000 buckets)."""
    chans = list(measured)
    fig, axes = _figure(10.0, 2.2, rows=len(chans))
    for ax, c in zip(axes, chans):
        for pred, colour, label in ((before, "#999999", "refitted base"), (after, "#1f77b4", "with effects")):
            r = np.where(held, measured[c] - pred[c], np.nan)
            ok = np.isfinite(r)
            x, y = envelope(t_s[ok], r[ok])
            ax.plot(x, y, lw=0.6, color=colour, label=label)
        ax.set_ylabel(f"{c} residual")
        ax.axhline(0, color="k", lw=0.4)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("log time (s), held-out blocks")
    return svg(fig, "discover-residuals")


def write_discover_report(path, title: str, summary: dict, t_s, measured, before, after, held) -> None:
    """The page: effects table, held-out RMS per channel, notes, residual figure."""
    rms = [{"channel": c, "before": summary["rms_before"][c], "after": summary["rms_after"][c]}
           for c in summary["rms_before"]]
    eff = [{"name": e["name"], "channels": ", ".join(e["channels"]),
            "params": ", ".join(f"{k}={v:.4g} ± {e['stderr'].get(k) or float('nan'):.2g}"
                                for k, v in e["params"].items() if v is not None)} for e in summary["effects"]]
    parts = [f"<h1>millpost discover: {html.escape(title)}</h1>",
             "<h2>Named effects</h2>" + (_table(eff, [("name", "effect", ""), ("channels", "channels", ""),
                                                     ("params", "parameters ± standard error", "")])
                                        if eff else "<p>none: the refitted base model explains the held-out data</p>"),
             "<h2>Held-out RMS</h2>" + _table(rms, [("channel", "channel", ""), ("before", "refitted base", ".4g"),
                                                   ("after", "with effects", ".4g")]),
             "<h2>Residuals</h2><figure>" + residual_figure(t_s, measured, before, after, held) + "</figure>",
             "<h2>Notes</h2><ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in summary["notes"]) + "</ul>"]
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>millpost discover: {html.escape(title)}"
            f"</title><style>{STYLE}</style></head><body>{''.join(parts)}</body></html>\n")
    write_atomic(path, page)
