"""A tool's tip FRF as a job file gives it: the table `[tools.N.frf]` (the fragment `millpost tap` prints).

    [tools.1.frf]
    x = [{fn_hz = 1800, zeta = 0.03, k_N_per_mm = 4000}]   # modes seen at the tip in machine X
    y = [{fn_hz = 1750, zeta = 0.03, k_N_per_mm = 3800}]   # optional: y = x (a round tool)

or a measured receptance, `csv = "frf.csv"` (relative to the job file) with the header
`f_hz, re_x_mm_per_N, im_x_mm_per_N, re_y_mm_per_N, im_y_mm_per_N` (any order) and one row per
frequency, ascending (blank lines and lines starting with # are skipped). A refusal names the file,
the field or the file's line and column; a table whose imaginary part is positive where |G| is largest is
refused (a driving-point receptance has Im G ≤ 0: another sign convention, or not a receptance), and the
doubts `DirectionFRF.doubts` lists (a band missing the resonance, m/N values) are noted by the check.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..config import Table, load_toml
from ..errors import ConfigError, ParseError
from .frf import DirectionFRF, Mode, ToolTipFRF

COLUMNS = ("f_hz", "re_x_mm_per_N", "im_x_mm_per_N", "re_y_mm_per_N", "im_y_mm_per_N")
FN_MAX_HZ = 5e4        # no tool-tip mode that matters sits above 50 kHz: a larger value is a slip
K_MAX_N_PER_MM = 1e7   # N/mm (10 N/nm): stiffer than any spindle, holder and tool at the tip


def frf_from_table(t: Table, base: Path) -> tuple[ToolTipFRF, Path | None]:
    """The FRF of a `[tools.N.frf]` table (`t`), and the CSV file it names (None for modes); `base`: the
    job file's folder."""
    t.done(("x", "y", "csv"))           # unknown fields first: a misspelt one is named, not a missing one
    if t.has("csv"):
        if t.has("x") or t.has("y"):
            raise t.fail("csv", t.data["csv"], "give modes (x, y) or a measured csv, not both")
        path = base / t.string("csv")
        if not path.is_file():
            raise t.fail("csv", str(path), "file not found")
        return read_frf_csv(path), path
    x = DirectionFRF(modes=_modes(t, "x"))
    y = DirectionFRF(modes=_modes(t, "y")) if t.has("y") else x
    return ToolTipFRF(x, y), None


def frf_from_file(path: str | Path, tool: int | None = None) -> tuple[int, ToolTipFRF]:
    """(tool number, FRF) of the `[tools.N.frf]` table in a TOML file (`millpost tap fit --toml` writes one,
    a job file holds one per tool): tool `tool`, or the only one the file gives."""
    path = Path(path)
    f = str(path)
    if not path.is_file():
        raise ConfigError("--frf", f, "file not found", file=f)
    tools = load_toml(path).get("tools", {})
    given = {int(k): v["frf"] for k, v in tools.items() if str(k).isdigit() and isinstance(v, dict) and "frf" in v} \
        if isinstance(tools, dict) else {}
    if not given:
        raise ConfigError("tools.N.frf", None, "no [tools.N.frf] table (the form `millpost tap fit --toml` writes)",
                          file=f)
    if tool is None and len(given) > 1:
        raise ConfigError("tools", sorted(given), "more than one tool has an FRF: choose one (--frf-tool N)", file=f)
    n = tool if tool is not None else next(iter(given))
    if n not in given:
        raise ConfigError(f"tools.{n}.frf", None, f"not in the file (tools with an FRF: {sorted(given)})", file=f)
    return n, frf_from_table(Table(given[n], f"tools.{n}.frf", f), path.parent)[0]


def _modes(t: Table, key: str) -> tuple[Mode, ...]:
    """The modes listed under `key` (fn_hz > 0, 0 < zeta < 1, k_N_per_mm > 0, with units as elsewhere)."""
    modes = []
    for m in t.tables(key):
        m.done(("fn_hz", "zeta", "k_N_per_mm"))     # a misspelt field is named before a missing one
        modes.append(Mode(m.number("fn_hz", gt=0, le=FN_MAX_HZ), m.number("zeta", gt=0, lt=1),
                          m.number("k_N_per_mm", gt=0, le=K_MAX_N_PER_MM)))
    return tuple(modes)


