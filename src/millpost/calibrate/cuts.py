"""Tables of steady cuts: the format and its reader (the fits: `millpost.calibrate.coefficients`).

A table of steady cuts is a CSV, one row per cut along +X beside a wall (ae ≥ D is a slot):

    diameter_mm,flutes,helix_deg,ae_mm,ap_mm,fz_mm,rpm[,climb][,fx_N,fy_N,fz_N][,spindle_power_W]

climb is 1 (down milling, default) or 0; fx_N, fy_N, fz_N are the mean force on the **tool** over whole
revolutions (the convention `millpost calc` prints: x along the feed, y to the left of it, z the tool
axis), spindle_power_W the mean cutting power (spindle power minus its no-load power at that speed).

One row is enough to fit (one test cut): what it cannot tell apart stays at the base material's values.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..engagement import Engagement
from ..errors import ParseError
from ..files import write_csv
from ..forces import Measurements, given_cut
from ..measure.log import read_table
from ..tools.cutter import Tool

CUT_COLUMNS = {
    "diameter_mm": "tool diameter (mm)", "flutes": "number of flutes", "helix_deg": "helix angle (deg)",
    "ae_mm": "radial width of cut (mm)", "ap_mm": "axial depth of cut (mm)", "fz_mm": "feed per tooth (mm)",
    "rpm": "spindle speed (rpm)", "climb": "1 climb, 0 conventional",
    "fx_N": "mean force on the tool along the feed (N)", "fy_N": "mean force on the tool, left of the feed (N)",
    "fz_N": "mean force on the tool along its axis (N)", "spindle_power_W": "mean cutting power (W)",
}
REQUIRED = ("diameter_mm", "flutes", "helix_deg", "ae_mm", "ap_mm", "fz_mm", "rpm")


@dataclass
class Cuts:
    """Steady cuts (N rows). force_N: (N, 3) mean force on the tool, feed frame, nan where not measured;
    power_W: (N,) cutting power, nan where not measured. Lengths mm, speeds rpm."""

    diameter_mm: np.ndarray
    flutes: np.ndarray
    helix_deg: np.ndarray
    ae_mm: np.ndarray
    ap_mm: np.ndarray
    fz_mm: np.ndarray
    rpm: np.ndarray
    climb: np.ndarray
    force_N: np.ndarray
    power_W: np.ndarray
    source: str = "<cuts>"

    def __len__(self) -> int:
        return len(self.ae_mm)

    @property
    def has_force(self) -> bool:
        return bool(np.isfinite(self.force_N).any())

    @property
    def has_power(self) -> bool:
        return bool(np.isfinite(self.power_W).any())

    def tools(self) -> list[Tool]:
        return [Tool(diameter_mm=float(d), flutes=int(n), helix_deg=float(h))
                for d, n, h in zip(self.diameter_mm, self.flutes, self.helix_deg)]

    def engagement(self) -> Engagement:
        """Per row the engagement of a straight cut along +X (`given_cut`), in row order."""
        parts, order = [], []
        tools = self.tools()
        keys = sorted({(t.diameter_mm, t.flutes, t.helix_deg, int(c)) for t, c in zip(tools, self.climb)})
        for key in keys:
            idx = np.flatnonzero([(t.diameter_mm, t.flutes, t.helix_deg, int(c)) == key
                                  for t, c in zip(tools, self.climb)])
            parts.append(given_cut(tools[idx[0]], self.ae_mm[idx], self.ap_mm[idx], climb=bool(key[3]), slices=8))
            order.append(idx)
        eng = Engagement.concatenate(parts)
        return eng.select(np.argsort(np.concatenate(order)))

    def measurements(self) -> Measurements:
        return Measurements(fz_mm=self.fz_mm, rpm=self.rpm, force_N=self.force_N if self.has_force else None,
                            power_W=self.power_W if self.has_power else None)

    def write(self, path: str | os.PathLike) -> None:
        cols = {"diameter_mm": self.diameter_mm, "flutes": self.flutes, "helix_deg": self.helix_deg,
                "ae_mm": self.ae_mm, "ap_mm": self.ap_mm, "fz_mm": self.fz_mm, "rpm": self.rpm, "climb": self.climb,
                "fx_N": self.force_N[:, 0], "fy_N": self.force_N[:, 1], "fz_N": self.force_N[:, 2],
                "spindle_power_W": self.power_W}
        write_csv(path, cols, {"flutes": "%d", "climb": "%d", "fz_mm": "%.6g", "rpm": "%.6g"})


def read_cuts(path: str | os.PathLike) -> Cuts:
    """Read a table of steady cuts; errors name file:row:column and what was expected."""
    def check(name, *, file, line, column):
        if name not in CUT_COLUMNS:
            raise ParseError(f"unknown column {name!r}", file=file, line=line, column=column, word=name,
                             expected=f"one of {', '.join(CUT_COLUMNS)}")
    cols, header_at = read_table(path, check, required=REQUIRED, describe=CUT_COLUMNS)
    n = len(cols["ae_mm"])
    if n == 0:
        raise ParseError("no cuts in the table", file=str(path), line=header_at + 1, column=1,
                         expected="one row per cut")
    names = list(cols)
    for key, rule, ok in (("diameter_mm", "> 0", lambda v: v > 0), ("flutes", "a whole number >= 1",
                                                                      lambda v: (v >= 1) & (v == np.round(v))),
                          ("ae_mm", "> 0", lambda v: v > 0), ("ap_mm", "> 0", lambda v: v > 0),
                          ("fz_mm", "> 0", lambda v: v > 0), ("rpm", "> 0", lambda v: v > 0),
                          ("helix_deg", "in [0, 60]", lambda v: (v >= 0) & (v <= 60)),
                          ("climb", "1 or 0", lambda v: (v == 0) | (v == 1))):
        if key in cols:
            bad = np.flatnonzero(~ok(cols[key]))
            if len(bad):
                line, text = _row_line(path, header_at, bad[0])
                column = len(",".join(text.split(",")[:names.index(key)])) + (1 if names.index(key) == 0 else 2)
                raise ParseError(f"{key} must be {rule}", file=str(path), line=line, column=column,
                                 word=f"{cols[key][bad[0]]:g}", expected=rule)
    nan = np.full(n, np.nan)
    force = np.column_stack([cols.get(k, nan) for k in ("fx_N", "fy_N", "fz_N")])
    power = cols.get("spindle_power_W", nan)
    if not (np.isfinite(force).any() or np.isfinite(power).any()):
        raise ParseError("no measured forces or power", file=str(path), line=header_at, column=1,
                         expected="columns fx_N, fy_N, fz_N and/or spindle_power_W")
    return Cuts(cols["diameter_mm"], cols["flutes"].astype(int), cols["helix_deg"], cols["ae_mm"], cols["ap_mm"],
                cols["fz_mm"], cols["rpm"], cols.get("climb", np.ones(n)).astype(int), force, power, str(path))


def _row_line(path, header_at: int, row: int) -> tuple[int, str]:
    """(1-based line number, text) of data row `row` (0-based; comments and blank lines skipped)."""
    k = -1
    for lineno, raw in enumerate(Path(path).read_text().splitlines(), start=1):
        if lineno > header_at and raw.strip() and not raw.lstrip().startswith("#"):
            k += 1
            if k == row:
                return lineno, raw
    return header_at + row + 1, ""
