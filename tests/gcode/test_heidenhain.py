"""HEIDENHAIN Klartext read through its RS-274 translation: the moves the TNC 640 user's manual
("Klartext programming", ID 892903) defines, checked against closed forms and against the same
program written by hand in RS-274/NGC."""

import math

import numpy as np
import pytest

from millpost.emit.write import FeedPlan, write_feeds
from millpost.errors import MillpostError, ParseError
from millpost.gcode import ReaderOptions, read_text
from millpost.gcode.convert import same_path
from millpost.gcode.dialects import detect
from millpost.gcode.heidenhain import HEIDENHAIN, blank, set_feed
from millpost.toolpath import ARC_CCW, ARC_CW, FEED, RAPID

from heidenhain_programs import SLOTS  # in the style Fusion 360's and NX's Heidenhain posts write

HH = ReaderOptions(dialect="heidenhain")

# SLOTS by hand in RS-274/NGC, line for line
SLOTS_NGC = """G21 G90 G17
(blank)
(blank)
(comment)
T1 M6 G43 S9000
(tolerance)
(tolerance)
G0 Z10 M3
G0 X-5 Y8
G1 Z-1.5 F300
G1 X65 F700 M8
G0 Z2
G0 X-5 Y20
G1 Z-3
G1 X65 Y20.5
G0 Z10
G0 X30 Y-2
G1 Z-4 F300
G1 X52 F900
(CC)
G3 X62 Y8 I0 J10
G1 Y32
G3 X52 Y42 R10
G1 X8
G3 X-2 Y32 I0 J-10
G1 Y8
(CC)
G3 X8 Y-2 I10 J0
G1 X30
G0 Z10 M5
M30
M2
"""


def _read(text: str, name: str = "t.h"):
    return read_text(text, name, HH)


def test_detected_from_the_text():
    assert detect(SLOTS) is not None and detect(SLOTS).name == "heidenhain"
    assert detect(SLOTS_NGC).name != "heidenhain"
    assert read_text(SLOTS, "t.h").dialect == "heidenhain"


def test_same_moves_as_the_program_written_by_hand_in_rs274():
    """§ 7.4: L is a line; FMAX a rapid; C an arc about CC; CR R+ the arc under 180°; CT the arc
    tangent to the previous element; IX/IY add to the last programmed position (§ 7.3)."""
    a, b = _read(SLOTS), read_text(SLOTS_NGC, "t.ngc", ReaderOptions(dialect="linuxcnc"))
    ta, tb = a.toolpath, b.toolpath
    assert len(ta) == len(tb) and ta.line.tolist() == tb.line.tolist()
    assert np.abs(ta.end - tb.end).max() < 1e-6
    assert np.array_equal(ta.kind, tb.kind)
    arcs = ta.kind >= ARC_CW
    assert np.abs(ta.center[arcs] - tb.center[arcs]).max() < 1e-6
    assert np.allclose(ta.feed_mm_min, tb.feed_mm_min, equal_nan=True)
    assert same_path(a, b, 1e-6) == []


def test_fmax_holds_for_its_block_only():
    """§ 7.2 (feed rate F): FMAX is rapid traverse for its block; the last F holds again after it."""
    tp = _read(SLOTS).toolpath
    rows = {int(ln): i for i, ln in enumerate(tp.line)}
    assert tp.kind[rows[12]] == RAPID and tp.kind[rows[14]] == FEED
    assert tp.feed_mm_min[rows[14]] == 700.0  # line 13's L Z-3 without F: the F700 of line 10 again


def test_arc_directions_and_ct_centre_closed_form():
    """§ 7.4: DR+ is counter-clockwise, DR- clockwise. CT: the centre lies on the normal of the
    previous element's direction at the start, equidistant from start and end."""
    text = """0 BEGIN PGM T MM
1 L X+0 Y+0 Z+0 R0 FMAX
2 L X+10 F500
3 CT X+20 Y+6
4 CC X+20 Y+0
5 C X+26 Y+0 DR-
6 END PGM T MM
"""
    tp = _read(text).toolpath
    ct = int(np.flatnonzero(tp.line == 4)[0])
    # start (10,0) heading +X: centre (10, r) with r² = 10² + (6 - r)² → r = 136/12
    r = 136 / 12
    assert tp.kind[ct] == ARC_CCW and np.allclose(tp.center[ct, :2], [10, r], atol=1e-9)
    c = int(np.flatnonzero(tp.line == 6)[0])
    assert tp.kind[c] == ARC_CW and np.allclose(tp.center[c, :2], [20, 0])
    # the arc from (20, 6) clockwise about (20, 0) to (26, 0): a quarter circle of radius 6
    assert tp.lengths()[c] == pytest.approx(math.pi * 6 / 2, rel=1e-9)


