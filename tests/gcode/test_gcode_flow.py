"""O-word control flow (LinuxCNC): subroutines with arguments and local parameters, if/elseif/else,
while, do/while, repeat, break, return values. Checked against positions worked out by hand, against
LinuxCNC's own rs274 when installed, and through emission and conversion (a line that runs several
times gets one F, the lowest any run wants; converted programs come out flattened)."""

from __future__ import annotations

import numpy as np
import pytest

import rs274_oracle
from conftest import SHARED_DATA
from millpost.emit import FeedPlan, write_feeds
from millpost.errors import ParseError
from millpost.gcode import ReaderOptions, read_program, read_text
from millpost.gcode.convert import convert, same_path
from millpost.gcode.dialects import get as get_dialect
from millpost.toolpath import RAPID

PROGRAM = """G21 G90
#<_safe> = 5
o100 sub
  G0 Z#<_safe>
  G0 X[#1-#3] Y#2
  G1 Z-1 F[#4]
  G2 X[#1-#3] Y#2 I#3 J0
  #<local> = 7
  G0 Z#<_safe>
o100 endsub
#<i> = 0
o10 while [#<i> LT 3]
  o100 call [#<i>*10] [0] [2] [100+#<i>]
  #<i> = [#<i>+1]
o10 endwhile
o20 repeat [2]
  G1 X50 Y[#<i>] F200
  #<i> = [#<i>+1]
o20 endrepeat
o30 if [#<i> GT 5]
  G0 X100
o30 elseif [#<i> GT 2]
  G0 X200
o30 else
  G0 X300
o30 endif
#<j> = 0
o40 do
  #<j> = [#<j>+1]
  o42 if [#<j> EQ 3]
    o40 break
  o42 endif
  G1 Z[-#<j>] F50
o40 while [#<j> LT 10]
o<twice> call [4]
G0 X#<_value> Y[EXISTS[#<local>]]
M2
o<twice> sub
  o<twice> return [#1*2]
  G0 X999
o<twice> endsub
"""


def test_flow_positions_by_hand():
    p = read_text(PROGRAM, "flow.ngc", ReaderOptions.linuxcnc())
    tp = p.toolpath
    assert p.control_flow
    circles = tp.kind >= 2
    # three calls: circles of radius 2 about (0,0), (10,0), (20,0), fed at 100, 101, 102 mm/min
    np.testing.assert_allclose(tp.center[circles][:, 0], [0, 10, 20])
    np.testing.assert_allclose(tp.feed_mm_min[circles], [100, 101, 102])
    assert len(set(tp.line[circles])) == 1  # one source line ran three times
    # repeat: two feeds to X50 at Y3 then Y4; if: i = 5 → elseif branch, X200
    feeds50 = (tp.kind == 1) & (tp.end[:, 0] == 50)
    np.testing.assert_allclose(tp.end[feeds50][:, 1], [3, 4])
    assert any((tp.kind == RAPID) & (tp.end[:, 0] == 200)) and not any(tp.end[:, 0] == 300)
    # do/while with break at j = 3: plunges to Z-1 and Z-2 only
    plunges = tp.end[(tp.feed_mm_min == 50), 2]
    np.testing.assert_allclose(plunges, [-1, -2])
    # return value 8 in #<_value>; #<local> was local to o100, so it does not exist here
    np.testing.assert_allclose(tp.end[-1], [8, 0, -2])
    assert not any(tp.end[:, 0] == 999)


@pytest.mark.skipif(not rs274_oracle.RS274, reason="LinuxCNC's rs274 is not installed")
def test_flow_matches_linuxcnc(tmp_path):
    f = tmp_path / "flow.ngc"
    f.write_text(PROGRAM)
    p = read_program(f, ReaderOptions.linuxcnc())
    trace = rs274_oracle.run(f)
    assert trace.error is None
    assert rs274_oracle.mismatches(p, trace) == []


@pytest.mark.parametrize("text,reason", [
    ("o1 while [1]\no1 endwhile\n", "lines again"),
    ("o5 call\nM2\n", "subroutine files are not supported"),
    ("o1 if [0]\nG0 X1\nM2\n", "not found before the end of the file"),
    ("o1 endwhile\n", "not open"),
    ("o7 frobnicate\n", "unknown O-word statement"),
])
def test_flow_errors_name_the_line(text, reason, monkeypatch):
    import millpost.gcode.interpret as interp
    monkeypatch.setattr(interp, "MAX_REPEATED_LINES", 10_000)
    with pytest.raises(ParseError) as info:
        read_text(text, "bad.ngc", ReaderOptions.linuxcnc())
    assert reason in str(info.value) and info.value.line >= 1


