"""Cutter radius compensation (G41/G42, G41.1/G42.1, G40): closed forms (a square's offset with arcs of
radius r about its convex corners, the intersection point of a concave corner, offset arcs of radius
R ± r about the same centre), LinuxCNC's refusals located at file:line:column, and LinuxCNC's own
interpreter `rs274` as the oracle on seeded random contours, its `bad/ccomp-*` cases and the Fusion
benchmark's in-control contours. The toolpath (and so the engagement) is the tool centre; emitting new
feeds keeps the compensation words and never splits a compensated move; convert refuses."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import rs274_oracle
from conftest import shared_data
from millpost import engagement, stock
from millpost.emit import FeedPlan, whole_moves, write_feeds
from millpost.errors import MillpostError, ParseError
from millpost.gcode import ReaderOptions, dialects, read_text
from millpost.gcode.convert import convert
from millpost.gcode.tool_table import read_tool_table
from millpost.emit import Fragment
from millpost.toolpath import ARC_CCW, ARC_CW, FEED, RAPID
from millpost.tools import Tool

needs_rs274 = pytest.mark.skipif(rs274_oracle.RS274 is None, reason="LinuxCNC's rs274 is not installed")
R = 1.5  # tool radius, mm (tool 1: 3 mm diameter)


def read(text: str, diameter_mm: float = 2 * R, name: str = "comp.ngc"):
    return read_text(text, name, ReaderOptions(dialect="linuxcnc", tool_diameters_mm={1: diameter_mm}))


def linuxcnc(diameter_mm: float) -> ReaderOptions:
    """LinuxCNC's frame (as rs274 assumes) with tool 1 of this diameter."""
    options = ReaderOptions.linuxcnc()
    options.tool_diameters_mm = {1: diameter_mm}
    return options


def moves(program):
    tp = program.toolpath
    return [(int(tp.kind[i]), tp.end[i].round(9).tolist(), np.nan_to_num(tp.center[i]).round(9).tolist())
            for i in range(len(tp))]


SQUARE = """G21 G90 G17 F600
T1 M6
G0 X0 Y-10
G41 G1 X0 Y0
Y20
X20
Y0
X0
Y10
G40 G1 X-10
M2
"""


def test_square_outside_gets_corner_arcs_of_tool_radius():
    """Clockwise round a 20 mm square with G41: sides offset outward by r, and at each convex corner an
    arc of radius r about the corner, clockwise, from one offset side to the next."""
    p = read(SQUARE)
    tp = p.toolpath
    cut = [i for i in range(len(tp)) if tp.kind[i] != RAPID]
    got = [(int(tp.kind[i]), tp.start[i][:2].tolist(), tp.end[i][:2].tolist()) for i in cut]
    r = R
    want = [
        (FEED, [0, -10], [-r, 0]),  # entry: ends at the end point offset along the entry's normal
        (FEED, [-r, 0], [-r, 20]),
        (ARC_CW, [-r, 20], [0, 20 + r]),
        (FEED, [0, 20 + r], [20, 20 + r]),
        (ARC_CW, [20, 20 + r], [20 + r, 20]),
        (FEED, [20 + r, 20], [20 + r, 0]),
        (ARC_CW, [20 + r, 0], [20, -r]),
        (FEED, [20, -r], [0, -r]),
        (ARC_CW, [0, -r], [-r, 0]),
        (FEED, [-r, 0], [-r, 10]),
        (FEED, [-r, 10], [-10, 10]),  # exit after G40: from the offset point to the programmed end
    ]
    assert [k for k, _, _ in got] == [k for k, _, _ in want]
    for (_, s, e), (_, ws, we) in zip(got, want):
        np.testing.assert_allclose(s, ws, atol=1e-12)
        np.testing.assert_allclose(e, we, atol=1e-12)
    arcs = [i for i in cut if tp.kind[i] == ARC_CW]
    corners = [[0, 20], [20, 20], [20, 0], [0, 0]]
    np.testing.assert_allclose(tp.center[arcs][:, :2], corners, atol=1e-12)
    np.testing.assert_allclose(np.hypot(*(tp.end[arcs] - tp.center[arcs])[:, :2].T), r, atol=1e-12)
    assert p.compensated[cut[:-1]].all() and p.compensated[cut[-1]]  # the exit move starts off the path
    assert tp.line[arcs].tolist() == [6, 7, 8, 9]  # a corner arc belongs to the move after the corner


