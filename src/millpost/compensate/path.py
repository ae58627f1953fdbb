"""The compensated path as the program can carry it: per move, the offset (mm, added to the programmed
point) at its end and at the points it is split at.

Lines: the offset runs linearly between the written points (the controller interpolates straight), so a
line whose wanted offset varies along it is split where the linear run misses the wanted offset by more
than the tolerance (a Douglas–Peucker refinement on the offset as a function of the path fraction),
never putting a written point closer to its neighbours than the controller's point spacing F·DT (the
programmed feed, mm/s, times the controller's block period 1/block_rate_Hz: closer points make it slow
down or skip them). Arcs are moved whole (end and centre by one vector, the radius kept): an arc starting
at a moved point is carried with it, and a cutting line before a cutting arc ends at the arc's mean wanted
offset, so the arc's start carries it. A move that does not cut keeps its end: it runs from a moved start
to its programmed end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..controller.execution import Execution
from ..toolpath import ARC_CW, Samples, Toolpath


@dataclass
class MoveOffsets:
    """Where move `move` is written: path fractions u (k,) increasing to 1 and the offsets (k, 3) mm there."""

    move: int
    u: np.ndarray
    offset_mm: np.ndarray


def _refine(u: np.ndarray, off: np.ndarray, pts: np.ndarray, tolerance_mm: float, spacing_mm: float) -> np.ndarray:
    """Indices into u (whose first entry is the move's start and last its end) of the written points: the
    ends, and where the linear run between written points misses `off` by more than the tolerance, the
    sample it misses most among those at least `spacing_mm` from both neighbours as written (pts + off)."""
    chosen = [0, len(u) - 1]
    written = pts + off
    while True:
        best, best_dev = -1, tolerance_mm
        for a, b in zip(chosen[:-1], chosen[1:]):
            if b - a < 2:
                continue
            w = ((u[a + 1:b] - u[a]) / max(u[b] - u[a], 1e-15))[:, None]
            dev = np.linalg.norm(off[a + 1:b] - ((1 - w) * off[a] + w * off[b]), axis=1)
            far = ((np.linalg.norm(written[a + 1:b] - written[a], axis=1) >= spacing_mm)
                   & (np.linalg.norm(written[a + 1:b] - written[b], axis=1) >= spacing_mm))
            dev = np.where(far, dev, 0.0)
            k = int(np.argmax(dev))
            if dev[k] > best_dev:
                best, best_dev = a + 1 + k, float(dev[k])
        if best < 0:
            return np.array(chosen)
        chosen = sorted(chosen + [best])


def plan_offsets(tp: Toolpath, samples: Samples, wanted_mm: np.ndarray, cutting: np.ndarray,
                 tolerance_mm: float, spacing_mm: np.ndarray) -> dict[int, MoveOffsets]:
    """Per moved move its written offsets, from the wanted offset per sample (N, 3) mm; `cutting` (per
    move) the moves to compensate, `spacing_mm` (per move) the least distance between written points."""
    u_all = Execution.sample_fractions(samples)
    by_move: dict[int, np.ndarray] = {}
    move = np.asarray(samples.move)
    order = np.argsort(move, kind="stable")
    bounds = np.searchsorted(move[order], np.arange(len(tp) + 1))
    for i in np.flatnonzero(cutting):
        idx = order[bounds[i]:bounds[i + 1]]
        idx = idx[u_all[idx] > 0]
        if len(idx):
            by_move[int(i)] = idx
    plan: dict[int, MoveOffsets] = {}
    end_off = np.zeros(3)
    for i in range(len(tp)):
        start_off = end_off
        arc = tp.kind[i] >= ARC_CW
        if arc and (np.any(start_off != 0) or i in by_move):
            end_off = start_off  # carried whole
            if np.any(start_off != 0):
                plan[i] = MoveOffsets(i, np.array([1.0]), start_off[None, :].copy())
            continue
        if arc or i not in by_move:
            end_off = np.zeros(3)
            continue
        idx = by_move[i]
        u = np.concatenate([[0.0], u_all[idx]])
        off = np.concatenate([start_off[None, :], wanted_mm[idx]])
        nxt = i + 1
        if nxt < len(tp) and tp.kind[nxt] >= ARC_CW and nxt in by_move:
            off[-1] = wanted_mm[by_move[nxt]].mean(axis=0)
        pts = np.concatenate([tp.start[i][None, :], samples.xyz_mm[idx]])
        keep = _refine(u, off, pts, tolerance_mm, float(spacing_mm[i]))[1:]
        plan[i] = MoveOffsets(i, u[keep], off[keep])
        end_off = off[-1]
    return plan


def commanded(tp: Toolpath, samples: Samples, plan: dict[int, MoveOffsets]) -> np.ndarray:
    """(N, 3) the commanded positions at the samples when the program is written with `plan`: each
    move's offset interpolated linearly in its path fraction between its start's offset (the previous
    move's end) and its written points (a move not in the plan: to 0 at its end; an arc: constant)."""
    u = Execution.sample_fractions(samples)
    out = np.array(samples.xyz_mm, float, copy=True)
    end_off = np.zeros((len(tp), 3))
    for i, mo in plan.items():
        end_off[i] = mo.offset_mm[-1]
    start_off = np.concatenate([np.zeros((1, 3)), end_off[:-1]])
    move = np.asarray(samples.move)
    for k in range(1, len(out)):
        i = int(move[k])
        mo = plan.get(i)
        if mo is None:
            out[k] += (1.0 - u[k]) * start_off[i]
        elif tp.kind[i] >= ARC_CW:
            out[k] += mo.offset_mm[-1]
        else:
            us = np.concatenate([[0.0], mo.u])
            offs = np.concatenate([start_off[i][None, :], mo.offset_mm])
            out[k] += [np.interp(u[k], us, offs[:, a]) for a in range(3)]
    return out
