"""Choosing the spindle speed per operation (`[limits] rpm = "optimize"`, opt-in).

An operation here is an S block: the moves that run at the speed one S word of the program sets (up to
the next S word), whatever tools cut in it. Its speed may move within the rpm window `recommend` uses
(`heuristics.rpm_range`: the material's surface-speed window for each tool that cuts there, n =
1000·v_c/(π·D), within the spindle's speed range; the window of a block is the common part of its
tools' windows). The feed limits are the job's own (`millpost.limits`) at the new speed: chip load per
tooth, minimum chip, the spindle's power and torque curves at that speed, tool breakage and
deflection, the drives; a higher S raises the feed the chip load allows and lowers the cutting torque
per mm/min, a lower S can lift a power or torque limit on a spindle past its base speed.

Each block's speed is chosen from a geometric grid over its window (`CANDIDATES` speeds, whole rpm) by
the schedule's own time of the block's samples (the minimum-time feed profile under all limits, the
same solver `optimize` runs): the fastest speed wins, and it replaces the programmed S only when it
shortens the block by at least `MIN_GAIN`. A speed at which the feed policy would hold more of the
block's samples at their programmed feed (a load over its bound there, caused by the new S) is
refused; if the schedule at the chosen speeds fails, `optimize` keeps the programmed S. Blocks where the feed depends on the speed (G95 feed per
revolution) or whose S is an expression keep their S; a program with O-word control flow keeps all.

Chatter (a tool with a tip FRF, `millpost.stability.check`): the candidates of a block its tools cut
also include the centres of its stable pockets (`scan_speeds`), and speeds at which every sample of the
block cuts within its stable depth come first: when some candidate clears, only those may be chosen; a
block whose programmed S chatters moves to the fastest that clears whatever the time; when none
clears, the block is chosen by time as before and its note says so. Among the speeds within `MIN_GAIN` of
the fastest, the one of largest margin (a_lim/ap) wins: the pocket's centre rather than its edge.
"""

from __future__ import annotations

import dataclasses
import math
from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from .controller import PathModes
from .emit import replace_numbers
from .errors import MillpostError
from .gcode.feed_mode import FeedMode
from .gcode.interpret import Program
from .gcode.lexer import lex_line
from .heuristics import rpm_range
from .job import Job
from .limits import build_limits
from .progress import Progress, reporting, silent
from .schedule import ScheduleOptions, schedule_samples
from .signals import step_times_s
from .stability.check import CutImmersion, SpeedScan, scan_speeds
from .toolpath import RAPID, Samples

CANDIDATES = 6     # speeds tried per block across its window
MIN_GAIN = 0.005   # relative shortening of a block's time that justifies changing its S


@dataclass
class SpeedBlock:
    """The moves one S word sets the speed of. line: its line; rpm: the programmed S (rpm); moves:
    the toolpath's cutting moves at it, span: all its moves (rapids too); tools: those that cut; window: (lo, hi, what sets hi) rpm, or None with `kept` saying why the S
    stays as programmed."""

    line: int
    rpm: float
    moves: np.ndarray
    span: np.ndarray
    tools: tuple[int, ...]
    window: tuple[float, float, str] | None = None
    kept: str = ""


def speed_blocks(job: Job, program: Program) -> list[SpeedBlock]:
    """The program's S blocks that cut, each with the speed window its tools allow (or why not)."""
    tp = program.toolpath
    s_lines: list[int] = []
    s_value: dict[int, float] = {}
    fixed: dict[int, str] = {}
    for n, body in enumerate(program.text.splitlines(), start=1):
        if "s" not in body.lower():
            continue
        try:  # parameters the text alone cannot give read as 0: an S written with them is not changed
            block = lex_line(body, n, program.path, defaultdict(float))
        except MillpostError:  # a line the reader never ran (after M2, block delete)
            continue
        word = next((w for w in block.words if w.letter == "S"), None)
        if word is not None:
            s_lines.append(n)
            s_value[n] = word.value
            if not _plain_number(word.text[1:]):
                fixed[n] = f"its S is written as {word.text!r}, not a number"
    at = np.searchsorted(np.array(s_lines, int), tp.line, side="right") - 1
    cutting = (tp.kind != RAPID) & (tp.rpm > 0)
    out = []
    for k, line in enumerate(s_lines):
        span = np.flatnonzero(at == k)
        moves = span[cutting[span]]
        if not len(moves):
            continue
        tools = tuple(int(t) for t in np.unique(tp.tool[moves]) if t >= 0 and int(t) in job.tools)
        blk = SpeedBlock(line, float(s_value[line]), moves, span, tools)
        out.append(blk)
        if program.control_flow:
            blk.kept = "the program has O-word control flow (a line may run at several speeds)"
        elif line in fixed:
            blk.kept = fixed[line]
        elif np.any(tp.rpm[moves] != blk.rpm):
            blk.kept = "its moves do not all run at its S"
        elif np.any(program.feed_mode[moves] == FeedMode.PER_REV):
            blk.kept = "it feeds per revolution (G95): its feeds change with S"
        elif not tools:
            blk.kept = "no described tool cuts at it"
        else:
            ranges = [rpm_range(job.tools[t], job.material, job.machine) for t in tools]
            lo, hi = max(r[0] for r in ranges), min(r[1] for r in ranges)
            if lo > hi:
                blk.kept = "its tools' surface-speed windows do not overlap"
            else:
                blk.window = (lo, hi, min(ranges, key=lambda r: r[1])[2])
    return out


