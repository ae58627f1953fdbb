"""The strict reader: what LinuxCNC 2.9 refuses is refused with file:line:column, the word and what
was expected (rs274, when installed, confirms that LinuxCNC refuses it too); values beyond the stated
ranges and work beyond the stated caps are refused with a clear error; never another exception."""

from __future__ import annotations

import pytest

import rs274_oracle
from conftest import shared_data
from millpost.errors import ParseError
from millpost.gcode import ReaderOptions, read_program, read_text
from millpost.gcode.expressions import MAX_DEPTH
from millpost.gcode.flow import MAX_REPEATED_LINES
from millpost.gcode.interpret import MAX_CYCLE_MOVES, MAX_CYCLE_MOVES_TOTAL

HEAD = "G21 G90 G17 F100\nS1000 M3\n"  # two lines: the case is on line 3
NINES = "9" * 309

# (block, column, word, reason, LinuxCNC refuses it too)
REFUSED = [
    ("G1 X1e308 Y2", 4, "X1e308", "exponent", True),
    ("G1 X2 F1.5e3", 7, "F1.5e3", "exponent", True),
    (f"G1 X{NINES}", 4, "X999", "out of range", False),
    ("G1 X1000001", 4, "X1000001", "out of range", False),
    (f"G{NINES}", 1, "G999", "out of range", True),
    (f"M{NINES}", 1, "M999", "out of range", True),
    (f"T{NINES}", 1, "T999", "out of range", True),
    ("T10000000000", 1, "T10000000000", "out of range", True),
    (f"G43 H{NINES}", 5, "H999", "out of range", False),
    (f"M98 P{NINES}", 5, "P999", "out of range", True),
    (f"#{NINES} = 1", 2, "999", "number too large", True),
    ("G1 X1 E3", 7, "E3", "E word with nothing", True),
    ("G1 X1 Q3", 7, "Q3", "Q word with nothing", True),
    ("G1 X1 P3", 7, "P3", "P word with nothing", True),
    ("G1 X1 R3", 7, "R3", "R word with nothing", True),
    ("G1 X1 K3", 7, "K3", "K word with nothing", True),
    ("G1 X1 L3", 7, "L3", "L word with nothing", True),
    ("G1 X1 D3", 7, "D3", "D word with nothing", True),
    ("G0 X1 H3", 7, "H3", "H word with nothing", True),
    ("G1 X1 I3", 7, "I3", "I word with nothing", True),
    ("G0 X1 J3", 7, "J3", "J word with nothing", True),
    ("Q1", 1, "Q1", "Q word with nothing", True),
    ("G80 R1", 5, "R1", "R word with nothing", True),
    ("G81 X1 Z-1 R1 P1", 15, "P1", "P word with nothing", True),
    ("G81 X1 Z-1 R1 K2", 15, "K2", "K word with nothing", True),
    ("G43 H1 D1", 8, "D1", "D word with nothing", True),
    ("G0 X1 N5", 7, "N5", "line number", True),
    ("G81 X1 Z-1 R1 L0", 15, "L0", "repeat count", True),
    ("G81 X1 Z-1 R1 A0", 15, "A0", "canned cycle", True),
    ("M3 M5", 4, "M5", "two M codes", True),
    ("M7 M8", 4, "M8", "two M codes", True),
    ("G1 X1 M1.5", 7, "M1.5", "non-negative integer", True),
    ("M-1", 1, "M-1", "non-negative integer", True),
    ("G91 G53 G0 X1", 1, "", "G53 in incremental", True),
    ("G4 P1 G2 X0 I1", 4, "P1", "G4 with G2/G3", True),
    ("G0 X[1/0]", 7, "/0]", "undefined", True),
    ("#1 = [-8 ** 0.5]", 10, "**", "undefined", False),
    ("#1 = [10 ** 200 * 10 ** 200]", 17, "* 10", "overflows", False),
    ("G0 X[EXP[800]]", 6, "EXP[800]]", "undefined", True),
    ("G0 X" + "[" * (MAX_DEPTH + 5) + "1" + "]" * (MAX_DEPTH + 5), None, "", "nested", False),
    ("G0 X[" + "-" * 3000 + "1]", None, "", "nested", False),
    ("G0 X nan", 4, "X", "not followed by a number", True),
    ("G2 X2 Y0 I1 J0 K0", 16, "K0", "K word given for an arc in the XY plane", True),
    ("G18 G2 X2 Z0 I1 K0 J0", 20, "J0", "J word given for an arc in the XZ plane", True),
    ("G19 G3 Y2 Z0 J1 K0 I0", 20, "I0", "I word given for an arc in the YZ plane", True),
    ("G0 Xinf", 4, "Xinf", "not followed by a number", True),
]