def test_cr_negative_radius_is_the_arc_over_180():
    """§ 7.4 (CR): R negative gives the arc larger than 180°, positive the smaller one."""
    base = "0 BEGIN PGM T MM\n1 L X+0 Y+0 Z+0 R0 FMAX\n2 CR X+10 Y+0 R{r} DR+ F300\n3 END PGM T MM\n"
    short, long = (_read(base.format(r=r)).toolpath for r in ("+6", "-6"))
    theta = 2 * math.asin(5 / 6)  # the angle the chord of 10 subtends on a radius of 6
    assert short.lengths()[-1] == pytest.approx(6 * theta, rel=1e-9)
    assert long.lengths()[-1] == pytest.approx(6 * (2 * math.pi - theta), rel=1e-9)
    h = math.sqrt(36 - 25)  # counter-clockwise from (0,0) to (10,0): under 180° about (5, h), over about (5, -h)
    assert np.allclose(short.center[-1, :2], [5, h]) and np.allclose(long.center[-1, :2], [5, -h])


@pytest.mark.parametrize("r, dr", [("+6", "DR+"), ("-6", "DR+"), ("+6", "DR-"), ("-6", "DR-")])
def test_ct_after_cr_is_tangent(r, dr):
    """§ 7.4 (CT): the arc continues the previous one tangentially, so both centres and the joint
    point lie on one line (the common normal)."""
    text = f"0 BEGIN PGM T MM\n1 L X+0 Y+0 Z+0 R0 FMAX\n2 CR X+10 Y+0 R{r} {dr} F300\n3 CT X+14 Y+9\n4 END PGM T MM\n"
    tp = _read(text).toolpath
    c1, p, c2 = tp.center[-2, :2], tp.end[-2, :2], tp.center[-1, :2]
    u, v = p - c1, c2 - p
    assert abs(u[0] * v[1] - u[1] * v[0]) < 1e-9 * np.linalg.norm(u) * np.linalg.norm(v)
    # and the direction of travel at the joint is the same on both arcs
    def direction(kind, centre):
        t = np.array([-(p - centre)[1], (p - centre)[0]])
        return t if kind == ARC_CCW else -t
    d1, d2 = direction(tp.kind[-2], c1), direction(tp.kind[-1], c2)
    assert np.dot(d1, d2) > 0


def test_blank_box_in_mm():
    """§ 3.2 (BLK FORM): 0.1 is the MIN point, 0.2 the MAX point (incremental: from the MIN point)."""
    assert blank(SLOTS) == ((0.0, 0.0, -10.0), (60.0, 40.0, 0.0))
    inch = "0 BEGIN PGM A INCH\n1 BLK FORM 0.1 Z X-1 Y+0 Z-2\n2 BLK FORM 0.2 IX+4 IY+3 Z+0\n"
    lo, hi = blank(inch)
    assert np.allclose(lo, [-25.4, 0, -50.8]) and np.allclose(hi, [76.2, 76.2, 0])
    assert blank("0 BEGIN PGM A MM\n1 L X+0 FMAX\n") is None


@pytest.mark.parametrize("block, word, column", [
    ("PLANE SPATIAL SPA+0 SPB+45 SPC+0 TURN FMAX", "PLANE", 3),
    ("L X+10 FMAX M128", "M128", 15),
    ("CYCL DEF 19.0 WORKING PLANE", "CYCL DEF 19", 3),
    ("CYCL DEF 22 ROUGH-OUT", "CYCL DEF 22", 3),
    ("FL X+10 Y+5 AN+45", "FL", 3),
    ("L X+10 FZ0.05", "FZ0.05", 10),
    ("TOOL CALL 1 X S5000", "X", 15),
    ("L X+10 G+5", "G+5", 10),
    ("SPLINE X+1", "SPLINE", 3),
    ("APPR LCT X+10 Y+20 Z-10 R10 RR F100", "APPR LCT", 3),
    ("DEP CT CCA180 R+2 F100", "DEP CT", 3),
])
def test_refused_with_file_line_column(block, word, column):
    """Tilted planes, TCPM, SL cycles, FK, APPR/DEP ("Approaching and departing a contour"), feed per
    tooth, other tool axes and unknown words are refused where they are written."""
    text = f"0 BEGIN PGM T MM\n1 L X+0 Y+0 Z+5 R0 FMAX\n2 {block}\n3 END PGM T MM\n"
    with pytest.raises(ParseError) as e:
        _read(text, "part.h")
    assert (e.value.file, e.value.line, e.value.column) == ("part.h", 3, column)
    assert word in e.value.word and len(e.value.word) < 15
    assert str(e.value).startswith("part.h:3:")


def test_incremental_from_an_unknown_position_is_refused():
    with pytest.raises(ParseError, match="incremental X from an unknown position"):
        _read("0 BEGIN PGM T MM\n1 L IX+5 F100\n2 END PGM T MM\n")


@pytest.mark.parametrize("line, f, expected", [
    ("10 L X+65 F700 M8 ; slot", "450", "10 L X+65 F450 M8 ; slot"),
    ("13 L Z-3", "300", "13 L Z-3 F300"),
    ("13 L Z-3 M8", "300", "13 L Z-3 F300 M8"),
    ("13 L Z-3 ; down", "300", "13 L Z-3 F300 ; down"),
    ("10 L X+65 F700 M8 ; slot", None, "10 L X+65 M8 ; slot"),
    ("10 L X+65 F700", None, "10 L X+65"),
])
def test_set_feed_changes_only_the_f_word(line, f, expected):
    assert set_feed(line, f) == expected