@pytest.mark.parametrize("turn_deg", [30.0, 60.0, 90.0, 135.0])
def test_concave_corner_is_the_intersection_of_the_offset_lines(turn_deg):
    """Along +X then turning left by θ with G41 (tool inside the turn): the offset lines meet at
    C + r·n₁ − r·tan(θ/2)·t₁ (C the corner, t₁ the first direction, n₁ its left normal)."""
    t = math.radians(turn_deg)
    c = np.array([20.0, 5.0])
    far = c + 30 * np.array([math.cos(t), math.sin(t)])
    p = read(f"G21 F500\nT1 M6\nG0 X0 Y{c[1] - 10}\nG41 G1 X0 Y{c[1]}\nX{c[0]}\nX{far[0]:.9f} Y{far[1]:.9f}\n"
             f"G40 G1 X{far[0]:.9f} Y{far[1] + 20:.9f}\nM2\n")
    tp = p.toolpath
    corner = c + R * np.array([0.0, 1.0]) - R * math.tan(t / 2) * np.array([1.0, 0.0])
    i = int(np.flatnonzero(tp.line == 5)[-1])  # X20: ends at the corner
    assert (tp.kind[tp.line == 6] == FEED).all()  # no arc at a concave corner
    np.testing.assert_allclose(tp.end[i][:2], corner, atol=1e-9)
    np.testing.assert_allclose(tp.start[i + 1][:2], corner, atol=1e-9)
    end = far + R * np.array([-math.sin(t), math.cos(t)])
    np.testing.assert_allclose(tp.end[i + 1][:2], end, atol=1e-9)


@pytest.mark.parametrize("side,radius", [("G42", 10 + R), ("G41", 10 - R)])
def test_arcs_keep_their_centre_with_radius_plus_or_minus_r(side, radius):
    """A counter-clockwise quarter arc of radius 10 about the origin, entered tangentially: on the right
    (G42, outside) the tool centre runs at 10 + r, on the left (inside) at 10 − r."""
    p = read(f"G21 F500\nT1 M6\nG0 X10 Y-10\n{side} G1 X10 Y0\nG3 X0 Y10 I-10 J0\nG1 X-10\nG40 G1 Y20\nM2\n")
    tp = p.toolpath
    arc = int(np.flatnonzero(tp.kind == ARC_CCW)[0])
    assert (tp.kind >= ARC_CW).sum() == 1  # tangent joins: no corner arcs
    np.testing.assert_allclose(tp.center[arc][:2], [0, 0], atol=1e-12)
    np.testing.assert_allclose(tp.start[arc][:2], [radius, 0], atol=1e-12)
    np.testing.assert_allclose(tp.end[arc][:2], [0, radius], atol=1e-12)
    np.testing.assert_allclose(tp.end[arc + 1][:2], [-10, radius], atol=1e-12)


def test_g41_1_takes_the_diameter_itself_and_a_negative_one_swaps_sides():
    a = read(SQUARE.replace("G41 G1", "G41.1 D3 G1"), diameter_mm=99)
    b = read(SQUARE.replace("G41 G1", "G42.1 D-3 G1"), diameter_mm=99)
    assert moves(a) == moves(b) == moves(read(SQUARE))


def test_inch_program_offsets_by_the_radius_in_mm():
    p = read(SQUARE.replace("G21", "G20"), diameter_mm=2 * R)
    np.testing.assert_allclose(p.toolpath.end[1][:2], [-R, 0], atol=1e-12)  # r stays 1.5 mm in an inch program


