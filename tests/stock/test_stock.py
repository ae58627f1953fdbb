"""Stock builders against exact volumes and closed-form geometry.

References: analytic box / cylinder / sphere volumes, the B-rep volume computed by OCCT, and the
exact position of a horizontal hole. Grids are placed off the geometry (sub-cell offsets) so the
rasteriser's tie rules and plane clamping are exercised.
"""

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

from millpost import stock
from millpost.errors import MillpostError


def test_box_volume_and_partial_cells():
    s = stock.box((0, 0, -5), (10, 6, 0), 0.1)
    assert s.top.shape == (60, 100)
    assert s.volume_mm3() == pytest.approx(10 * 6 * 5, rel=1e-9)
    # 10.03 x 6.01 at 0.1 mm: the last column/row centre lies outside, so it stays empty
    s = stock.box((0, 0, -5), (10.03, 6.01, 0), 0.1)
    assert s.top.shape == (61, 101)
    assert s.volume_mm3() == pytest.approx(10 * 6 * 5, rel=1e-9)
    assert s.intervals(5, 5) == [(-5.0, 0.0)] and s.intervals(100, 5) == []


def test_heights_are_stored_above_the_stock_origin():
    """A block stores its heights above z0 = its top face, so its uncut top is all zeros (pages the OS
    has not committed); so does a mesh block. A copy is equal and independent."""
    s = stock.box((0, 0, 2), (10, 6, 7), 0.1)
    assert (s.z0, s.z_floor, s.z_max) == (7.0, -5.0, 7.0) and not s.top.any()
    c = s.copy()
    c.top[3, 4] = -1.0
    assert s.top[3, 4] == 0.0 and c.volume_mm3() == pytest.approx(s.volume_mm3() - 0.01, rel=1e-9)
    m = trimesh.creation.box(extents=(10, 6, 5))
    m.apply_translation((5, 3, 4.5))
    s = stock.from_triangles(m.triangles, 0.1)
    assert (s.z0, s.z_floor, s.n_multi) == (7.0, -5.0, 0) and not s.top.any()
    assert s.volume_mm3() == pytest.approx(10 * 6 * 5, rel=1e-9)


def test_an_uncut_block_commits_no_memory_for_its_top():
    """A 100 × 100 mm block at 25 µm (16 M columns, 61 MiB of float32 tops) raises the process's resident
    memory by less than 4 MiB until it is cut; its volume (which reads every column) too."""
    status = Path("/proc/self/status")
    if not status.exists():
        pytest.skip("needs /proc/self/status (Linux) to read the resident memory")

    def rss_mib():
        return next(int(ln.split()[1]) for ln in status.read_text().splitlines() if ln.startswith("VmRSS:")) / 1024

    before = rss_mib()
    s = stock.box((0, 0, 0), (100, 100, 50), 0.025)
    assert s.volume_mm3() == pytest.approx(100 * 100 * 50, rel=1e-9)
    assert rss_mib() - before < 4.0


def test_a_column_crossing_too_many_surfaces_is_refused():
    """32 stacked plates: the vertical lines through them cross 64 surfaces, more than a column holds;
    the error says where instead of keeping a garbled column (31 plates, 62 surfaces, still fit)."""
    def plates(n):
        return np.concatenate([trimesh.creation.box(extents=(4, 4, 0.5), transform=trimesh.transformations
                                                    .translation_matrix((2, 2, 0.25 + k))).triangles
                               for k in range(n)])
    s = stock.from_triangles(plates(31), 0.5)
    assert s.volume_mm3() == pytest.approx(31 * 4 * 4 * 0.5, rel=1e-9) and len(s.intervals(3, 3)) == 31
    with pytest.raises(MillpostError, match=r"x = \d+\.\d+, y = \d+\.\d+ mm crosses more than 62 surfaces"):
        stock.from_triangles(plates(32), 0.5)


def test_memory_check_names_the_cell_that_would_fit():
    with pytest.raises(MillpostError, match=r"needs \d+ MiB.*at least 9\d\.\d µm"):
        stock.box((0, 0, 0), (1000, 1000, 50), 0.025, max_memory_mb=500)
    # no cell requested: 25 µm when it fits, coarsened just enough otherwise
    assert stock.choose_cell((0, 0), (100, 100), None, max_memory_mb=500) == 0.025
    h = stock.choose_cell((0, 0), (1000, 1000), None, max_memory_mb=500)
    assert 0.095 < h < 0.1 and 1e6 / h**2 * 5.125 / 2**20 <= 500


def test_rotated_box_mesh_volume_and_heights():
    m = trimesh.creation.box(extents=(20, 12, 7))
    m.apply_transform(trimesh.transformations.rotation_matrix(math.radians(17), (0, 0, 1)))
    m.apply_translation((0.0123, -0.0071, 3.5))
    s = stock.from_triangles(m.triangles, 0.05)
    assert s.n_multi == 0
    assert s.volume_mm3() == pytest.approx(20 * 12 * 7, rel=5e-4)
    inside = s.top > s.z_floor
    assert s.z0 == pytest.approx(7.0) and np.allclose(s.z0 + s.top[inside], 7.0, atol=1e-5)


