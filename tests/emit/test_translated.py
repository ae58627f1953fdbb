"""A program in a language read through a translation (`Dialect.translate`) is written back in that
language with only F words changed, and reads back to the same path."""

import re

import numpy as np

from millpost.gcode import ReaderOptions, dialects, read_text
from millpost.gcode.convert import same_path
from millpost.emit.write import FeedPlan, write_feeds
from millpost.registry import plugins

# A toy language: `MOVE` is G1, `JUMP` is G0, `#` starts a comment; one RS-274 line per source line.
_F = re.compile(r"\bF\s*[-+]?\d*\.?\d*")


def _translate(text: str, file: str) -> str:
    lines = text.split("\n")
    return "\n".join(re.sub(r"#(.*)$", r"(\1)", ln).replace("MOVE", "G1").replace("JUMP", "G0") for ln in lines)


def _set_feed(line: str, f: str | None) -> str:
    code, sep, comment = line.partition("#")
    if f is None:
        code = _F.sub("", code).rstrip() + (" " if sep else "")
    elif _F.search(code):
        code = _F.sub("F" + f, code, count=1)
    else:
        code = code.rstrip() + f" F{f}" + (" " if sep else "")
    return code + sep + comment


TOY = dialects.Dialect("toy", translate=_translate, set_feed=_set_feed)
SOURCE = """G21 G90 # metric
JUMP X0 Y0 Z1
MOVE Z-1 F100
MOVE X20 F600 # a slot
MOVE Y20
MOVE X0 F600
M2
"""


def test_written_back_in_its_language_with_only_feeds_changed(monkeypatch):
    monkeypatch.setitem(plugins("dialects"), "toy", TOY)
    program = read_text(SOURCE, "toy.nc", ReaderOptions(dialect="toy"))
    assert program.source == SOURCE and program.text.splitlines()[1] == "G0 X0 Y0 Z1"
    tp = program.toolpath
    assert tp.line.tolist() == [2, 3, 4, 5, 6]
    feeds = tp.feed_mm_min.copy()
    feeds[2], feeds[3] = 450.0, 600.0  # the slot slower, the next move at the last move's F
    out = write_feeds(program, FeedPlan(feeds, {}))
    assert out.splitlines() == ["G21 G90 # metric", "JUMP X0 Y0 Z1", "MOVE Z-1 F100", "MOVE X20 F450 # a slot",
                                "MOVE Y20 F600", "MOVE X0 F600", "M2"]
    again = read_text(out, "toy.nc", ReaderOptions(dialect="toy"))
    assert same_path(program, again) == []
    assert np.allclose(again.toolpath.feed_mm_min[1:], [100, 450, 600, 600])


def test_text_only_evaluation_takes_undefined_operations_as_zero():
    """The writer reads lines with unknown parameters (all 0) only to locate their words: a division
    by such a 0 (a translation's computed arc) gives 0 there, while a real run still refuses it."""
    import pytest

    from millpost.emit.write import UnknownParameters
    from millpost.errors import ParseError
    from millpost.gcode.lexer import lex_line

    block = lex_line("G1 X[1/#<_a>] F100", 1, "t.nc", UnknownParameters())
    assert [(w.letter, w.value) for w in block.words] == [("G", 1.0), ("X", 0.0), ("F", 100.0)]
    with pytest.raises(ParseError, match="undefined"):
        lex_line("G1 X[1/#<_a>] F100", 1, "t.nc", {"_a": 0.0})
