"""Reading Siemens SINUMERIK 840D sl / 828D programs (millpost.gcode.sinumerik).

Semantics from the SINUMERIK 840D sl / 828D programming manuals: "Fundamentals" (FB) and "Job
planning" (AV), cited per test. Each program is compared with the same motion written by hand in
RS-274 (read to the same moves within 1e-6 mm), or with closed-form arc centres and end points.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np
import pytest

from millpost.emit.write import FeedPlan, write_feeds
from millpost.errors import ParseError
from millpost.gcode import ReaderOptions, dialects, read_program, read_text
from millpost.gcode.convert import same_path
from millpost.gcode.lexer import source_lines
from millpost.toolpath import ARC_CCW, ARC_CW, FEED, RAPID


def sin(text: str):
    return read_text(text, "part.mpf", ReaderOptions(dialect="sinumerik"))


def ngc(text: str):
    return read_text(text, "part.ngc", ReaderOptions(dialect="linuxcnc"))


def assert_same_moves(a, b, tol: float = 1e-6) -> None:
    ta, tb = a.toolpath, b.toolpath
    assert len(ta) == len(tb)
    assert ta.kind.tolist() == tb.kind.tolist()
    assert np.allclose(ta.start, tb.start, atol=tol) and np.allclose(ta.end, tb.end, atol=tol)
    assert np.allclose(ta.center, tb.center, atol=tol, equal_nan=True)
    assert np.allclose(ta.feed_mm_min, tb.feed_mm_min, rtol=1e-9, equal_nan=True)


FUSION_STYLE = """%_N_PART_MPF
;$PATH=/_N_MPF_DIR
; T1  D=10 CR=0 - ZMIN=-3 - flat end mill
N10 G90 G94 G40 G17 G710
N20 T="FLAT10" D1
N30 M6
N40 S6000 M3 M8
N50 G54
N60 CYCLE832(0.01,_SEMIFIN,1)
N70 G0 X-10 Y0 Z15
N80 G0 Z2
N90 G1 Z-3 F300.
N100 G1 X50 F1200. ; first pass
N110 G2 X60 Y10 I0 J10
N120 G3 X50 Y20 CR=10
N130 G1 X0
N140 G0 Z15
N150 M9
N160 M5
N170 M30
"""
FUSION_NGC = """(part)
G90 G94 G40 G17 G21
T1
M6 G43
S6000 M3 M8
G54
G64 P0.01
G0 X-10 Y0 Z15
G0 Z2
G1 Z-3 F300.
G1 X50 F1200.
G2 X60 Y10 I0 J10
G3 X50 Y20 R10
G1 X0
G0 Z15
M9
M5
M30
"""


def test_a_cam_posted_program_reads_as_its_rs274_equivalent():
    """FB "Fundamentals of NC programming": ';' comments, N block numbers; G710 metric with feeds in
    mm/min; T="name" with D1 and M6 (FB "Tool change"); CYCLE832 (high speed settings) is a tolerance."""
    a = sin(FUSION_STYLE)
    b = ngc(FUSION_NGC)
    assert a.dialect == "sinumerik" and a.source == FUSION_STYLE
    assert_same_moves(a, b)
    assert a.toolpath.line.tolist() == list(range(10, 18))
    assert a.tools == [1] and a.spindle_rpm == [6000.0]


def test_detected_from_the_text():
    """G710, N numbers with ';' comments, T="..", CYCLE832 mark a Sinumerik program; plain RS-274 is not one."""
    assert dialects.detect(FUSION_STYLE).name == "sinumerik"
    assert read_text(FUSION_STYLE, "part.mpf").dialect == "sinumerik"
    assert dialects.detect(FUSION_NGC).name != "sinumerik"
    assert dialects.detect("N10 G0 X0 Y0 (start)\nN20 G1 X10 F100\nN30 M30\n").name != "sinumerik"


def test_cr_sign_picks_the_arc_over_180_degrees():
    """FB "Circular interpolation with radius and end point (CR)": CR=+r the arc of at most 180°,
    CR=-r the one over 180°. From (0,0) to (10,0) with r=10, G2: centres (5, ∓√75)."""
    for r, cy in ((10, -math.sqrt(75)), (-10, math.sqrt(75))):
        p = sin(f"N10 G17 G90 G0 X0 Y0 Z0\nN20 G2 X10 Y0 CR={r} F100\nN30 M30\n")
        arc = p.toolpath
        assert arc.kind[1] == ARC_CW
        assert np.allclose(arc.center[1, :2], [5.0, cy], atol=1e-9)
        sweep = arc.lengths()[1] / 10.0
        assert math.isclose(sweep, 2 * math.asin(0.5) if r > 0 else 2 * math.pi - 2 * math.asin(0.5), rel_tol=1e-9)


def test_ijk_incremental_by_default_and_ac_absolute():
    """FB "Circular interpolation with center and end point": I, J, K are incremental from the start
    point by default; I=AC(..) gives the centre in absolute coordinates."""
    a = sin("N10 G90 G0 X10 Y0\nN20 G3 X-10 Y0 I=AC(0) J=AC(0) F500\nN30 G3 X10 Y0 I10 J0\n")
    b = ngc("G90 G0 X10 Y0\nG3 X-10 Y0 I-10 J0 F500\nG3 X10 Y0 I10 J0\n")
    assert_same_moves(a, b)
    assert np.allclose(a.toolpath.center[1:, :2], 0.0)


def test_ac_in_g91_and_ic_in_g90_are_per_word():
    """FB "Absolute dimensions (G90, AC)" / "Incremental dimensions (G91, IC)": X=AC(..) is absolute
    in a G91 block, X=IC(..) incremental in a G90 block; only that word."""
    a = sin("N10 G90 G0 X1 Y2 Z3\nN20 G1 X=IC(4) Y10 F100\nN30 G91 X=AC(0) Y-1\nN40 X2 Z=AC(-1)\n")
    b = ngc("G90 G0 X1 Y2 Z3\nG1 X5 Y10 F100\nX0 Y9\nX2 Z-1\n")
    assert_same_moves(a, b)


def test_g4_f_is_seconds_and_g4_s_spindle_revolutions():
    """FB "Dwell time (G4)": G4 F<s> waits seconds; G4 S<n> waits n revolutions of the spindle
    (at S1200: 30 revolutions = 1.5 s). The dwell's F does not change the feed."""
    p = sin("N10 G0 X0 Y0\nN20 S1200 M3\nN30 G1 X10 F100\nN40 G4 F2.5\nN50 G4 S30\nN60 X20\n")
    dwells = [e.value for e in p.events if e.kind == "dwell"]
    assert dwells == pytest.approx([2.5, 1.5])
    assert p.toolpath.feed_mm_min[-1] == pytest.approx(100.0)


