"""Reading G-code: lexer (text → words), interpreter (modal state → moves), dialects.

    program = read_program("part.nc")           # a Program; program.toolpath holds the moves in mm
    program = read_text(text, name="part.nc")
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import MillpostError, ParseError
from ..toolpath import RAPID
from . import dialects
from .feed_mode import FeedMode
from .interpret import Event, Interpreter, Program, ReaderOptions

__all__ = ["Event", "FeedMode", "Program", "ReaderOptions", "check_program", "read_program", "read_text"]

# The largest program file read: ~10 M blocks, for which the reader holds ~1.3 GB of moves (124 bytes
# each) beside the text, and reads for ~2 minutes; a larger file is refused before it is read.
MAX_PROGRAM_BYTES = 256 * 1024 * 1024


def read_text(text: str, name: str = "<string>", options: ReaderOptions | None = None) -> Program:
    """Interpret G-code text. Raises ParseError (file:line:column, word, expected) on refusal."""
    options = options or ReaderOptions()
    dialect = dialects.get(options.dialect) if options.dialect else dialects.detect(text)
    interp = Interpreter(options, name, dialect)
    ngc = dialect.translate(text, name) if dialect.translate else text
    try:
        interp.run(ngc)
        program = interp.finish(name, ngc)
    except ParseError as e:
        origin = getattr(ngc, "origins", {}).get(e.line)  # a line a translation added from another file
        if origin is None:
            raise
        raise ParseError(e.reason, file=origin[0], line=origin[1], column=e.column, word=e.word,
                         expected=e.expected) from e
    if dialect.translate:
        program.source = text
    return program


def read_program(path: str | Path, options: ReaderOptions | None = None) -> Program:
    """Read and interpret a G-code file (UTF-8, or Latin-1 when it is not UTF-8)."""
    path = Path(path)
    size = path.stat().st_size
    if size > MAX_PROGRAM_BYTES:
        raise ParseError(f"program of {size / 2**20:.0f} MB is larger than millpost reads", file=str(path), line=1,
                         column=1, word=f"{size / 2**20:.0f} MB",
                         expected=f"at most {MAX_PROGRAM_BYTES // 2**20} MB (about 10 million blocks)")
    data = path.read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    if "\x00" in text:
        raise ParseError("binary file, not G-code text", file=str(path), line=1, column=text.index("\x00") + 1,
                         word="NUL", expected="a text file of G-code")
    return read_text(text, str(path), options)


def check_program(program: Program) -> None:
    """A program with no motion has nothing to simulate or optimize, and one with a non-finite
    coordinate or feed cannot be run: say so instead of failing later."""
    tp = program.toolpath
    if len(tp) == 0:
        raise MillpostError(f"{program.path}: the program has no moves (nothing to simulate or optimize)")
    bad = ~(np.isfinite(tp.start).all(axis=1) & np.isfinite(tp.end).all(axis=1)
            & (np.isfinite(tp.feed_mm_min) | (tp.kind == RAPID)))
    if bad.any():
        raise MillpostError(f"{program.path}:{int(tp.line[np.argmax(bad)])}: a coordinate or feed of this move is "
                            "not a finite number")
