"""LinuxCNC's own interpreter (`rs274 -g`, Debian's linuxcnc-uspace) as the oracle for what a program
means: runs it and reads the canonical trace into moves comparable with millpost's."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

RS274 = shutil.which("rs274")
_CALL = re.compile(r"^\s*(?:\d+\s+)?N[.\d]*\s+(\w+)\((.*)\)\s*$")
# ARC_FEED(first_end, second_end, first_axis, second_axis, rotation, axis_end_point, a, b, c): per plane,
# the (first, second, normal) axes are XY-Z, ZX-Y, YZ-X, as millpost's PLANE_AXES.
_PLANES = {"CANON_PLANE_XY": (0, 1, 2), "CANON_PLANE_XZ": (2, 0, 1), "CANON_PLANE_YZ": (1, 2, 0)}


@dataclass
class Trace:
    """Moves from the canonical trace: kind, end point in the program's units, feed in mm/min (LinuxCNC's
    canon converts SET_FEED_RATE with the units in force when it is called: `G20 F6` is 6 mm/min), and
    whether the units were inches; `error` holds the interpreter's message when it stopped on one."""

    moves: list[tuple[str, tuple[float, float, float], float | None, bool]]
    error: str | None


def run(program: Path, timeout: float = 60.0, *, diameters_mm: dict[int, float] | None = None,
        tool_table: Path | None = None) -> Trace:
    """Run `rs274 -g` with `tool_table`, or tools 1..99 of zero length (tool lengths unknown, as millpost
    assumes) and diameters `diameters_mm` (default 0). The standalone rs274 reads a table in inches.
    rs274 shares its tool data through $HOME/.tool.mmap: each run gets its own HOME, or concurrent runs
    (other tests, other users) would swap tool tables under each other."""
    diameters_mm = diameters_mm or {}
    with tempfile.TemporaryDirectory() as home:
        table = Path(home) / "tools.tbl"
        table.write_text("".join(f"T{i} P{i} Z0 D{diameters_mm.get(i, 0.0) / 25.4!r}\n" for i in range(1, 100)))
        proc = subprocess.run([RS274, "-t", str(tool_table or table), "-g", str(program)], capture_output=True,
                              text=True, timeout=timeout, cwd=program.parent, stdin=subprocess.DEVNULL,
                              errors="replace", env={**os.environ, "HOME": home})
    return parse(proc.stdout + proc.stderr)


def parse(text: str) -> Trace:
    """Moves of a canonical trace (rs274 output or a LinuxCNC test's `expected` file). The first line that
    is neither a canonical call nor rs274's "executing" banner is the interpreter's error message."""
    moves = []
    plane = (0, 1, 2)
    feed = None
    inch = False
    err = None
    for line in text.splitlines():
        m = _CALL.match(line)
        if not m:
            if err is None and line.strip() and line.strip() != "executing":
                err = line.strip()
            continue
        name, args = m.group(1), m.group(2)
        if name == "USE_LENGTH_UNITS":
            inch = "INCHES" in args
        elif name == "SELECT_PLANE":
            plane = _PLANES.get(args.strip(), plane)
        elif name == "SET_FEED_RATE":  # in the length units in force when it is set (the canon keeps mm)
            feed = float(args) * (25.4 if inch else 1.0)
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            v = [float(x) for x in args.split(",")]
            moves.append(("rapid" if name == "STRAIGHT_TRAVERSE" else "feed", tuple(v[:3]),
                          None if name == "STRAIGHT_TRAVERSE" else feed, inch))
        elif name == "ARC_FEED":
            v = [float(x) for x in args.split(",")]
            end = [0.0, 0.0, 0.0]
            end[plane[0]], end[plane[1]], end[plane[2]] = v[0], v[1], v[5]
            moves.append(("arc_cw" if v[4] < 0 else "arc_ccw", tuple(end), feed, inch))
    return Trace(moves, err)


def mismatches(program, trace: Trace, tol: float = 1e-4, prefix: bool = False) -> list[str]:
    """Differences between millpost's moves and a trace: kind, end point and feed, each within `tol`
    in the program's units (the trace's units at that move). The two are aligned greedily, skipping
    moves of no length on either side: LinuxCNC emits some (a bare G0, polar cycle blocks) and both
    keep moves shorter than the trace's 4 printed decimals. With `prefix`, the trace stopped early
    (an error) and only its moves must be matched."""
    from millpost.toolpath import KIND_NAMES

    tp = program.toolpath
    out: list[str] = []
    i = j = 0
    prev_ours = tp.start[0] if len(tp) else None
    prev_theirs = None
    while i < len(tp) and j < len(trace.moves):
        kind, end, feed, inch = trace.moves[j]
        scale = 25.4 if inch else 1.0
        mine = tp.end[i] / scale
        same = KIND_NAMES[tp.kind[i]] == kind and max(abs(a - b) for a, b in zip(mine, end)) <= tol
        if same:
            if feed is not None and abs(tp.feed_mm_min[i] - feed) > tol * scale * max(1.0, feed / scale):
                out.append(f"move {i} (line {tp.line[i]}): feed {tp.feed_mm_min[i]:g} vs {feed:g} mm/min")
            prev_ours, prev_theirs = tp.end[i], end
            i, j = i + 1, j + 1
        elif prev_theirs is not None and max(abs(a - b) for a, b in zip(end, prev_theirs)) <= tol:
            j += 1  # a move of no length in the trace
        elif prev_ours is not None and max(abs(tp.end[i] - prev_ours)) / scale <= tol:
            prev_ours = tp.end[i]
            i += 1  # a move of no length here
        else:
            out.append(f"move {i} (line {tp.line[i]}): {KIND_NAMES[tp.kind[i]]} {mine.round(5).tolist()} "
                       f"vs trace move {j}: {kind} {list(end)}")
            break
    rest_ours = [k for k in range(i, len(tp)) if max(abs(tp.end[k] - tp.start[k])) > 1e-9]
    if not out and j < len(trace.moves):
        out.append(f"trace has {len(trace.moves) - j} more moves from move {j}: {trace.moves[j]}")
    if not out and rest_ours and not prefix:
        out.append(f"millpost has {len(rest_ours)} more moves from line {tp.line[rest_ours[0]]}")
    return out
