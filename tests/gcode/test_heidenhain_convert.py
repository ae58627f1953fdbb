"""`millpost convert --to heidenhain`: a Klartext writer whose output reads back to the same moves,
and, where LinuxCNC's `rs274` is installed, LinuxCNC → Klartext → LinuxCNC runs the same canonical
moves in LinuxCNC's own interpreter."""

import os
import re
import shutil
import subprocess

import numpy as np
import pytest

from millpost.cli import main
from millpost.errors import ParseError
from millpost.gcode import ReaderOptions, dialects, read_text
from millpost.gcode.convert import convert, same_path

RS274 = shutil.which("rs274")
needs_rs274 = pytest.mark.skipif(RS274 is None, reason="LinuxCNC's rs274 is not installed")
HH = dialects.get("heidenhain")

LINUXCNC = """(a pocket corner, a helix and a dwell)
G21 G90 G17 G94
T1 M6 G43 H1
S8000 M3
M8
G0 X0 Y0 Z5
G1 Z-1 F200
G1 X20 F800
G3 X30 Y10 I0 J10
G2 X40 Y20 R10
G1 Y30
G3 X40 Y30 Z-3 I-5 J0 P2
G4 P0.5
G1 X0 F600
G0 Z10
M9
M5
M2
"""


def _read(text, name, dialect):
    return read_text(text, name, ReaderOptions(dialect=dialect))


def test_klartext_written_reads_back_to_the_same_moves():
    program = _read(LINUXCNC, "in.ngc", "linuxcnc")
    text = convert(program, HH)
    lines = text.splitlines()
    assert lines[0] == "0 BEGIN PGM IN MM" and lines[-1].endswith("END PGM IN MM")
    assert all(re.match(rf"{k} ", ln) for k, ln in enumerate(lines))  # numbered blocks
    assert "TOOL CALL 1 Z S8000" in text and "L Z+5 FMAX" in text.replace("X+0 Y+0 ", "")
    assert "CC X+20 Y+10" in text and "C X+30 Y+10 DR+" in text  # G3 about (20, 10): counter-clockwise
    assert "CP IPA+720 IZ-2 DR+" in text  # two full turns down 2 mm (P2, end = start)
    assert "CYCL DEF 9.1 DWELL 0.5" in text
    back = _read(text, "out.h", "heidenhain")
    assert same_path(program, back, 1e-6) == []
    a, b = program.toolpath, back.toolpath
    assert np.array_equal(a.kind, b.kind) and np.allclose(a.feed_mm_min, b.feed_mm_min, equal_nan=True)
    arcs = a.kind >= 2
    assert np.abs(a.center[arcs] - b.center[arcs]).max() < 1e-9
    assert np.allclose(a.lengths(), b.lengths())
    dwell = [e.value for e in back.events if e.kind == "dwell"]
    assert dwell == [0.5]


def test_inch_program_is_written_in_mm():
    program = _read("G20 G90 G17\nG0 X0 Y0 Z0.1\nG1 Z-0.05 F10\nG1 X1.25 F40\nM2\n", "in.ngc", "linuxcnc")
    text = convert(program, HH)
    assert "BEGIN PGM IN MM" in text and "L X+31.75 F1016" in text
    assert same_path(program, _read(text, "out.h", "heidenhain")) == []


def test_arcs_in_g18_and_g19_are_written_as_cc_in_their_plane():
    """G18/G19 arcs (and a helix along the normal) as CC with the plane's two coordinates and C (TNC 640
    manual, "Circle center CC"): read back, the same moves."""
    program = _read("G21 G90 G17\nG0 X10 Y0 Z0\nG18 G2 X0 Z10 I-10 K0 F100\nG3 X10 Z0 I0 K-10 Y3\n"
                    "G19 G3 Y-3 Z6 J-3 K3\nG17 G2 X0 Y-3 I-5 J0\nM2\n", "in.ngc", "linuxcnc")
    text = convert(program, HH)
    assert "CC X+0 Z+0" in text and "C X+0 Z+10 DR-" in text and "CC Y+0 Z+3" in text
    back = _read(text, "out.h", "heidenhain")
    assert same_path(program, back, 1e-6) == []
    a, b = program.toolpath, back.toolpath
    assert np.array_equal(a.kind, b.kind) and np.array_equal(a.plane, b.plane)
    arcs = a.kind >= 2
    assert np.abs(a.center[arcs] - b.center[arcs]).max() < 1e-9


