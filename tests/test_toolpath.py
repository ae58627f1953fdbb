"""Arc geometry against closed forms: length, helix length, bounding box, resampling."""

import math

import numpy as np
import pytest

from millpost.toolpath import ARC_CCW, ARC_CW, FEED, Toolpath


def one_move(kind, start, end, center=(np.nan,) * 3, plane=0, turns=0):
    return Toolpath(
        kind=np.array([kind], np.int8), start=np.array([start], float), end=np.array([end], float),
        center=np.array([center], float), plane=np.array([plane], np.int8),
        turns=np.array([turns], np.int32), feed_mm_min=np.array([100.0]), rpm=np.array([0.0]),
        tool=np.array([1], np.int32), line=np.array([1], np.int32), block=np.array([0], np.int32))


@pytest.mark.parametrize("plane", [0, 1, 2])
@pytest.mark.parametrize("kind", [ARC_CW, ARC_CCW])
def test_quarter_and_full_arc_lengths_each_plane(plane, kind):
    from millpost.toolpath import PLANE_AXES
    a, b, n = PLANE_AXES[plane]
    r = 5.0
    start, end, center = np.zeros(3), np.zeros(3), np.zeros(3)
    start[a] = r
    end[b] = r if kind == ARC_CCW else -r
    tp = one_move(kind, start, end, center, plane)
    assert tp.lengths()[0] == pytest.approx(math.pi * r / 2, rel=1e-12)
    full = one_move(kind, start, start, center, plane)
    assert full.lengths()[0] == pytest.approx(2 * math.pi * r, rel=1e-12)
    bb = full.bbox()
    assert bb[0][a] == pytest.approx(-r) and bb[1][a] == pytest.approx(r)
    assert bb[0][b] == pytest.approx(-r) and bb[1][b] == pytest.approx(r)


def test_helix_length_and_turns():
    r, pitch, turns = 3.0, 1.5, 2
    tp = one_move(ARC_CCW, (r, 0, 0), (r, 0, -pitch * (turns + 1)), (0, 0, 0), turns=turns)
    expect = (turns + 1) * math.hypot(2 * math.pi * r, pitch)
    assert tp.lengths()[0] == pytest.approx(expect, rel=1e-12)


def test_bbox_of_arc_includes_only_swept_extremes():
    # CW from (0, 5) to (5, 0) about the origin sweeps the first quadrant only.
    tp = one_move(ARC_CW, (0, 5, 0), (5, 0, 0), (0, 0, 0))
    np.testing.assert_allclose(tp.bbox(), [[0, 0, 0], [5, 5, 0]], atol=1e-12)
    # CCW between the same points sweeps the other 270 degrees.
    tp = one_move(ARC_CCW, (0, 5, 0), (5, 0, 0), (0, 0, 0))
    np.testing.assert_allclose(tp.bbox(), [[-5, -5, 0], [5, 5, 0]], atol=1e-12)


def test_resample_points_lie_on_the_arc_and_curvature_is_one_over_r():
    r = 4.0
    tp = one_move(ARC_CCW, (r, 0, 0), (-r, 0, 0), (0, 0, 0))
    s = tp.resample(0.01)
    np.testing.assert_allclose(np.hypot(s.xyz_mm[:, 0], s.xyz_mm[:, 1]), r, rtol=1e-12)
    assert s.s_mm[-1] == pytest.approx(math.pi * r)
    np.testing.assert_allclose(np.linalg.norm(s.tangent, axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(s.curvature, axis=1), 1 / r, rtol=1e-12)
    # the tangent is the numerical derivative of position
    num = np.diff(s.xyz_mm, axis=0) / np.diff(s.s_mm)[:, None]
    mid = 0.5 * (s.tangent[1:] + s.tangent[:-1])
    np.testing.assert_allclose(num, mid, atol=1e-5)


def test_line_resample_spacing():
    tp = one_move(FEED, (0, 0, 0), (10, 0, 0))
    s = tp.resample(0.3)
    assert len(s) == 35 and np.all(np.diff(s.s_mm) <= 0.3 + 1e-12)
    assert s.xyz_mm[-1, 0] == 10.0


def test_axis_shares_over_a_whole_move_are_the_closed_forms():
    """The largest |t_i| anywhere on a move: a line's direction cosines; a quarter arc from θ = 0 to π/2
    has its tangent along Y at the start and along X at the end (both 1); a helical quarter from θ = π/2
    to π of radius 1 dropping 1 mm has L = √((π/2)² + 1) and shares (π/2)/L in the plane, 1/L along Z;
    a CW quarter from θ = 0 to −π/2 passes both too."""
    from millpost.gcode import read_text
    tp = read_text("G21 G90 G17\nG0 X1 Y0 Z0\nG3 X0 Y1 I-1 J0 F100\nG3 X-1 Y0 Z-1 I0 J-1\nG1 X2 Y4 Z0\n"
                   "G2 X1 Y3 I-1 J0\nM2\n").toolpath
    L = np.hypot(np.pi / 2, 1.0)
    expected = [[1, 0, 0], [1, 1, 0], [np.pi / 2 / L, np.pi / 2 / L, 1 / L],
                np.array([3, 4, 1]) / np.sqrt(26), [1, 1, 0]]
    np.testing.assert_allclose(tp.axis_shares(), expected, atol=1e-12)