def _plain_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def choose_speeds(job: Job, program: Program, samples: Samples, eng, options: ScheduleOptions, modes: PathModes,
                  zones: np.ndarray, progress: Progress = silent, cut: CutImmersion | None = None
                  ) -> tuple[Program, Samples, dict]:
    """The program and samples at the chosen speeds (the text with the new S words, toolpath and samples
    with the new rpm) and a summary: per S block its line, programmed and chosen S, window and times.
    modes, zones: the program's path modes and its programmed corners' blend arcs (`controller.path_modes`,
    `controller.blend_zones`); cut: the samples' immersion for the chatter check (None: no tool has an FRF)."""
    blocks = speed_blocks(job, program)
    free = [b for b in blocks if b.window is not None]
    sample_block = np.full(len(samples), -1)
    for k, b in enumerate(blocks):
        sample_block[np.isin(samples.move, b.moves)] = k
    grids = {id(b): _grid(*b.window[:2]) for b in free}
    scans = {id(b): scan_speeds(job, cut, np.flatnonzero(sample_block == k), grids[id(b)], b.rpm)
             for k, b in enumerate(blocks) if b.window is not None}
    grids.update({key: scan.speeds for key, scan in scans.items() if scan is not None})
    tries = max((len(g) for g in grids.values()), default=0)
    times = [_block_times(job, program, samples, eng, options, modes, zones, blocks, sample_block)]  # as programmed
    for c in range(tries):  # the c-th speed of every block's grid at once (the blocks' times are their own)
        progress("spindle speeds", c, tries)
        rpm = {b.line: float(grids[id(b)][min(c, len(grids[id(b)]) - 1)]) for b in free}
        times.append(_block_times(job, program, _with_rpm(samples, blocks, sample_block, rpm), eng, options, modes,
                                  zones, blocks, sample_block))
    progress("spindle speeds", tries, tries)
    chosen: dict[int, float] = {}
    rows = []
    for k, b in enumerate(blocks):
        row = {"line": b.line, "tools": list(b.tools), "programmed_rpm": b.rpm, "rpm": b.rpm}
        if b.window is None:
            rows.append({**row, "changed": False, "reason": f"S kept: {b.kept}"})
            continue
        grid = grids[id(b)]
        t0, held0 = times[0][0][k], times[0][1][k]
        # a speed at which the feed policy must hold more of the block's samples at their programmed feed
        # (a load over its bound there because of the new S) is no candidate
        t = np.array([times[1 + c][0][k] if times[1 + c][1][k] <= held0 else np.inf for c in range(len(grid))])
        rows.append(_decide(job, b, row, grid, t, t0, scans[id(b)]))
        if rows[-1]["changed"]:
            chosen[b.line] = rows[-1]["rpm"]
    summary = {"mode": "optimize", "blocks": rows, "changed": sum(r["changed"] for r in rows)}
    if not chosen:
        return program, samples, summary
    tp = program.toolpath
    move_rpm = tp.rpm.copy()
    for b in blocks:
        if b.line in chosen:
            move_rpm[b.span[tp.rpm[b.span] > 0]] = chosen[b.line]
    text = replace_numbers(program, {line: {"S": rpm} for line, rpm in chosen.items()})
    new_program = dataclasses.replace(program, text=text, toolpath=dataclasses.replace(tp, rpm=move_rpm))
    return new_program, _with_rpm(samples, blocks, sample_block, chosen), summary


