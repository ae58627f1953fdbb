"""The reader on hand-written programs: arcs against closed forms in every plane and style, modal
rules, units, offsets, and clear refusals; plus a fuzz test (hypothesis): no input gives a traceback."""

from __future__ import annotations

import math

import numpy as np
import pytest

import rs274_oracle
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from millpost.cli import main
from millpost.errors import ParseError
from millpost.gcode import FeedMode, ReaderOptions, read_text
from millpost.gcode.summary import summary


def moves(text: str, **kw):
    return read_text(text, "t.nc", ReaderOptions(**kw)).toolpath


@pytest.mark.parametrize("plane,axes", [("G17", (0, 1, 2)), ("G18", (2, 0, 1)), ("G19", (1, 2, 0))])
@pytest.mark.parametrize("g", ["G2", "G3"])
@pytest.mark.parametrize("style", ["ijk", "r", "r_neg"])
def test_half_and_three_quarter_arcs_each_plane(plane, axes, g, style):
    a, b, n = axes
    L = "XYZ"
    ijk = "IJK"
    r = 5.0
    # start at first-axis = +r (around the origin), end at second-axis = ±r: a quarter or three quarters
    start = {L[a]: r, L[b]: 0.0, L[n]: 0.0}
    ccw = g == "G3"
    end_b = r if (style != "r_neg") == ccw else -r
    end = {L[a]: 0.0, L[b]: end_b, L[n]: 2.0}
    if style == "ijk":
        centre = f"{ijk[a]}{-r} {ijk[b]}0"
    else:
        centre = f"R{r if style == 'r' else -r}"
    text = (f"G21 G90 {plane}\nG0 " + " ".join(f"{k}{v}" for k, v in start.items()) + "\n"
            f"{g} " + " ".join(f"{k}{v}" for k, v in end.items()) + f" {centre} F100\nM2\n")
    tp = moves(text)
    quarter = (style != "r_neg") == (end_b * (1 if ccw else -1) > 0) if style != "ijk" else True
    sweep = math.pi / 2 if (style != "r_neg") else 3 * math.pi / 2
    if style == "ijk":
        sweep = math.pi / 2 if (ccw == (end_b > 0)) else 3 * math.pi / 2
    assert quarter or style == "r_neg"
    assert tp.lengths()[1] == pytest.approx(math.hypot(r * sweep, 2.0), rel=1e-12)
    np.testing.assert_allclose(tp.center[1][[a, b]], [0, 0], atol=1e-12)


def test_full_circle_helix_inch_and_turns():
    tp = moves("G20 G90 G17\nG0 X1 Y0 Z0\nG3 X1 Y0 Z-0.1 I-1 J0 P3 F10\nM2\n")
    r, pitch = 25.4, 2.54
    assert tp.lengths()[1] == pytest.approx(math.hypot(3 * 2 * math.pi * r, pitch), rel=1e-12)
    np.testing.assert_allclose(tp.bbox(), [[-r, -r, -pitch], [r, r, 0]], atol=1e-9)
    assert tp.feed_mm_min[1] == pytest.approx(254.0)


def test_units_switch_mid_program_and_incremental():
    # LinuxCNC sets F10 before the block's G20 (rs274: SET_FEED_RATE(10) in mm, then inches): 10 mm/min
    tp = moves("G21 G90\nG0 X10 Y0 Z0\nG20 G91 G1 X1 F10\nG21 G90 G1 X0\nM2\n")
    np.testing.assert_allclose(tp.end[:, 0], [10, 35.4, 0])
    np.testing.assert_allclose(tp.feed_mm_min[1:], [10.0, 10.0])


def test_g92_g52_offsets_and_work_offsets():
    tp = moves("G21 G90\nG0 X10 Y10 Z5\nG92 X0 Y0\nG1 X5 F100\nG92.1\nG1 X0\nM2\n", work_offsets_mm={})
    np.testing.assert_allclose(tp.end[:, 0], [10, 5, 0])


