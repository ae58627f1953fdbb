"""Progress of long stages for a person at a terminal.

A stage reports through a callback ``progress(stage, done, total)`` (any units; ``total`` ≤ 0 when the
stage cannot tell how far it is) and imports nothing of the terminal; the CLI passes `Bars`, which
draws one bar per stage on stderr when it is a terminal (with the elapsed time running even while a
stage reports nothing) and stays silent when piped. `stage` wraps a step that reports no fractions.

Code below an API that takes no callback (the schedule's windows, the numba kernels' first compile)
reports to `current()`: the callback an enclosing `reporting` block set in this process (worker
processes forked from it stay silent), else nothing.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import TextIO

Progress = Callable[[str, float, float], None]


def silent(stage: str, done: float, total: float) -> None:
    """A progress callback that shows nothing."""


_reporting: ContextVar[tuple[int, "Progress"] | None] = ContextVar("millpost_progress", default=None)


@contextmanager
def reporting(progress: Progress) -> Iterator[None]:
    """Within the block, `current()` in this process is `progress`."""
    token = _reporting.set((os.getpid(), progress))
    try:
        yield
    finally:
        _reporting.reset(token)


def current() -> Progress:
    """The callback of the enclosing `reporting` block when set in this process; else `silent`."""
    set_by = _reporting.get()
    return set_by[1] if set_by is not None and set_by[0] == os.getpid() else silent


@contextmanager
def stage(progress: Progress, name: str) -> Iterator[None]:
    """Report `name` as started, then finished, around a step that cannot count its work."""
    progress(name, 0.0, 0.0)
    yield
    progress(name, 1.0, 1.0)


class Bars:
    """Progress bars on a terminal (rich), one per stage, removed when the run ends; nothing at all
    when the stream is not a terminal or `enabled` is False. Use as a context manager or call `close`."""

    def __init__(self, stream: TextIO | None = None, enabled: bool | None = None) -> None:
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self._live = None
        self._tasks: dict[str, int] = {}

    def __call__(self, stage: str, done: float, total: float) -> None:
        if not self.enabled:
            return
        if self._live is None:
            from rich.console import Console
            from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeElapsedColumn
            self._live = Progress(TextColumn("{task.description:>28}"), BarColumn(), TaskProgressColumn(),
                                  TimeElapsedColumn(), console=Console(file=self.stream), transient=True)
            self._live.start()
        if stage not in self._tasks:
            self._tasks[stage] = self._live.add_task(stage, total=None)
        task = self._tasks[stage]
        if total > 0:
            self._live.update(task, total=total, completed=done)
            if done >= total:
                self._live.stop_task(task)

    def close(self) -> None:
        if self._live is not None:
            self._live.stop()
            self._live = None

    def __enter__(self) -> "Bars":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def resolve(progress: Progress | bool | None) -> Progress:
    """A callback from what an API caller gives: a callback as is; True → bars on stderr; None → bars
    when stderr is a terminal; False → silent. (Bars made here are closed at interpreter exit.)"""
    if callable(progress):
        return progress
    if progress is False:
        return silent
    bars = Bars(enabled=True if progress else None)
    if not bars.enabled:
        return silent
    import atexit
    atexit.register(bars.close)
    return bars