def _decide(job: Job, b: SpeedBlock, row: dict, grid: np.ndarray, t: np.ndarray, t0: float, scan: SpeedScan | None
            ) -> dict:
    """The summary row of a free block `b` (its start `row`) with the speed chosen among the candidates
    `grid` (rpm) by their times `t` (s; inf: refused) against the programmed time `t0`, and with the
    block's chatter scan (None: no tool of it has an FRF) taken first (module docstring)."""
    lo, hi, what = b.window
    if scan is not None and (scan.programmed >= 1.0 or np.any(scan.clears & np.isfinite(t))):  # stable first
        t = np.where(scan.clears, t, np.inf)
    best = int(np.argmin(t))
    if scan is not None and np.isfinite(t[best]):  # within MIN_GAIN of the fastest: the most stable
        best = int(np.argmax(np.where(t <= t[best] * (1 + MIN_GAIN), scan.margins, -np.inf)))
    window = (f"window {lo:.0f}–{hi:.0f} rpm: the material's surface speed for "
              + ", ".join(f"T{n} ({job.tools[n].diameter_mm:g} mm)" for n in b.tools)
              + (" within the spindle's range" if what == "surface_speed" else ", capped by the spindle's maximum"))
    row.update(window_rpm=[round(lo, 1), round(hi, 1)], time_s=round(float(t0), 3))
    if scan is not None and not scan.programmed >= 1.0 and scan.clears[best] and np.isfinite(t[best]):
        new = float(grid[best])
        out = {**row, "rpm": new, "changed": True, "optimized_time_s": round(float(t[best]), 3),
               "reason": f"S{b.rpm:g} → S{new:g}: a stable pocket, its cuts within the stable depth "
                         f"(a_lim/ap ≥ {scan.margins[best]:.2f}; at S{b.rpm:g} {scan.programmed:.2f}): "
                         f"{t[best]:.2f} s instead of {t0:.2f} s ({window})"}
    elif np.isfinite(t[best]) and t[best] < t0 * (1 - MIN_GAIN):
        new = float(grid[best])
        out = {**row, "rpm": new, "changed": True, "optimized_time_s": round(float(t[best]), 3),
               "reason": f"S{b.rpm:g} → S{new:g}: its cuts take {t[best]:.2f} s instead of {t0:.2f} s "
                         f"under the same limits ({window})"}
    else:
        out = {**row, "changed": False,
               "reason": f"S{b.rpm:g} kept: no speed in the {window} shortens its cuts by {MIN_GAIN:.1%} or more"}
    if scan is not None:
        _chatter_row(out, scan, float(scan.margins[best]) if out["changed"] else scan.programmed)
    return out


def _chatter_row(row: dict, scan: SpeedScan, margin: float) -> None:
    """A block's chatter entry (`row["chatter"]`): the margins a_lim/ap (smallest over its samples) at the
    programmed and at the block's final speed, whether that one clears (every sample stable) and the
    candidate speeds that would; a reason that says when its cuts still chatter."""
    row["chatter"] = {"programmed_margin": round(scan.programmed, 3), "margin": round(margin, 3),
                      "clears": margin >= 1.0, "clearing_rpm": [float(v) for v in scan.speeds[scan.clears]]}
    if margin < 1.0:
        row["reason"] += (f"; its cuts chatter at S{row['rpm']:g} (a_lim/ap {margin:.2f})"
                          + ("" if scan.clears.any() else ": no candidate speed in the window clears them"))


def _grid(lo: float, hi: float) -> np.ndarray:
    """Whole-rpm speeds spread geometrically over [lo, hi]."""
    a, z = math.ceil(lo), math.floor(hi)
    if z <= a:
        return np.array([float(z if z >= lo else lo)])
    return np.unique(np.clip(np.round(np.geomspace(a, z, CANDIDATES)), a, z))


def _with_rpm(samples: Samples, blocks: list[SpeedBlock], sample_block: np.ndarray, rpm: dict[int, float]) -> Samples:
    new = samples.rpm.copy()
    for k, b in enumerate(blocks):
        if b.line in rpm:
            new[(sample_block == k) & (samples.rpm > 0)] = rpm[b.line]
    return dataclasses.replace(samples, rpm=new)


def _block_times(job: Job, program: Program, samples: Samples, eng, options: ScheduleOptions, modes: PathModes,
                 zones: np.ndarray, blocks: list[SpeedBlock], sample_block: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per block the scheduled time (s) of its samples under the job's limits at the samples' rpm (inf
    for every block when a segment's solve fails), and how many of its samples the feed policy holds."""
    limits = build_limits(job, samples, eng, program.toolpath, modes=modes, zones=zones)
    with reporting(silent):  # the stage is "spindle speeds", not the schedule's own
        sched = schedule_samples(samples, limits, options)
    mine = sample_block >= 0
    held = np.zeros(len(samples), bool)
    for mask in limits.held.values():
        held |= mask
    held_count = np.bincount(sample_block[mine & held], minlength=len(blocks))
    if any(not s.status.ok for _, _, s in sched.segments):
        return np.full(len(blocks), np.inf), held_count
    dt = step_times_s(samples.s_mm, np.nan_to_num(sched.feed_mm_s, nan=0.0))
    return np.bincount(sample_block[mine], weights=dt[mine], minlength=len(blocks)), held_count
