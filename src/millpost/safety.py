"""Safety gates: what millpost checks before it writes anything, because what it writes runs on a
real machine.

Each gate has a name. A gate that fires refuses (the CLI exits 2 with the message) unless the user
overrides it by name — `--allow NAME` on the command line or ``[safety] allow = ["NAME"]`` in the
job — in which case its message becomes a warning in the notes. Two gates cannot be overridden:
a rapid into material is a crash whatever the user says, and an output must never replace an input.

- ``rapid`` (always refused): a rapid move runs into material, checked from the first point whose
  position is known (every axis named by a move, or the first feed move), before and after cutting.
- ``no-cut``: the feed moves remove no material at all: the stock is open (an STL missing a face) or
  not where the program's work zero puts it (a misplaced box), so every limit would read zero.
- ``below-stock``: a feed move takes the tool tip more than `THROUGH_CUT_MM` below the stock's bottom
  where the tool overlaps the stock (into the table or vise); less than that is a through-cut into a
  spoilboard, noted.
- ``flute-length``: the tool meets material deeper than its flute length (the shank rubs, chips
  cannot leave).
- ``spindle-off``: the tool meets material where the program has not turned the spindle on (no M3/M4
  with S before it). Allowed for a spindle switched by hand (a trim router), whose speed is then the
  job's ``spindle_rpm``, else the program's S word in force; with neither the job is refused: millpost
  never guesses a spindle speed. A spindle the program runs (M3/M4) with no S word in force is not
  off: it turns at the job's ``spindle_rpm``, else the job is refused (not a gate).
- ``large``: the resampled path would need more than `MAX_SAMPLES` samples, or more than 80 % of the
  memory free now (an estimate at `BYTES_PER_SAMPLE`, made before any of it is allocated).
- ``clobber`` (always refused): an output path is an input (program, job, stock, tool, material or
  machine file), another output, or a folder that does not exist.
- ``slower``: the optimized program, or one tool's work in it, would take more than `[limits]
  slower_max` (1.25) × the programmed time because the programmed cuts exceed hard limits (spindle power, torque, the tool's strength, the
  drives) that no feed millpost writes brings them under: the machine cannot cut the program as
  planned; the refusal lists per tool the lines, the limit and how far over it the programmed feed is
  (a lighter cut, another tool or a stronger spindle). Checked after the schedule, before anything is
  written.
- ``overload``: a cut exceeds a hard load limit (the tool's breaking force, buckling or torsion, the
  spindle's power or torque, a drive's current) even at the lowest feed millpost writes (the
  minimum-chip feed, or the programmed one if lower): no feed makes it safe, whatever the time; the
  refusal lists per limit how far over it is and the lines.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .errors import MillpostError, SafetyError
from .files import check_writable
from .gcode.interpret import Program
from .toolpath import RAPID, Samples, segments_per_move
from .tools import Tool

THROUGH_CUT_MM = 1.0  # below the stock bottom by at most this: a through-cut (noted), beyond: refused
MAX_SAMPLES = 10_000_000  # path samples of one run, whatever the memory
# peak bytes per path sample at 8 axial slices: the engagement 1.1-1.4 kB (tracemalloc, sample jobs);
# optimize 1.3 kB of peak resident memory a sample at 0.76-2.3 M samples (benchmarks/end_to_end.py,
# streamed forces, limits and replay), rounded up to 4 kB for Clarabel windows and denser engagements
BYTES_PER_SAMPLE = {"simulate": 1_500, "optimize": 4_000}


@dataclass(frozen=True)
class Gate:
    """One check: its name (for --allow and [safety] allow) and whether the user may override it."""

    name: str
    overridable: bool
    what: str


GATES = {g.name: g for g in (
    Gate("rapid", False, "a rapid move runs into material"),
    Gate("no-cut", True, "the feed moves remove no material"),
    Gate("below-stock", True, f"the tool goes more than {THROUGH_CUT_MM:g} mm below the stock bottom"),
    Gate("flute-length", True, "the tool meets material deeper than its flute length"),
    Gate("spindle-off", True, "the tool cuts material with the spindle off"),
    Gate("large", True, "the path needs more samples or memory than stated"),
    Gate("clobber", False, "an output would replace an input or another output"),
    Gate("slower", True, "the programmed cuts exceed hard limits so far that the optimized program is more "
                         "than slower_max × the programmed time"),
    Gate("overload", True, "a cut exceeds a hard limit even at the lowest feed millpost writes"),
)}


def refuse_or_note(gate: str, message: str, allow: Iterable[str], notes: list[str]) -> None:
    """Raise SafetyError for a gate the user has not overridden; else keep the message as a warning."""
    if gate in allow and GATES[gate].overridable:
        notes.append(f"warning ({gate}, allowed): {message}")
        return
    hint = (f"; if this is intended, rerun with --allow {gate} (or [safety] allow = [\"{gate}\"] in the job)"
            if GATES[gate].overridable else "")
    raise SafetyError(f"{message} (refused{hint})", gate=gate)


# --- files --------------------------------------------------------------------------------------
def check_outputs(outputs: Mapping[str, str | os.PathLike | None], inputs: Iterable[str | os.PathLike]) -> None:
    """Before any work: every output can be written (its folder exists) and none replaces an input
    or another output (same file by path, symlink or hard link). `outputs` maps a label (the flag
    or key that named it) to its path, None when not given."""
    ins = [Path(p) for p in inputs]
    seen: dict[str, Path] = {}
    for label, out in outputs.items():
        if out is None or str(out) == "-":
            continue
        out = Path(out)
        for other_label, other in [(f"input {p}", p) for p in ins] + [(f"{k} {v}", v) for k, v in seen.items()]:
            if _same_file(out, other):
                raise SafetyError(f"{label} {out} is the same file as the {other_label}: millpost never replaces "
                                  "an input or writes two outputs to one file; choose another output path "
                                  "(refused)", gate="clobber")
        check_writable(out, label)
        seen[label] = out


def _same_file(a: Path, b: Path) -> bool:
    if a.exists() and b.exists():
        return os.path.samefile(a, b)
    return a.resolve() == b.resolve()


# --- the samples ------------------------------------------------------------------------------
def estimate_samples(program: Program, ds_mm: float) -> int:
    """How many samples `Toolpath.resample(ds_mm)` will make, without making them."""
    L = program.toolpath.lengths()
    L = L[L > 1e-9]
    if not len(L):
        return 0
    n = segments_per_move(L, ds_mm)
    return int(min(float(n.sum()) + 1.0, 1e18)) if np.all(np.isfinite(n)) else 10**18


def check_size(program: Program, ds_mm: float, allow: Iterable[str], notes: list[str], *,
               stage: str = "optimize") -> None:
    """The ``large`` gate before resampling at `ds_mm`: the number of samples and their memory are
    estimated first, and refused beyond `MAX_SAMPLES` or the free memory."""
    import psutil

    n = estimate_samples(program, ds_mm)
    need = n * BYTES_PER_SAMPLE[stage]
    room = 0.8 * psutil.virtual_memory().available  # as the stock grid's cell choice allows itself
    if n > MAX_SAMPLES or need > room:
        refuse_or_note("large", f"{program.path}: {n:,} path samples at ds_mm = {ds_mm:g} would need about "
                       f"{need / 1e9:.1f} GB ({stage}; ceiling {MAX_SAMPLES:,} samples and 80 % of the "
                       f"{room / 0.8e9:.1f} GB free): raise ds_mm, or split the program", allow, notes)


def spindle_off_message(path: str, line: int, block: str = "", started: int | None = None) -> str:
    """What is wrong and what to write when the tool cuts at `path`:`line` (its text `block`, if given)
    with the spindle off, or (started: the line of the M3/M4 that runs it) on at no known speed."""
    quoted = f" (block '{block.strip()}')" if block.strip() else ""
    if started is not None:
        return (f"{path}:{line}: the tool cuts material at an unknown spindle speed{quoted}: the M3/M4 at line "
                f"{started} runs the spindle with no S word in force: expected S<rpm> before this line, or its "
                "speed as spindle_rpm = <rpm> in the job")
    return (f"{path}:{line}: the tool cuts material with the spindle off{quoted}: expected M3/M4 with S<rpm> before this "
            "line; a spindle switched by hand turns at spindle_rpm = <rpm> in the job, else at the program's S word")


def _in_force(events: list[tuple[int, float]], moves: np.ndarray) -> np.ndarray:
    """Per move index, the value of the last (move, value) event at or before it (0 before the first)."""
    at, value = np.array(events, float).T if events else (np.zeros(0), np.zeros(0))
    k = np.searchsorted(at, moves, side="right") - 1
    return np.where(k >= 0, value[np.maximum(k, 0)] if len(value) else 0.0, 0.0)


def _spindle_started(program: Program, moves: np.ndarray) -> np.ndarray:
    """Per move index, the line of the M3/M4 that runs the spindle there (0 where it is off)."""
    on = [(e.move, e.line if e.value[0] in ("cw", "ccw") else 0) for e in program.events
          if e.kind == "spindle" and e.value[0] != "speed"]
    return _in_force(on, moves).astype(int)


def check_spindle(program: Program, samples: Samples, eng, hand_rpm: float | None, allow: Iterable[str],
                  notes: list[str]) -> Samples:
    """Where the tool meets material (ap > 0) at no spindle speed (programmed rpm 0). Run by an M3/M4
    with no S word in force, it turns at the job's ``spindle_rpm`` (noted), else the job is refused
    (millpost never guesses a speed). Off, the ``spindle-off`` gate: allowed, the spindle is switched
    by hand and turns, wherever the program leaves it off, at `hand_rpm` (the job's ``spindle_rpm``:
    what the dial is set to), else at the program's S word in force (set without M3): the samples are
    returned with that speed; allowed with neither, refused."""
    rpm = np.asarray(samples.rpm, float)
    stopped = (eng.ap_mm > 1e-9) & (rpm <= 0)
    if not stopped.any():
        return samples
    lines = program.text.splitlines()

    def block(k: int) -> tuple[int, str]:
        line = int(samples.line[k])
        return line, lines[line - 1] if 0 < line <= len(lines) else ""

    started = _spindle_started(program, np.asarray(samples.move))
    running = stopped & (started > 0)
    by_hand = np.zeros(len(rpm))
    if running.any():
        k = int(np.argmax(running))
        if hand_rpm is None:
            raise MillpostError(spindle_off_message(program.path, *block(k), started=int(started[k])))
        by_hand[running] = float(hand_rpm)
        notes.append(f"note: where the program runs the spindle with no S word (M3/M4 at line {int(started[k])}), "
                     f"it turns at {hand_rpm:g} rpm (the job's spindle_rpm)")
    off = stopped & ~running
    if not off.any():
        return replace(samples, rpm=np.where(rpm > 0, rpm, by_hand))
    k = int(np.argmax(off))
    msg = f"{spindle_off_message(program.path, *block(k))} ({len(np.unique(samples.line[off]))} line(s))"
    refuse_or_note("spindle-off", msg, allow, notes)
    if hand_rpm is not None:
        by_hand[off] = float(hand_rpm)
        notes.append(f"note: where the program leaves the spindle off, it turns at {hand_rpm:g} rpm (the job's "
                     "spindle_rpm, switched by hand)")
    else:  # the S word in force at each move: the last one set before it
        words = [(e.move, float(e.value)) for e in program.events if e.kind == "s_word"]
        by_hand[off] = _in_force(words, np.asarray(samples.move))[off]
        if np.any(off & (by_hand <= 0)):
            bad = int(samples.line[np.argmax(off & (by_hand <= 0))])
            raise MillpostError(f"{program.path}:{bad}: the tool cuts with the spindle off (allowed: switched by "
                                "hand) but its speed is unknown: give spindle_rpm = <rpm> in the job (the speed "
                                "it is set to), or an S<rpm> word before this line; millpost does not guess a "
                                "spindle speed")
        speeds = ", ".join(f"S{v:g}" for v in np.unique(by_hand[off]))
        notes.append(f"note: where the program leaves the spindle off, it turns at the S word in force ({speeds}; "
                     "switched by hand; spindle_rpm in the job sets another speed)")
    return replace(samples, rpm=np.where(rpm > 0, rpm, by_hand))


def _per_sample(tools: Tool | Mapping[int, Tool], numbers: np.ndarray, attr: str, missing: float) -> np.ndarray:
    """A tool attribute (mm) at each sample from its tool number (`missing` where no tool is described)."""
    if isinstance(tools, Tool):
        return np.full(len(numbers), float(getattr(tools, attr)))
    out = np.full(len(numbers), missing)
    for n, t in tools.items():
        out[numbers == n] = float(getattr(t, attr))
    return out


def check_cut(program: Program, bounds: np.ndarray, tools: Tool | Mapping[int, Tool], samples: Samples, eng,
              allow: Iterable[str], notes: list[str]) -> None:
    """The gates on the simulated cut: ``no-cut``, ``below-stock`` and ``flute-length``. `bounds` is the
    stock's [[x0, y0, z_bottom], [x1, y1, z_top]] (mm) before cutting."""
    f = program.path
    feed = np.asarray(samples.kind) != RAPID
    xyz = samples.xyz_mm
    R = _per_sample(tools, np.asarray(samples.tool), "radius_mm", 0.0)
    (x0, y0, zb), (x1, y1, zt) = bounds
    over = ((xyz[:, 0] > x0 - R) & (xyz[:, 0] < x1 + R) & (xyz[:, 1] > y0 - R) & (xyz[:, 1] < y1 + R))
    removed = float(np.nansum(np.where(feed, eng.volume_mm3, 0.0)))
    if removed <= 0.0:
        inside = feed & over & (xyz[:, 2] < zt)
        stock_text = f"X {x0:g}..{x1:g} Y {y0:g}..{y1:g} Z {zb:g}..{zt:g} mm"
        if not feed.any():
            msg = f"{f}: the program has no feed moves: nothing is cut"
        elif zt <= zb:
            msg = (f"{f}: the stock holds no material at all ({stock_text}): an open mesh (an STL missing a face) "
                   "or a solid that did not rasterise")
        elif inside.any():
            msg = (f"{f}:{int(samples.line[np.argmax(inside)])}: the feed moves pass through the stock's bounds "
                   f"({stock_text}) but remove no material: the stock is empty where the tool goes (an STL "
                   "missing a face, or a solid in another frame)")
        else:
            p = xyz[feed]
            msg = (f"{f}: no feed move reaches the stock: the feed moves span X {p[:, 0].min():g}..{p[:, 0].max():g} "
                   f"Y {p[:, 1].min():g}..{p[:, 1].max():g} Z {p[:, 2].min():g}..{p[:, 2].max():g} mm, the stock "
                   f"is {stock_text} (is it where the program's work zero puts it?)")
        refuse_or_note("no-cut", msg, allow, notes)
    below = np.where(feed & over, zb - xyz[:, 2], 0.0)
    if below.max(initial=0.0) > 1e-3:
        k = int(np.argmax(below))
        msg = (f"{f}:{int(samples.line[k])}: the tool tip goes {below[k]:.3f} mm below the stock bottom "
               f"(Z {xyz[k, 2]:.3f} mm, bottom at Z {zb:g} mm) on {len(np.unique(samples.line[below > 1e-3]))} line(s)")
        if below[k] > THROUGH_CUT_MM:
            refuse_or_note("below-stock", msg + ": into the table or the vise", allow, notes)
        else:
            notes.append(f"note: {msg}: a through-cut (within {THROUGH_CUT_MM:g} mm)")
    if eng.depth_mm is not None:
        flute = _per_sample(tools, np.asarray(samples.tool), "flute_len", math.inf)
        deep = feed & (eng.depth_mm > flute + 1e-3)
        if deep.any():
            k = int(np.flatnonzero(deep)[np.argmax((eng.depth_mm - flute)[deep])])
            tool = tools if isinstance(tools, Tool) else tools[int(samples.tool[k])]
            given = "" if tool.flute_length_mm is not None else " (3·D assumed: give flute_length_mm)"
            msg = (f"{f}:{int(samples.line[k])}: the tool meets material {eng.depth_mm[k]:.3f} mm deep, deeper than "
                   f"its flute length {flute[k]:g} mm{given} (T{int(samples.tool[k])}, "
                   f"{len(np.unique(samples.line[deep]))} line(s)): the shank would rub and chips cannot leave")
            refuse_or_note("flute-length", msg, allow, notes)