def test_sphere_columns_are_exact_chords():
    r = 4.0
    m = trimesh.creation.icosphere(subdivisions=6, radius=r)
    s = stock.from_triangles(m.triangles, 0.05)
    assert s.volume_mm3() == pytest.approx(m.volume, rel=5e-4)
    # a column near the centre holds one interval [-z, z] with z the mesh chord (within sag)
    xs, ys = s.cell_centres()
    i, j = int(np.argmin(abs(xs - 1.0))), int(np.argmin(abs(ys - 0.5)))
    (lo, hi), = s.intervals(i, j)
    zc = math.sqrt(r * r - xs[i] ** 2 - ys[j] ** 2)
    assert hi == pytest.approx(zc, abs=2e-3) and lo == pytest.approx(-zc, abs=2e-3)


@pytest.fixture(scope="module")
def part():
    """40x30x20 block with a 15 deep pocket, a Ø12 horizontal through hole (an undercut) and a dome."""
    bd = pytest.importorskip("build123d")
    blk = bd.Box(40, 30, 20, align=(bd.Align.MIN, bd.Align.MIN, bd.Align.MIN))
    pocket = bd.Pos(8, 8, 20 - 6) * bd.Box(12, 14, 6, align=(bd.Align.MIN, bd.Align.MIN, bd.Align.MIN))
    hole = bd.Pos(20, 15, 8) * bd.Rot(90, 0, 0) * bd.Cylinder(6, 40)
    dome = bd.Pos(30, 15, 20) * bd.Sphere(6)
    return (blk - pocket - hole) + (dome - bd.Pos(30, 15, 20 - 6) * bd.Box(14, 14, 12))


def test_brep_stl_step_agree_with_each_other_and_the_solid(part, tmp_path):
    import build123d as bd

    h = 0.1
    s_shape = stock.from_shape(part, h)
    assert s_shape.volume_mm3() == pytest.approx(part.volume, rel=5e-4)
    step = tmp_path / "part.step"
    bd.export_step(part, str(step))
    s_step = stock.load(step, h)
    stl = tmp_path / "part.stl"
    bd.export_stl(part, str(stl), tolerance=1e-4, angular_tolerance=0.05)
    s_stl = stock.load(stl, h)
    for other in (s_step, s_stl):
        assert other.top.shape == s_shape.top.shape
        assert (other.x0, other.y0, other.z0 + other.z_floor) == pytest.approx((s_shape.x0, s_shape.y0,
                                                                                 s_shape.z0 + s_shape.z_floor))
        assert other.volume_mm3() == pytest.approx(part.volume, rel=5e-4)
        d = np.abs((other.z0 + other.top) - (s_shape.z0 + s_shape.top))
        assert np.mean(d <= 2 * h / 10) > 0.995 and d.sum() * h * h < 5e-4 * part.volume
    assert s_step.z0 == s_shape.z0 and np.array_equal(s_step.top, s_shape.top)


def test_horizontal_hole_is_an_undercut(part):
    h = 0.1
    s = stock.from_shape(part, h)
    xs, ys = s.cell_centres()
    i, j = int(np.argmin(abs(xs - 20.05))), int(np.argmin(abs(ys - 3.05)))
    dx = xs[i] - 20
    half = math.sqrt(36 - dx * dx)
    (lo1, hi1), (lo0, hi0) = s.intervals(i, j)
    assert (lo0, hi0) == pytest.approx((0.0, 8 - half), abs=0.01)
    assert (lo1, hi1) == pytest.approx((8 + half, 20.0), abs=0.01)
    assert s.z0 + s.top[j, i] == pytest.approx(20.0)
    # the pocket floor is a single interval from the floor
    i, j = int(np.argmin(abs(xs - 10))), int(np.argmin(abs(ys - 20)))
    assert s.intervals(i, j) == [(0.0, pytest.approx(14.0, abs=1e-5))]


def test_python_file_stock(tmp_path):
    pytest.importorskip("build123d")
    f = tmp_path / "stock.py"
    f.write_text("from build123d import Box, Cylinder, Pos\n"
                 "def stock():\n    return Box(20, 10, 5) - Pos(0, 0, 0) * Cylinder(2, 5)\n")
    s = stock.load(f, 0.05)
    exact = 20 * 10 * 5 - math.pi * 4 * 5
    assert s.volume_mm3() == pytest.approx(exact, rel=5e-4)
    bad = tmp_path / "bad.py"
    bad.write_text("x = 1\n")
    with pytest.raises(MillpostError, match="must define `stock`"):
        stock.load(bad, 0.05)


def test_export_stl_round_trip(tmp_path):
    s = stock.box((0, 0, 0), (10, 8, 4), 0.05)
    s.top[40:80, 50:120] = 2.5 - s.z0  # a 2 x 3.5 x 1.5 pocket
    out = tmp_path / "final.stl"
    s.export_stl(out)
    m = trimesh.load(out)
    assert m.is_watertight
    # the exported solid spans column centres, so its volume is the stock's less a half-cell rim
    rim = (10 + 8) * 2 * 0.025 * 4
    assert m.volume == pytest.approx(s.volume_mm3() - rim, rel=2e-3)
