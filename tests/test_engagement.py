"""Engagement stepping against closed forms and an exact geometric reference, at 25 µm cells.

Paths are rotated off the grid and shifted by sub-cell offsets (grid-aligned paths hide errors).
Closed forms: slot arc [0, π] and area D·ap; side milling wall angle arccos(1 − 2ae/D) and area
ae·ap; ball slot per-slice radius √(2Rz − z²), κ = arccos(1 − z/R) and the circular-segment area.
The inside-corner test compares with the arc computed from the exact swept geometry (distance to
the programmed polyline), sampled every 0.01°.
"""

import math

import numpy as np
import pytest
import trimesh

from millpost import stock
from millpost.engagement import _kappa, simulate
from millpost.errors import MillpostError
from millpost.toolpath import FEED, RAPID, Toolpath
from millpost.tools import Tool

H = 0.025


def polyline(pts, kinds=None) -> Toolpath:
    pts = np.asarray(pts, float)
    n = len(pts) - 1
    return Toolpath(kind=np.asarray(kinds if kinds is not None else [FEED] * n, np.int8), start=pts[:-1],
                    end=pts[1:], center=np.full((n, 3), np.nan), plane=np.zeros(n, np.int8),
                    turns=np.zeros(n, np.int32), feed_mm_min=np.full(n, 600.0), rpm=np.full(n, 12000.0),
                    tool=np.ones(n, np.int32), line=np.arange(10, 10 + n, dtype=np.int32),
                    block=np.arange(n, dtype=np.int32))


def rotated_block(centre_xy, theta, size_xy, z0, z1):
    m = trimesh.creation.box(extents=(size_xy[0], size_xy[1], z1 - z0))
    T = trimesh.transformations.rotation_matrix(theta, (0, 0, 1))
    T[:3, 3] = (centre_xy[0], centre_xy[1], 0.5 * (z0 + z1))
    m.apply_transform(T)
    return m.triangles


def frame(theta):
    f = np.array([math.cos(theta), math.sin(theta)])
    return f, np.array([-f[1], f[0]])


def test_slot_is_half_circle_and_area_is_d_times_ap():
    D, ap, th = 6.0, 1.7, math.radians(23)
    f, _ = frame(th)
    o = np.array([10.0113, 8.0071])
    s = stock.box((0, 0, 0), (20, 16, 10), H)
    a, b = o - 9 * f, o + 9 * f
    e = simulate(s, Tool(D), polyline([(*a, 10 - ap), (*b, 10 - ap)]).resample(0.1))
    k = slice(40, 140)
    # the slot walls are tangent at φ = 0 and π: the ends sit on the wall within a cell
    assert np.degrees(np.abs(e.phi_st[k]).mean()) <= 0.2 and np.degrees(np.abs(e.phi_ex[k] - math.pi).mean()) <= 0.2
    assert e.ap_mm[k] == pytest.approx(ap, abs=1e-5)
    assert np.mean(e.area_mm2[k]) == pytest.approx(D * ap, rel=5e-3)
    assert np.mean(e.ae_mm[k]) == pytest.approx(D, rel=1e-6)
    np.testing.assert_allclose(e.dz_mm[k].sum(axis=1), ap, rtol=1e-5)
    np.testing.assert_allclose(e.kappa[k], math.pi / 2)
    # the flat tool's one κ (no per-slice array) is exactly what its profile gives at every slice
    np.testing.assert_array_equal(e.kappa, _kappa(Tool(D), e.z_mm))
    np.testing.assert_allclose(np.hypot(e.feed_dir[k, 0], e.feed_dir[k, 1]), 1.0)
    np.testing.assert_allclose(e.feed_dir[k, :2], np.tile(f, (100, 1)), atol=1e-9)