def test_optimized_feeds_written_back_only_f_changes_same_path():
    """Only F words change, the rest of every block keeps its bytes, and the program read back takes
    the same path (within 1e-4 mm) at the written feeds."""
    program = _read(SLOTS)
    tp = program.toolpath
    feeds = tp.feed_mm_min * np.linspace(0.5, 1.5, len(tp))
    out = write_feeds(program, FeedPlan(feeds, {}))
    again = _read(out)
    assert same_path(program, again) == []
    cutting = tp.kind != RAPID
    assert np.allclose(again.toolpath.feed_mm_min[cutting], feeds[cutting], rtol=1e-3)
    for old, new in zip(SLOTS.splitlines(), out.splitlines()):
        strip = lambda s: " ".join(w for w in s.split() if not (w.startswith("F") and w[1:2].isdigit()))  # noqa: E731
        assert strip(old) == strip(new)
        assert "FMAX" not in old or old == new


def test_dialect_is_registered():
    from millpost.gcode import dialects
    assert dialects.get("heidenhain") is HEIDENHAIN


def _moves(text: str):
    tp = _read(text).toolpath
    return tp, {int(ln): i for i, ln in enumerate(tp.line)}


def test_q_parameters_fn_and_formulas():
    """§ 9.3 (FN 0-4: assignment and the four operations) and § 9.8 (formulas: SQ, SQRT, SIN in
    degrees, PI, ^, precedence): the values the coordinates then take."""
    text = """0 BEGIN PGM Q MM
1 FN 0: Q1 = +10
2 FN0: Q2 = 25
3 FN 1: Q3 = +Q1 + +Q2
4 FN 2: Q4 = +Q2 - -5
5 FN 3: Q5 = +Q1 * +3
6 FN 4: Q6 = +Q2 / +Q1
7 Q7 = SQ(Q1) + SQRT(Q2) * SIN(30) - PI ^ 2
8 QL8 = (Q1 + 2) * 3
9 L X+Q3 Y-Q4 Z+Q5 R0 FMAX
10 L X+Q6 Y+Q7 Z+QL8 F100
11 END PGM Q MM
"""
    tp, at = _moves(text)
    assert np.allclose(tp.end[at[10]], [35, -30, 30])
    assert np.allclose(tp.end[at[11]], [2.5, 100 + 2.5 - math.pi ** 2, 36])


def test_section_repeat_runs_rep_plus_one_times():
    """§ 8.4 (program section repeats): CALL LBL 1 REP 2 jumps back to LBL 1 twice, so the section
    runs three times; the repeat count may be written as the TNC shows it (REP 2/2)."""
    text = """0 BEGIN PGM R MM
1 FN 0: Q1 = 40
2 L X-5 Y+0 Z+0.5 R0 FMAX
3 LBL 1
4 L IZ-1 F100
5 L X+Q1 F300
6 L IZ-1 F100
7 L X-5 F300
8 CALL LBL 1 REP 2/2
9 L Z+10 FMAX
10 END PGM R MM
"""
    tp = _read(text).toolpath
    cuts = tp.kind == FEED
    assert cuts.sum() == 12 and tp.line[cuts].tolist() == [5, 6, 7, 8] * 3
    assert np.allclose(tp.end[cuts][-1], [-5, 0, 0.5 - 6])


def test_subprogram_call_runs_up_to_lbl_0():
    """§ 8.3 (subprograms): CALL LBL n runs the blocks after LBL n up to LBL 0, then the block after
    the call; a named label ("CONT") too."""
    text = """0 BEGIN PGM S MM
1 L X+0 Y+0 Z+2 R0 FMAX
2 CALL LBL "CONT"
3 L IX+5 FMAX
4 CALL LBL 7
5 L Z+50 FMAX
6 M30
7 LBL "CONT"
8 L Z-1 F100
9 L IY+10 F300
10 LBL 0
11 LBL 7
12 L IY-10 F300
13 LBL 0
14 END PGM S MM
"""
    tp = _read(text).toolpath
    assert tp.line.tolist() == [2, 9, 10, 4, 13, 6]
    assert np.allclose(tp.end[-2], [5, 0, -1]) and np.allclose(tp.end[-1], [5, 0, 50])