def _rs274_refuses(tmp_path, text: str) -> bool:
    f = tmp_path / "case.ngc"
    f.write_text(text)
    return rs274_oracle.run(f).error is not None


@pytest.mark.parametrize("block,column,word,reason,lcnc", REFUSED, ids=[c[0][:30] for c in REFUSED])
def test_refused_with_file_line_column_word_and_expected(tmp_path, block, column, word, reason, lcnc):
    text = HEAD + block + "\nM2\n"
    with pytest.raises(ParseError) as info:
        read_text(text, "case.ngc", ReaderOptions.linuxcnc())
    err = info.value
    assert reason in err.reason, str(err)
    assert (err.file, err.line) == ("case.ngc", 3) and err.expected, str(err)
    if column is not None:
        assert err.column == column, str(err)
    assert word in err.word and len(str(err)) < 400, str(err)
    if lcnc and rs274_oracle.RS274:
        assert _rs274_refuses(tmp_path, text), f"LinuxCNC runs {block!r}"


# words that a block's codes do use: LinuxCNC runs these, and millpost reads the same moves
ACCEPTED = [
    "G0 Z5\nG83 X1 Y1 Z-3 R1 Q0.5",
    "G0 Z5\nG73 X1 Y1 Z-3 R1 Q0.5 L2",
    "G0 Z5\nG82 X1 Y1 Z-1 R1 P0.5",
    "G0 Z5\nG84 X1 Y1 Z-1 R1 P0.5",
    "G0 Z5\nG86 X1 Y1 Z-1 R1 P0.5\nG80",
    "G0 X1 Y0\nG2 X1 Y0 I-1 J0 P2",
    "G0 X1 Y0\nG3 X-1 Y0 R1",
    "G10 L2 P1 X1\nG54 G0 X0",
    "G64 P0.1 Q0.1\nG1 X1",
    "G43 H1\nG0 Z1",
    "G4 P0.5\nG1 X1 S2000 T1",
    "G0 Z1 M8\nM5 M9",
    "M98 P100 L2\nM2\nO100\nG91 G1 X1\nG90\nM99",
]


@pytest.mark.parametrize("body", ACCEPTED, ids=[c.split("\n")[-1][:30] for c in ACCEPTED])
def test_words_used_by_their_codes_are_read_as_linuxcnc_runs_them(tmp_path, body):
    text = HEAD + body + "\nM2\n"
    program = read_text(text, "ok.ngc", ReaderOptions.linuxcnc())
    assert len(program.toolpath) > 0
    if rs274_oracle.RS274:
        f = tmp_path / "ok.ngc"
        f.write_text(text)
        trace = rs274_oracle.run(f)
        assert trace.error is None, trace.error
        assert rs274_oracle.mismatches(program, trace) == []


@pytest.mark.parametrize("text,reason", [
    ("o1 do\nG0 X1\nG0 X0\no1 while [1]\nM2\n", "lines again"),
    ("#1 = 0\no1 while [#1 LT 1000000000]\nG0 X[#1 MOD 7]\n#1 = [#1 + 1]\no1 endwhile\nM2\n", "lines again"),
    ("o1 repeat [99999999]\nG0 X1\no1 endrepeat\nM2\n", "lines again"),
    ("M98 P1 L999999999\nM2\nO1\nG0 X1\nM99\n", "lines again"),
    ("G0 Z10\nG83 X0 Y0 Z-10 R100000 Q0.001 F100\n", "moves"),
    ("G0 Z10\nG81 X0 Y0 Z-10 R1 L999999999 F100\n", "moves"),
])
def test_loops_pecks_and_repeats_are_capped(text, reason):
    with pytest.raises(ParseError) as info:
        read_text(text, "cap.ngc", ReaderOptions.linuxcnc())
    assert reason in str(info.value) and info.value.line >= 1 and info.value.expected


def test_caps_are_what_the_readme_states():
    assert (MAX_REPEATED_LINES, MAX_CYCLE_MOVES, MAX_CYCLE_MOVES_TOTAL) == (100_000, 100_000, 1_000_000)


def test_canned_cycle_programs_under_the_caps_are_read():
    # 600 holes of 50 pecks: 91 200 moves in total, each block well under the cap per block
    holes = "".join(f"X{i % 30} Y{i // 30}\n" for i in range(1, 600))
    program = read_text("G21 G90 F100\nG0 Z5\nG83 X0 Y0 Z-10 R1 Q0.22\n" + holes + "G80\nM2\n", "holes.ngc")
    assert len(program.toolpath) > 600 * 50 * 3