def test_g700_takes_inches_and_inch_per_minute():
    """FB "Inch or metric dimensions (G70/G700, G71/G710)": G700 geometry and feed in inches."""
    p = sin("N10 G700 G90 G0 X0 Y0\nN20 G1 X1 F10\n")
    assert np.allclose(p.toolpath.end[-1], [25.4, 0, 0])
    assert p.toolpath.feed_mm_min[-1] == pytest.approx(254.0)


def test_g70_takes_feeds_in_the_programmed_unit_with_a_note():
    """FB "Inch or metric dimensions": G70 sets the geometry only; the feed's unit is the basic
    system's, taken to be the programmed one (a note says so)."""
    p = sin("N10 G70 G90 G0 X0 Y0\nN20 G1 X1 F10\n")
    assert np.allclose(p.toolpath.end[-1], [25.4, 0, 0]) and p.toolpath.feed_mm_min[-1] == pytest.approx(254.0)
    assert any(e.kind == "comment" and "basic system" in str(e.value) for e in p.events)


def test_r_parameters_and_arithmetic_run_in_block_order():
    """FB "Arithmetic parameters (R)" / "Value assignments": R1=5 R2=R1*2 in one block gives R2 = 10;
    X=R2+5 is computed; functions SIN, SQRT, POT, TRUNC."""
    p = sin("N10 R1=5 R2=R1*2\nN20 G0 X=R2+5 Y=SQRT(POT(3)+16) Z=TRUNC(-2.7)\nN30 X=R1*SIN(30)\n")
    assert np.allclose(p.toolpath.end, [[15, 5, -2], [2.5, 5, -2]])


def test_def_variables_and_if_else():
    """AV "Definition of user variables (DEF)", "Program jumps: IF-ELSE-ENDIF"."""
    p = sin("N10 DEF REAL DEPTH=-2, STEP\nN20 STEP=0.5\nN30 IF DEPTH<-1\nN40 G0 X1\nN50 ELSE\nN60 G0 X2\n"
            "N70 ENDIF\nN80 G0 Z=DEPTH+STEP\n")
    assert np.allclose(p.toolpath.end, [[1, 0, 0], [1, 0, -1.5]])


def test_while_loop_and_repeat_until():
    """AV "Program loop with condition at start of loop (WHILE)" and "... at end of loop (REPEAT)"."""
    p = sin("N10 R1=0\nN20 WHILE R1<3\nN30 G1 X=R1 F100\nN40 R1=R1+1\nN50 ENDWHILE\n"
            "N60 REPEAT\nN70 G1 Y=R1 F100\nN80 R1=R1-1\nN90 UNTIL R1<=1\n")
    assert np.allclose(p.toolpath.end[:, :2], [[0, 0], [1, 0], [2, 0], [2, 3], [2, 2]])


def test_a_loop_without_end_is_refused_at_its_lines():
    """AV "Endless program loop (LOOP)": LOOP ... ENDLOOP runs until a jump leaves it; a jump out of a
    loop cannot be laid out as structure, so the loop is read as written and stops at the reader's cap
    on repeated lines, naming a line of the loop."""
    with pytest.raises(ParseError) as e:
        sin("N10 G0 X0 Y0 Z5\nN20 LOOP\nN30 G91 G1 X1 F1000\nN40 ENDLOOP\n")
    assert e.value.line in (2, 3, 4) and "loop" in str(e.value).lower()


def test_msg_and_notes_are_events():
    """FB "Messages (MSG)": a message, no motion."""
    p = sin('N10 MSG("roughing (pass 1)")\nN20 G0 X1\n')
    assert any(e.kind == "comment" and "roughing" in str(e.value) for e in p.events)


@pytest.mark.parametrize("line, column, word", [
    ("N20 TRAORI", 5, "TRAORI"),
    ("N20 CYCLE800(1,\"TC1\",0,57,0,0,0,0,0,0,0,0,0,-1)", 5, "CYCLE800"),
    ("N20 POCKET3(10,0,1,-5)", 5, "POCKET3"),
    ("N20 SPOS=90", 5, "SPOS=90"),
    ("N20 G33 Z-10 K1.5", 5, "G33"),
    ("N20 G1 X10 FOO", 12, "FOO"),
    ("N20 G1 X=$AA_IW[X]", 10, "$AA_IW"),
    ("N20 WHILE R1<3", 5, "WHILE"),
    ("N20 REPEAT LBL1 P=2", 12, "LBL1"),
    ("N20 X1 L100", 8, "L100"),
])
def test_refused_with_file_line_and_column(line, column, word):
    """Out of reach (5-axis, swivel, pocket cycles, spindle positioning, thread cutting, unknown
    commands, system variables, an unclosed loop) is refused where it is written."""
    with pytest.raises(ParseError) as e:
        sin(f"N10 G0 X0\n{line}\nN30 M30\n")
    assert (e.value.file, e.value.line, e.value.column) == ("part.mpf", 2, column)
    assert e.value.word.startswith(word)