def test_polar_lines_and_arcs_about_the_pole():
    """§ 7.5: LP PR/PA is the point at radius PR and angle PA (degrees, from +X counter-clockwise)
    about the pole CC; CP PA an arc about the pole to that angle; CP IPA+720 with IZ two turns of a
    helix; IPR/IPA add to the last position's radius/angle."""
    text = """0 BEGIN PGM P MM
1 L X+0 Y+0 Z+5 R0 FMAX
2 CC X+10 Y+10
3 LP PR+5 PA+0 F300
4 CP PA+90 DR+
5 CP IPA+720 IZ-2 DR+
6 LP IPR+5
7 LP PA+180 IPR-3
8 END PGM P MM
"""
    tp, at = _moves(text)
    assert np.allclose(tp.end[at[4], :2], [15, 10]) and np.allclose(tp.end[at[5], :2], [10, 15])
    assert tp.kind[at[5]] == ARC_CCW and tp.lengths()[at[5]] == pytest.approx(2 * math.pi * 5 / 4)
    assert tp.lengths()[at[6]] == pytest.approx(math.hypot(2 * 2 * math.pi * 5, 2))  # two turns, 2 mm down
    assert np.allclose(tp.end[at[6]], [10, 15, 3])
    assert np.allclose(tp.end[at[7], :2], [10, 20]) and np.allclose(tp.end[at[8], :2], [3, 10])


def test_rnd_and_chf_at_line_corners():
    """§ 7.4: RND R inserts the arc of radius R tangent to both lines (tangent points R·tan(θ/2)
    from the corner, θ the change of direction); CHF s cuts the corner from s before it to s after it.
    Incremental coordinates after them count from the corner."""
    text = """0 BEGIN PGM R MM
1 L X+0 Y+0 Z-1 R0 FMAX
2 L X+10 F300
3 RND R2
4 L Y+10
5 CHF 3
6 L X+0
7 RND R1 F100
8 L IX-5 IY-5
9 END PGM R MM
"""
    tp, at = _moves(text)
    assert np.allclose(tp.end[at[3], :2], [8, 0])
    assert tp.kind[at[4]] == ARC_CCW and np.allclose(tp.center[at[4], :2], [8, 2])
    assert np.allclose(tp.end[at[4], :2], [10, 2]) and tp.lengths()[at[4]] == pytest.approx(math.pi)
    assert np.allclose(tp.start[at[6], :2], [10, 7]) and np.allclose(tp.end[at[6], :2], [7, 10])
    d = math.tan(math.radians(45 / 2))  # a 45° turn, radius 1
    assert np.allclose(tp.end[at[7], :2], [d, 10])
    assert np.allclose(tp.center[at[8], :2], [d, 9]) and tp.lengths()[at[8]] == pytest.approx(math.pi / 4)
    assert tp.feed_mm_min[at[8]] == 100 and np.allclose(tp.end[at[9], :2], [-5, 5])


def test_datum_shift_moves_the_frame():
    """CYCL DEF 7 (datum shift): the program's coordinates count from the shifted datum; an
    incremental move after it continues from where the tool is."""
    text = """0 BEGIN PGM D MM
1 L X+0 Y+0 Z+5 R0 FMAX
2 CYCL DEF 7.0 DATUM SHIFT
3 CYCL DEF 7.1 X+10
4 CYCL DEF 7.2 IY+5
5 L IX+1 F100
6 L X+0 Y+0
7 END PGM D MM
"""
    shifted = _read(text)
    by_hand = read_text("G21 G90\nG0 X0 Y0 Z5\n(7.0)\nG52 X10\nG52 Y5\nG1 X-9 Y-5 F100\nG1 X0 Y0\nM2\n", "d.ngc",
                        ReaderOptions(dialect="linuxcnc"))
    assert np.abs(shifted.toolpath.end - by_hand.toolpath.end).max() < 1e-9


LOOPED = """0 BEGIN PGM FL MM
1 TOOL CALL 1 Z S9000
2 L X+0 Y+0 Z+5 R0 FMAX M3
3 L Z+0.5 F300
4 LBL 1
5 L IZ-1 F100
6 L X+10 F600
7 CT X+15 Y+3
8 L X+20 Y+10
9 RND R2
10 L X+0
11 CC X+0 Y+5
12 C X+0 Y+0 DR+
13 CR X+5 Y+5 R-5 DR-
14 L X+0 Y+0
15 CALL LBL 1 REP 2
16 L Z+10 FMAX
17 END PGM FL MM
"""


def test_write_back_with_repeats_and_computed_arcs():
    """A program whose lines run several times (a section repeat) and whose arcs the translation
    computes (CT, RND, CR): feeds written back, only F words changed, the same path read back."""
    program = _read(LOOPED)
    feeds = program.toolpath.feed_mm_min * 0.8
    out = write_feeds(program, FeedPlan(feeds, {}))
    again = _read(out)
    assert same_path(program, again) == []
    assert [ln.split(" F")[0] for ln in out.splitlines()] == [ln.split(" F")[0] for ln in LOOPED.splitlines()]
    assert "16 L Z+10 FMAX" in out.splitlines()


CYCLE = """0 BEGIN PGM D MM
1 TOOL CALL 1 Z S3000
2 L X+10 Y+10 Z+20 R0 FMAX M3
3 CYCL DEF 200 DRILLING ~
  Q200=+2 ;SET-UP CLEARANCE ~
  Q201=-15 ;DEPTH ~
  Q206=+150 ;FEED RATE FOR PLNGNG ~
  Q202={peck} ;PLUNGING DEPTH ~
  Q210=+0 ;DWELL TIME AT TOP ~
  Q203=+1 ;SURFACE COORDINATE ~
  Q204={second} ;2ND SET-UP CLEARANCE ~
  Q211={dwell} ;DWELL TIME AT DEPTH
12 L FMAX M99
13 L X+30 FMAX M99
14 CYCL CALL
15 END PGM D MM
"""