@pytest.mark.parametrize("frac", [0.1, 0.25, 0.4, 0.5])
@pytest.mark.parametrize("side", ["up", "down"])
def test_side_milling_entry_angle_and_area(frac, side):
    """Material beyond a wall at R − ae from the path: up milling (material left) engages
    [0, arccos(1 − 2ae/D)], down milling [π − arccos(1 − 2ae/D), π]."""
    D, ap = 10.0, 2.0
    R, ae = D / 2, frac * D
    th = math.radians(17 if side == "up" else 33)
    f, n = frame(th)
    o = np.array([0.0123, -0.0077])
    sgn = 1 if side == "up" else -1
    W = 30.0
    tris = rotated_block(o + n * sgn * (R - ae + W / 2), th, (W, W), 0, 10)
    s = stock.from_triangles(tris, H)
    a, b = o - 10 * f, o + 10 * f
    e = simulate(s, Tool(D), polyline([(*a, 10 - ap), (*b, 10 - ap)]).resample(0.1))
    k = slice(60, 140)
    wall = math.acos(1 - 2 * ae / D)
    if side == "up":
        wall_err, tan_err = e.phi_ex[k] - wall, e.phi_st[k] - 0.0
    else:
        wall_err, tan_err = e.phi_st[k] - (math.pi - wall), e.phi_ex[k] - math.pi
    assert np.degrees(np.abs(wall_err).mean()) <= 0.2
    assert np.degrees(np.abs(tan_err).mean()) <= 0.2
    assert np.mean(e.area_mm2[k]) == pytest.approx(ae * ap, rel=5e-3)
    assert np.mean(e.ae_mm[k]) == pytest.approx(ae, rel=5e-3)


def test_ball_slot_at_partial_depth():
    D, ap, th = 6.0, 1.5, math.radians(29)
    R = D / 2
    f, _ = frame(th)
    o = np.array([10.0041, 8.0187])
    s = stock.box((0, 0, 0), (20, 16, 10), H)
    a, b = o - 9 * f, o + 9 * f
    e = simulate(s, Tool(D, shape="ball"), polyline([(*a, 10 - ap), (*b, 10 - ap)]).resample(0.1), slices=8)
    k = slice(40, 140)
    z = (np.arange(8) + 0.5) * ap / 8
    np.testing.assert_allclose(e.z_mm[k], np.tile(z, (100, 1)), atol=1e-5)
    np.testing.assert_allclose(e.r_mm[k], np.tile(np.sqrt(2 * R * z - z * z), (100, 1)), atol=1e-5)
    np.testing.assert_allclose(e.kappa[k], np.tile(np.arccos(1 - z / R), (100, 1)), atol=1e-4)
    np.testing.assert_allclose(e.phi_st[k], 0.0, atol=math.radians(0.2))
    np.testing.assert_allclose(e.phi_ex[k], math.pi, atol=math.radians(0.2))
    segment = R * R * math.acos((R - ap) / R) - (R - ap) * math.sqrt(2 * R * ap - ap * ap)
    assert np.mean(e.area_mm2[k]) == pytest.approx(segment, rel=5e-3)
    assert np.mean(e.volume_mm3[k] / e.step_mm[k]) == pytest.approx(segment, rel=5e-3)


