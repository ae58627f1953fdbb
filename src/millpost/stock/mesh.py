"""Stock from solids: a closed triangle mesh rasterised along vertical rays through the cell centres.

Sources: triangle arrays, STL files (trimesh), STEP files and build123d / CadQuery / OCP shapes
(tessellated with an absolute chordal tolerance of a tenth of a cell), and Python files that build
a build123d object. build123d is imported only when a B-rep is given (it costs seconds and ~400 MB).
"""

from __future__ import annotations

import os
import runpy
from pathlib import Path

import numpy as np

from .._kernels import compiling, raster
from ..errors import MillpostError
from .grid import Stock, choose_cell, grid_shape, multi_index_arrays, zeroed

ANGULAR_TOL_RAD = 0.1


def from_triangles(tris: np.ndarray, cell_mm: float | None = None, *, max_memory_mb: float | None = None,
                   bounds: np.ndarray | None = None) -> Stock:
    """Rasterise a closed, outward-oriented triangle soup (n, 3, 3) in mm.

    bounds: optional [[x0, y0], [x1, y1]] of the grid (default: the mesh's XY extent). The floor is the
    mesh's lowest z; columns whose material does not start there, or that hold several intervals,
    are stored as multi columns (with the gaps in their material).
    """
    tris = np.ascontiguousarray(tris, dtype=np.float64)
    if tris.ndim != 3 or tris.shape[1:] != (3, 3) or len(tris) == 0:
        raise MillpostError("stock mesh: expected a non-empty (n, 3, 3) array of triangles")
    lo3, hi3 = tris.reshape(-1, 3).min(0), tris.reshape(-1, 3).max(0)
    xy0, xy1 = (lo3[:2], hi3[:2]) if bounds is None else (np.asarray(bounds[0], float), np.asarray(bounds[1], float))
    h = choose_cell(xy0, xy1, cell_mm, max_memory_mb)
    nx, ny = grid_shape(xy0, xy1, h)
    z0 = _main_face_height(tris)  # heights are stored above it: z rounded to float32, less z0
    zf = np.float32(np.float64(np.float32(lo3[2])) - z0)
    tol = 1e-3 * h
    top = zeroed((ny, nx))
    count = np.zeros(nx * ny, np.uint8)
    with compiling(raster.first_pass):
        raster.first_pass(tris, float(xy0[0]), float(xy0[1]), h, nx, ny, z0, float(zf), tol, top, count)
    bits, rank = multi_index_arrays(nx * ny)
    with compiling(raster.multi_columns):
        ptr, crossings, full = raster.multi_columns(count, bits, rank, top.reshape(-1), zf)
    del count
    if full >= 0:
        x, y = xy0[0] + (full % nx + 0.5) * h, xy0[1] + (full // nx + 0.5) * h
        raise MillpostError(f"stock mesh: the vertical line at x = {x:.4f}, y = {y:.4f} mm crosses more than "
                            f"{raster.COUNT - 1} surfaces, more than a column can hold")
    if crossings // 2 >= 2**31:
        raise MillpostError(f"stock mesh: {crossings // 2} gaps in the columns exceed the 2**31 the stock can index")
    # at most one gap per two crossings; the pages past the gaps written are never touched (no memory)
    lo = np.empty(crossings // 2 + 1, np.float32)
    hi = np.empty_like(lo)
    with compiling(raster.multi_gaps):
        w = raster.multi_gaps(tris, float(xy0[0]), float(xy0[1]), h, nx, ny, z0, zf, bits, rank, ptr, lo, hi,
                              top.reshape(-1))
    return Stock(float(xy0[0]), float(xy0[1]), h, float(zf), top, bits, rank, ptr, lo[:w], hi[:w], z0)


def _main_face_height(tris: np.ndarray) -> float:
    """The stock's z0: the height of the largest horizontal up-facing area of the mesh (a block's top
    face; on the float32 grid), where most columns' tops then store 0; the lowest z when nothing faces
    straight up."""
    z = tris[:, :, 2].astype(np.float32)
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    area = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])  # XY area, > 0 facing up
    flat = (z[:, 0] == z[:, 1]) & (z[:, 0] == z[:, 2]) & (area > 0)
    if not flat.any():
        return float(z.min())
    heights, which = np.unique(z[flat, 0], return_inverse=True)
    return float(heights[np.argmax(np.bincount(which, weights=area[flat]))])


def from_stl(path: str | os.PathLike, cell_mm: float | None = None, **kw) -> Stock:
    """Stock from an STL (or any mesh file trimesh reads), in mm."""
    import trimesh

    try:
        mesh = trimesh.load(os.fspath(path), force="mesh")
    except (ValueError, OSError) as exc:
        raise MillpostError(f"{path}: cannot read mesh: {exc}") from exc
    if len(mesh.faces) == 0:
        raise MillpostError(f"{path}: mesh has no triangles")
    if mesh.volume < 0:  # inward-facing winding
        mesh.invert()
    return from_triangles(mesh.triangles, cell_mm, **kw)


