"""Commands between moves: they stop the motion and take time (s). A dwell lasts its P, a tool change
`tool_change_s`, a spindle start (to speed) `spindle_start_s`, coolant `coolant_s`, any other command
that waits for the motion to end (spindle stop or speed, tool length, user M codes) `command_s`."""

from __future__ import annotations

import numpy as np

from ..toolpath import Toolpath
from .model import ControllerModel

# events that wait for the motion to stop, and which time of the model each costs
PAUSE_KINDS = {"dwell": None, "tool_change": "tool_change_s", "coolant": "coolant_s", "tool_length": "command_s",
               "m_code": "command_s", "stop": None}


def pauses_s(program, model: ControllerModel) -> np.ndarray:
    """Per junction of the program's toolpath (len(moves)+1; index i = before move i): the time the
    controller stands still there for the program's commands, nan where nothing waits for the motion
    to end. Dwells last their P; a spindle start `spindle_start_s`, other spindle commands
    `command_s`; a tool change `tool_change_s`; coolant `coolant_s`; tool length and user M codes
    `command_s`."""
    out = np.full(len(program.toolpath) + 1, np.nan)
    for e in program.events:
        if e.kind == "spindle":
            cost = model.spindle_start_s if e.value[0] in ("cw", "ccw") else model.command_s
        elif e.kind in PAUSE_KINDS:
            name = PAUSE_KINDS[e.kind]
            cost = float(e.value) if e.kind == "dwell" else getattr(model, name) if name else 0.0
        else:
            continue
        out[e.move] = np.nan_to_num(out[e.move]) + cost
    return out


def stops(tp: Toolpath, pauses: np.ndarray | None) -> np.ndarray:
    """Per move: whether the motion must stop before it (a pause or a jump in position)."""
    stop = np.zeros(len(tp), bool)
    if pauses is not None:
        stop |= np.isfinite(np.asarray(pauses, float)[:len(tp)])
    if len(tp) > 1:
        stop[1:] |= np.linalg.norm(tp.start[1:] - tp.end[:-1], axis=1) > 1e-6
    return stop


def paused_s(pauses: np.ndarray | None, first: int, last: int) -> float:
    """Time (s) stood still between move `first` and the end of move `last`: the pauses at the
    junctions after the first motion, up to the last (times count from the first motion to the end of
    the last)."""
    if pauses is None:
        return 0.0
    inside = np.arange(len(pauses))
    return float(np.nansum(np.where((inside > first) & (inside <= last), pauses, 0.0)))