def _exact_arc(centre, f, n, R, in_stock, swept_pts):
    """Engaged [φ_st, φ_ex] at a ring of radius R about `centre`: material is inside the stock and
    farther than R from the programmed polyline travelled so far (the exact swept region)."""
    phi = np.radians(np.arange(0, 180.0001, 0.01))
    q = centre + R * (np.sin(phi)[:, None] * f + np.cos(phi)[:, None] * n)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(swept_pts, axis=0), axis=1) > 1e-12])
    swept_pts = swept_pts[keep]
    a, b = swept_pts[:-1], swept_pts[1:]
    ab = b - a
    t = np.clip(np.einsum("pij,ij->pi", q[:, None, :] - a[None], ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
    d = np.linalg.norm(q[:, None, :] - (a[None] + t[..., None] * ab[None]), axis=2).min(axis=1)
    on = in_stock(q) & (d > R)
    if not on.any():
        return np.nan, np.nan
    return phi[on][0], phi[on][-1]


def test_inside_corner_engagement_rises_and_returns():
    """Down milling along a wall with ae = 0.25D, then a 90° left turn into the next wall."""
    D, ap, ae = 6.0, 2.0, 1.5
    R = D / 2
    th = math.radians(11)
    f1, n1 = frame(th)
    f2, n2 = frame(th + math.pi / 2)
    o = np.array([15.0091, 15.0043])
    s = stock.box((0, 0, 0), (30, 30, 10), H)
    xs, ys = s.cell_centres()
    X, Y = np.meshgrid(xs, ys)

    def in_stock(q):  # material outside the pre-cut pocket {u < R - ae, v > -R + ae} (path frame)
        u = (q[..., 0] - o[0]) * f1[0] + (q[..., 1] - o[1]) * f1[1]
        v = (q[..., 0] - o[0]) * n1[0] + (q[..., 1] - o[1]) * n1[1]
        return ~((u < R - ae) & (v > -R + ae))

    s.top[~in_stock(np.stack([X, Y], -1))] = s.z_floor
    pts = np.array([o - 10 * f1, o, o + 10 * f2])
    sm = polyline([(*p, 10 - ap) for p in pts]).resample(0.05)
    e = simulate(s, Tool(D), sm, look_ahead_mm=0.15)
    width = np.degrees(e.phi_ex[:, 0] - e.phi_st[:, 0])
    steady = math.degrees(math.acos(1 - 2 * ae / D))
    first = slice(60, 160)  # on the first wall, before the corner
    last = slice(len(sm) - 100, len(sm) - 40)
    assert np.abs(width[first] - steady).mean() < 0.3
    assert np.abs(width[last] - steady).mean() < 0.3
    corner = np.arange(180, 260)
    assert width[corner].max() > steady + 45  # the engagement rises in the corner...
    # ...exactly as the swept geometry says, sample by sample
    errs = []
    for k in corner:
        p = sm.xyz_mm[k, :2]
        # the ring is the path point 0.15 mm further on, framed by the path direction there
        sa = sm.s_mm[k] + 0.15
        centre = np.array([np.interp(sa, sm.s_mm, sm.xyz_mm[:, 0]), np.interp(sa, sm.s_mm, sm.xyz_mm[:, 1])])
        f = f1 if sa < 10 - 1e-6 else f2 if sa > 10 + 1e-6 else e.feed_dir[k, :2]
        np.testing.assert_allclose(e.feed_dir[k, :2], f, atol=1e-9)
        n = np.array([-f[1], f[0]])
        swept = np.vstack([pts[0], *([pts[1]] if sm.s_mm[k] > 10 else []), p])
        st, ex = _exact_arc(centre, f, n, R, in_stock, swept)
        errs.append(np.degrees([e.phi_st[k, 0] - st, e.phi_ex[k, 0] - ex]))
    errs = np.abs(np.array(errs))
    assert np.nanmean(errs) < 0.3 and np.nanmax(errs) < 2.0


def test_rapid_into_stock_names_the_line():
    s = stock.box((0, 0, 0), (20, 20, 10), 0.1)
    tp = polyline([(-5, 10, 12), (-5, 10, 9), (25, 10, 9)], kinds=[FEED, RAPID])
    with pytest.raises(MillpostError, match="line 11: rapid move runs into the stock"):
        simulate(s, Tool(6.0), tp.resample(0.1))
    # the same move as a feed cuts a slot of 6 x 1 mm over the 20 mm block
    s = stock.box((0, 0, 0), (20, 20, 10), 0.1)
    v0 = s.volume_mm3()
    e = simulate(s, Tool(6.0), polyline([(-5, 10, 12), (-5, 10, 9), (25, 10, 9)]).resample(0.1))
    assert v0 - s.volume_mm3() == pytest.approx(e.volume_mm3.sum())
    assert e.volume_mm3.sum() == pytest.approx(20 * 6 * 1, rel=5e-3)


def test_undercut_column_cut_through_its_top_interval():
    """A slot at the depth of a horizontal hole's roof removes only material above the cutter."""
    bd = pytest.importorskip("build123d")
    blk = bd.Box(30, 20, 20, align=(bd.Align.MIN, bd.Align.MIN, bd.Align.MIN))
    hole = bd.Pos(15, 10, 8) * bd.Rot(0, 90, 0) * bd.Cylinder(3, 40)  # along x
    part = blk - hole
    s = stock.from_shape(part, 0.05)
    assert s.n_multi > 0
    v0 = s.volume_mm3()
    # slot along x over the hole at z = 12: cuts 20-12 = 8 mm deep, the hole roof is at z = 11
    e = simulate(s, Tool(4.0), polyline([(-5, 10, 12), (35, 10, 12)]).resample(0.1))
    assert v0 - s.volume_mm3() == pytest.approx(30 * 4 * 8, rel=2e-3)
    # deeper slot at z = 9 cuts through the roof into the hole: the removed cross-section is the
    # 4-wide strip from 20 down to 9 less the part of the Ø6 hole inside it
    s2 = stock.from_shape(part, 0.05)
    v0 = s2.volume_mm3()
    e = simulate(s2, Tool(4.0), polyline([(-5, 10, 9), (35, 10, 9)]).resample(0.1))
    # hole ∩ strip |y-10| <= 2, z in [9, 11]: integrate the circle chord above z = 9
    zz = np.linspace(9, 11, 20001)
    half = np.sqrt(np.maximum(9 - (zz - 8) ** 2, 0))
    hole_area = np.trapezoid(2 * np.minimum(half, 2), zz)
    assert v0 - s2.volume_mm3() == pytest.approx(30 * (4 * 11 - hole_area), rel=2e-3)
    assert e.ap_mm[200] == pytest.approx(11.0, abs=1e-4)
    i, j = int((15 - s2.x0) / 0.05), int((10.025 - s2.y0) / 0.05)
    assert s2.intervals(i, j) == [(0.0, pytest.approx(5.0, abs=1e-3))]


def test_bridge_over_a_gap_cut_into_the_gap_and_rapid_through_it():
    """A 20 × 10 block z 0..2 under a bridge z 5..8 over its middle 10 mm in x (a gap 2..5 below the
    bridge, columns outside it single): the removed volume of each cut equals the stock's loss and the
    closed form, a cut ending in the gap leaves the top at the gap's bottom, and a rapid through the
    cleared bridge passes while one into the lower block crashes."""
    tris = np.concatenate([rotated_block((10, 5), 0.0, (20, 10), 0, 2), rotated_block((10, 5), 0.0, (10, 10), 5, 8)])
    s = stock.from_triangles(tris, 0.05)
    assert s.n_multi == 200 * 200  # the bridge's columns
    assert s.volume_mm3() == pytest.approx(20 * 10 * 2 + 10 * 10 * 3, rel=1e-6)
    i, j = 200, 50  # x 10.025, y 2.525: under the bridge
    assert s.intervals(i, j) == [(5.0, 8.0), (0.0, 2.0)]
    # a Ø4 slot along x at y = 5 down to z = 6.5: 1.5 mm off the bridge only
    v0 = s.volume_mm3()
    e = simulate(s, Tool(4.0), polyline([(-5, 5, 6.5), (25, 5, 6.5)]).resample(0.1))
    assert v0 - s.volume_mm3() == pytest.approx(e.volume_mm3.sum(), rel=1e-6)
    assert e.volume_mm3.sum() == pytest.approx(10 * 4 * 1.5, rel=2e-3)
    assert s.intervals(i, 101) == [(5.0, 6.5), (0.0, 2.0)] and s.intervals(i, j) == [(5.0, 8.0), (0.0, 2.0)]
    # the same slot at z = 4 ends in the gap: the bridge goes (the rest of 5..6.5), the top drops to 2
    v0 = s.volume_mm3()
    e = simulate(s, Tool(4.0), polyline([(-5, 5, 4), (25, 5, 4)]).resample(0.1))
    assert v0 - s.volume_mm3() == pytest.approx(e.volume_mm3.sum(), rel=1e-6)
    assert e.volume_mm3.sum() == pytest.approx(10 * 4 * 1.5, rel=2e-3)
    assert s.z0 + float(s.top[101, i]) == 2.0 and s.intervals(i, 101) == [(0.0, 2.0)]
    # now a rapid along the slot at z = 3 (tip above the lower block) touches nothing; one at z = 1 crashes
    simulate(s, Tool(4.0), polyline([(-5, 5, 12), (-5, 5, 3), (25, 5, 3)], kinds=[FEED, RAPID]).resample(0.1))
    with pytest.raises(MillpostError, match="rapid move runs into the stock"):
        simulate(s, Tool(4.0), polyline([(-5, 5, 12), (-5, 5, 1), (25, 5, 1)], kinds=[FEED, RAPID]).resample(0.1))


def test_lowpass_is_scipys_gaussian_filter_per_run():
    """The area/ae low-pass equals scipy.ndimage.gaussian_filter1d (mode "nearest") on each continuous
    run, runs shorter than the kernel included."""
    from scipy.ndimage import gaussian_filter1d

    from millpost.engagement import _lowpass

    rng = np.random.default_rng(3)
    x = rng.normal(size=300)
    fresh = np.zeros(300, bool)
    fresh[[0, 2, 5, 40, 299]] = True  # runs of 2, 3, 35, 259 and 1 samples
    for sigma in (0.4, 1.0, 2.5):
        ref = x.copy()
        for a, b in ((0, 2), (2, 5), (5, 40), (40, 299)):
            ref[a:b] = gaussian_filter1d(x[a:b], sigma, mode="nearest")
        assert np.allclose(_lowpass(x, fresh, sigma), ref, rtol=0, atol=1e-13)