def shape_triangles(shape, tolerance_mm: float) -> np.ndarray:
    """Triangles of a build123d / CadQuery / OCP solid meshed at an absolute chordal tolerance (mm).

    The shape's cached triangulation is discarded first: OCCT would otherwise return an older,
    coarser mesh, and build123d's own `tessellate` treats the tolerance as relative.
    """
    from OCP.BRep import BRep_Tool
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS, TopoDS_Shape

    ocp = _as_ocp(shape, TopoDS_Shape)
    BRepTools.Clean_s(ocp)
    BRepMesh_IncrementalMesh(ocp, tolerance_mm, False, ANGULAR_TOL_RAD, True)
    out = []
    exp = TopExp_Explorer(ocp, TopAbs_FACE)
    while exp.More():
        face = TopoDS.Face(exp.Current())
        loc = TopLoc_Location()
        poly = BRep_Tool.Triangulation_s(face, loc)
        exp.Next()
        if poly is None:
            continue
        trsf = loc.Transformation()
        nodes = np.array([[p.X(), p.Y(), p.Z()] for p in
                          (poly.Node(i).Transformed(trsf) for i in range(1, poly.NbNodes() + 1))])
        idx = np.array([[t.Value(1), t.Value(2), t.Value(3)] for t in poly.Triangles()]) - 1
        if face.Orientation() == TopAbs_REVERSED:
            idx = idx[:, [0, 2, 1]]
        out.append(nodes[idx])
    if not out:
        raise MillpostError("stock solid: tessellation produced no triangles")
    return np.concatenate(out)


def _as_ocp(shape, TopoDS_Shape):
    """The OCP TopoDS_Shape inside a build123d object, BuildPart context, CadQuery Workplane/Shape."""
    for attr in ("part", "val"):  # build123d BuildPart has .part; CadQuery Workplane has .val()
        inner = getattr(shape, attr, None)
        if inner is not None and not hasattr(shape, "wrapped"):
            shape = inner() if callable(inner) else inner
    ocp = getattr(shape, "wrapped", shape)
    if not isinstance(ocp, TopoDS_Shape) or ocp.IsNull():
        raise MillpostError(f"stock solid: expected a build123d or CadQuery solid, got {type(shape).__name__}")
    return ocp


def from_shape(shape, cell_mm: float | None = None, *, max_memory_mb: float | None = None) -> Stock:
    """Stock from a build123d / CadQuery / OCP solid, tessellated at a tenth of the cell size."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib
    from OCP.TopoDS import TopoDS_Shape

    box = Bnd_Box()
    BRepBndLib.Add_s(_as_ocp(shape, TopoDS_Shape), box)
    lo, hi = box.CornerMin(), box.CornerMax()
    h = choose_cell((lo.X(), lo.Y()), (hi.X(), hi.Y()), cell_mm, max_memory_mb)
    return from_triangles(shape_triangles(shape, h / 10), h, max_memory_mb=max_memory_mb)


def from_step(path: str | os.PathLike, cell_mm: float | None = None, **kw) -> Stock:
    """Stock from a STEP file (mm)."""
    from build123d import import_step

    if not Path(path).is_file():
        raise MillpostError(f"{path}: no such STEP file")
    try:
        shape = import_step(os.fspath(path))
    except Exception as exc:  # OCCT raises assorted types on bad files
        raise MillpostError(f"{path}: cannot read STEP: {exc}") from exc
    return from_shape(shape, cell_mm, **kw)


def from_python(path: str | os.PathLike, cell_mm: float | None = None, **kw) -> Stock:
    """Stock from a Python file that defines `stock`: a build123d/CadQuery solid or a function
    without arguments returning one."""
    try:
        ns = runpy.run_path(os.fspath(path))
    except (OSError, SyntaxError) as exc:
        raise MillpostError(f"{path}: cannot run stock script: {exc}") from exc
    if "stock" not in ns:
        raise MillpostError(f"{path}: the script must define `stock` (a solid, or a function returning one)")
    obj = ns["stock"]
    return from_shape(obj() if callable(obj) and not hasattr(obj, "wrapped") else obj, cell_mm, **kw)


def load(path: str | os.PathLike, cell_mm: float | None = None, **kw) -> Stock:
    """Stock from a file by its suffix: .stl/.obj/.ply/.off (mesh), .step/.stp, .py."""
    suffix = Path(path).suffix.lower()
    if suffix in (".step", ".stp"):
        return from_step(path, cell_mm, **kw)
    if suffix == ".py":
        return from_python(path, cell_mm, **kw)
    if suffix in (".stl", ".obj", ".ply", ".off", ".glb", ".3mf"):
        return from_stl(path, cell_mm, **kw)
    raise MillpostError(f"{path}: unknown stock file type {suffix!r} (use .stl, .step, .stp or .py)")