def test_fusion_and_haas_z_retracts_go_to_safe_height_and_say_so():
    prog = read_text("G21 G90\nG0 X0 Y0 Z15\nG1 Z-2 F300\nG28 G91 Z0.\nG90\nG53 G0 Z0.\nM30\n", "f.nc")
    assert prog.toolpath.end[3:, 2].tolist() == [15.0, 15.0]  # after G28's intermediate point
    assert any("G28" in n and "assumed" in n for n in prog.notes)
    assert any("G53" in n and "assumed" in n for n in prog.notes)


def test_inverse_time_and_per_rev_feeds():
    tp = moves("G21 G90\nG0 X0 Y0 Z0\nG93 G1 X10 F6\nG94 S1000 M3\nG95 G1 X20 F0.1\nM2\n")
    assert tp.feed_mm_min[1] == pytest.approx(60.0)  # 10 mm in 1/6 min
    assert tp.feed_mm_min[2] == pytest.approx(100.0)  # 0.1 mm/rev at 1000 rpm


def test_feed_mode_per_move():
    program = read_text("G21 G90\nG0 X0 Y0 Z0\nG93 G1 X10 F6\nG94 S1000 M3\nG95 G1 X20 F0.1\nM2\n", "t.nc")
    assert program.feed_mode.tolist() == [FeedMode.PER_MINUTE, FeedMode.INVERSE_TIME, FeedMode.PER_REV]
    assert [int(m) for m in FeedMode] == [930, 940, 950]  # G93, G94, G95 as the interpreter's G codes (× 10)


@pytest.mark.parametrize("text,line,word,what", [
    ("G21\nG1 X10 F100 G41 D1\n", 2, "D1", "diameter of tool 1"),
    ("G21\nG0 A90\n", 2, "A90", "A axis motion"),
    ("G21\nG68.2 X0 Y0 Z0 I0 J45 K0\n", 2, "G68.2", "tilted work plane"),
    ("G21\nG43.4 H1\n", 2, "G43.4", "tool centre point"),
    ("G21\nG1 X10\n", 2, "", "no feed rate"),
    ("G21 G1 X1 F10\nG2 X5 Y5 I1 J0\n", 2, "I1", "radius to end of arc"),
    ("G21\nG0 G1 X1\n", 2, "G1", "two G codes"),
    ("G21\nG1 X1 X2 F1\n", 2, "X2", "appears twice"),
    ("G21\nG1 X1 F10 $\n", 2, "$", "unexpected character"),
])
def test_refusals_name_line_word_and_expectation(text, line, word, what):
    with pytest.raises(ParseError) as info:
        read_text(text, "job.nc")
    err = info.value
    assert err.file == "job.nc" and err.line == line and what in str(err) and err.expected
    if word:
        assert err.word.upper() == word.upper()


def test_cli_exit_code_and_message(tmp_path, capsys):
    bad = tmp_path / "bad.nc"
    bad.write_text("G21\nG1 X1 F10 G42 D3\n")
    assert main(["inspect", str(bad)]) == 2
    assert f"{bad}:2:" in capsys.readouterr().err


def test_inspect_summary_numbers():
    prog = read_text("G21 G90 G17\nT3 M6\nS8000 M3\nG0 X0 Y0 Z5\nG1 Z0 F100\nG2 X10 Y0 I5 J0 F200\nG0 Z5\nM30\n")
    s = summary(prog)
    assert s["moves"] == {"rapid": 2, "feed": 1, "arc": 1}
    assert s["feed_length_mm"] == pytest.approx(5 + 5 * math.pi)
    np.testing.assert_allclose(s["bbox_mm"], [[0, 0, 0], [10, 5, 5]], atol=1e-12)
    assert s["tools"] == [3] and s["spindle_rpm"] == [8000.0]
    assert s["time_at_programmed_feed_s"] == pytest.approx(5 / 100 * 60 + 5 * math.pi / 200 * 60)


