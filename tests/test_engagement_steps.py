"""Axial slices on a stepped wall: a flat end mill side-cuts along a wall whose near strip is lower (a
pocket's earlier level, a stepped wall, a restart), so the stock under the ring has a step inside the
axial depth. The slice boundaries must hold the step, so each slice sees one arc.

Closed forms (up milling, material to the left, Altintas' φ from +y): below the step the material
starts R − ae₁ from the path, so the engaged arc is [0, arccos(1 − 2ae₁/D)]; above it R − ae₂,
[0, arccos(1 − 2ae₂/D)]. The Kienzle mean force is additive over axial disks, so the exact mean is the
sum of the two bands' means (each band a uniform cut of its own arc and thickness).
"""

import math

import numpy as np
import pytest

from millpost import stock
from millpost._kernels import engage as K
from millpost.engagement import Engagement, simulate
from millpost.forces.kienzle import Kienzle
from millpost.tools import Tool
from test_engagement import frame, polyline

CELL = 0.025
D, AP, STEP = 10.0, 3.0, 1.3      # tool diameter, axial depth, step height above the tip (mm)
AE_LOW, AE_HIGH = 3.0, 1.5        # radial width below and above the step (mm)
SLICES = 8


def stepped_side_cut(theta_deg: float = 17.0):
    """The engagement of the steady part of a side cut along the stepped wall (path rotated off the grid,
    shifted by a sub-cell offset), and its slices' count."""
    R, th = D / 2, math.radians(theta_deg)
    f, n = frame(th)
    o = np.array([15.0123, 14.9923])
    s = stock.box((0, 0, 0), (30, 30, 10), CELL)
    xs = s.x0 + (np.arange(s.nx) + 0.5) * CELL
    ys = s.y0 + (np.arange(s.ny) + 0.5) * CELL
    y = (xs[None, :] - o[0]) * n[0] + (ys[:, None] - o[1]) * n[1]   # distance left of the path
    pz = 10.0 - AP                                                    # tool tip height (stock top at 10)
    s.top[y < R - AE_LOW] = s.z_floor
    s.top[(y >= R - AE_LOW) & (y < R - AE_HIGH)] = pz + STEP - s.z0
    a, b = o - 12 * f, o + 12 * f
    e = simulate(s, Tool(D), polyline([(*a, pz), (*b, pz)]).resample(0.1), slices=SLICES)
    return e.select(slice(80, 160))


@pytest.fixture(scope="module")
def cut():
    return stepped_side_cut()


def test_step_is_a_slice_boundary_and_each_slice_has_its_bands_arc(cut):
    """Every slice lies wholly below or above the step, slices below have the lower material's arc and
    those above the upper's (closed forms), within 0.2° on average; the thicknesses sum to ap."""
    assert cut.ap_mm == pytest.approx(AP, abs=1e-5)
    np.testing.assert_allclose(cut.dz_mm.sum(axis=1), AP, rtol=1e-9)
    lo_z, hi_z = cut.z_mm - 0.5 * cut.dz_mm, cut.z_mm + 0.5 * cut.dz_mm
    below = hi_z <= STEP + 1e-6
    assert np.all(below | (lo_z >= STEP - 1e-6))
    assert np.all(below.sum(axis=1) == 4)     # bands 1.3 and 1.7 mm share 8 slices as 4 + 4 (thinnest slices)
    low = math.acos(1 - 2 * AE_LOW / D)
    high = math.acos(1 - 2 * AE_HIGH / D)
    want = np.where(below, low, high)
    assert np.degrees(np.abs(cut.phi_ex - want).mean()) <= 0.2
    assert np.degrees(np.abs(cut.phi_st).mean()) <= 0.2
    # the swept cross-section: each band's width times its thickness
    assert np.mean(cut.area_mm2) == pytest.approx(AE_LOW * STEP + AE_HIGH * (AP - STEP), rel=5e-3)


