"""What a program does, in numbers: the `millpost inspect` report and the per-move CSV."""

from __future__ import annotations

import csv
import io

import numpy as np

from ..toolpath import ARC_CW, FEED, KIND_NAMES, RAPID
from .interpret import Program


def summary(program: Program) -> dict:
    """Counts, lengths (mm), bounding box of the swept path (mm, arc extremes included), tools,
    spindle speeds (rpm) and the time at programmed feeds (s: feed moves at their F, plus dwells;
    rapids excluded because their speed is the machine's, not the program's)."""
    tp = program.toolpath
    L = tp.lengths()
    rapid = tp.kind == RAPID
    cutting = ~rapid
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(cutting & (tp.feed_mm_min > 0), L / tp.feed_mm_min * 60.0, 0.0)
    bbox = tp.bbox()
    return {
        "file": program.path,
        "dialect": program.dialect,
        "units": program.units[0] if len(program.units) == 1 else program.units,
        "blocks": program.blocks,
        "moves": {"rapid": int(rapid.sum()), "feed": int((tp.kind == FEED).sum()),
                  "arc": int((tp.kind >= ARC_CW).sum())},
        "feed_length_mm": float(L[cutting].sum()),
        "rapid_length_mm": float(L[rapid].sum()),
        "bbox_mm": None if len(tp) == 0 else [[float(v) for v in bbox[0]], [float(v) for v in bbox[1]]],
        "tools": program.tools,
        "spindle_rpm": program.spindle_rpm,
        "time_at_programmed_feed_s": float(t.sum() + program.dwell_s),
        "dwell_s": program.dwell_s,
        "notes": program.notes,
    }


def moves_csv(program: Program) -> str:
    """CSV `line,kind,x,y,z,feed_mm_min`: end points in mm in the program frame, one row per move."""
    tp = program.toolpath
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["line", "kind", "x", "y", "z", "feed_mm_min"])
    for i in range(len(tp)):
        x, y, z = tp.end[i]
        f = tp.feed_mm_min[i]
        w.writerow([int(tp.line[i]), KIND_NAMES[tp.kind[i]], f"{x:.6f}", f"{y:.6f}", f"{z:.6f}",
                    "" if np.isnan(f) else f"{f:.6f}"])
    return out.getvalue()