@pytest.mark.parametrize("peck, second, dwell, ngc", [
    ("+15", "+2", "+0", "G99 G81 Z-14 R3 F150"),
    ("+15", "+2", "+0.5", "G99 G82 Z-14 R3 P0.5 F150"),
    ("+5", "+2", "+0", "G99 G83 Z-14 R3 Q5 F150"),
    ("+5", "+19", "+0", "G98 G83 Z-14 R3 Q5 F150"),
])
def test_drilling_cycle_200_runs_as_the_rs274_cycle(peck, second, dwell, ngc):
    """Cycle 200 DRILLING (TNC 640 cycles manual, cycle 200): rapid to the set-up clearance Q200 above
    the surface Q203, drill at Q206 to Q203 + Q201 in infeeds of Q202 (one when Q202 ≥ the depth),
    dwell Q211 at depth, retract to the set-up clearance (here from Z20 when the 2nd set-up
    clearance is Q203 + Q204 = Z20). M99 on a positioning block and CYCL CALL call it."""
    text = CYCLE.format(peck=peck, second=second, dwell=dwell)
    by_hand = f"""G21 G90 G17
T1 M6 G43 S3000
G0 X10 Y10 Z20 M3
{ngc.replace(" Z", " X10 Y10 Z", 1)}
{ngc.replace(" Z", " X30 Z", 1)}
{ngc}
M2
"""
    a, b = _read(text).toolpath, read_text(by_hand, "d.ngc", ReaderOptions(dialect="linuxcnc")).toolpath
    assert len(a) == len(b) and np.abs(a.end - b.end).max() < 1e-9
    assert np.array_equal(a.kind, b.kind) and np.allclose(a.feed_mm_min, b.feed_mm_min, equal_nan=True)
    bottom = a.end[:, 2].min()
    assert bottom == pytest.approx(1 - 15)


def test_cycle_parameters_not_modelled_are_refused():
    text = CYCLE.format(peck="+5", second="+2", dwell="+0").replace("Q210=+0", "Q210=+1")
    with pytest.raises(ParseError, match="dwell at the top") as e:
        _read(text, "d.h")
    assert (e.value.line, e.value.column, e.value.word) == (9, 3, "Q210")  # where Q210 is set


def test_fusion_style_tool_change_retract_and_f_max():
    """L M140 MB MAX (retract to the top of the tool axis) and "F MAX" written apart, as posts do."""
    text = "0 BEGIN PGM F MM\n1 TOOL CALL 3 Z S5000\n2 L M140 MB MAX\n3 L X+5 Y+5 R0 F MAX\n4 L Z+2 FMAX\n" \
           "5 L M140 MB+10\n6 END PGM F MM\n"
    tp = _read(text).toolpath
    assert tp.kind.tolist() == [RAPID] * 4
    assert np.allclose(tp.end[-1], [5, 5, 12])


ISO = """%DRILL G71 *
N10 G30 G17 X+0 Y+0 Z-20 *
N20 G31 G90 X+100 Y+100 Z+0 *
N30 T1 G17 S3000 *
N40 G00 G40 G90 Z+100 M03 *
N50 X+10 Y+10 *
N60 G01 Z-5 F200 *
N70 I+50 J+10 *
N80 G03 X+90 Y+10 F500 *
N90 X+10 Y+10 *
N100 G02 X+30 Y+30 R+20 *
N110 G00 Z+100 M30 *
N99999999 %DRILL G71 *
"""


def test_iso_mode_reads_as_its_rs274_equivalent():
    """ISO programs (TNC 640 manual, ISO programming): blocks end in *, %name G71 * begins and ends
    the program, I/J are the circle centre in absolute coordinates and stay in force, T n G17 S.. calls
    the tool."""
    assert detect(ISO).name == "heidenhain"
    by_hand = """G21 G90 G17
(blank)
(blank)
T1 M6 G43 S3000
G0 Z100 M3
X10 Y10
G1 Z-5 F200
(centre)
G3 X90 Y10 I40 J0 F500
X10 Y10 I-40 J0
G2 X30 Y30 R20
G0 Z100 M30
"""
    a = read_text(ISO, "d.h").toolpath
    b = read_text(by_hand, "d.ngc", ReaderOptions(dialect="linuxcnc")).toolpath
    assert a.line.tolist() == b.line.tolist() and np.abs(a.end - b.end).max() < 1e-9
    assert np.abs(a.center[a.kind >= ARC_CW] - b.center[b.kind >= ARC_CW]).max() < 1e-9
    assert set_feed("N60 G01Z-5F200*", "150") == "N60 G01Z-5F150*"
    assert set_feed("N50 X+10 Y+10 *", "150") == "N50 X+10 Y+10 F150 *"