@pytest.mark.parametrize("text,line,word,what", [
    ("G21 F100\nT1 M6\nG0 X0 Y0\nG41 G1 X1\n", 4, "X1", "entry move is not greater than the tool radius"),
    ("G21 F100\nT1 M6\nG0 X0 Y0\nG41 G1 X10\nX20\nY1\nX10\nG40 G1 X0\nM2\n", 7, "X10",
     "Straight feed in concave corner cannot be reached by the tool without gouging"),
    ("G21 F100\nT1 M6\nG0 X0 Y-10\nG41 G1 X0 Y0\nG3 X2 Y0 I1 J0\nM2\n", 5, "X2", "Tool radius not less than arc"),
    ("G21 F100\nT1 M6\nG0 X0 Y-10\nG41 G1 X0 Y0\nY10\nG40\nG2 X2 Y10 I1\nM2\n", 7, "G2", "must be straight"),
    ("G21 F100\nT1 M6\nG0 X0 Y-10\nG41 G1 X0 Y0\nG43 H1\n", 5, "G43", "Cannot change tool offset"),
    ("G21 F100\nT1 M6\nG0 X0 Y-10\nG41 G1 X0 Y0\nG42\n", 5, "G42", "Cannot turn cutter radius comp on when on"),
    ("G21 F100\nT1 M6\nG0 X0 Y-10\nG41 G1 X0 Y0\nG18\n", 5, "G18", "Cannot change planes"),
    ("G21 F100\nT1 M6\nG0 X0 Y-10\nG41 G1 X0 Y0\nT1 M6\n", 5, "M6", "Cannot change tools"),
    ("G21 F100\nT1 M6\nG0 X0 Y-10\nG41 G1 X0 Y0\nG81 X5 R1 Z-1\n", 5, "G81", "canned cycles"),
    ("G21 F100\nT1 M6\nG0 X0 Y-10\nG41 G1 X0 Y0\nG28\n", 5, "G28", "g28 or g30"),
    ("G21 F100\nT1 M6\nG0 X0 Y-10\nG41 G1 X0 Y0\nG92 X0\n", 5, "G92", "axis offsets"),
    ("G21 F100\nT1 M6\nG19\nG41\n", 4, "G41", "only in XY, XZ planes"),
    ("G21 F100\nT1 M6\nG41 D7 G1 X5\n", 3, "D7", "diameter of tool 7"),
    ("G21 F100\nT1 M6\nG41 D1.5 G1 X5\n", 3, "D1.5", "whole number"),
    ("G21 F100\nT1 M6\nG41.1 G1 X5\n", 3, "G41.1", "no D word"),
])
def test_refusals_are_located(text, line, word, what):
    with pytest.raises(ParseError) as info:
        read(text)
    err = info.value
    assert err.file == "comp.ngc" and err.line == line and err.column >= 1 and err.expected
    assert what in str(err) and err.word.upper() == word.upper()


def test_tool_table_diameters_are_read_in_its_units():
    table = read_tool_table(shared_data("linuxcnc", "tests", "ccomp", "mill-zchanges", "test.tbl"), units="inch")
    assert table.diameters_mm[4] == pytest.approx(25.4) and table.lengths_mm[2] == pytest.approx(0.7 * 25.4)
    assert table.diameters_mm[32] == 0.0 and set(table.orientation.values()) == {0}


def test_convert_refuses_rather_than_drop_the_offset():
    with pytest.raises(MillpostError, match="cutter radius compensation"):
        convert(read(SQUARE), dialects.get("grbl"))


# --- rs274 as the oracle ---------------------------------------------------------------------------------


