"""Dialect conversion: every corpus file re-posted to its own dialect and to grbl (and the others) reads
back to the same path within 1e-4 mm (end points, cutting length), canned cycles expanded."""

from __future__ import annotations

import pytest

from conftest import SHARED_DATA
from millpost.cli import main
from millpost.errors import MillpostError, ParseError
from millpost.gcode import ReaderOptions, dialects, read_program, read_text
from millpost.gcode.convert import convert, same_path

EXT = {".ngc", ".nc", ".gcode", ".tap"}
FILES = sorted(p for p in SHARED_DATA.rglob("*") if p.suffix.lower() in EXT) if SHARED_DATA.exists() else []


@pytest.mark.skipif(not FILES, reason="../shared/data is absent (third-party corpus)")
@pytest.mark.parametrize("path", FILES, ids=[str(p.relative_to(SHARED_DATA)) for p in FILES])
def test_round_trip_through_own_dialect_and_grbl(path):
    try:
        program = read_program(path)
    except ParseError:
        return  # refusals are covered by the corpus test
    if program.compensated.any():  # tool-centre moves cannot be re-posted as G41/G42: refused, not changed
        with pytest.raises(MillpostError, match="cutter radius compensation"):
            convert(program, dialects.get("grbl"))
        return
    for name in {program.dialect, "grbl"}:
        target = dialects.get(name)
        try:
            text = convert(program, target)
        except ParseError as exc:  # what the target cannot run (G43 H on grbl, offsets set in the program)
            assert f"{path}:" in str(exc) and ": convert: " in str(exc)
            continue
        back = read_text(text, f"{path.name}->{name}", ReaderOptions(dialect=name))
        assert same_path(program, back) == [], name
        if len(program.toolpath):
            assert back.toolpath.bbox() == pytest.approx(program.toolpath.bbox(), abs=1e-4)


def test_canned_cycles_expand_for_grbl_and_keep_feeds(tmp_path):
    src = tmp_path / "drill.nc"
    src.write_text("%\nO0001\nG21 G90 G17\nT2 M6\nS1200 M3\nG0 X0 Y0 Z10\nG98 G83 X5 Y5 Z-6 R2 Q2.5 F120\n"
                   "X15\nG80\nG0 Z20\nM30\n%\n")
    out = tmp_path / "drill_grbl.nc"
    assert main(["convert", str(src), "--to", "grbl", "-o", str(out)]) == 0
    text = out.read_text()
    assert "G83" not in text and "G81" not in text
    a, b = read_program(src), read_program(out)
    assert same_path(a, b) == []
    assert b.tools == [2] and b.spindle_rpm == [1200.0]
    feeds = b.toolpath.feed_mm_min[b.toolpath.kind == 1]
    assert set(feeds.tolist()) == {120.0}


def test_inch_program_stays_in_inches(tmp_path):
    src = tmp_path / "inch.ngc"
    src.write_text("G20 G90 G17\nG0 X0 Y0 Z0.1\nG1 Z-0.05 F5\nG2 X1 Y0 I0.5 J0\nG21\nG1 X30 F100\nM2\n")
    out = tmp_path / "inch.nc"
    assert main(["convert", str(src), "--to", "fanuc", "-o", str(out)]) == 0
    text = out.read_text()
    assert "G20" in text and "G21" in text and text.startswith("%")
    assert same_path(read_program(src), read_program(out)) == []


def test_path_modes_keep_their_tolerances():
    # G64 P (blending) and Q (LinuxCNC's naive-CAM merge of straight feeds) both reach the output
    src = read_text("G21 G90 G17\nG64 P0.02 Q0.005\nG1 X1 F100\nG64 P0.01\nX2\nG64\nX3\nG61\nX4\nM2\n")
    text = convert(src, dialects.get("linuxcnc"))
    assert [ln for ln in text.splitlines() if ln.startswith(("G64", "G61"))] == \
        ["G64 P0.02 Q0.005", "G64 P0.01", "G64", "G61"]
