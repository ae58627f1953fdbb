"""The report page: one HTML file with its figures inline (SVG) and no outside references, so it
opens offline and can be mailed or archived as is."""

from __future__ import annotations

import html
import os

from ..files import write_atomic
from ..summary import JobStatus
from . import figures
from .data import ReportData, operation_times

STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.15em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; } td, th { padding: 0.2em 0.7em; text-align: right; }
td:first-child, th:first-child { text-align: left; } tr:nth-child(even) { background: #f4f4f4; }
.headline { font-size: 1.1em; } figure { margin: 0.5em 0; } svg { max-width: 100%; height: auto; }
"""
STYLE += f".status-{JobStatus.SOLVED} {{ color: #2ca02c; }} .status-{JobStatus.FALLBACK} {{ color: #d62728; }}\n"


def headline(summary: dict) -> str:
    """One line a machinist reads: status, cycle time programmed → optimized (change), the baseline,
    and the limit that holds the feed most of the time."""
    before, after = summary.get("cycle_time_before_s"), summary.get("cycle_time_after_s")
    base = summary.get("cycle_time_baseline_s")
    if before is None or after is None:
        return "no optimize summary given: cycle times unknown"
    text = f"{summary.get('status', '?')}: cycle time {before:.1f} s programmed → {after:.1f} s optimized"
    if before > 0:
        text += f" ({100 * (after / before - 1):+.0f} %)"
    if base:
        text += f"; one safe constant feed per tool and programmed F: {base:.1f} s"
    binding = summary.get("binding") or {}
    if binding:
        name, share = max(binding.items(), key=lambda kv: kv[1])
        text += f"; feed held mostly by {name} ({100 * share:.0f} % of cutting time)"
    return text


def _table(rows: list[dict], columns: list[tuple[str, str, str]]) -> str:
    head = "".join(f"<th>{html.escape(title)}</th>" for _, title, _ in columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(format(r[key], fmt))}</td>" for key, _, fmt in columns)
                   + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def render(data: ReportData) -> str:
    """The whole page as text."""
    s = data.summary
    rows = operation_times(data)
    status = html.escape(str(s.get("status", "")))
    parts = [f"<h1>millpost job report: {html.escape(data.title)}</h1>",
             f'<p class="headline status-{status}">{html.escape(headline(s))}</p>']
    if s.get("message"):
        parts.append(f"<p>{html.escape(s['message'])}</p>")
    binding = s.get("binding", {})
    if binding:
        parts.append("<p>What limits the feed (share of cutting time): " + html.escape(", ".join(
            f"{k} {100 * v:.0f} %" for k, v in sorted(binding.items(), key=lambda kv: -kv[1]))) + "</p>")
    parts += ["<h2>Cycle time per operation</h2>",
              "<p>Feed moves only, rapids left out: at the programmed F, at the baseline F (per tool and programmed "
              "F, as a machinist tunes a CAM program's cutting, plunge and lead-in feeds: the highest constant feed "
              "that exceeds no limit anywhere those moves cut; plunges and approaches at most their caps) and as "
              "the controller model executes the optimized program (with its ramps). The headline's totals are the controller model's for the whole program.</p>",
              _table([{**r, "operation": f"{k + 1}. {r['operation']}"} for k, r in enumerate(rows)],
                     [("operation", "operation", ""), ("tool", "tool", "d"),
                      ("length_mm", "cut length (mm)", ".0f"), ("programmed_s", "programmed (s)", ".1f"),
                      ("baseline_s", "baseline (s)", ".1f"), ("optimized_s", "optimized (s)", ".1f")]),
              f"<figure>{figures.cycle_times(data)}</figure>",
              "<h2>Feed along the path</h2><p>From the first cut to the last: the programmed feed (grey) and the "
              "optimized feed as executed (blue), each with the lowest and highest feed of every stretch drawn; "
              "below, the share of each stretch's cutting length each limit holds. Dotted lines: operation starts, "
              "numbered as in the table.</p>", f"<figure>{figures.feed_along_path(data)}</figure>",
              "<h2>Loads against their limits</h2><p>Along the path at the optimized feed; the last panel is each "
              "limit's largest value over its bound on the whole program replayed (drive current included).</p>",
              f"<figure>{figures.loads_vs_limits(data)}</figure>",
              "<h2>Top view</h2><p>Every cutting move, coloured by the lowest optimized feed at each spot; "
              "crosses where it is slower than programmed.</p>", f"<figure>{figures.top_view(data)}</figure>"]
    if data.stock is not None:
        parts += ["<h2>Final stock</h2>", f"<figure>{figures.stock_map(data)}</figure>"]
    parts += _lobes_section(data)
    parts += _surface_section(data)
    notes = list(s.get("notes", []))
    for name, h in s.get("held", {}).items():
        notes.append(f"{name} ({h['kind']}) held by the feed policy on {h['line_count']} lines "
                     f"(from line {h['lines'][0]}): {h['reason']}")
    if s.get("chip_floor_unmet_samples"):
        notes.append(f"{s['chip_floor_unmet_samples']} samples cannot reach the material's minimum chip "
                     "(the tool rubs there)")
    parts.append("<h2>Notes</h2>" + ("<ul>" + "".join(f"<li>{html.escape(str(n))}</li>" for n in notes) + "</ul>"
                                     if notes else "<p>none</p>"))
    body = "\n".join(parts)
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>millpost: '
            f"{html.escape(data.title)}</title><style>{STYLE}</style></head><body>\n{body}\n</body></html>\n")


def _lobes_section(data: ReportData) -> list[str]:
    """The stability lobes per tool with a tip FRF (nothing without one; a note when they cannot be drawn)."""
    if not data.lobes and not data.lobes_note:
        return []
    text = ("<h2>Chatter: stability lobes</h2><p>Per tool with a tip FRF: the zero-order limiting depth against "
            "spindle speed over the spindle's range, at the immersions the tool cuts (most cut first), with its "
            "stable pockets (triangles); the program's cuts at their speed and depth, crosses where a cut is above "
            "the stable depth of its own immersion (the lines the notes list).</p>")
    if data.lobes_note:
        return [text, f"<p>No lobes here: {html.escape(data.lobes_note)}.</p>"]
    return [text] + [f"<figure>{figures.stability_lobes(t)}</figure>" for t in data.lobes]


def write_report(path: str | os.PathLike, data: ReportData) -> None:
    """Write the page atomically."""
    write_atomic(path, render(data))


_SURFACE_MAP = ("The deflected tool's envelope against the programmed one, at each sample that finishes a wall or a "
                "floor (wall where both): red material left, blue overcut.")


def compensation_page(summary: dict, figure: str) -> str:
    """The page of `millpost compensate --report`: the predicted surface error per operation before and
    after, and its map (`figures.surface_error_map`)."""
    title = html.escape(str(summary.get("program", "")))
    body = "\n".join([
        f"<h1>millpost compensate: {title}</h1>",
        '<p class="headline">predicted surface error (RMS over walls and floors) '
        f'{summary["surface_error_before_um"]:.1f} → {summary["surface_error_after_um"]:.1f} µm</p>',
        _surface_table(summary["operations"], ("before", "after")),
        f"<h2>Surface error along walls and floors</h2><p>{_SURFACE_MAP}</p>", f"<figure>{figure}</figure>"])
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>millpost compensate: {title}'
            f"</title><style>{STYLE}</style></head><body>\n{body}\n</body></html>\n")


def _surface_table(operations: list[dict], states: tuple[str, ...]) -> str:
    """Per operation and surface it finishes, each state's RMS and largest error (µm)."""
    rows = [{"operation": op["operation"], "surface": surf,
             **{f"{st}_{k}": op[st][surf][f"{k}_um"] for st in states for k in ("rms", "max")}}
            for op in operations for surf in ("wall", "floor") if surf in op[states[0]]]
    return _table(rows, [("operation", "operation", ""), ("surface", "surface", "")]
                  + [(f"{st}_rms", f"RMS {st} (µm)", ".1f") for st in states]
                  + [(f"{st}_max", f"largest {st} (µm)", ".1f") for st in states])


def _surface_section(data: ReportData) -> list[str]:
    """The predicted surface error as programmed and as optimized (nothing when the trace has none)."""
    states = tuple(st for st in ("programmed", "optimized") if f"surface_error_{st}_um" in data.trace)
    entry = data.summary.get("surface_error")
    if not states or not entry:
        return []
    t = data.trace
    figure = figures.surface_error_map(t["x"], t["y"], {st: t[f"surface_error_{st}_um"] for st in states})
    return ["<h2>Predicted surface error</h2><p>Where the tool bends under the predicted force (its beam and the "
            "machine's compliance), at the programmed and at the optimized feed: a faster feed pushes harder. "
            f"{_SURFACE_MAP}</p>", _surface_table(entry["operations"], states), f"<figure>{figure}</figure>"]