def test_iso_mode_refuses_what_it_does_not_read():
    with pytest.raises(ParseError, match="G6 is not supported") as e:
        read_text(ISO.replace("N90 X+10 Y+10 *", "N90 G06 X+10 Y+10 *"), "d.h")
    assert (e.value.line, e.value.column, e.value.word) == (10, 5, "G06")


def test_comment_continued_with_tilde_and_cycle_feed_from_a_parameter():
    """A comment broken with ~ goes on in the next line (as Fusion 360 writes its header); a cycle's
    feed Q206 may be a Q parameter (Q206=Q2, as hyperMILL writes); the feed of a cycle call is not
    rewritten in the calling block (it is Q206's)."""
    text = """0 BEGIN PGM D MM
1 ; a long description of the machine~
 Head
2 TOOL CALL 5 Z S943
3 FN 0:Q2=75 ; Z FEED RATE
4 L X+0 Y+0 Z+50 R0 F MAX M3
5 CYCL DEF 200 DRILLING~
    Q200=5 ;SET-UP CLEARANCE~
    Q201=-15 ;DEPTH~
    Q206=Q2 ;FEED RATE FOR PLUNGING~
    Q202=15 ;PLUNGING DEPTH~
    Q210=0 ;DWELL TIME AT TOP~
    Q203=0 ;SURFACE COORDINATE~
    Q204=50 ;2ND SET-UP CLEARANCE~
    Q211=0 ;DWELL TIME AT BOTTOM
6 L X+10 Y+10 R0 F MAX M99
7 END PGM D MM
"""
    tp = _read(text).toolpath
    assert set(tp.feed_mm_min[tp.kind == FEED]) == {75.0} and tp.end[:, 2].min() == -15
    with pytest.raises(MillpostError, match="Q206"):
        set_feed("6 L X+10 Y+10 R0 F MAX M99", "60")


def test_untilted_plane_and_tcpm_off_are_accepted():
    """PLANE RESET STAY and FUNCTION RESET TCPM put the control in the 3-axis state without moving
    (NX and hyperMILL write them before each operation); PLANE RESET TURN would move rotary axes."""
    base = "0 BEGIN PGM T MM\n1 {}\n2 L X+0 Y+0 Z+5 R0 FMAX\n3 END PGM T MM\n"
    for block in ("PLANE RESET STAY", "FUNCTION RESET TCPM"):
        assert len(_read(base.format(block)).toolpath) == 1
    with pytest.raises(ParseError, match="tilted working planes"):
        _read(base.format("PLANE RESET TURN FMAX"))


def test_tool_call_feed_fauto_cc_alone_and_machine_coordinates():
    """§ 6.3: the F of TOOL CALL is the feed until a block programs another, and FAUTO's; § 7.4: CC
    without coordinates takes the last programmed position; M91: the coordinates of the block are
    machine coordinates (as G53), after which incremental moves of that axis are refused (where the
    tool is in the program's frame is the machine's business)."""
    text = """0 BEGIN PGM T MM
1 TOOL CALL 1 Z S1000 F250
2 L X+0 Y+0 Z+5 R0 FMAX
3 L X+10
4 CC
5 L X+20 F900
6 L X+30 FAUTO
7 C X-10 Y+0 DR+
8 STOP
9 L Z+0 FMAX M91
10 END PGM T MM
"""
    program = _read(text)
    tp, at = program.toolpath, {int(ln): i for i, ln in enumerate(program.toolpath.line)}
    assert tp.feed_mm_min[at[4]] == 250 and tp.feed_mm_min[at[6]] == 900 and tp.feed_mm_min[at[7]] == 250
    assert np.allclose(tp.center[at[8], :2], [10, 0]) and tp.kind[at[8]] == ARC_CCW  # about the point of line 3
    assert any(e.kind == "stop" and e.value == 0 for e in program.events)
    with pytest.raises(ParseError, match="incremental Z from an unknown position"):
        _read(text.replace("10 END PGM T MM", "10 L IZ+5 FMAX\n11 END PGM T MM"))


def test_feed_from_a_q_parameter():
    """F may name a Q parameter (FQ2, as hyperMILL writes its feeds); the feed written back takes the
    place of that F word."""
    text = "0 BEGIN PGM Q MM\n1 FN 0: Q2 = +750\n2 L X+0 Y+0 Z-1 R0 FMAX\n3 L X+10 FQ2\n4 END PGM Q MM\n"
    assert _read(text).toolpath.feed_mm_min[-1] == 750
    assert set_feed("3 L X+10 FQ2", "600") == "3 L X+10 F600"


def test_tool_oversizes_are_refused():
    """§ 6.3: DL/DR in TOOL CALL are oversizes of the tool's length and radius; the control would cut
    DL higher and DR wider than programmed, which millpost does not model: refused, zeros accepted."""
    base = "0 BEGIN PGM T MM\n1 TOOL CALL 1 Z S1000 {}\n2 L X+0 Y+0 Z+5 R0 FMAX\n3 END PGM T MM\n"
    assert len(_read(base.format("DL+0 DR+0")).toolpath) == 1
    for word in ("DL+0.2", "DR-0.05"):
        with pytest.raises(ParseError, match="oversize") as e:
            _read(base.format(word))
        assert e.value.word == word