def test_modal_drilling_cycles_run_at_each_position_that_follows():
    """Cycles manual, "CYCLE81 - Drilling, centering", "CYCLE82 - Drilling, counterboring", and FB
    "Modal subprogram call (MCALL)": RTP, RFP, SDIS, DP or DPR (DPR from RFP); rapid to RFP+SDIS, feed to
    the depth, (DTB seconds of dwell,) rapid back to RTP; MCALL alone ends the modal call. The same holes
    written as G98 G81/G82 from Z = RTP."""
    a = sin("N10 G90 G17 G710\nN20 G0 X0 Y0 Z10\nN30 F120.\nN40 MCALL CYCLE81(10, 0, 2, -6, )\nN50 X5 Y5\n"
            "N60 X15\nN70 MCALL\nN80 G0 X30 Y0\nN90 CYCLE82(10, 0, 2, , 4, 0.5)\nN100 X40\nN110 M30\n")
    b = ngc("G90 G17 G21\nG0 X0 Y0 Z10\nF120.\n(mcall)\nG98 G81 X5 Y5 R2 Z-6\nX15\nG80\nG0 X30 Y0\n"
            "G98 G82 R2 Z-4 P0.5\nG0 X40\nM30\n")
    assert_same_moves(a, b)
    assert a.toolpath.line.tolist() == b.toolpath.line.tolist()
    assert [e.value for e in a.events if e.kind == "dwell"] == pytest.approx([0.5])


def test_deep_hole_cycle_is_g83_or_g73_and_what_g83_cannot_make_is_refused():
    """Cycles manual, "CYCLE83 - Deep-hole drilling": VARI=1 chip removal (G83), VARI=0 chip breaking
    (G73), infeed FDPR or RFP - FDEP (as Fusion 360's 840D post writes it); a degression DAM, or a dwell
    at the depth (_DTD), is refused (G83 pecks are equal and do not dwell)."""
    a = sin("N10 G0 X0 Y0 Z10\nN20 F100\nN30 CYCLE83(10, 0, 2, -12, , , 3, 0, , 0, 1, 1)\n")
    b = ngc("G0 X0 Y0 Z10\nF100\nG98 G83 R2 Z-12 Q3\n")
    assert_same_moves(a, b)
    fusion = sin("N10 G0 X0 Y0 Z10\nN20 F100\nN30 MCALL CYCLE83(10, 0, 2, -12, , -3, , 0, , , 1, 1, , 3, 0, 0, 0)\n"
                 "N40 X0 Y0\nN50 MCALL\n")
    assert_same_moves(fusion, ngc("G0 X0 Y0 Z10\nF100\n(mcall)\nG98 G83 X0 Y0 R2 Z-12 Q3\nG80\n"))
    with pytest.raises(ParseError, match="_DTD"):
        sin("N10 G0 X0 Y0 Z10\nN20 CYCLE83(10, 0, 2, -12, , -3, , 0, , , 1, 1, , 3, 0, 0.5, 0)\n")
    with pytest.raises(ParseError) as e:
        sin("N10 G0 X0 Y0 Z10\nN20 CYCLE83(10, 0, 2, -12, , , 3, 1, , 0, 1, 1)\n")
    assert (e.value.line, e.value.word) == (2, "1") and "DAM" in str(e.value)


def test_tapping_and_boring_cycles_are_g84_g85_g89_g86():
    """Cycles manual, "CYCLE84 - Tapping without compensating chuck": the feed is |PIT| (or MPIT's ISO
    coarse pitch, negative: left-hand, G74) times SST (else the S in force), and the programmed F is in
    force again after the cycle; "CYCLE85 - Boring 1": feed in at FFR, (DTB dwell: G89,) feed out at
    RFF = FFR, modal with MCALL; "CYCLE86 - Boring 2": feed in, dwell, spindle stop, rapid out (G86)."""
    a = sin("N10 G0 X0 Y0 Z10 S500 M3\nN20 F200\nN30 CYCLE84(10, 0, 2, -10, , , 3, , 1.5, , 400)\nN40 G1 X10\n"
            "N50 MCALL CYCLE85(10, 0, 2, -8, , 0.5, 150, 150)\nN60 X20\nN70 X30\nN80 MCALL\nN90 G1 X0\n"
            "N100 CYCLE86(10, 0, 2, -5, , 1, 3, 0, 0, 0, 90)\nN110 CYCLE84(10, 0, 2, -6, , , , -8)\nN120 G1 X5\n"
            "N130 CYCLE85(10, 0, 2, , 4, , 100)\n")
    b = ngc("G0 X0 Y0 Z10 S500 M3\nF200\nG98 G84 R2 Z-10 F600\nG1 X10 F200\n(mcall)\nX20 G98 G89 R2 Z-8 P0.5 F150\n"
            "X30\nG80 F200\nG1 X0\nG98 G86 R2 Z-5 P1\nG98 G74 R2 Z-6 F625\nG1 X5 F200\nG98 G85 R2 Z-4 F100\n")
    assert_same_moves(a, b)