_word = st.one_of(
    st.tuples(st.sampled_from("GMXYZIJKRFSPQTLN"), st.floats(-1e4, 1e4, allow_nan=False)).map(
        lambda t: f"{t[0]}{t[1]:.4g}"),
    st.sampled_from(["(c)", ";x", "%", "/", "*12", "#1=2", "[1+2]", "#<a>", "o100 sub", "G91.1", "G90.1",
                     "G83", "G81", "G80", "G17", "G18", "G19", "G20", "G21", "G92", "G28", "G53", "A0", "@1", "^30"]),
    st.text(max_size=4))


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.lists(_word, max_size=6).map(" ".join), max_size=8))
def test_fuzz_never_crashes(lines):
    try:
        read_text("\n".join(lines), "fuzz.nc")
    except ParseError as err:
        assert err.line >= 1


def test_fanuc_fine_boring_back_boring_and_g80_return_to_g0():
    text = ("%\nO0001\nG21 G90 G17\nG0 X0 Y0 Z10\nG98 G76 X5 Y5 Z-10 R2 Q0.5 P500 F100\nG80\nZ15.\n"
            "G0 X20 Y0 Z10\nG87 X20 Y0 Z-4 R-12 Q0.5 F80\nG80\nM30\n%\n")
    prog = read_text(text, "f.nc", ReaderOptions(dialect="fanuc"))
    tp = prog.toolpath
    ends = tp.end.tolist()
    # G76: to the hole at the initial level, down to R, feed to Z, shift +X by Q, rapid out, shift back
    assert ends[1:7] == [[5, 5, 10], [5, 5, 2], [5, 5, -10], [5.5, 5, -10], [5.5, 5, 10], [5, 5, 10]]
    assert tp.kind[3] == 1 and prog.dwell_s == pytest.approx(0.5)  # Fanuc P in milliseconds
    assert ends[7] == [5, 5, 15] and tp.kind[7] == 0  # after G80, Fanuc returns to G0
    # G87: shift, rapid below the part to R, shift back, feed up to Z, shift, rapid up, shift back
    assert ends[9:16] == [[20, 0, 10], [20.5, 0, 10], [20.5, 0, -12], [20, 0, -12], [20, 0, -4], [20.5, 0, -4],
                          [20.5, 0, 10]]
    assert ends[16] == [20, 0, 10]


def test_fanuc_peck_tapping_reverses_out_to_r_after_each_peck():
    """Fanuc G84 with Q (Fusion's peck tapping): the tap feeds Q deeper each peck and reverses out to R
    at the same synchronised feed, then the last peck to Z and out to the clear level. R2 Z-10 Q4: pecks to
    -2 and -6, then -10 and out to the clear level Z10: 2·(4 + 8) + 12 + 20 = 56 mm fed, all at F625."""
    text = "%\nO0001\nG21 G90 G17\nG0 X0 Y0 Z10\nS500 M3\nG98 G84 X0 Y0 Z-10 R2 Q4 F625\nG80\nM30\n%\n"
    prog = read_text(text, "t.nc", ReaderOptions(dialect="fanuc"))
    tp = prog.toolpath
    tap = prog.cycle == 840
    assert tp.end[tap, 2].tolist() == [10, 2, -2, 2, -6, 2, -10, 10]
    fed = tap & (tp.kind == 1)
    lengths = np.linalg.norm(tp.end[fed] - tp.start[fed], axis=1)
    assert lengths.sum() == pytest.approx(56)
    assert np.all(tp.feed_mm_min[fed] == 625)
    assert any("peck tapping" in n and "line 6" in n for n in prog.notes)


