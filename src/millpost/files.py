"""Output files are written whole or not at all: through a temporary file in the target's folder,
renamed into place when complete. A reader never sees a half-written file, a failure (or Ctrl-C)
leaves any old file untouched, and the file keeps the mode of the one it replaces (a new file gets
the mode the umask gives, as `open` would). Errors name the user's path, never the temporary one."""

from __future__ import annotations

import json
import math
import os
import stat
import tempfile
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .errors import MillpostError


def check_writable(path: str | os.PathLike, what: str = "output") -> Path:
    """Refuse an output path that cannot be written: its folder is missing or not a folder, or the
    path is a folder. Called before the work starts so a long run does not end in this error."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise MillpostError(f"{what} {path}: is a folder, not a file")
    if not folder.is_dir():
        raise MillpostError(f"{what} {path}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise MillpostError(f"{what} {path}: the folder {folder} is not writable")
    return path


def _new_file_mode() -> int:
    """The mode `open(..., "w")` gives a new file: 0o666 less the process umask."""
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


PENDING: set[str] = set()  # temporary files being written now (`remove_pending` on an abrupt exit)


def remove_pending() -> None:
    """Remove the temporary files of the outputs still being written (before the process ends at once,
    `millpost.cli.run` on Ctrl-C): no half-written file is left beside a target."""
    for tmp in list(PENDING):
        try:
            os.unlink(tmp)
        except OSError:
            pass


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary path beside `path` to write to; renamed onto `path` when the block ends without
    error, removed otherwise. (Its suffix is not the target's: give writers the format explicitly.)"""
    path = check_writable(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".millpost-tmp", dir=path.parent)
    except OSError as exc:
        raise MillpostError(f"output {path}: cannot write there ({exc.strerror})") from None
    os.close(fd)
    PENDING.add(tmp)
    try:
        yield Path(tmp)
        try:
            mode = stat.S_IMODE(os.stat(path).st_mode)
        except FileNotFoundError:
            mode = _new_file_mode()
        os.chmod(tmp, mode)
        try:
            os.replace(tmp, path)
        except OSError as exc:
            raise MillpostError(f"output {path}: cannot replace it ({exc.strerror})") from None
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
        PENDING.discard(tmp)


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


def json_text(data: object, what: str = "summary") -> str:
    """Strict JSON (RFC 8259: no NaN or Infinity). A non-finite number is a bug upstream: refused
    with the key that holds it rather than printed as invalid JSON."""
    try:
        return json.dumps(data, indent=2, allow_nan=False)
    except ValueError:
        raise MillpostError(f"{what}: {_non_finite(data) or 'a value'} is not a finite number; "
                            "refusing to write invalid JSON") from None


def _non_finite(data: object, where: str = "") -> str | None:
    """The dotted key of the first NaN/infinite float in nested dicts and lists."""
    if isinstance(data, float) and not math.isfinite(data):
        return where or "the value"
    items = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, (list, tuple)) else ()
    for k, v in items:
        found = _non_finite(v, f"{where}.{k}" if where else str(k))
        if found:
            return found
    return None
