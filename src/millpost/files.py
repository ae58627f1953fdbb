"""Output files are written whole or not at all: through a temporary file in the target's folder,
renamed into place when complete. A reader never sees a half-written file, and a failure leaves any
old file untouched."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import numpy as np


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary path beside `path` to write to; renamed onto `path` when the block ends without
    error, removed otherwise. (Its suffix is not the target's: give writers the format explicitly.)"""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".millpost-tmp", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_atomic(path: str | os.PathLike, text: str) -> None:
    """Write text (newlines as given) to `path` atomically."""
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        fh.write(text)


def write_csv(path: str | os.PathLike, columns: Mapping[str, np.ndarray],
              formats: Mapping[str, str] | None = None) -> None:
    """Equal-length columns as CSV with a header row, atomically; numbers as "%.6g" unless
    `formats` names another printf format for the column."""
    formats = formats or {}
    table = np.column_stack([np.asarray(v, float) for v in columns.values()])
    with atomic_path(path) as tmp:
        np.savetxt(tmp, table, fmt=[formats.get(k, "%.6g") for k in columns], delimiter=",",
                   header=",".join(columns), comments="")
