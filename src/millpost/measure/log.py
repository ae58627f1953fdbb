"""The measurement log format: one row per sample, units in the column names.

CSV (UTF-8, comma separated, one header row) or NPZ (one array per column). Columns:

| column | meaning |
|---|---|
| `t_s` (required) | time of the sample (s), non-decreasing; any origin, any rate |
| `x_mm, y_mm, z_mm` | tool tip position, program frame (mm: work offset and tool length applied); with them every row is placed on the program's path by where the tool was |
| `line` | the program line the controller reports |
| `spindle_rpm` | spindle speed (rpm) |
| `fx_N, fy_N, fz_N` | force on the **workpiece** along machine +X, +Y, +Z (what a table dynamometer reads: −the force on the tool; a fit checks each channel's sign against the model and refuses one that runs against it) |
| `spindle_power_W` | spindle (VFD output) power (W) |
| `spindle_current_A` | spindle (VFD output) current (A) |
| `ix_A, iy_A, iz_A` | axis motor currents (A, signed: positive pushes the axis towards +) |

Other columns are kept when their name ends in a unit (`_Hz`, `_V`, `_A`, `_W`, `_N`, `_mm`, `_rpm`,
`_s`, `_pct`, `_C`, `_Nm`, `_kW`), e.g. `output_frequency_Hz`. A missing value is `nan`.

Comment lines start with `#`. Two kinds carry meaning:

    # meta <key>=<value>                               e.g. # meta start_epoch_s=1700000000.25
    # gap t_start_s=<s> t_end_s=<s> reason=<text>       an interval in which samples were lost

A gap says that no sample was taken (or kept) between its two times; `millpost log` writes one for every
interval it lost (timeouts, exception responses, a vanished server, overruns), so that nothing is lost
silently. In NPZ, gaps are the arrays `gap_t_start_s`, `gap_t_end_s`, `gap_reason`, metadata `meta_<key>`.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ParseError
from ..files import atomic_path
from ._csv import parse_numbers

COLUMNS = {
    "t_s": "time (s)",
    "x_mm": "tool position X (mm)", "y_mm": "tool position Y (mm)", "z_mm": "tool position Z (mm)",
    "line": "program line",
    "spindle_rpm": "spindle speed (rpm)",
    "fx_N": "force on the workpiece X (N)", "fy_N": "force on the workpiece Y (N)",
    "fz_N": "force on the workpiece Z (N)",
    "spindle_power_W": "spindle power (W)", "spindle_current_A": "spindle current (A)",
    "ix_A": "X motor current (A)", "iy_A": "Y motor current (A)", "iz_A": "Z motor current (A)",
}
UNIT_SUFFIXES = ("Hz", "V", "A", "W", "N", "mm", "rpm", "s", "pct", "C", "Nm", "kW")
_EXTRA = re.compile(r"^[a-z][a-z0-9_]*_(" + "|".join(UNIT_SUFFIXES) + r")$")
_GAP = re.compile(rb"^#\s*gap\s+t_start_s=(\S+)\s+t_end_s=(\S+)(?:\s+reason=(.*?))?\s*$", re.M)
_META = re.compile(rb"^#\s*meta\s+([A-Za-z_][\w.]*)=(.*?)\s*$", re.M)


@dataclass(frozen=True)
class Gap:
    """An interval (s, log time) in which samples were lost, and why."""

    t_start_s: float
    t_end_s: float
    reason: str = ""

    def line(self) -> str:
        return f"# gap t_start_s={self.t_start_s:.6f} t_end_s={self.t_end_s:.6f} reason={self.reason}"


@dataclass
class Log:
    """A measurement log: equal-length float columns (`t_s` first), lost intervals, metadata."""

    columns: dict[str, np.ndarray]
    gaps: list[Gap] = field(default_factory=list)
    meta: dict[str, str] = field(default_factory=dict)
    path: str = "<log>"

    def __post_init__(self) -> None:
        if "t_s" not in self.columns:
            raise ParseError("a log needs a t_s column", file=self.path, line=1, column=1, expected="t_s")
        n = len(self.columns["t_s"])
        for name, values in self.columns.items():
            if len(values) != n:
                raise ParseError(f"column {name} has {len(values)} values, t_s has {n}", file=self.path, line=1,
                                 column=1, word=name, expected="columns of equal length")

    def __len__(self) -> int:
        return len(self.columns["t_s"])

    @property
    def t_s(self) -> np.ndarray:
        return self.columns["t_s"]

    def has(self, name: str) -> bool:
        """The column exists and holds at least one finite value."""
        return name in self.columns and bool(np.isfinite(self.columns[name]).any())

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def select(self, index) -> "Log":
        """The rows at `index` (gaps and metadata kept)."""
        return Log({k: v[index] for k, v in self.columns.items()}, list(self.gaps), dict(self.meta), self.path)


def check_column_name(name: str, *, file: str = "<log>", line: int = 1, column: int = 1) -> None:
    """Refuse a column that is neither a known one nor a name ending in a unit."""
    if name not in COLUMNS and not _EXTRA.match(name):
        raise ParseError(f"unknown column {name!r}", file=file, line=line, column=column, word=name,
                         expected=f"one of {', '.join(COLUMNS)}, or a name ending in a unit "
                                  f"(_{', _'.join(UNIT_SUFFIXES)})")


def read_log(path: str | os.PathLike) -> Log:
    """Read a CSV or NPZ log. Errors name file:row:column, the offending text and what was expected."""
    path = Path(path)
    if path.suffix.lower() == ".npz":
        return _read_npz(path)
    data = path.read_bytes()
    columns, header_at = read_table(path, check_column_name, required=("t_s",), data=data)
    check_time(columns["t_s"], str(path), data, header_at)
    comments = b"\n".join(_comment_lines(data))
    gaps = [Gap(float(a), float(b), (r or b"").decode("utf-8", "replace")) for a, b, r in _GAP.findall(comments)]
    meta = {k.decode(): v.decode("utf-8", "replace") for k, v in _META.findall(comments)}
    return Log(columns, gaps, meta, str(path))


def _comment_lines(data: bytes) -> list[bytes]:
    """The lines that start with '#' (found with bytes.find: a log has millions of rows, a few comments)."""
    out, pos = [], 0 if data.startswith(b"#") else data.find(b"\n#")
    while pos >= 0:
        start = pos if data[pos:pos + 1] == b"#" else pos + 1
        end = data.find(b"\n", start)
        out.append(data[start:len(data) if end < 0 else end].rstrip(b"\r"))
        pos = -1 if end < 0 else data.find(b"\n#", end)
    return out


def read_table(path: str | os.PathLike, check_name, *, required: tuple[str, ...] = (),
               describe: dict[str, str] | None = None, data: bytes | None = None) -> tuple[dict[str, np.ndarray], int]:
    """A numeric CSV table with one header row (comment lines start with #): ({column: values}, header line).
    check_name(name, file=, line=, column=) refuses unknown columns; `required` columns must be present.
    Errors are ParseErrors at file:row:column naming the field and what was expected (`describe`: column
    meanings for the message)."""
    name = str(path)
    data = Path(path).read_bytes() if data is None else data
    header_at, header = _header(data, name)
    names = [h.strip() for h in header.split(",")]
    col = 1
    for h_raw, h in zip(header.split(","), names):
        check_name(h, file=name, line=header_at, column=col)
        col += len(h_raw) + 1
    for k, h in enumerate(names):
        if h in names[:k]:
            raise ParseError(f"column {h!r} appears twice", file=name, line=header_at,
                             column=len(",".join(header.split(",")[:k])) + 2, word=h, expected="each column once")
    missing = [r for r in required if r not in names]
    if missing:
        raise ParseError(f"the header has no {', '.join(missing)} column", file=name, line=header_at, column=1,
                         word=header[:40], expected=f"a header row naming {', '.join(required)} and the other columns")
    table = parse_numbers(data, _line_start(data, header_at + 1), len(names))
    if table is None:
        _locate_bad_field(data, name, header_at, names, describe or COLUMNS)
    return dict(zip(names, table)), header_at


def _line_start(data: bytes, line: int) -> int:
    """Byte offset of 1-based line `line` (len(data) past the end)."""
    pos = 0
    for _ in range(line - 1):
        pos = data.find(b"\n", pos)
        if pos < 0:
            return len(data)
        pos += 1
    return pos


def _header(data: bytes, name: str) -> tuple[int, str]:
    """(1-based line number, text) of the first line that is neither blank nor a comment."""
    pos, lineno = 0, 0
    while pos < len(data):
        end = data.find(b"\n", pos)
        end = len(data) if end < 0 else end
        lineno += 1
        text = data[pos:end].decode("utf-8", "replace").strip("\r")
        pos = end + 1
        if text.strip() and not text.lstrip().startswith("#"):
            return lineno, text
    raise ParseError("no header row", file=name, line=max(lineno, 1), column=1,
                     expected="a header row naming the columns (t_s, ...)")


def _locate_bad_field(data: bytes, name: str, header_at: int, names: list[str], describe: dict[str, str]) -> None:
    """Scan the rows after a failed fast parse and raise at the first bad field."""
    for lineno, raw in enumerate(data.decode("utf-8", "replace").splitlines(), start=1):
        if lineno <= header_at or not raw.strip() or raw.lstrip().startswith("#"):
            continue
        fields = raw.split(",")
        if len(fields) != len(names):
            raise ParseError(f"{len(fields)} fields, the header has {len(names)}", file=name, line=lineno,
                             column=len(raw) + 1 if len(fields) < len(names) else
                             len(",".join(fields[:len(names)])) + 1,
                             word=raw[:40], expected=f"{len(names)} comma-separated values ({', '.join(names)})")
        col = 1
        for text, h in zip(fields, names):
            try:
                float(text)
            except ValueError:
                raise ParseError(f"not a number in column {h}", file=name, line=lineno, column=col,
                                 word=text.strip(), expected=f"a number ({describe.get(h, h)}; nan when missing)"
                                 ) from None
            col += len(text) + 1
    raise ParseError("unreadable table", file=name, line=header_at + 1, column=1,
                     expected="rows of comma-separated numbers")  # pragma: no cover - the scan finds it


def check_time(t: np.ndarray, name: str, data: bytes | None = None, header_at: int = 0) -> None:
    """Refuse a time column t (s) with a value that is not finite or goes back: a ParseError at file `name`,
    at the row's line in `data` (the file's bytes, header on line `header_at`) or, without data, row + 1."""
    bad = np.flatnonzero(~np.isfinite(t))
    back = np.flatnonzero(np.diff(t) < 0)
    if len(bad) or len(back):
        row = int(min(bad[0] if len(bad) else len(t), back[0] + 1 if len(back) else len(t)))
        line = data_line(data, header_at, row) if data is not None else row + 1
        word = f"{float(t[row]):g}"
        raise ParseError("t_s must be finite and never decrease", file=name, line=line, column=1, word=word,
                         expected=f"a time >= {float(t[row - 1]):g} s" if row > 0 and np.isfinite(t[row]) else
                         "a finite time (s)")


def data_line(data: bytes, header_at: int, row: int) -> int:
    """1-based file line of data row `row` (0-based), skipping comments and blank lines."""
    k = -1
    for lineno, raw in enumerate(data.splitlines(), start=1):
        if lineno <= header_at or not raw.strip() or raw.lstrip().startswith(b"#"):
            continue
        k += 1
        if k == row:
            return lineno
    return header_at + row + 1


def _read_npz(path: Path) -> Log:
    name = str(path)
    with np.load(path, allow_pickle=False) as z:
        keys = list(z.keys())
        gaps = []
        if "gap_t_start_s" in keys:
            reasons = z["gap_reason"] if "gap_reason" in keys else [""] * len(z["gap_t_start_s"])
            gaps = [Gap(float(a), float(b), str(r)) for a, b, r in zip(z["gap_t_start_s"], z["gap_t_end_s"], reasons)]
        meta = {k[5:]: str(z[k]) for k in keys if k.startswith("meta_")}
        columns = {}
        for k in keys:
            if k.startswith(("gap_", "meta_")):
                continue
            check_column_name(k, file=name, line=1, column=keys.index(k) + 1)
            a = z[k]
            if a.ndim != 1 or not np.issubdtype(a.dtype, np.number):
                raise ParseError(f"array {k} must be a 1-D numeric array, got {a.dtype} {a.shape}", file=name,
                                 line=1, column=keys.index(k) + 1, word=k, expected="one number per sample")
            columns[k] = a.astype(float)
    if "t_s" not in columns:
        raise ParseError("no t_s array", file=name, line=1, column=1, expected="an array named t_s")
    columns = {"t_s": columns.pop("t_s"), **columns}
    log = Log(columns, gaps, meta, name)
    check_time(log.t_s, name)
    return log


def write_log(path: str | os.PathLike, log: Log) -> None:
    """Write a log whole (temporary file, then rename): CSV or NPZ by the file's suffix."""
    path = Path(path)
    names = list(log.columns)
    if path.suffix.lower() == ".npz":
        arrays = dict(log.columns)
        arrays["gap_t_start_s"] = np.array([g.t_start_s for g in log.gaps], float)
        arrays["gap_t_end_s"] = np.array([g.t_end_s for g in log.gaps], float)
        arrays["gap_reason"] = np.array([g.reason for g in log.gaps], dtype=str)
        arrays.update({f"meta_{k}": np.array(v) for k, v in log.meta.items()})
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
        return
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        fh.write(_preamble(log.meta))
        for g in log.gaps:
            fh.write(g.line() + "\n")
        fh.write(",".join(names) + "\n")
        if len(log):
            np.savetxt(fh, np.column_stack([log.columns[k] for k in names]), fmt=_formats(names), delimiter=",")


