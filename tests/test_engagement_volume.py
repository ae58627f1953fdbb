"""Total removed volume against exact booleans (manifold3d) of the swept tool, and the compiled tool
profile against `Tool`.

The reference sweeps each straight segment as the convex hull of the tool solid at its two ends
(a cylinder for the flat mill, sphere + cylinder for the ball) and subtracts all of them from the
block; circles are 256-gons, which bounds the reference's own error near 1e-4.
"""

import math

import numpy as np
import pytest

from millpost import stock
from millpost._kernels import engage as K
from millpost.engagement import _tool_params, simulate
from millpost.tools import Tool

from test_engagement import polyline

manifold3d = pytest.importorskip("manifold3d")
M = manifold3d.Manifold
SEG = 256
TOP, H = 10.0, 0.025


def tool_solid(tool: Tool, p) -> "manifold3d.Manifold":
    R, tall = tool.radius_mm, 30.0
    x, y, z = p
    if tool.shape == "ball":
        ball = M.sphere(R, SEG).translate((x, y, z + R))
        return M.batch_hull([ball, M.cylinder(tall, R, R, SEG).translate((x, y, z + R))])
    return M.cylinder(tall, R, R, SEG).translate((x, y, z))


def exact_removed(tool: Tool, pts, lo, hi) -> float:
    block = M.cube(tuple(np.subtract(hi, lo)), False).translate(tuple(lo))
    hulls = [M.batch_hull([tool_solid(tool, a), tool_solid(tool, b)]) for a, b in zip(pts[:-1], pts[1:])]
    rest = M.batch_boolean([block] + hulls, manifold3d.OpType.Subtract)
    return block.volume() - rest.volume()


def zigzag(theta, z, ae, n_pass=6, length=14.0, origin=(10.0137, 8.0061)):
    f = np.array([math.cos(theta), math.sin(theta)])
    nrm = np.array([-f[1], f[0]])
    o = np.asarray(origin) - 0.5 * length * f - 0.5 * (n_pass - 1) * ae * nrm
    pts = []
    for i in range(n_pass):
        a, b = o + i * ae * nrm, o + i * ae * nrm + length * f
        pts += [a, b] if i % 2 == 0 else [b, a]
    return np.array([(x, y, z) for x, y in pts])


def trochoid(z, n_seg=300, rt=1.5, advance=0.3, loops=6, origin=(6.0071, 8.0133)):
    t = np.linspace(0, loops * 2 * math.pi, n_seg + 1)
    x = origin[0] + advance * t / (2 * math.pi) + rt * np.sin(t)
    y = origin[1] - rt * np.cos(t) + rt
    return np.column_stack([x, y, np.full_like(x, z)])


@pytest.mark.parametrize("shape,path", [("flat", "zigzag"), ("ball", "zigzag"), ("flat", "trochoid")])
def test_removed_volume_matches_exact_booleans(shape, path):
    tool = Tool(6.0, shape=shape)
    lo, hi = (0, 0, 0), (20, 16, TOP)
    if path == "zigzag":
        pts = zigzag(math.radians(17), TOP - 2.0, 0.4 * 6.0)
    else:
        pts = trochoid(TOP - 2.0)
    s = stock.box(lo, hi, H)
    v0 = s.volume_mm3()
    e = simulate(s, tool, polyline(pts).resample(0.1))
    removed = v0 - s.volume_mm3()
    assert e.volume_mm3.sum() == pytest.approx(removed, rel=1e-9)
    assert removed == pytest.approx(exact_removed(tool, pts, lo, hi), rel=1e-3)
    # the low-noise ring cross-section integrates to the same volume (the first sample has no step:
    # it removes the tool's footprint where the path starts inside the block)
    ring = np.sum(e.area_mm2 * e.step_mm) + e.volume_mm3[e.step_mm == 0].sum()
    assert ring == pytest.approx(removed, rel=2e-2)


@pytest.mark.parametrize("tool", [Tool(6.0), Tool(6.0, shape="ball"), Tool(8.0, shape="bull", corner_radius_mm=1.0),
                                  Tool(6.0, shape="chamfer", tip_angle_deg=60, tip_diameter_mm=0.5)])
def test_compiled_profile_matches_tool(tool):
    shape, R, rc, r_tip, tan_half = _tool_params(tool)
    r = np.linspace(0, tool.radius_mm, 101)
    z = np.linspace(0, tool.radius_mm * 3, 101)
    got_h = [K.surface_height(v, shape, R, rc, r_tip, tan_half) for v in r]
    got_r = [K.profile_radius(v, shape, R, rc, r_tip, tan_half) for v in z]
    np.testing.assert_allclose(got_h, tool.height_at(r), atol=1e-12)
    np.testing.assert_allclose(got_r, tool.radius_at(z), atol=1e-12)
