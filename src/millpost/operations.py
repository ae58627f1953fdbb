"""A program's operations as its CAM post wrote them: a run of path samples under one tool and one
comment (Fusion, FreeCAD and most posts write the operation's name as a comment before it), and the
lines a machinist restarts the program from."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Operation:
    """A run of the program under one tool and one CAM comment (the operation's name as posted)."""

    name: str
    tool: int
    index: np.ndarray  # sample indices
    line: int = 0  # where it starts: its comment's line (the first operation under it), else its first sample's


def operations_from_lines(lines: np.ndarray, tools: np.ndarray, comments: list[tuple[int, str]]) -> list[Operation]:
    """Operations by source line: a sample belongs to the last comment at or before its line (the
    operation name a CAM post writes before each) and to its tool."""
    comment_lines = np.array([c[0] for c in comments], int)
    texts = [c[1] for c in comments]
    at = np.searchsorted(comment_lines, lines, side="right") - 1 if len(comment_lines) else np.full(len(lines), -1)
    ops: dict[tuple[int, int], list[int]] = {}
    for k, key in enumerate(zip(at.tolist(), tools.astype(int).tolist())):
        ops.setdefault(key, []).append(k)
    out, named = [], set()
    for (c, tool), idx in sorted(ops.items(), key=lambda kv: kv[1][0]):
        if tool < 0:
            continue
        # its comment's line, once: a second tool under the same comment starts at its own first move
        start = int(comment_lines[c]) if c >= 0 and c not in named else int(lines[idx[0]])
        named.add(c)
        out.append(Operation(texts[c].strip() if c >= 0 else f"T{tool}", tool, np.asarray(idx), start))
    return out


def program_operations(program, samples) -> list[Operation]:
    """The operations of a read program over its samples (`operations_from_lines`, the program's comments)."""
    comments = [(e.line, str(e.value)) for e in program.events if e.kind == "comment"]
    return operations_from_lines(samples.line, samples.tool, comments)


def restart_points(program, samples) -> list[dict]:
    """Where the program may be restarted (a broken tool, a stop): each operation's start, {"line",
    "operation", "tool"}, in program order. Restarted there, the optimized program's descents below
    the stock's top still keep their plunge feeds (`millpost.limits.restart_descents`); its air moves
    through space cut before may run up to `air_feed_max_mm_min` (the machine's maximum by default),
    which assumes the operations before it ran."""
    return [{"line": op.line, "operation": op.name, "tool": op.tool} for op in program_operations(program, samples)]