def test_refusals_say_where():
    program = _read("G21 G90 G18\nG0 X0 Y0 Z0\nG2 X0 Z0 I5 K0 Y-5 P2 F100\nM2\n", "in.ngc", "linuxcnc")
    with pytest.raises(ParseError, match="outside the XY plane") as e:
        convert(program, HH)
    assert (e.value.file, e.value.line) == ("in.ngc", 3)


@pytest.mark.parametrize("job", ["adaptive_pocket", "ball_roughing", "forging_contour", "offset_pocket",
                                 "sawcut_facing", "slotting"])
def test_sample_programs_convert_and_read_back(job, tmp_path):
    """The CLI reads the Klartext it wrote back and refuses when the path differs (1e-4 mm)."""
    src = os.path.join(os.path.dirname(__file__), "..", "..", "sample_jobs", job, "program.nc")
    out = tmp_path / "out.h"
    assert main(["convert", src, "--to", "heidenhain", "-o", str(out)]) == 0
    assert out.read_text().startswith("0 BEGIN PGM")


_CALL = re.compile(r"^\s*\d+\s+N\S*\s+(STRAIGHT_TRAVERSE|STRAIGHT_FEED|ARC_FEED)\((.*)\)\s*$")


def _canonical(path, tmp_path) -> list[tuple[str, list[float]]]:
    """rs274's motion calls and their arguments (program units)."""
    table = tmp_path / "tools.tbl"
    table.write_text("".join(f"T{i} P{i} Z{0.1 * i:.1f} D0.25 ;\n" for i in range(1, 10)))
    params = tmp_path / "params.var"
    params.write_text("")
    proc = subprocess.run([RS274, "-v", str(params), "-t", str(table), "-g", str(path)], capture_output=True,
                          text=True, timeout=60, stdin=subprocess.DEVNULL, cwd=path.parent,
                          env={**os.environ, "HOME": str(tmp_path)})
    calls = []
    for line in proc.stdout.splitlines():
        m = _CALL.match(line)
        if m:
            calls.append((m.group(1), [float(v) for v in re.split(r"[,\s]+", m.group(2).strip()) if v][:6]))
    assert calls, proc.stdout + proc.stderr
    return calls


@needs_rs274
def test_linuxcnc_to_heidenhain_to_linuxcnc_is_rs274_equal(tmp_path):
    src = tmp_path / "in.ngc"
    src.write_text(LINUXCNC)
    klartext = tmp_path / "mid.h"
    back = tmp_path / "back.ngc"
    assert main(["convert", str(src), "--to", "heidenhain", "-o", str(klartext)]) == 0
    assert main(["convert", str(klartext), "--to", "linuxcnc", "-o", str(back)]) == 0
    want, got = _canonical(src, tmp_path), _canonical(back, tmp_path)
    assert [c for c, _ in got] == [c for c, _ in want]
    worst = max(np.abs(np.subtract(g, w)).max() for (_, g), (_, w) in zip(got, want))
    assert worst < 1e-4


def test_a_move_that_goes_nowhere_stays_a_move():
    """Klartext coordinates are modal and only changed ones are written; a move to where the tool is
    writes them all, so that the converted program has the same moves (calibration plans map their
    rows to moves by count)."""
    program = _read("G21 G90\nG0 X1 Y2 Z3\nG1 Z3 F100\nG1 X5\nM2\n", "in.ngc", "linuxcnc")
    text = convert(program, HH)
    assert "L X+1 Y+2 Z+3 F100" in text and "L X+5" in text
    assert len(_read(text, "out.h", "heidenhain").toolpath) == len(program.toolpath)
