"""`convert --to sinumerik`: RS-274 programs re-posted in Sinumerik's words (G710, ';' comments, N
numbers, G4 F in seconds, M30) read back to the same moves; with LinuxCNC's `rs274 -g` where installed,
LinuxCNC → Sinumerik → LinuxCNC gives LinuxCNC's own moves."""

from __future__ import annotations

import re

import pytest

import rs274_oracle
from conftest import SHARED_DATA
from millpost.cli import main
from millpost.errors import MillpostError, ParseError
from millpost.gcode import ReaderOptions, dialects, read_program, read_text
from millpost.gcode.convert import convert, same_path

LINUXCNC = """(pocket corner and two holes)
G21 G90 G17 G94
T2 M6 G43
S1200 M3 M8
G0 X0 Y0 Z10
G64 P0.02
G1 Z-1 F200
G1 X20 F800
G2 X30 Y10 I0 J10
G3 X20 Y20 I-10 J0 P2
G4 P1.5
G98 G83 X5 Y5 Z-6 R2 Q2.5 F120
X15
G80
G0 Z20
G59.1
G0 X1
M2
"""


def test_written_in_sinumerik_words_and_read_back_to_the_same_path(tmp_path):
    """FB "Dwell time": G4 takes F in seconds (never P); "Inch/metric dimensions": G710; ';' comments,
    N numbers, M30; G64 P → G641 ADIS=, arc turns P → TURN=, G59.1 → G507 (read back as G59.1)."""
    src = tmp_path / "part.ngc"
    src.write_text(LINUXCNC)
    out = tmp_path / "part.mpf"
    assert main(["convert", str(src), "--to", "sinumerik", "-o", str(out)]) == 0
    text = out.read_text()
    code = [ln.partition(";")[0] for ln in text.splitlines()]
    assert "G710" in text and "N20 G710" in text and text.rstrip().endswith("M30")
    assert any(re.search(r"\bG4 F1\.5\b", c) for c in code) and not any(re.search(r"\bG4\b.*\bP", c) for c in code)
    assert not any("(" in c or "G21" in c or "G43" in c or "G83" in c for c in code)
    assert "G641 ADIS=0.02" in text and "TURN=1" in text and "G507" in text and " D1" in text
    a, b = read_program(src), read_program(out)
    assert b.dialect == "sinumerik"
    assert same_path(a, b) == []
    assert [e.value for e in b.events if e.kind == "dwell"] == pytest.approx([1.5])
    assert b.tools == [2] and b.spindle_rpm == [1200.0]


def test_g28_has_no_sinumerik_equivalent():
    program = read_text("G21 G90\nG0 X0 Y0 Z5\nG28 Z10\nM2\n", "home.ngc", ReaderOptions.linuxcnc())
    with pytest.raises(MillpostError, match="G28"):
        convert(program, dialects.get("sinumerik"))


@pytest.mark.skipif(rs274_oracle.RS274 is None, reason="rs274 (LinuxCNC 2.9's interpreter) is not installed")
def test_linuxcnc_to_sinumerik_to_linuxcnc_gives_linuxcncs_moves(tmp_path):
    """rs274 -g of the original and of the program brought back from Sinumerik trace the same moves,
    and the Sinumerik program read by millpost matches the original's trace."""
    src = tmp_path / "part.ngc"
    src.write_text(LINUXCNC)
    original = read_program(src, ReaderOptions.linuxcnc())
    sin = read_text(convert(original, dialects.get("sinumerik")), "part.mpf", ReaderOptions(dialect="sinumerik"))
    back = tmp_path / "back.ngc"
    back.write_text(convert(sin, dialects.get("linuxcnc")))
    traced, traced_back = rs274_oracle.run(src), rs274_oracle.run(back)
    assert traced.error is None and traced_back.error is None
    assert rs274_oracle.mismatches(sin, traced) == []
    assert rs274_oracle.mismatches(read_program(back, ReaderOptions.linuxcnc()), traced) == []
    assert rs274_oracle.mismatches(original, traced_back) == []


EXT = {".ngc", ".nc", ".gcode", ".tap"}
FILES = sorted(p for p in SHARED_DATA.rglob("*") if p.suffix.lower() in EXT) if SHARED_DATA.exists() else []


@pytest.mark.skipif(not FILES, reason="../shared/data is absent (third-party corpus)")
def test_real_programs_round_trip_through_sinumerik():
    """Every corpus program millpost reads and can re-post goes to Sinumerik and back to the same path."""
    checked = 0
    for path in FILES:
        try:
            program = read_program(path)
            text = convert(program, dialects.get("sinumerik"))
        except (ParseError, MillpostError):
            continue  # refusals (reading, or what convert cannot re-post) are tested elsewhere
        back = read_text(text, f"{path.name}.mpf", ReaderOptions(dialect="sinumerik"))
        assert same_path(program, back) == [], path
        checked += 1
    assert checked > 0