def test_m98_loops_like_rs274():
    """LinuxCNC's tests/interp/m98m99/05-M98-loops: M98 P1 L10, L0, L2 of a G91 G99 G81 subprogram.
    Each cycle block after the first rapids to R from where it is (a move of no length) as LinuxCNC
    does: 51 moves, as rs274 gives."""
    path = shared_data("linuxcnc", "tests", "interp", "m98m99", "05-M98-loops", "test.ngc")
    program = read_program(path, ReaderOptions.linuxcnc())
    assert len(program.toolpath) == 51
    expected = rs274_oracle.parse((path.parent / "expected").read_text())
    assert len(expected.moves) == 51 and rs274_oracle.mismatches(program, expected, prefix=True) == []
    if rs274_oracle.RS274:
        trace = rs274_oracle.run(path)
        assert len(trace.moves) == 51 and rs274_oracle.mismatches(program, trace, prefix=True) == []


CYCLE_SEQUENCES = """G21 F100
G0 Z5
G91 G99 G81 X1 Z-2 R-4 L2
G90 G80 G0 Z5
G91 G98 G81 X1 Z-2 R-4 L2
G90 G80 G0 Z5
G99 G81 X1 Z-2 R1
X2 R2
X3 R0.5
G98 X4 R1.5
X5 R6
G80 G0 Z0
G83 X6 Z-3 R1 Q1
X7 R0.5
G99 X8 R2 L2
G80
G0 Z3
G81 X1 Z-1.0 R1
G83 X2 Z-1 R2 Q0.3
G73 X3 Z-1 R1.5 Q0.4
G80
M2
"""


def test_cycle_sequences_move_for_move_like_rs274(tmp_path):
    """Zero-length rapids included: the count of moves equals LinuxCNC's, not only the path."""
    program = read_text(CYCLE_SEQUENCES, "seq.ngc", ReaderOptions.linuxcnc())
    assert len(program.toolpath) == 146  # rs274: 146 moves
    if rs274_oracle.RS274:
        f = tmp_path / "seq.ngc"
        f.write_text(CYCLE_SEQUENCES)
        trace = rs274_oracle.run(f)
        assert trace.error is None and len(trace.moves) == len(program.toolpath)
        assert rs274_oracle.mismatches(program, trace) == []


def test_fanuc_k_repeats_a_cycle():
    text = "%\nO1000\nG21 G90 G17 F100\nG0 X0 Y0 Z5\nG91 G81 X10 Z-3 R-4 K3\nG80 G90\nM30\n%\n"
    program = read_text(text, "k.nc", ReaderOptions(dialect="fanuc"))
    drilled = program.toolpath.end[program.toolpath.kind == 1]
    assert drilled[:, 0].tolist() == [10.0, 20.0, 30.0]


def test_g49_with_h0_is_fanuc_style_only(tmp_path):
    """Centroid/Haas posts write `G49 H0`; LinuxCNC 2.9 refuses the H (rs274 says so when installed)."""
    text = "G21 G90\nG49 H0\nG0 X1\nM2\n"
    read_text(text, "h.nc", ReaderOptions(dialect="fanuc"))
    with pytest.raises(ParseError, match="h.nc:2:5: H word"):
        read_text(text, "h.nc", ReaderOptions(dialect="linuxcnc"))
    if rs274_oracle.RS274:
        f = tmp_path / "h.ngc"
        f.write_text(text)
        assert rs274_oracle.run(f).error is not None


def test_a_program_beyond_the_size_ceiling_is_refused_before_reading(tmp_path, monkeypatch):
    import millpost.gcode as gcode

    f = tmp_path / "big.nc"
    f.write_text("G0 X1\n" * 1000)
    monkeypatch.setattr(gcode, "MAX_PROGRAM_BYTES", 5000)
    with pytest.raises(ParseError) as info:
        read_program(f)
    assert str(f) in str(info.value) and "MB" in info.value.word and info.value.line == 1


def test_an_off_plane_arc_offset_is_read_where_the_controller_ignores_it():
    """grbl and Fanuc posts may write K0 on XY arcs; their controllers ignore it: read as written there."""
    for dialect in ("grbl", "fanuc"):
        tp = read_text(HEAD + "G2 X2 Y0 I1 J0 K0\nM2\n", "k.nc", ReaderOptions(dialect=dialect)).toolpath
        assert tp.center[-1].tolist()[:2] == [1.0, 0.0]