def test_kienzle_mean_force_matches_the_two_band_closed_form(cut):
    """The Kienzle mean force (k_c1.1 = 700 N/mm², m_c = 0.25, Al alloy order) of the 8 step-split slices
    equals the exact sum of the two bands within 1 % (8 uniform slices put the step mid-slice: 1.3 mm
    falls in slice [1.125, 1.5], whose lower 0.175 mm then takes the upper arc, ~4 % off)."""
    tool, model, fz, rpm = Tool(D), Kienzle.from_coefficients(700.0, 0.25), 0.05, 10000.0
    got = model.predict(cut, fz, rpm, tool, peaks=False).force_feed_N.mean(axis=0)
    bands = [Engagement.uniform([0.0], [math.acos(1 - 2 * ae / D)], t, D / 2) for ae, t in
             ((AE_LOW, STEP), (AE_HIGH, AP - STEP))]
    want = sum(model.predict(e, fz, rpm, tool, peaks=False).force_feed_N[0] for e in bands)
    assert np.hypot(*got[:2]) == pytest.approx(np.hypot(*want[:2]), rel=0.01)
    np.testing.assert_allclose(got[:2], want[:2], rtol=0.01, atol=0.01 * np.hypot(*want[:2]))


def test_sloped_wall_along_the_grid_keeps_the_uniform_slices_bit_for_bit():
    """A side cut along a steep drafted wall (7° from vertical) parallel to the grid: near the arc's end the
    ring runs along a row of columns of one height inside the axial depth, but the stock is not flat there
    (one cell out along the radius it is 0.2 mm higher): no level, the slices are exactly ap/K,
    (s + ½)·ap/K as before."""
    R, pz = D / 2, 10.0 - AP
    o = np.array([15.0, 15.0])
    s = stock.box((0, 0, 0), (30, 30, 10), CELL)
    ys = s.y0 + (np.arange(s.ny) + 0.5) * CELL
    # its foot 0.2 mm inside the tool's reach: at the ring's tangent point (φ = 0) the wall stands 1.6 mm high
    height = pz + (ys - (o[1] + R - 0.2)) / math.tan(math.radians(7.0))
    wall = np.clip(height, s.z0 + s.z_floor, 10.0) - s.z0
    s.top[:] = wall[:, None].astype(np.float32)
    e = simulate(s, Tool(D), polyline([(*(o - (12, 0)), pz), (*(o + (12, 0)), pz)]).resample(0.1), slices=SLICES)
    k = (e.ap_mm > 1e-6) & (e.step_mm > 0)   # the samples whose slices were stepped
    assert k.sum() > 100
    assert np.array_equal(e.z_mm[k], (np.arange(SLICES) + 0.5)[None, :] * (e.ap_mm[k, None] / SLICES))


def _place(levels, ap, K_=SLICES):
    lv = np.zeros(64)
    lv[:len(levels)] = levels
    n = K._drop_levels(lv, len(levels), K_ - 1, ap)
    zr, th, zm = np.empty(K_ + 1), np.empty(K_), np.empty(K_)
    uniform, dzs = K._place(lv, n, ap, K_, zr, th, zm)
    return uniform, dzs, zr, th, zm


def test_no_level_places_the_uniform_slices_bit_for_bit():
    for ap in (2.7, 0.1, 13.3):
        uniform, dzs, zr, th, zm = _place([], ap)
        assert uniform and dzs == ap / SLICES
        assert list(zr) == [s * (ap / SLICES) for s in range(SLICES + 1)]
        assert list(zm) == [(s + 0.5) * (ap / SLICES) for s in range(SLICES)]


def test_levels_become_boundaries_and_extra_levels_are_dropped_nearest_first():
    """Three levels: boundaries, each further slice going to the band whose slices are thickest (bands
    0.4, 1.6, 0.6, 0.4 mm of ap = 3: 1 + 4 + 2 + 1 slices). Nine levels (more than K − 1 = 7): the level
    nearest a neighbour (or an end) goes, one at a time: of the pairs 0.04 and 0.06 mm apart the lower."""
    uniform, _, zr, th, zm = _place([0.4, 2.0, 2.6], 3.0)
    assert not uniform
    np.testing.assert_allclose(zr, [0, 0.4, 0.8, 1.2, 1.6, 2.0, 2.3, 2.6, 3.0], atol=1e-12)
    np.testing.assert_allclose(th, np.diff(zr))
    np.testing.assert_allclose(zm, zr[:-1] + 0.5 * np.diff(zr))
    _, _, zr, _, _ = _place([0.3, 0.6, 0.66, 1.0, 1.5, 1.8, 2.1, 2.5, 2.54], 3.0)
    np.testing.assert_allclose(zr, [0, 0.3, 0.66, 1.0, 1.5, 1.8, 2.1, 2.54, 3.0], atol=1e-12)