def _random_contour(rng: np.random.Generator) -> str:
    """A contour of lines and arcs (IJK or R) compensated on a random side, in G17 (X-Y) or G18 (Z-X), mm
    or inch, absolute or incremental, with rapids, moves along the third axis and entry/exit moves."""
    side = rng.choice(["G41", "G42"])
    plane = rng.choice(["G17", "G18"])
    u, v, w, iu, iv = ("X", "Y", "Z", "I", "J") if plane == "G17" else ("Z", "X", "Y", "K", "I")
    inch = rng.random() < 0.25
    s = 1 / 25.4 if inch else 1.0
    incremental = rng.random() < 0.25
    lines = [f"{'G20' if inch else 'G21'} G90 {plane} F{800 * s:.2f}", "T1 M6",
             f"G0 {u}0 {v}{-15 * s:.4f} {w}{2 * s:.4f}", f"G1 {w}{-s:.4f}", f"{side} G1 {u}0 {v}0"]
    if incremental:
        lines.append("G91")
    x = y = 0.0
    heading = math.pi / 2
    for _ in range(int(rng.integers(4, 10))):
        heading += rng.uniform(-2.2, 2.2)
        length = rng.uniform(4, 15) * s
        nx, ny = round(x + length * math.cos(heading), 4), round(y + length * math.sin(heading), 4)
        ex, ey = (nx - x, ny - y) if incremental else (nx, ny)
        roll = rng.random()
        if roll < 0.35:
            bulge = rng.uniform(0.3, 1.5) * length / 2 * rng.choice([-1, 1])
            mx, my = (x + nx) / 2, (y + ny) / 2
            cx, cy = mx - bulge * math.sin(heading), my + bulge * math.cos(heading)
            g = "G2" if rng.random() < 0.5 else "G3"
            if rng.random() < 0.3:
                radius = math.hypot(cx - x, cy - y)
                ccw_centre_left = (g == "G3") == (bulge > 0)
                lines.append(f"{g} {u}{ex:.4f} {v}{ey:.4f} R{radius if ccw_centre_left else -radius:.4f}")
            else:
                lines.append(f"{g} {u}{ex:.4f} {v}{ey:.4f} {iu}{cx - x:.4f} {iv}{cy - y:.4f}")
        elif roll < 0.45:
            lines.append(f"G0 {u}{ex:.4f} {v}{ey:.4f}")
            lines.append("G1")
        else:
            lines.append(f"G1 {u}{ex:.4f} {v}{ey:.4f}")
        if rng.random() < 0.15:
            lines.append(f"G1 {w}{rng.uniform(-0.5, 0.5) * s:.4f}" if incremental else f"G1 {w}{-2 * s:.4f}")
        x, y = nx, ny
    out = (x - 20 * s * math.cos(heading + 1), y - 20 * s * math.sin(heading + 1))
    lines += ["G90", f"G40 G1 {u}{out[0]:.4f} {v}{out[1]:.4f}", f"G0 {w}{5 * s:.4f}", "M2"]
    return "\n".join(lines) + "\n"


@needs_rs274
def test_random_contours_match_rs274(tmp_path):
    """Seeded random contours of lines and arcs, both sides, several tool sizes: every program LinuxCNC
    runs gives the same moves here (end points within 1e-4 mm); every one it refuses is refused here
    with its message."""
    rng = np.random.default_rng(13)
    ran = refused = 0
    for k in range(120):
        text = _random_contour(rng)
        diameter = float(rng.choice([0.5, 2.0, 4.0, 8.0]))
        path = tmp_path / f"c{k}.ngc"
        path.write_text(text)
        trace = rs274_oracle.run(path, diameters_mm={1: diameter})
        try:
            program = read_text(text, str(path), linuxcnc(diameter))
        except ParseError as err:
            assert trace.error is not None and trace.error in err.reason, (text, diameter, trace.error, str(err))
            refused += 1
            continue
        assert trace.error is None, (text, diameter, trace.error)
        assert rs274_oracle.mismatches(program, trace) == [], (text, diameter)
        ran += 1
    assert ran >= 70 and refused >= 15, (ran, refused)


@needs_rs274
@pytest.mark.parametrize("units,turn_deg,accepted", [
    ("G21", -0.5, True), ("G21", -2.0, True), ("G21", -2.8, False), ("G20", -0.05, True), ("G20", -0.1, False)])
