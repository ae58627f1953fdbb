"""Chip thickness on arcs against the tool makers' circular-interpolation closed form.

Sandvik Coromant, Metalcutting technical guide, milling, "circular interpolation" (also Harvey
Performance, "Circular Interpolation: Machining Circular Tool Paths"): a cutter of diameter D_c whose
centre runs a circle so that its edge generates diameter D_m, in stock pre-cut to D_w,
- inside (a bore opened from D_w to D_m): radial engagement a_e = (D_m² − D_w²) / (4 (D_m − D_c)),
  feed at the edge = centre feed × D_m / (D_m − D_c);
- outside (a boss turned from D_w down to D_m): a_e = (D_w² − D_m²) / (4 (D_m + D_c)),
  feed at the edge = centre feed × D_m / (D_m + D_c);
so the thickest chip per unit of the centre's feed per tooth is
h_max / f_z = (edge feed / centre feed) · sin φ, cos φ = 1 − 2 a_e / D_c (φ ≤ 90°, else 1).

millpost's chip per unit centre feed is `Engagement.edge` (the edge/centre feed ratio) times the
largest sin φ of the arcs the stepping finds in a 25 µm height field: both halves are checked.
"""

import math

import numpy as np
import pytest

from millpost import stock
from millpost.engagement import simulate
from millpost.gcode import read_text
from millpost.limits import max_sin
from millpost.toolpath import ARC_CW, ARC_CCW
from millpost.tools import Tool

H = 0.025
D_C = 6.0


def _circle_job(inside: bool, d_m: float, d_w: float):
    """A circle of the tool centre that opens a bore (inside) or turns a boss (outside), climb milling
    (CCW inside, CW outside), 2 mm deep, centred on (30.0113, 30.0071) (off the grid)."""
    cx, cy = 30.0113, 30.0071
    s = stock.box((0, 0, 0), (60, 60, 10), H)
    xs, ys = s.cell_centres()
    r = np.hypot(xs[None, :] - cx, ys[:, None] - cy)  # (ny, nx), as the tops
    if inside:
        s.top[r < d_w / 2] = s.z_floor          # the pre-cut bore
        rho = (d_m - D_C) / 2
        arc = f"G3 X{cx + rho:.4f} Y{cy:.4f} I{-rho:.4f} J0"
        lead = f"G1 X{cx:.4f} Y{cy:.4f} Z8 F600\nG1 X{cx + rho:.4f} Y{cy:.4f}"
    else:
        s.top[r > d_w / 2] = s.z_floor          # the boss, pre-turned to D_w
        rho = (d_m + D_C) / 2
        arc = f"G2 X{cx + rho:.4f} Y{cy:.4f} I{-rho:.4f} J0"
        lead = f"G1 X{cx + rho + 8:.4f} Y{cy:.4f} Z8 F600\nG1 X{cx + rho:.4f} Y{cy:.4f}"
    text = f"G21 G90 G17\nG0 X{cx + rho + 8 if not inside else cx:.4f} Y{cy:.4f} Z15\n{lead}\n{arc} F600\nM30\n"
    path = read_text(text).toolpath
    samples = path.resample(0.1)
    eng = simulate(s, Tool(D_C, flutes=3), samples)
    on_arc = np.isin(samples.kind, (ARC_CW, ARC_CCW))
    theta = np.arctan2(samples.xyz_mm[:, 1] - cy, samples.xyz_mm[:, 0] - cx) % (2 * np.pi)
    # the steady part of the circle: away from the lead-in's own cut at θ = 0
    steady = on_arc & (theta > math.radians(60)) & (theta < math.radians(300))
    return eng, steady


@pytest.mark.parametrize("d_m,d_w", [(10.0, 8.0), (12.0, 11.0), (16.0, 15.6)])
def test_inside_arc_chip_is_the_closed_form(d_m, d_w):
    eng, steady = _circle_job(True, d_m, d_w)
    ae = (d_m**2 - d_w**2) / (4 * (d_m - D_C))
    phi = math.acos(max(1 - 2 * ae / D_C, 0.0))
    ratio = d_m / (d_m - D_C)
    np.testing.assert_allclose(eng.edge[steady], ratio, rtol=2e-3)
    chip = eng.edge[steady] * max_sin(eng.select(np.flatnonzero(steady)))
    assert np.median(chip) == pytest.approx(ratio * math.sin(phi), rel=0.02)
    # thicker than the same radial step on a straight wall, cos φ = 1 − 2 (D_m − D_w) / (2 D_c)
    straight = math.sin(math.acos(1 - (d_m - d_w) / D_C))
    assert np.median(chip) > 1.5 * straight


@pytest.mark.parametrize("d_m,d_w", [(20.0, 22.0), (12.0, 12.8)])
def test_outside_arc_chip_is_the_closed_form(d_m, d_w):
    eng, steady = _circle_job(False, d_m, d_w)
    ae = (d_w**2 - d_m**2) / (4 * (d_m + D_C))
    phi = math.acos(max(1 - 2 * ae / D_C, 0.0))
    ratio = d_m / (d_m + D_C)
    np.testing.assert_allclose(eng.edge[steady], ratio, rtol=2e-3)
    chip = eng.edge[steady] * max_sin(eng.select(np.flatnonzero(steady)))
    assert np.median(chip) == pytest.approx(ratio * math.sin(phi), rel=0.02)


def test_straight_moves_keep_the_centre_feed():
    s = stock.box((0, 0, 0), (40, 20, 10), H)
    samples = read_text("G21 G90\nG0 X-5 Y10.0037 Z8\nG1 X45 F600\nM30\n").toolpath.resample(0.1)
    eng = simulate(s, Tool(D_C), samples)
    np.testing.assert_array_equal(eng.edge, 1.0)