@pytest.mark.parametrize("call, word", [
    ("CYCLE84(10, 0, 2, -10, , , 3, , 1.5, , 400, 200)", "200"),
    ("CYCLE84(10, 0, 2, -10, , , 3, 7)", "7"),
    ("CYCLE84(10, 0, 2, -10, , , 3, , 1.5, , 400, , , , , 1)", "1"),
    ("CYCLE84(10, 0, 2, -10)", "CYCLE84"),
    ("CYCLE85(10, 0, 2, -10, , , 100, 300)", "300"),
    ("CYCLE86(10, 0, 2, -10, , , 3, 1, 0, 0, 90)", "1"),
    ("CYCLE86(10, 0, 2, -10, , , 4)", "4"),
])
def test_what_g84_g85_g86_cannot_make_is_refused(call, word):
    """A retract speed SST1 other than SST, a thread size without its ISO pitch, pecking tapping
    (_VARI), no pitch; a feed out RFF other than FFR; a lift-off (RPA/RPO/RPAP) or a counter-clockwise
    restart (SDIR=4) after boring: refused at the parameter."""
    with pytest.raises(ParseError) as e:
        sin(f"N10 G0 X0 Y0 Z10 S500 M3 F100\nN20 {call}\n")
    assert e.value.line == 2 and e.value.word == word


def test_hole_patterns_run_the_modal_cycle_at_each_hole():
    """Cycles manual, "HOLES1 - Row of holes" (reference point, angle, distance of the first hole,
    spacing, number) and "HOLES2 - Circle of holes" (centre, radius, start angle, indexing angle 0: a
    full circle, number) under MCALL: the modal cycle at each hole in order, through the frame."""
    a = sin("N10 G0 X0 Y0 Z10 F100\nN20 MCALL CYCLE81(10, 0, 2, -5)\nN30 HOLES1(10, 20, 90, 5, 10, 3)\n"
            "N40 HOLES2(0, 0, 10, 0, 0, 4)\nN50 TRANS X100\nN60 HOLES1(0, 0, 0, 0, 5, 2)\nN70 MCALL\nN80 G1 X0 Y0\n")
    b = ngc("G0 X0 Y0 Z10 F100\nG98 G81 X10 Y25 R2 Z-5\nX10 Y35\nX10 Y45\nX10 Y0\nX0 Y10\nX-10 Y0\nX0 Y-10\n"
            "X100 Y0\nX105 Y0\nG80\nG1 X100 Y0\n")
    assert_same_moves(a, b)
    with pytest.raises(ParseError) as e:
        sin("N10 G0 X0 Y0 Z10\nN20 HOLES1(10, 20, 90, 5, 10, 3)\n")
    assert (e.value.line, e.value.column, e.value.word) == (2, 5, "HOLES1")
    with pytest.raises(ParseError) as e:
        sin("N10 G0 X0 Y0 Z10\nN20 MCALL CYCLE81(10, 0, 2, -5)\nN30 CYCLE801(0, 0, 0, 5, 5, 2, 2)\n")
    assert (e.value.line, e.value.column) == (3, 5) and e.value.word.startswith("CYCLE801")


def test_jumps_forward_and_backward_to_labels():
    """AV "Program jumps to jump markers (GOTOB, GOTOF, GOTO)" and "Conditional program jumps (IF)":
    a backward jump repeats the blocks from its label, a forward jump skips to its label."""
    p = sin("N10 R1=0\nN20 G0 X0 Y0 Z5\nLOOP1:\nN40 G1 X=R1*10 F100\nN50 R1=R1+1\nN60 IF R1<3 GOTOB LOOP1\n"
            "N70 IF R1==3 GOTOF SKIP\nN80 G1 Y50\nSKIP: ; here\nN100 G1 Y10\nN110 GOTOF END1\nN120 G1 Y99\n"
            "END1:\nN140 M30\n")
    assert np.allclose(p.toolpath.end[1:, :2], [[0, 0], [10, 0], [20, 0], [20, 10]])
    assert p.toolpath.line.tolist()[1:] == [4, 4, 4, 10]


@pytest.mark.parametrize("text, line, column, word", [
    ("N10 GOTOF NOWHERE\nN20 M30\n", 1, 11, "NOWHERE"),
    ("N10 GOTOF LL1\nLL1: G0 X1\n", 2, 6, "G0 X1"),
    ("N10 G0 X1\nN20 G1 X2 F10 GOTOB N10\n", 2, 15, "GOTOB"),
])
def test_jumps_that_cannot_be_laid_out_are_refused(text, line, column, word):
    """A label that is not there, a label sharing its line with a block, a jump inside a block."""
    with pytest.raises(ParseError) as e:
        sin(text)
    assert (e.value.line, e.value.column) == (line, column) and e.value.word.startswith(word)


def test_opening_angle_from_end_point_or_centre():
    """FB "Circular interpolation with opening angle and center point (AR)": G3 X10 Y0 AR=90 from the
    origin has its centre on the chord's bisector at (5, 5) (left of the chord for G3, a < 180°);
    AR=270 puts it at (5, -5); G2 I5 J0 AR=90 from (10, 0) ends at the start turned 90° clockwise about
    (15, 0): (15, 5)."""
    p = sin("N10 G17 G90 G0 X0 Y0 Z0\nN20 G3 X10 Y0 AR=90 F100\nN30 G2 I5 J0 AR=90\nN40 G0 X0 Y0\n"
            "N50 G91 G3 X10 AR=270\n")
    tp = p.toolpath
    assert tp.kind.tolist() == [RAPID, ARC_CCW, ARC_CW, RAPID, ARC_CCW]
    assert np.allclose(tp.center[[1, 2, 4], :2], [[5, 5], [15, 0], [5, -5]], atol=1e-9)
    assert np.allclose(tp.end[[1, 2, 4], :2], [[10, 0], [15, 5], [10, 0]], atol=1e-9)
    assert tp.lengths()[4] == pytest.approx(1.5 * math.pi * math.sqrt(50), rel=1e-9)