def test_cut_back_arc_sweep_tolerance_is_rs274s(tmp_path, units, turn_deg, accepted):
    """A line joining an inside arc at a slight convex angle (under the 0.05 rad corner tolerance, so no
    corner arc): the arc starts a little behind its offset start. rs274 2.9 refuses it once the sweep
    grows by more than 0.001 rad in an inch program, 0.0254 rad in a mm one (measured)."""
    b = math.radians(turn_deg)
    s = 1 / 25.4 if units == "G20" else 1.0
    cx, cy = (10 - 5 * math.sin(b)) * s, 5 * math.cos(b) * s
    ex, ey = cx + 5 * s, cy
    text = (f"{units} F100\nT1 M6\nG0 X0 Y{-5 * s:.6f}\nG41 G1 X0 Y0\nG1 X{10 * s:.6f} Y0\n"
            f"G3 X{ex:.6f} Y{ey:.6f} I{cx - 10 * s:.6f} J{cy:.6f}\nG1 X{ex + 5 * s:.6f} Y{ey - 5 * s:.6f}\n"
            f"G40 G1 X{ex + 10 * s:.6f}\nM2\n")
    path = tmp_path / "t.ngc"
    path.write_text(text)
    trace = rs274_oracle.run(path, diameters_mm={1: 4.0})
    assert (trace.error is None) == accepted
    if accepted:
        assert rs274_oracle.mismatches(read_text(text, "t.ngc", linuxcnc(4.0)), trace) == []
    else:
        with pytest.raises(ParseError, match="Arc move in concave corner"):
            read_text(text, "t.ngc", linuxcnc(4.0))


def _expected_error(path: Path) -> str:
    return path.read_text().splitlines()[0].lstrip(";").strip()


@pytest.mark.parametrize("name", ["ccomp-arcexit.ngc", "ccomp-gouging.ngc"])
def test_linuxcnc_bad_cases_are_refused_with_its_message(name):
    path = shared_data("linuxcnc", "tests", "interp", "bad", name)
    with pytest.raises(ParseError) as info:
        read_text(path.read_text(), str(path), ReaderOptions.linuxcnc())
    assert info.value.reason == _expected_error(path) and info.value.line >= 2


@needs_rs274
def test_fusion_in_control_contours_match_rs274(tmp_path):
    """The Fusion benchmark's two in-control contours (G41/G42 D03 with arcs and entry/exit moves), cut
    out of the excerpt (rs274 stops at its G69 line) and run with a 3 mm tool 3."""
    text = shared_data("fusion-fanuc-benchmark", "fusion_benchmark_1001_3axis_excerpt.nc").read_text()
    body = text[text.index("(2D-CONTOUR WITH COMPENSATION LEFT)"):text.index("(2D-BORE)")]
    body = "\n".join(ln for ln in body.splitlines() if not ln.startswith(("G00 A", "M01")))
    prog = tmp_path / "fusion_comp.ngc"
    prog.write_text("G21 G90 G17\n" + body + "\nM30\n")
    trace = rs274_oracle.run(prog, diameters_mm={3: 3.0})
    program = read_text(prog.read_text(), str(prog), ReaderOptions(dialect="linuxcnc", tool_diameters_mm={3: 3.0}))
    assert trace.error is None and program.compensated.sum() >= 20
    assert rs274_oracle.mismatches(program, trace) == []


# --- the compensated path downstream --------------------------------------------------------------------

BOSS = """G21 G90 G17
T1 M6
S8000 M3
G0 X70 Y0 Z5
G1 Z-3 F300
G41 D1 G1 X60 Y10 F900
X10
Y30
X50
Y10
G40 G1 X70 Y0
G0 Z5
M30
"""