def read_frf_csv(path: str | Path) -> ToolTipFRF:
    """A measured tool-tip receptance (mm/N) in X and Y from a CSV file with the `COLUMNS`."""
    path = Path(path)
    rows: list[tuple[int, list[str]]] = []
    for n, text in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), start=1):
        if text.strip() and not text.lstrip().startswith("#"):
            rows.append((n, text.split(",")))
    if not rows:
        raise ParseError("empty FRF table", file=str(path), line=1, column=1, expected="a header: " + ", ".join(COLUMNS))
    head_line, head = rows[0]
    names = [h.strip() for h in head]
    missing = [c for c in COLUMNS if c not in names]
    if missing or len(names) != len(COLUMNS):
        extra = [h for h in names if h not in COLUMNS]
        raise ParseError(f"FRF header: missing {', '.join(missing) or 'nothing'}", file=str(path), line=head_line,
                         column=1, word=", ".join(extra), expected="the columns " + ", ".join(COLUMNS))
    order = [names.index(c) for c in COLUMNS]
    table = np.array([_row(path, n, cells, order) for n, cells in rows[1:]]).reshape(-1, len(COLUMNS))
    if len(table) < 2:
        raise ParseError("an FRF table needs at least two frequencies", file=str(path), line=rows[-1][0], column=1)
    for k in range(1, len(table)):
        if table[k, 0] <= table[k - 1, 0]:
            n, cells = rows[k + 1]
            raise ParseError("frequencies must ascend", file=str(path), line=n, column=_column(cells, order[0]),
                             word=cells[order[0]].strip(), expected=f"more than {table[k - 1, 0]:g} Hz")
    f = table[:, 0]
    for d, re, im in (("x", 1, 2), ("y", 3, 4)):
        k = int(np.argmax(np.hypot(table[:, re], table[:, im])))
        if table[k, im] > 0:
            n, cells = rows[k + 1]
            raise ParseError(f"Im G_{d} > 0 where |G_{d}| is largest ({f[k]:g} Hz): not a driving-point receptance "
                             "(its imaginary part is ≤ 0 at every frequency)", file=str(path), line=n,
                             column=_column(cells, order[im]), word=cells[order[im]].strip(),
                             expected="G = displacement / force in mm/N, Im G < 0 (a response in the opposite "
                                      "direction, or an accelerance or mobility, gives another sign)")
    x = DirectionFRF(f_hz=f, measured_mm_per_N=table[:, 1] + 1j * table[:, 2])
    y = DirectionFRF(f_hz=f, measured_mm_per_N=table[:, 3] + 1j * table[:, 4])
    return ToolTipFRF(x, y)


def _row(path: Path, line: int, cells: list[str], order: list[int]) -> list[float]:
    """One row's numbers in `COLUMNS` order; a cell that is not a finite number (or a negative
    frequency) is refused at its line and column."""
    if len(cells) != len(COLUMNS):
        raise ParseError(f"{len(cells)} cells", file=str(path), line=line, column=1,
                         expected=f"{len(COLUMNS)}: " + ", ".join(COLUMNS))
    out = []
    for name, i in zip(COLUMNS, order):
        text = cells[i].strip()
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or (name == "f_hz" and value < 0):
            raise ParseError(f"{name} is not a {'frequency ≥ 0' if name == 'f_hz' else 'finite number'}",
                             file=str(path), line=line, column=_column(cells, i), word=text,
                             expected="Hz" if name == "f_hz" else "mm/N")
        out.append(value)
    return out


def _column(cells: list[str], i: int) -> int:
    """The 1-based character column where cell `i` starts (past its leading spaces)."""
    start = sum(len(c) + 1 for c in cells[:i])
    return start + len(cells[i]) - len(cells[i].lstrip()) + 1