def test_trans_and_atrans_move_the_frame_the_moves_are_read_in():
    """FB "Programmable zero offset (TRANS, ATRANS)": TRANS replaces the offset, ATRANS adds to it,
    TRANS alone clears it; the moves are in the workpiece frame, as the same moves written there."""
    a = sin("N10 G90 G0 X0 Y0 Z5\nN20 TRANS X100 Y50\nN30 G1 X0 Y0 F100\nN40 ATRANS X10 Z-1\nN50 X0 Y=AC(1)\n"
            "N60 G91 X1\nN70 G90 CYCLE81(5, 0, 1, -3)\nN80 TRANS\nN90 G0 X0 Y0\nN100 ROT\n")
    b = ngc("G90 G0 X0 Y0 Z5\n(trans)\nG1 X100 Y50 F100\n(atrans)\nX110 Y51\nG91 X1\nG90 G98 G81 R0 Z-4\n(trans)\n"
            "G0 X0 Y0\n(rot)\n")
    assert_same_moves(a, b)


def _turned(x: float, y: float, degrees: float = 30) -> tuple[float, float]:
    a = math.radians(degrees)
    return x * math.cos(a) - y * math.sin(a), x * math.sin(a) + y * math.cos(a)


def test_rot_turns_the_moves_about_the_frame_origin():
    """FB "Programmable rotation (ROT, AROT)": ROT RPL=30 in G17 turns the following moves by 30°
    counter-clockwise about Z; a square contour with an arc reads as the same contour written with
    the turned coordinates. Incremental moves and arc centres (I/J, I=AC) turn too, an arc keeps its
    direction, a move missing an axis word keeps that coordinate of the rotated frame."""
    a = sin("N10 G17 G90 G0 X0 Y0 Z5\nN20 ROT RPL=30\nN30 G1 X10 Y0 F100\nN40 Y10\nN50 X0\nN60 Y0\n"
            "N70 G2 X10 Y0 I5 J0\nN80 G91 G1 X5 Y5\nN90 X=AC(0)\nN100 G90 G3 X0 Y10 I=AC(0) J=AC(7.5)\n")
    moves = [(1, (10, 0)), (1, (10, 10)), (1, (0, 10)), (1, (0, 0)), (2, (10, 0), (5, 0)), (1, (15, 5)),
             (1, (0, 5)), (3, (0, 10), (0, 2.5))]
    text = "G17 G90 G0 X0 Y0 Z5\nF100\n"
    for g, end, *centre in moves:
        x, y = _turned(*end)
        text += f"G{g} X{x:.12f} Y{y:.12f}"
        if centre:
            i, j = _turned(*centre[0])
            text += f" I{i:.12f} J{j:.12f}"
        text += "\n"
    assert_same_moves(a, ngc(text))


def test_arot_is_composed_after_trans_and_rot_alone_clears():
    """FB "Programmable rotation (ROT, AROT)" and "Frame instructions": TRANS X20 Y10 then AROT RPL=90
    turns about the translated origin (X10 reads at (20, 20)); a second AROT adds its angle; ATRANS
    after it moves along the turned axes; ROT with an angle replaces the frame (the offset cleared);
    ROT alone clears the rotation; ROT Z.. is the same rotation about Z."""
    a = sin("N10 G0 X0 Y0 Z5\nN20 TRANS X20 Y10\nN30 AROT RPL=90\nN40 G1 X10 Y0 F100\nN50 AROT RPL=-45\n"
            "N60 ATRANS X1\nN70 X0 Y0\nN80 ROT Z90\nN90 X10 Y0\nN100 ROT\nN110 X10 Y0\n")
    h = math.sqrt(0.5)
    b = ngc(f"G0 X0 Y0 Z5\n(trans)\n(arot)\nG1 X20 Y20 F100\n(arot)\n(atrans)\nX{20 + h} Y{10 + h}\n(rot)\n"
            "X0 Y10\n(rot)\nX10 Y0\n")
    assert_same_moves(a, b)


def test_scale_multiplies_the_frame_coordinates_and_arc_radii():
    """FB "Programmable scale factor (SCALE, ASCALE)": SCALE X2 Y2 doubles the contour (end points,
    I/J, CR) about the frame origin; ASCALE multiplies the current scale; an ATRANS after it moves by
    the scaled offset; SCALE alone clears. Without arcs in the program the factors may differ."""
    a = sin("N10 G0 X0 Y0 Z5\nN20 SCALE X2 Y2\nN30 G1 X10 Y0 F100\nN40 G3 X10 Y10 I0 J5\nN50 G2 X0 Y10 CR=5\n"
            "N60 ATRANS X1\nN70 G1 X0 Y1\nN80 ASCALE X0.5 Y0.5\nN90 X0 Y1\nN100 SCALE\nN110 X3 Y3\n")
    b = ngc("G0 X0 Y0 Z5\nG1 X20 Y0 F100\nG3 X20 Y20 I0 J10\nG2 X0 Y20 R10\nG1 X2 Y2\nX2 Y1\nX3 Y3\n")
    assert_same_moves(a, b)
    c = sin("N10 G0 X0 Y0 Z5\nN20 SCALE X2\nN30 G1 X5 Y5 F100\nN40 TRANS X1 Y1\nN50 ASCALE Y3\nN60 X1 Y1\n")
    assert_same_moves(c, ngc("G0 X0 Y0 Z5\nG1 X10 Y5 F100\nX2 Y4\n"))