def test_engagement_follows_the_tool_centre():
    """A 6 mm tool round a 40 × 20 boss standing in a 42 × 22 block, 3 mm deep: the compensated tool
    grazes the boss and removes exactly the 1 mm ring, (42·22 − 40·20)·3 = 372 mm³ (the programmed,
    uncompensated path would cut 3 mm into the boss)."""
    p = read(BOSS, diameter_mm=6.0)
    block = stock.box((9.0, 9.0, -10.0), (51.0, 31.0, 0.0), 0.05)
    v0 = block.volume_mm3()
    engagement.simulate(block, Tool(6.0, flutes=3), p.toolpath.resample(0.05))
    assert v0 - block.volume_mm3() == pytest.approx(372.0, rel=0.02)


def test_compensated_moves_are_never_split():
    p = read(BOSS, diameter_mm=6.0)
    tp = p.toolpath
    i = int(np.flatnonzero((tp.line == 7) & (tp.kind == FEED))[0])  # the X10 side
    frags = [Fragment(i, 0.0, 0.5, 700.0 / 60), Fragment(i, 0.5, 1.0, 450.0 / 60),
             Fragment(1, 0.0, 1.0, 200.0 / 60)]  # mm/s
    whole = whole_moves(p, frags)
    assert Fragment(i, 0.0, 1.0, 450.0 / 60) in whole and Fragment(1, 0.0, 1.0, 200.0 / 60) in whole and len(whole) == 2
    plan = FeedPlan.programmed(p)
    plan.feed_mm_min[i] = 450.0
    plan.fragments[i] = [(0.5, 700.0), (1.0, 450.0)]  # even a plan that asks for a split gets one F
    text = write_feeds(p, plan)
    assert text.splitlines()[6].replace(" ", "") == "X10F450"  # one F (spaced as the program is)
    assert len(text.splitlines()) == len(BOSS.splitlines())


@needs_rs274
def test_new_feeds_keep_the_compensated_path_under_rs274(tmp_path):
    """Feeds changed on every cutting move (the corner arcs' lines too): rs274 reads the written program
    back to the same moves as the original, with the compensation words untouched."""
    p = read(BOSS, diameter_mm=6.0)
    plan = FeedPlan.programmed(p)
    cut = p.toolpath.kind != RAPID
    plan.feed_mm_min[cut] = 100.0 + 50.0 * np.arange(cut.sum())
    text = write_feeds(p, plan)
    assert "G41 D1 G1 X60 Y10 F" in text and "G40 G1 X70 Y0 F" in text
    a, b = tmp_path / "a.ngc", tmp_path / "b.ngc"
    a.write_text(BOSS)
    b.write_text(text)
    ta, tb = (rs274_oracle.run(x, diameters_mm={1: 6.0}) for x in (a, b))
    assert ta.error is None and tb.error is None
    assert [(k, e) for k, e, _, _ in ta.moves] == [(k, e) for k, e, _, _ in tb.moves]
    back = read(text, diameter_mm=6.0)
    assert rs274_oracle.mismatches(back, tb) == []
    assert back.toolpath.feed_mm_min[cut].tolist() == sorted(back.toolpath.feed_mm_min[cut].tolist())


JOB = """program = "program.nc"
material = "al6061"
machine = "vmc-small"

[stock]
box = [[0, 0, -10], [60, 40, 0]]
cell_mm = 0.2

[tools.1]
diameter_mm = 6
flutes = 3
helix_deg = 35
flute_length_mm = 16
stickout_mm = 24
"""