def test_emitted_feeds_on_repeated_lines_take_the_lowest(tmp_path):
    p = read_text(PROGRAM, "flow.ngc", ReaderOptions.linuxcnc())
    plan = FeedPlan.programmed(p)
    cut = p.toolpath.kind != RAPID
    plan.feed_mm_min[cut] = p.toolpath.feed_mm_min[cut] * 0.5
    text = write_feeds(p, plan)
    back = read_text(text, "emitted.ngc", ReaderOptions.linuxcnc())
    assert len(back.toolpath) == len(p.toolpath)
    np.testing.assert_allclose(back.toolpath.end, p.toolpath.end, atol=1e-9)
    # never faster than planned; the circle line runs at the lowest of its three runs (50 mm/min)
    assert np.all(back.toolpath.feed_mm_min[cut] <= plan.feed_mm_min[cut] + 1e-9)
    np.testing.assert_allclose(back.toolpath.feed_mm_min[p.toolpath.kind >= 2], 50.0)
    # control lines and lines without moves keep their bytes
    keep = [ln for ln in PROGRAM.splitlines() if ln.lstrip().lower().startswith(("o", "#"))]
    assert all(ln in text.splitlines() for ln in keep)
    if rs274_oracle.RS274:
        f = tmp_path / "emitted.ngc"
        f.write_text(text)
        assert rs274_oracle.run(f).error is None


def test_convert_flattens_control_flow():
    p = read_text(PROGRAM, "flow.ngc", ReaderOptions.linuxcnc())
    out = convert(p, get_dialect("grbl"))
    assert "o100" not in out.lower() and "#" not in out
    back = read_text(out, "flat.nc", ReaderOptions())
    assert not back.control_flow
    assert same_path(p, back, tol_mm=1e-3) == []


@pytest.mark.skipif(not (SHARED_DATA / "camotics").is_dir(), reason="../shared/data/camotics not present")
def test_genes_encoder_reads_as_linuxcnc_does():
    """A hand-written LinuxCNC program (CAMotics example) with subroutines, while, do and if."""
    f = SHARED_DATA / "camotics" / "examples" / "genes-encoder" / "genes-encoder.ngc"
    p = read_program(f, ReaderOptions.linuxcnc())
    assert len(p.toolpath) > 1000
    if rs274_oracle.RS274:
        assert rs274_oracle.mismatches(p, rs274_oracle.run(f)) == []


FANUC = """%
O1000 (main)
G21 G90 G17
#1 = 0
G0 X0 Y0 Z1
M98 P2 L3
G0 X100
M98 P0002 L0
M30
O2 (drill one hole, one step over in X each run)
#1 = [#1 + 1]
G91 G0 X5
G90 G1 Z-1 F100
G0 Z1
M99
%
"""


def test_fanuc_subprogram_runs_l_times_and_shares_parameters():
    p = read_text(FANUC, "fanuc.nc", ReaderOptions())
    tp = p.toolpath
    plunges = tp.end[(tp.kind != RAPID)]
    np.testing.assert_allclose(plunges[:, 0], [5, 10, 15])  # L3; L0 runs nothing
    assert tp.end[-1, 0] == 100
    assert len(set(tp.line[tp.kind != RAPID])) == 1


def test_m99_in_the_main_program_ends_it_and_m98_needs_p():
    p = read_text("G21 G90\nG1 X1 F100\nM99\nG1 X2\n", "m99.nc", ReaderOptions())
    assert len(p.toolpath) == 1 and any("M99" in n for n in p.notes)
    with pytest.raises(ParseError) as info:
        read_text("G21\nM98 L2\nM30\n", "m98.nc", ReaderOptions())
    assert info.value.line == 2 and "P" in info.value.expected
    with pytest.raises(ParseError) as info:
        read_text("G21\nM98 P7\nM30\n", "m98.nc", ReaderOptions())
    assert "O7" in str(info.value)


def test_flow_starting_late_and_a_call_on_the_last_line_without_newline():
    """The reader reads straight-line text without line bookkeeping and takes it up at the first
    control statement: lines before it must still be reachable, and the return from a call on an
    unterminated last line must end the program, not restart it."""
    text = "G21 G90\nG0 X1\no100 sub\nG1 X5 F100\no100 endsub\nG0 Y2\no100 call"
    p = read_text(text, "late.ngc", ReaderOptions.linuxcnc())
    np.testing.assert_allclose(p.toolpath.end, [[1, 0, 0], [1, 2, 0], [5, 2, 0]])