def test_mirror_flips_the_axis_and_swaps_the_arc_direction():
    """FB "Programmable mirroring (MIRROR, AMIRROR)": MIRROR X0 flips X (the value is ignored) and
    swaps G2/G3 (and G41/G42), also in arc blocks where the direction is modal; AMIRROR Y0 composed
    after it flips Y too (a half turn: the arcs turn their programmed way again); MIRROR alone clears."""
    a = sin("N10 G0 X0 Y0 Z5\nN20 MIRROR X0\nN30 G1 X10 Y0 F100\nN40 G2 X20 Y0 I5 J0\nN50 X30 I5\n"
            "N60 AMIRROR Y0\nN70 G3 X0 Y10 CR=20\nN80 MIRROR\nN90 G1 X5 Y5\n")
    b = ngc("G0 X0 Y0 Z5\nG1 X-10 Y0 F100\nG3 X-20 Y0 I-5 J0\nX-30 I-5\nG3 X0 Y-10 R20\nG1 X5 Y5\n")
    assert_same_moves(a, b)
    ngc_text = dialects.get("sinumerik").translate("N10 MIRROR Y0\nN20 G42 G1 X10 Y10 F100\n", "part.mpf")
    assert "G[42-[" in ngc_text


@pytest.mark.parametrize("text, line, column, word", [
    ("N10 SCALE X2 Y3\nN20 G2 X10 Y0 CR=5\n", 1, 5, "SCALE X2 Y3"),
    ("N10 SCALE Z2\n", 1, 11, "Z2"),
    ("N10 MIRROR Z0\n", 1, 12, "Z0"),
    ("N10 G0 X0\nN20 ROT X30\n", 2, 9, "X30"),
    ("N10 G18\nN20 ROT RPL=30\n", 2, 9, "RPL=30"),
    ("N10 ROT RPL=30\nN20 G0 X0 Y0\nN30 G3 X10 Y0 AR=90 F10\n", 3, 15, "AR=90"),
    ("N10 ROT RPL=30\nN20 G18 G2 X10 Z0 K5 F10\n", 2, 12, "X10"),
])
def test_frames_not_modelled_are_refused(text, line, column, word):
    """A scale different in X and Y in a program with arcs, Z scaling or mirroring, rotation about X or
    Y, a rotation in G18/G19, and arcs by AR/CIP/CT or outside G17 under a rotation are refused where
    they are written."""
    with pytest.raises(ParseError) as e:
        sin(text)
    assert (e.value.line, e.value.column) == (line, column) and e.value.word.startswith(word)


REAL = os.environ.get("MILLPOST_SINUMERIK_PROGRAMS")
REAL_FILES = sorted(p for p in Path(REAL).rglob("*") if p.suffix.lower() in (".mpf", ".spf", ".nc")) if REAL else []


@pytest.mark.skipif(not REAL_FILES, reason="set MILLPOST_SINUMERIK_PROGRAMS to a folder of real Sinumerik programs")
@pytest.mark.parametrize("path", REAL_FILES, ids=[p.name for p in REAL_FILES])
def test_real_programs_read_or_refused_and_written_back_with_only_f_changed(path):
    """A real program is read (or refused at file:line:column); read, its feeds scaled by 0.8 are
    written back changing only F words, and it reads back to the same path."""
    try:
        program = read_program(path, ReaderOptions(dialect="sinumerik"))
    except ParseError as err:
        assert err.file == str(path) and err.line >= 1 and err.column >= 1, str(err)
        return
    source = program.source
    assert len(source_lines(program.text)) >= len(source_lines(source))
    out = write_feeds(program, FeedPlan(program.toolpath.feed_mm_min * 0.8, {}))
    f_word = re.compile(r"\bF\s*=?\s*[-+]?[\w.]+")
    for a, b in zip(source_lines(source), source_lines(out)):
        assert f_word.sub("", a).split() == f_word.sub("", b).split(), (a, b)
    again = read_text(out, str(path), ReaderOptions(dialect="sinumerik"))
    assert same_path(program, again) == []


def test_circle_through_an_intermediate_point():
    """FB "Circular interpolation with intermediate and end points (CIP)": from (0,0) through (5,5) to
    (10,0) is the clockwise half circle about (5,0); CIP stays modal (through (15,-5) to (20,0):
    counterclockwise about (15,0)); in G91 the points are from the start; out of the plane refused."""
    p = sin("N10 G17 G90 G0 X0 Y0 Z0\nN20 CIP X10 Y0 I1=5 J1=5 F100\nN30 X20 Y0 I1=15 J1=-5\n"
            "N40 G91 CIP X10 Y0 I1=5 J1=5\nN50 G90 G1 X0\n")
    tp = p.toolpath
    assert tp.kind.tolist() == [RAPID, ARC_CW, ARC_CCW, ARC_CW, FEED]
    assert np.allclose(tp.center[1:4, :2], [[5, 0], [15, 0], [25, 0]], atol=1e-9)
    assert np.allclose(tp.lengths()[1:4], 5 * math.pi)
    with pytest.raises(ParseError) as e:
        sin("N10 G0 X0 Y0 Z0\nN20 CIP X10 Y0 Z-1 I1=5 J1=5 F100\n")
    assert (e.value.line, e.value.column, e.value.word) == (2, 16, "Z-1")


def test_a_plain_program_with_g710_is_sinumerik():
    """G710 (FB "Inch/metric dimensions") is read by no RS-274 dialect: one such word settles the
    dialect even in a program that otherwise looks plain (`;` comments, M30 as Fanuc posts end), as a
    dataset's slotting program opens with `G90 G94 G710`; an RS-274 comment naming it does not."""
    text = ("G90 G94 G710\n; slot, 10 mm end mill\nT1 D1\nM6\nS3000 M3\nG0 X-10 Y0 Z5\nG1 Z-3 F100\n"
            "G1 X100 F300\nG0 Z50\nM30\n")
    assert dialects.detect(text).name == "sinumerik"
    tp = read_text(text, "slot.mpf").toolpath
    assert tp.end[-2].tolist() == [100.0, 0.0, -3.0] and tp.feed_mm_min[-2] == 300.0
    assert dialects.detect("(post for G710 controls)\nG21 G90\nG1 X10 F100\nM30\n").name != "sinumerik"