def test_dialect_facts_live_in_the_dialect():
    """The reader asks the Dialect, not its name: a dwell P in Fanuc counts milliseconds (G4 only
    without a decimal point, a canned cycle's always); G4 P1500 and G4 P1.5 wait 1.5 s on Fanuc,
    1500 s and 1.5 s on LinuxCNC. A G80 keeps G0 in Fanuc, leaves no motion in LinuxCNC."""
    from millpost.gcode import dialects
    fanuc, lcnc = dialects.get("fanuc"), dialects.get("linuxcnc")
    assert fanuc.dwell_s(1500, decimal_point=False) == 1.5 and fanuc.dwell_s(1.5) == 1.5
    assert fanuc.dwell_s(500, cycle=True) == 0.5 and lcnc.dwell_s(500, cycle=True) == 500
    for name, wait in (("fanuc", 3.0), ("linuxcnc", 1501.5)):
        prog = read_text("G21 G90\nG4 P1500\nG4 P1.5\nM2\n", "d.nc", ReaderOptions(dialect=name))
        assert prog.dwell_s == pytest.approx(wait)
    text = "G21 G90\nG0 X0 Y0 Z5\nG80\nX1\nM2\n"
    assert read_text(text, "d.nc", ReaderOptions(dialect="fanuc")).toolpath.end[-1].tolist() == [1, 0, 5]
    with pytest.raises(ParseError, match="no motion mode"):
        read_text(text, "d.nc", ReaderOptions(dialect="linuxcnc"))


def test_detection_weighs_distinct_markers():
    """Fusion's Fanuc post writes %, O1001, G28 G91 and G43 Z H (Fanuc) and G00 on every rapid (also a
    Mach3 marker): the distinct Fanuc markers win. LinuxCNC's own o-word sample programs with an
    O-number-looking line stay LinuxCNC."""
    from millpost.gcode import dialects
    fusion = ("%\nO1001\nG90 G94 G17 G49 G40 G80\nG21\nG28 G91 Z0.\nG90\n(2D-FACE)\nT1 M06\nS5000 M03\n"
              "G54\nG00 X80. Y-24.375\nG43 Z15. H01\n" + "G00 Z5.\nG01 Z-1. F500.\nG00 Z15.\n" * 10 + "M30\n%\n")
    assert dialects.detect(fusion).name == "fanuc"
    mach3 = "G00 G49 G40  G17 G80 G90 G21\nM04 S12000\n" + "G00 Z6\nG00 X0 Y0\nG01 Z-0.4\n" * 10 + "M30\n%\n"
    assert dialects.detect(mach3).name == "mach3"
    lcnc = "O0100\no100 sub\nG1 X1 F100\no100 endsub\no100 call\no100 call\nM2\n"
    assert dialects.detect(lcnc).name == "linuxcnc"


def test_f_on_a_units_change_line_is_in_the_units_before_it_on_linuxcnc(tmp_path):
    """LinuxCNC sets the feed rate before the block's length units (its order of execution: rs274 prints
    SET_FEED_RATE(6) before USE_LENGTH_UNITS(INCHES), and the canon keeps 6 mm/min): CAMotics' vcarve
    starts `G20 F6` and runs at 6 mm/min on LinuxCNC, not 6 in/min (its harness run took 25 times the
    model's time). grbl converts F with the block's units. Either way a warning says which was read."""
    text = "G20 F6\nG0 X0 Y0 Z0\nG1 X1\nM2\n"
    lcnc = read_text(text, "u.ngc", ReaderOptions(dialect="linuxcnc"))
    assert lcnc.toolpath.feed_mm_min[-1] == pytest.approx(6.0)
    assert any("F6 shares its line with the change to inch" in n for n in lcnc.notes)
    grbl = read_text(text, "u.nc", ReaderOptions(dialect="grbl"))
    assert grbl.toolpath.feed_mm_min[-1] == pytest.approx(6 * 25.4)
    if rs274_oracle.RS274:
        (tmp_path / "u.ngc").write_text(text)
        trace = rs274_oracle.run(tmp_path / "u.ngc")
        assert trace.moves[-1][2] == pytest.approx(6.0)  # mm/min
        assert rs274_oracle.mismatches(lcnc, trace) == []
