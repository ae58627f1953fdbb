"""The real corpus in ../shared/data (Fusion, FreeCAD, CAMotics, pygcode, LinuxCNC): every file is read,
or refused with a line-numbered reason; never a traceback. Where LinuxCNC's interpreter `rs274` is
installed, it is the oracle: a file it runs must give the same moves (kind, end point, feed) within
1e-4 in program units, and a file millpost refuses for a reason other than an out-of-scope feature
must be refused by rs274 too (a program error, not a gap in millpost). Both run with every tool 3 mm in
diameter, so that programs with cutter radius compensation (G41/G42) are compared on the offset path."""

from __future__ import annotations

from pathlib import Path

import pytest

import gcode_mutants
import rs274_oracle
from conftest import SHARED_DATA
from millpost.errors import ParseError
from millpost.gcode import ReaderOptions, read_program

EXTENSIONS = {".ngc", ".nc", ".gcode", ".tap", ".cnc"}
CORPUS = sorted(p for p in SHARED_DATA.rglob("*") if p.suffix.lower() in EXTENSIONS) if SHARED_DATA.exists() else []
# LinuxCNC 2.9 feeds G84 along the wrong axis in G18/G19 (its own `expected` traces record the bug).
LINUXCNC_BUGS = {"g84/g18", "g84/g19"}
DIAMETERS_MM = {n: 3.0 for n in range(1, 100)}


def out_of_scope(err: ParseError) -> bool:
    return "not supported" in err.reason or "unknown G code" in err.reason


@pytest.mark.skipif(not CORPUS, reason=f"{SHARED_DATA} is absent (third-party corpus, not in the repo)")
@pytest.mark.parametrize("path", CORPUS, ids=[str(p.relative_to(SHARED_DATA)) for p in CORPUS])
def test_corpus_file(path: Path) -> None:
    try:
        options = ReaderOptions.linuxcnc()
        options.tool_diameters_mm = DIAMETERS_MM
        program = read_program(path, options)
    except ParseError as err:
        assert err.line >= 1 and err.column >= 1 and err.expected, str(err)
        assert str(path) in str(err)
        if out_of_scope(err) or rs274_oracle.RS274 is None:
            return
        trace = rs274_oracle.run(path, diameters_mm=DIAMETERS_MM)
        assert trace.error is not None, f"millpost refused a program LinuxCNC runs: {err}"
        return
    # read: every position, arc centre, feed, speed and dwell a finite number, and moves only from blocks
    # (a file of subroutine definitions only, like ngcgui_lib/helix.ngc, runs no block and has no move)
    assert gcode_mutants.nonfinite(program) is None, f"{path}: {gcode_mutants.nonfinite(program)}"
    assert program.blocks >= 1 or len(program.toolpath.kind) == 0, f"{path}: moves from {program.blocks} blocks"
    if rs274_oracle.RS274 is None or any(bug in str(path) for bug in LINUXCNC_BUGS):
        return
    trace = rs274_oracle.run(path, diameters_mm=DIAMETERS_MM)
    # where LinuxCNC stopped early (an M code it does not know, '%' mid-file, ...) the moves before agree
    assert rs274_oracle.mismatches(program, trace, prefix=trace.error is not None) == []