def test_tangential_arc_after_a_line_and_after_an_arc():
    """FB "Circular interpolation with tangential transition (CT)": after the line along +X to (10,0),
    CT to (20,10) is the quarter circle about (10,10), counter-clockwise; CT (modal) on to (30,0), its start
    direction +Y, is the clockwise 270° arc about (30,10); after G2 CR=10 to (40,10) about (40,0) (end
    direction +X) CT to (50,0) turns clockwise about (40,0)."""
    a = sin("N10 G17 G90 G0 X0 Y0 Z0\nN20 G1 X10 F100\nN30 CT X20 Y10\nN40 X30 Y0\nN50 G2 X40 Y10 CR=10\n"
            "N60 CT X50 Y0\n")
    b = ngc("G17 G90 G0 X0 Y0 Z0\nG1 X10 F100\nG3 X20 Y10 I0 J10\nG2 X30 Y0 I10 J0\nG2 X40 Y10 R10\n"
            "G2 X50 Y0 I0 J-10\n")
    assert_same_moves(a, b)
    assert a.toolpath.kind.tolist()[2:] == [ARC_CCW, ARC_CW, ARC_CW, ARC_CW]


def test_tangential_arc_in_g18_and_g19_and_incremental():
    """FB "Circular interpolation with tangential transition (CT)": the tangent is the previous element's
    in the active plane (G18: Z/X, G19: Y/Z); in G91 the end point is from the start."""
    a = sin("N10 G18 G90 G0 X0 Y0 Z0\nN20 G1 Z10 F100\nN30 CT Z20 X10\nN40 G19 G1 Y0 Z30\nN50 G91 CT Y10 Z10\n")
    b = ngc("G18 G90 G0 X0 Y0 Z0\nG1 Z10 F100\nG3 Z20 X10 K0 I10\nG19 G1 Y0 Z30\nG91 G2 Y10 Z10 J10 K0\n")
    assert_same_moves(a, b)


def test_tangential_arc_in_a_loop_takes_the_tangent_of_each_run():
    """FB "CT" with AV "Program section repetitions" (WHILE): each run's CT is tangent to the line before
    it in that run (the tangent is computed as the program runs, not from the text)."""
    a = sin("N10 G17 G90 G0 X0 Y0 Z0\nN20 R1=0\nN30 WHILE R1<2\nN40 G91 G1 X=10+R1 F100\nN50 CT X10 Y10\n"
            "N60 G1 Y10\nN70 R1=R1+1\nN80 ENDWHILE\n")
    b = ngc("G17 G90 G0 X0 Y0 Z0\nG91 G1 X10 F100\nG3 X10 Y10 I0 J10\nG1 Y10\nX11\nG3 X10 Y10 I0 J10\nG1 Y10\n")
    assert_same_moves(a, b)


@pytest.mark.parametrize("text, line, column, word", [
    ("N10 CT X10 Y10 F100\n", 1, 5, "CT"),
    ("N10 G1 X0 Y0 F100\nN20 G1 X10\nN30 CT X20 Y10 I5\n", 3, 16, "I5"),
])
def test_tangential_arc_refusals(text, line, column, word):
    """FB "CT": the arc is set by the tangent and the end point alone; a CT needs a path element before it."""
    with pytest.raises(ParseError) as e:
        sin(text)
    assert (e.value.file, e.value.line, e.value.column) == ("part.mpf", line, column) and word in str(e.value)


def _files(folder: Path, **files: str) -> Path:
    for name, text in files.items():
        (folder / name.replace("__", ".")).write_text(text)
    return folder / "MAIN.MPF"


def read_sin(path: Path):
    return read_program(path, ReaderOptions(dialect="sinumerik"))


def test_subprogram_calls_by_name_with_runs_by_l_number_and_by_call(tmp_path):
    """FB "Subprogram technique" ("Subprogram call", "Program repetition P"): PART1 P2 runs PART1.SPF
    twice, L12 runs _N_L12_SPF, CALL "PART1" once more; M17 and RET return; a PROC header is read.
    The same moves as the RS-274 written out by hand."""
    main = _files(tmp_path, MAIN__MPF="N10 G17 G90 G0 X0 Y0 Z5\nN20 G1 Z-1 F200\nN30 PART1 P2\nN40 L12\n"
                  'N50 CALL "PART1"\nN60 G1 X0 Y0 F500\nN70 M30\n',
                  PART1__SPF="PROC PART1\nN10 G91 G1 X10 F300\nN20 Y10\nN30 G90\nN40 M17\n",
                  _N_L12_SPF="G1 X50 F400\nIF R1 == 0\nG1 Y0\nENDIF\nRET\n")
    a = read_sin(main)
    b = ngc("G17 G90 G0 X0 Y0 Z5\nG1 Z-1 F200\nG91 X10 F300\nY10\nX10\nY10\nG90 G1 X50 F400\nY0\n"
            "G91 X10 F300\nY10\nG90 G1 X0 Y0 F500\nM30\n")
    assert_same_moves(a, b)
    assert a.toolpath.line.tolist()[:3] == [1, 2, 10]  # a subprogram's moves: lines past the program's (7)