@needs_rs274
def test_optimize_keeps_compensation_and_rs274_reads_back_the_same_path(tmp_path):
    """`optimize` on a compensated contour round a boss: the engagement follows the tool centre (the
    job's 6 mm tool 1), the written program keeps G41 D1 / G40 on their lines with only F changed, and
    rs274 runs it to the same moves as the original."""
    from millpost.job import load_job
    from millpost.optimize import optimize

    (tmp_path / "program.nc").write_text(BOSS)
    (tmp_path / "job.toml").write_text(JOB)
    result = optimize(load_job(tmp_path), progress=False)
    assert result.summary["status"] == "solved" and result.summary["removed_volume_mm3"] > 1000
    assert max(result.summary["limits"].values()) <= 1.005
    def words(line):
        return line.split(" F")[0].split("F")[0]

    # only F words change; a line may be preceded by added pieces of its own move (the plunge beside the
    # block is split where it enters the air clearance), each a bare G1 to a point on the way
    out = [words(line) for line in result.text.splitlines()]
    kept = [line for line in out if line in {words(old) for old in BOSS.splitlines()}]
    assert kept == [words(old) for old in BOSS.splitlines()]
    assert all(line.startswith("G1 Z") for line in out if line not in kept)
    emitted = tmp_path / "emitted.ngc"
    emitted.write_text(result.text)
    original, back = (rs274_oracle.run(p, diameters_mm={1: 6.0}) for p in (tmp_path / "program.nc", emitted))
    assert original.error is None and back.error is None
    assert _merged(original.moves) == _merged(back.moves)


def _merged(moves, tol=1e-4):
    """rs274's moves as (kind, end) with a straight feed move continuing the previous one in the same
    direction merged into it: the path, whichever points it is split at."""
    out = []
    start = np.zeros(3)
    for kind, end, _, _ in moves:
        end = np.asarray(end)
        if out and kind == out[-1][0] == "feed":
            a, b = out[-1][1] - out[-1][2], end - out[-1][1]
            if np.linalg.norm(np.cross(a, b)) <= tol * max(np.linalg.norm(a), 1.0) and a @ b > 0:
                out[-1] = (kind, end, out[-1][2])
                start = end
                continue
        out.append((kind, end, start))
        start = end
    return [(k, tuple(np.round(e, 4))) for k, e, _ in out]


def test_inverse_time_feeds_under_compensation_are_timed_by_the_programmed_move():
    """G93 with compensation: LinuxCNC runs the offset move (and its corner arc) at the programmed
    length × F, so a new feed v is written as F·v/v₀ (not v over the offset path's length)."""
    text = ("G21 F600\nT1 M6\nG0 X0 Y-10\nG41 G1 X0 Y0\nG93\nG1 Y20 F30\nX20 F30\nY0 F20\nG94\n"
            "G40 G1 X-10 F600\nM2\n")
    p = read(text)
    tp = p.toolpath
    cut = tp.kind != RAPID
    np.testing.assert_allclose(tp.feed_mm_min[tp.line == 7], 20 * 30)  # corner arc and side: 20 mm × 30/min
    plan = FeedPlan.programmed(p)
    plan.feed_mm_min[cut] *= 0.5
    back = read(write_feeds(p, plan))
    np.testing.assert_allclose(back.toolpath.feed_mm_min[cut], 0.5 * tp.feed_mm_min[cut], rtol=1e-3)
    assert "X20 F15" in write_feeds(p, plan)


@pytest.mark.parametrize("comp", ["G41 ", ""])
def test_inverse_time_move_of_no_length_keeps_its_f(comp):
    """G93: a move of no length still takes 1/F minutes, whatever feed is planned for it, so its F is
    kept (it was written F0, which LinuxCNC refuses in inverse time, or divided by zero under G41)."""
    text = (f"G21 F600\nT1 M6\nG0 X0 Y-10\n{comp}G1 X0 Y0\nG93\nG1 Y20 F30\nG1 Y20 F20\nX20 F30\nG94\n"
            "G40 G1 X-10 F600\nM2\n")
    p = read(text)
    plan = FeedPlan.programmed(p)
    plan.feed_mm_min[p.toolpath.kind != RAPID] *= 0.5
    out = write_feeds(p, plan).splitlines()
    assert out[6] == "G1 Y20 F20"
    assert out[5] == "G1 Y20 F15" and out[7] == "X20 F15"