def _preamble(meta: dict[str, str]) -> str:
    return "# millpost log 1\n" + "".join(f"# meta {k}={v}\n" for k, v in meta.items())


def _formats(names: list[str]) -> list[str]:
    return ["%.6f" if k == "t_s" else "%d" if k == "line" else "%.6g" for k in names]


class LogWriter:
    """A CSV log written row by row (for a logger): rows and gaps go to a temporary file beside `path`,
    flushed as they come; `close()` renames it onto `path`, so the file is complete up to the last row
    written. Use as a context manager; an exception still closes (keeps what was logged)."""

    def __init__(self, path: str | os.PathLike, names: list[str], meta: dict[str, str] | None = None) -> None:
        for k, h in enumerate(names):
            check_column_name(h, column=k + 1)
        if names[0] != "t_s":
            raise ValueError("the first column of a log is t_s")
        self.path, self.names = Path(path), list(names)
        self._ctx = atomic_path(self.path)
        self._tmp = self._ctx.__enter__()
        self._fh = open(self._tmp, "w", newline="")
        self._fh.write(_preamble(meta or {}) + ",".join(names) + "\n")
        self._fmt = _formats(names)
        self.rows = 0
        self.gaps: list[Gap] = []

    def row(self, values) -> None:
        self._fh.write(",".join("nan" if not math.isfinite(v) else f % v for f, v in zip(self._fmt, values)) + "\n")
        self.rows += 1

    def gap(self, gap: Gap) -> None:
        self._fh.write(gap.line() + "\n")
        self.gaps.append(gap)

    def flush(self) -> None:
        self._fh.flush()

    def close(self) -> None:
        if self._fh.closed:
            return
        self._fh.close()
        self._ctx.__exit__(None, None, None)

    def __enter__(self) -> "LogWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