def test_tools_called_by_name_are_numbered_as_sinumerik_numbers_them():
    """§ 6.3 (TOOL CALL: tool number or tool name in quotes, as hyperMILL and NX post): a job describes
    tools by number, so each name gets the next number by first appearance (a name of digits: that
    number), the rule of Sinumerik's T="name"; a note says which number each name got."""
    text = """0 BEGIN PGM T MM
1 TOOL DEF "DRILL 5 (HSS)"
2 TOOL CALL "MILL_D10" Z S8000 F500
3 L X+0 Y+0 Z+5 R0 FMAX
4 TOOL CALL "DRILL 5 (HSS)" Z S3000
5 L X+10 FMAX
6 TOOL CALL "MILL_D10" Z S8000
7 TOOL CALL "7" Z S1000
8 L Z+10 FMAX
9 END PGM T MM
"""
    program = _read(text)
    assert program.tools == [2, 1, 7]
    notes = [str(e.value) for e in program.events if e.kind == "comment" and "tool " in str(e.value)]
    assert notes[:2] == ["tool DRILL 5 [HSS] = T1", "tool MILL_D10 = T2"]
    sin = read_text('N10 T="DRILL 5 (HSS)"\nN20 T="MILL_D10" M6\nN30 G0 X0\nN40 T="7" M6\nN50 X1\n', "t.mpf",
                    ReaderOptions(dialect="sinumerik"))
    assert sin.tools == [2, 7]
    with pytest.raises(ParseError, match="a tool name in quotes") as e:
        _read('0 BEGIN PGM T MM\n1 TOOL CALL "MILL Z S100\n2 END PGM T MM\n', "p.h")
    assert (e.value.line, e.value.column) == (2, 13)


# arcs in the ZX and YZ planes ("Circle center CC": the plane is that of the two coordinates given)
PLANES = """0 BEGIN PGM P MM
1 TOOL CALL 1 Z S1000
2 L X+10 Y+0 Z+0 R0 FMAX
3 CC X+0 Z+0
4 C X+0 Z+10 DR+ F300
5 C X+10 Z+0 DR-
6 CR X+0 Z-10 R+10 DR-
7 CC Y+0 Z+0
8 L X+0 Y+10 Z+0
9 C Y+0 Z+10 DR+
10 C Y+10 Z+0 X+5 DR-
11 CC X+0 Y+0
12 C X+5 Y-10 DR-
13 END PGM P MM
"""

PLANES_NGC = """G21 G90 G17
T1 M6 G43 S1000
G0 X10 Y0 Z0
(CC)
G18 G3 X0 Z10 I-10 K0 F300
G18 G2 X10 Z0 I0 K-10
G18 G2 X0 Z-10 R10
(CC)
G1 X0 Y10 Z0
G19 G3 Y0 Z10 J-10 K0
G19 G2 X5 Y10 Z0 J0 K-10
(CC)
G17 G2 X5 Y-10 I-5 J-10
M2
"""


def test_arcs_in_the_zx_and_yz_planes_closed_form():
    """"Circle center CC" (§ 7.4): CC X.. Z.. is the centre in the ZX plane, CC Y.. Z.. in YZ, and the
    C/CR blocks after it arc in that plane (the third axis: a helix). DR+ turns positively about the
    plane's normal (counter-clockwise looking against +Y in ZX: Z towards X, as RS-274's G3 in G18),
    so DR+ from X+10 Z+0 about the origin to X+0 Z+10 is three quarters, through X+0 Z-10, and DR- back
    retraces it (through X-7.07 Z-7.07 halfway). Same moves as the program written by hand in RS-274."""
    a = _read(PLANES)
    b = read_text(PLANES_NGC, "t.ngc", ReaderOptions(dialect="linuxcnc"))
    ta, tb = a.toolpath, b.toolpath
    assert len(ta) == len(tb) and np.abs(ta.end - tb.end).max() < 1e-6
    assert np.array_equal(ta.kind, tb.kind) and np.array_equal(ta.plane, tb.plane)
    arcs = ta.kind >= ARC_CW
    assert np.abs(ta.center[arcs] - tb.center[arcs]).max() < 1e-6
    assert same_path(a, b, 1e-6) == []
    at = {int(ln): i for i, ln in enumerate(ta.line)}
    lengths = ta.lengths()
    assert lengths[at[5]] == pytest.approx(1.5 * math.pi * 10, rel=1e-9)
    third = ta.points(np.array([at[5]]), np.array([1 / 3]))[0]
    assert np.allclose(third, [0, 0, -10], atol=1e-6)  # DR+ in ZX: from +X through -Z
    half = ta.points(np.array([at[6]]), np.array([0.5]))[0]
    assert np.allclose(half, [-10 / math.sqrt(2), 0, -10 / math.sqrt(2)], atol=1e-6)
    assert lengths[at[7]] == pytest.approx(math.pi * 10 / 2, rel=1e-9)
    # CR in ZX: R+ the arc under 180°, DR- (X towards Z) from X+10 Z+0 to X+0 Z-10: about X+10 Z-10
    assert np.allclose(ta.center[at[7]], [10, 0, -10], atol=1e-6)
    # DR+ in YZ: Y towards Z, from Y+10 Z+0 about the origin to Y+0 Z+10 is the quarter through Y+7.07 Z+7.07
    half = ta.points(np.array([at[10]]), np.array([0.5]))[0]
    assert np.allclose(half, [0, 10 / math.sqrt(2), 10 / math.sqrt(2)], atol=1e-6)
    # the helix: a quarter clockwise in YZ, X rising from 0 to 5 along the way
    mid = ta.points(np.array([at[11]]), np.array([0.5]))[0]
    assert np.allclose(mid, [2.5, 10 / math.sqrt(2), 10 / math.sqrt(2)], atol=1e-6)
    assert tuple(ta.plane[[at[5], at[10], at[13]]]) == (1, 2, 0)