@needs_rs274
@pytest.mark.parametrize("text", [
    "G21 F500\nT1 M6\nG0 X0 Y-10\nG41 G1 X0 Y0\nY10\nM0\nX10\nM1\nY0\nG40 G1 X20\nM2\n",  # M0/M1 flush
    "G21 F500\nT1 M6\nG0 X0 Y-10\nG41 G1 X0 Y0\nY10\nG40\nG41\nX10 Y20\nY0\nG40 G1 X20\nM2\n",  # on again
    "G21 F500\nT1 M6\nG0 X0 Y-10\nG41 G0 X0 Y0\nG1 Y10\nS100 M3\n(hello)\nG4 P1\nX10\nG1 Z-1\nZ0\nY0\n"
    "G40 G0 X20\nM2\n",  # rapids, events and Z-only moves while compensating
    "G21 F500\nG0 X0 Y-10\nG41 D0\nG1 Y0\nX10\nG40 G1 Y-10\nM2\n",  # no tool in the spindle: radius 0
    "G21 F500\nT1 M6\nG0 X0 Y-10\nG41.1 D2\nG40\nG1 X5\nM2\n",  # LinuxCNC's ccomp/early-exit
    "G21 F500\nT1 M6\nG0 X0 Y0\nG41 G1 X10 Y0\nG3 X10 Y0 I-10 J0\nG40 G1 X0\nM2\n",  # full circle
    "G21 F500\nT1 M6\nG0 X0 Y0\nG41 G1 X10 Y0\nG3 X10 Y0 I-10 J0 P2 Z-2\nG1 X5 Y5\nG40 G1 X0\nM2\n",  # helix
    "G21 F500\nT1 M6\nG0 X-5 Y-20\nG41 G0 X0 Y-10\nG1 Y0\nG2 X10 Y0 R5\nG2 X20 Y0 R-5\nG40 G1 X30\nM2\n",
])
def test_held_moves_across_other_blocks_match_rs274(tmp_path, text):
    path = tmp_path / "t.ngc"
    path.write_text(text)
    trace = rs274_oracle.run(path, diameters_mm={1: 3.0})
    assert trace.error is None
    assert rs274_oracle.mismatches(read_text(text, "t.ngc", linuxcnc(3.0)), trace) == []


@pytest.mark.parametrize("name", ["interp/inside-corners/test.ngc", "interp/cam-nisley/cam.ngc",
                                  "interp/crazy-paths/test.ngc", "ccomp/mill-zchanges/test.ngc",
                                  "ccomp/mill-g90g91g92/test.ngc"])
def test_new_feeds_on_linuxcnc_compensated_programs_keep_the_path(name):
    """Random lower feeds on every cutting move of LinuxCNC's compensated test programs (inch tool
    table): read back, the same tool-centre path, and no move faster than planned."""
    path = shared_data("linuxcnc", "tests", *name.split("/"))
    options = ReaderOptions.linuxcnc().use_tool_table(shared_data("linuxcnc", "tests", "interp", "cam-nisley",
                                                                   "test.tbl"), units="inch")
    p = read_text(path.read_text(), str(path), options)
    tp = p.toolpath
    cut = tp.kind != RAPID
    assert p.compensated.sum() >= 10
    plan = FeedPlan.programmed(p)
    plan.feed_mm_min[cut] = np.round(tp.feed_mm_min[cut] * np.random.default_rng(1).uniform(0.3, 1.0, cut.sum()), 1)
    back = read_text(write_feeds(p, plan), "back.ngc", options)
    np.testing.assert_allclose(back.toolpath.end, tp.end, atol=2e-3)
    assert (back.toolpath.feed_mm_min[cut] <= plan.feed_mm_min[cut] * (1 + 1e-9)).all()


def test_program_ending_while_compensating_ends_the_held_move_at_its_offset_point():
    """No G40 and no M2/M30: the last move is not left out (rs274 would drop it); it ends at its own
    offset end point, and the assumption is noted."""
    p = read("G21 F500\nT1 M6\nG0 X0 Y-10\nG41 G1 X0 Y0\nY10\nX10\n")
    np.testing.assert_allclose(p.toolpath.end[-1][:2], [10, 10 + R], atol=1e-12)
    assert p.toolpath.line[-1] == 6 and any("cutter compensation on" in n for n in p.notes)