def test_a_subprogram_runs_in_the_callers_frame_and_its_tapping_feed_is_restored(tmp_path):
    """FB "Programmable rotation", Cycles manual "CYCLE84": a contour subprogram called under ROT runs
    turned; after a subprogram that ends with CYCLE84 the caller's next move is at the programmed F
    again (kept where the main program has CYCLE84/85 too: a subprogram with CYCLE84 called from a
    program without is refused)."""
    main = _files(tmp_path, MAIN__MPF="N10 G0 X0 Y0 Z5 S500 M3\nN20 ROT RPL=90\nN30 CONTOUR\nN40 ROT\n"
                  "N50 TAP\nN60 G1 X1 Y1\nN70 CYCLE84(10, 0, 2, -6, , , 3, , 1, , 400)\nN80 M30\n",
                  CONTOUR__SPF="N10 G1 X10 Y0 F300\nN20 Y5\nN30 M17\n",
                  TAP__SPF="N10 F250\nN20 CYCLE84(10, 0, 2, -6, , , 3, , 1, , 400)\nN30 M17\n")
    b = ngc("G0 X0 Y0 Z5 S500 M3\nG1 X0 Y10 F300\nX-5 Y10\nF250\nG98 G84 R2 Z-6 F400\nG1 X1 Y1 F250\nG98 G84 R2 Z-6 F400\n")
    assert_same_moves(read_sin(main), b)
    main.write_text("N10 G0 X0 Y0 Z5 S500 M3\nN20 F100\nN30 TAP\nN40 M30\n")
    with pytest.raises(ParseError, match="CYCLE84/85") as e:
        read_sin(main)
    assert (e.value.line, e.value.column) == (3, 5)


def test_subprograms_nest_and_lower_case_spf_is_found(tmp_path):
    """FB "Subprogram technique" ("Nesting depth"): a subprogram calls another; part2.spf in lower case."""
    main = _files(tmp_path, MAIN__MPF="G0 X0 Y0 Z0\nPART1\nM30\n", PART1__SPF="G1 X5 F100\nPART2 P3\nM17\n",
                  part2__spf="G91 G1 Y1 F100\nG90\nM17\n")
    assert_same_moves(read_sin(main), ngc("G0 X0 Y0 Z0\nG1 X5 F100\nG91 Y1\nY1\nY1\nG90\nM30\n"))


@pytest.mark.parametrize("files, where, word", [
    ({"MAIN__MPF": "G0 X0 Y0\nN20 PART9 P2\nM30\n"}, ("MAIN.MPF", 2, 5), "PART9"),
    ({"MAIN__MPF": "G0 X0\nPART1\nM30\n", "PART1__SPF": "PROC PART1(REAL DEPTH)\nM17\n"}, ("PART1.SPF", 1, 11), "("),
    ({"MAIN__MPF": "G0 X0\nPART1\nM30\n", "PART1__SPF": "G1 X1 F100\nPART1\nM17\n"}, ("PART1.SPF", 2, 1), "PART1"),
    ({"MAIN__MPF": "G0 X0\nPART1 P0\nM30\n", "PART1__SPF": "M17\n"}, ("MAIN.MPF", 2, 7), "P0"),
    ({"MAIN__MPF": "G1 X0 F100\nPART1\nM30\n", "PART1__SPF": "G0 Z1\nG1 X5\nM17\n"}, ("PART1.SPF", 2, 1), "G1"),
    ({"MAIN__MPF": "G0 X0\nPART1\nM30\n", "PART1__SPF": "G1 X5 F100 M17\n"}, ("PART1.SPF", 1, 12), "M17"),
    ({"MAIN__MPF": "G0 X0\nPART1\nM30\n", "PART1__SPF": "G1 X5 F100\nSPOS=0\nM17\n"}, ("PART1.SPF", 2, 1), "SPOS"),
    ({"MAIN__MPF": "G0 X0\nPART1\nG91\nN40 PART1\nM30\n", "PART1__SPF": "G0 X1\nM17\n"}, ("MAIN.MPF", 4, 5),
     "G90 G17"),
    ({"MAIN__MPF": "G0 X0\nPART1\nM30\n", "PART1__SPF": "PROC PART1 SAVE\nM17\n"}, ("PART1.SPF", 1, 12), "SAVE"),
])
def test_subprogram_refusals_name_the_file_line_and_column(tmp_path, files, where, word):
    """FB "Subprogram technique": a missing file is refused at the call naming the file looked for; an
    error in a subprogram names the subprogram's file and line; recursion, PROC parameters, P0, a
    subprogram's feed move before its own F (its feeds are not written back), M17 with other words."""
    with pytest.raises(ParseError) as e:
        read_sin(_files(tmp_path, **files))
    assert (Path(e.value.file).name, e.value.line, e.value.column) == where and word in str(e.value)
    if where[0] == "MAIN.MPF" and word == "PART9":
        assert "PART9.SPF" in str(e.value)


def test_an_error_the_interpreter_finds_in_a_subprogram_names_its_file_and_line(tmp_path):
    """A subprogram's lines run past the program's end: an interpreter error there names the .SPF line."""
    main = _files(tmp_path, MAIN__MPF="G0 X0 Y0 Z0\nPART1\nM30\n", PART1__SPF="G1 X5 F100\nG1 X=1/R1\nM17\n")
    with pytest.raises(ParseError) as e:
        read_sin(main)
    assert (Path(e.value.file).name, e.value.line) == ("PART1.SPF", 2)


def test_subprograms_after_the_end_are_not_noted_as_unexecuted(tmp_path):
    """The subprograms appended after M30 run when called: no "after program end" note names them."""
    main = _files(tmp_path, MAIN__MPF="G0 X0 Y0 Z0\nPART1\nM30\n", PART1__SPF="G1 X5 F100\nM17\n")
    assert not any("after program end" in n for n in read_sin(main).notes)