@pytest.mark.parametrize("block, word, column", [
    ("CT X+5 Z+5", "CT", 3),
    ("LP PR+5 PA+90", "LP", 3),
    ("CP PA+90 DR+", "CP", 3),
    ("C X+0 Z-10 DR+ RL", "C", 3),
    ("CC X+1 Y+2 Z+3", "CC", 3),
])
def test_other_plane_arcs_out_of_reach_are_refused(block, word, column):
    """Tangent (CT) and polar (LP, CP) arcs after a CC outside XY, and compensation on an arc outside
    the working plane, are refused where they are written."""
    text = f"0 BEGIN PGM T MM\n1 L X+10 Y+0 Z+0 R0 FMAX\n2 CC X+0 Z+0\n3 {block}\n4 END PGM T MM\n"
    with pytest.raises(ParseError) as e:
        _read(text, "part.h")
    assert (e.value.file, e.value.line, e.value.column) == ("part.h", 4, column)
    assert word in e.value.word


def test_dep_lt_continues_the_last_element_by_len():
    """"Approaching and departing a contour", DEP LT: from the last contour point PE a straight line of
    length LEN continuing the last contour element tangentially, to PN (after a line: along it; after
    an arc: along its end tangent). Same moves as the program written by hand in RS-274."""
    text = """0 BEGIN PGM D MM
1 L X+0 Y+0 Z-5 R0 FMAX
2 L X+30 Y+20 F100
3 DEP LT LEN+13 F200
4 L X+40 Y+0 FMAX
5 CC X+40 Y+10
6 C X+50 Y+10 DR+ F100
7 DEP LT LEN5
8 END PGM D MM
"""
    k = 13 / math.hypot(30, 20)
    ngc = f"""G21 G90 G17
G0 X0 Y0 Z-5
G1 X30 Y20 F100
G1 X{30 + 30 * k:.12f} Y{20 + 20 * k:.12f} F200
G0 X40 Y0
(CC)
G3 X50 Y10 I0 J10 F100
G1 X50 Y15
M2
"""
    a, b = _read(text), read_text(ngc, "t.ngc", ReaderOptions(dialect="linuxcnc"))
    assert np.abs(a.toolpath.end - b.toolpath.end).max() < 1e-6 and same_path(a, b, 1e-6) == []
    assert np.allclose(a.toolpath.feed_mm_min, b.toolpath.feed_mm_min, equal_nan=True)
    for block, message in (("L X+5 RL F100\n3 DEP LT LEN5", "radius compensation"),
                           ("DEP LT F100", "one LEN"), ("DEP LN LEN5", "approach and departure")):
        with pytest.raises(ParseError, match=message) as e:
            _read(f"0 BEGIN PGM D MM\n1 L X+0 Y+0 Z-5 R0 FMAX\n2 {block}\n9 END PGM D MM\n", "d.h")
        assert e.value.line in (3, 4) and e.value.column >= 1


def test_xy_contour_with_compensation_after_a_zx_arc():
    """In a program with arcs outside XY every arc names its plane: an XY arc that turns RL on, a ZX
    arc, then RR and an RND in XY read as G17/G18 arcs (compensation only in XY)."""
    text = """0 BEGIN PGM T MM
1 TOOL CALL 1 Z S1000
2 L X+0 Y+0 Z+0 R0 FMAX
3 CC X+10 Y+0
4 C X+20 Y+0 DR+ RL F100
5 L X+30 Y+0 R0
6 CC X+30 Z+5
7 C X+35 Z+5 DR-
8 L Z+0
9 L X+40 Y+0 RR
10 RND R2
11 L X+40 Y+10
12 END PGM T MM
"""
    tp = read_text(text, "t.h", ReaderOptions(dialect="heidenhain", tool_diameters_mm={1: 4.0})).toolpath
    assert tp.line.tolist() == [3, 5, 6, 8, 9, 10, 11, 12]
    assert tp.plane.tolist() == [0, 0, 0, 1, 1, 0, 0, 0] and tp.kind[3] == ARC_CW  # L Z+0 after it: still G18
