"""The stock as a height field with sparse gaps (a Z-map with a dexel overflow).

Cells are square, `cell_mm` wide, cell (i, j) has its centre at (x0 + (i + ½)h, y0 + (j + ½)h).
Most columns hold one interval of material [z_floor, top]; columns with undercuts (a horizontal
hole, an overhang, a bottom above z_floor) are "multi" columns whose material is [z_floor, top] less
the gaps listed for them in a CSR list (sorted top-down). A vertical 3-axis cutter only lowers tops
(into the bottom of a gap when the cut ends inside one): the gaps never change and nothing is
allocated while cutting. Memory: 4 B a column for the top, 3/16 B for the index of the multi
columns, 12 B per gap (one per hole a column crosses).

Heights are stored relative to the stock's own origin z0 (a block's top face; a mesh's largest
up-facing face), in an array whose memory the OS commits page by page when first written (`zeroed`):
a column still at z0 stores 0, so the top of an uncut block costs no memory until the tool reaches
it (a page holds 512 K columns, 2 MiB, where the system has huge pages; else 1024, 4 KiB).
"""

from __future__ import annotations

import math
import mmap
import os
from dataclasses import dataclass

import numpy as np

from .._kernels.columns import gaps_length, is_multi, multi_index
from ..errors import MillpostError
from ..files import atomic_path

DEFAULT_CELL_MM = 0.025
BYTES_PER_CELL = 4 + 1 + 3 / 16  # float32 top + the builder's uint8 crossing count + the multi index


@dataclass
class Stock:
    """Material as columns over a regular XY grid (mm).

    z0: the origin of the stored heights (mm): top, z_floor and the gaps are heights above z0 (absolute
    z = z0 + stored; float32 resolution is that of the height above z0). z_max, bounds and intervals
    give absolute heights.
    top: (ny, nx) float32 top of material per column (z_floor for an empty column).
    multi_bits: int64 words, bit c & 63 of word c >> 6 set for the multi columns (flat id c = j·nx + i),
    the columns with other than one [z_floor, top] interval (one word when there are none).
    multi_rank: int32 per word, the multi columns in the words before it; column c is multi column
    m = multi_rank[c >> 6] + (set bits of its word below c).
    gap_ptr: int32 CSR pointers (multi columns + 1) into gap_lo/gap_hi (float32 bottoms/tops of the
    empty z ranges of each multi column, top-down; those above its top no longer matter).
    """

    x0: float
    y0: float
    cell_mm: float
    z_floor: float
    top: np.ndarray
    multi_bits: np.ndarray
    multi_rank: np.ndarray
    gap_ptr: np.ndarray
    gap_lo: np.ndarray
    gap_hi: np.ndarray
    z0: float = 0.0

    @property
    def ny(self) -> int:
        return self.top.shape[0]

    @property
    def nx(self) -> int:
        return self.top.shape[1]

    @property
    def n_multi(self) -> int:
        return len(self.gap_ptr) - 1

    @property
    def z_max(self) -> float:
        """Highest material in the stock now (mm)."""
        return self.z0 + float(self.top.max())

    def bounds(self) -> np.ndarray:
        """[[xmin, ymin, zfloor], [xmax, ymax, zmax]] of the grid (mm)."""
        return np.array([[self.x0, self.y0, self.z0 + self.z_floor],
                         [self.x0 + self.nx * self.cell_mm, self.y0 + self.ny * self.cell_mm, self.z_max]])

    def volume_mm3(self) -> float:
        """Material volume: column lengths times the cell area (mm³)."""
        h2 = self.cell_mm ** 2
        length = float(np.sum(self.top, dtype=np.float64)) - self.top.size * self.z_floor
        if self.n_multi:
            length -= gaps_length(self.top.reshape(-1), self.z_floor, self.multi_bits, self.multi_rank, self.gap_ptr,
                                  self.gap_lo, self.gap_hi)
        return length * h2

    def intervals(self, i: int, j: int) -> list[tuple[float, float]]:
        """Material intervals (bottom, top) of column (i, j), top-down, in absolute z; empty ones left out."""
        c = j * self.nx + i
        out, t = [], float(self.top[j, i])
        if self.n_multi and is_multi(c, self.multi_bits):
            m = int(multi_index(c, self.multi_bits, self.multi_rank))
            for lo, hi in zip(self.gap_lo[self.gap_ptr[m]:self.gap_ptr[m + 1]],
                              self.gap_hi[self.gap_ptr[m]:self.gap_ptr[m + 1]]):
                if lo < t:
                    out.append((float(hi), t))
                    t = float(lo)
        out.append((self.z_floor, t))
        return [(self.z0 + lo, self.z0 + hi) for lo, hi in out if hi > lo]

    def cell_centres(self) -> tuple[np.ndarray, np.ndarray]:
        """x of the column centres (nx,) and y of the row centres (ny,), mm."""
        h = self.cell_mm
        return self.x0 + (np.arange(self.nx) + 0.5) * h, self.y0 + (np.arange(self.ny) + 0.5) * h

    def copy(self) -> "Stock":
        """An independent copy (its top commits memory only for the rows that are not all z0)."""
        top = zeroed(self.top.shape)
        for j0 in range(0, self.ny, 256):  # 256 rows at a time: the any() temporary stays small
            rows = j0 + np.flatnonzero(self.top[j0:j0 + 256].any(axis=1))
            top[rows] = self.top[rows]
        return Stock(self.x0, self.y0, self.cell_mm, self.z_floor, top, self.multi_bits.copy(),
                     self.multi_rank.copy(), self.gap_ptr.copy(), self.gap_lo.copy(), self.gap_hi.copy(), self.z0)

    def export_stl(self, path: str | os.PathLike, max_cells: int = 1_000_000) -> None:
        """Write the height field as a closed binary STL (mm): top surface through the column tops,
        vertical skirt and a flat bottom at z_floor. Columns are block-maximum-pooled so at most
        about `max_cells` remain; undercut intervals below the top are not drawn."""
        f = max(1, math.ceil(math.sqrt(self.top.size / max_cells)))
        ny, nx = -(-self.ny // f), -(-self.nx // f)
        pad = np.full((ny * f, nx * f), self.z_floor, np.float32)
        pad[: self.ny, : self.nx] = self.top
        z = self.z0 + pad.reshape(ny, f, nx, f).max(axis=(1, 3)).astype(np.float64)
        tris = _heightfield_triangles(z, self.x0, self.y0, self.cell_mm * f, self.z0 + self.z_floor)
        _write_binary_stl(path, tris)


def _heightfield_triangles(z: np.ndarray, x0: float, y0: float, h: float, zf: float) -> np.ndarray:
    """Triangles (n, 3, 3) of a closed solid: vertices at block centres on top, a skirt down to zf
    along the outer ring of centres, and a bottom face. Outward normals (counter-clockwise)."""
    ny, nx = z.shape
    xs = x0 + (np.arange(nx) + 0.5) * h
    ys = y0 + (np.arange(ny) + 0.5) * h
    X, Y = np.meshgrid(xs, ys)
    P = np.stack([X, Y, z], axis=-1)
    a, b, c, d = P[:-1, :-1], P[:-1, 1:], P[1:, 1:], P[1:, :-1]
    top = np.concatenate([np.stack([a, b, c], -2).reshape(-1, 3, 3), np.stack([a, c, d], -2).reshape(-1, 3, 3)])
    # outer ring of top vertices, counter-clockwise seen from above
    ring = np.concatenate([P[0, :], P[1:, -1], P[-1, -2::-1], P[-2:0:-1, 0]])
    nxt = np.roll(ring, -1, axis=0)
    low, low_n = ring.copy(), nxt.copy()
    low[:, 2] = zf
    low_n[:, 2] = zf
    skirt = np.concatenate([np.stack([ring, low, low_n], 1), np.stack([ring, low_n, nxt], 1)])
    ctr = np.array([[xs.mean(), ys.mean(), zf]])
    bottom = np.stack([np.repeat(ctr, len(low), 0), low_n, low], 1)
    return np.concatenate([top, skirt, bottom])


def _write_binary_stl(path: str | os.PathLike, tris: np.ndarray) -> None:
    """Binary STL, written whole or not at all."""
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, ln, out=np.zeros_like(n), where=ln > 0)
    rec = np.zeros(len(tris), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"], rec["v"] = n, tris
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fh.write(b"millpost stock".ljust(80, b" "))
        fh.write(np.uint32(len(tris)).tobytes())
        fh.write(rec.tobytes())


def grid_shape(xy_min, xy_max, cell_mm: float) -> tuple[int, int]:
    """(nx, ny) columns covering the XY rectangle at the cell size."""
    w = np.asarray(xy_max, float) - np.asarray(xy_min, float)
    nx, ny = (max(1, math.ceil(v / cell_mm - 1e-6)) for v in w)
    return nx, ny


def choose_cell(xy_min, xy_max, cell_mm: float | None = None, max_memory_mb: float | None = None) -> float:
    """The cell size to use (mm): the requested one if it fits in memory (else a MillpostError saying
    what would fit), or the default 25 µm coarsened just enough to fit when none is requested.

    The limit is `max_memory_mb`, or 80 % of the memory available now.
    """
    if max_memory_mb is None:
        import psutil

        max_memory_mb = 0.8 * psutil.virtual_memory().available / 2**20
    area = float(np.prod(np.asarray(xy_max, float) - np.asarray(xy_min, float)))
    need = lambda h: area / h**2 * BYTES_PER_CELL / 2**20  # noqa: E731
    fit = math.sqrt(area * BYTES_PER_CELL / 2**20 / max_memory_mb)
    if cell_mm is None:
        return max(DEFAULT_CELL_MM, math.ceil(fit * 1e4) / 1e4)
    if not (math.isfinite(cell_mm) and cell_mm > 0):
        raise MillpostError(f"stock cell size {cell_mm!r} mm: must be > 0")
    if need(cell_mm) > max_memory_mb:
        raise MillpostError(
            f"a stock grid of {area:.0f} mm² at {cell_mm * 1000:g} µm cells needs {need(cell_mm):.0f} MiB, "
            f"more than the {max_memory_mb:.0f} MiB allowed; use a cell of at least {fit * 1000:.1f} µm")
    return cell_mm


def zeroed(shape: tuple[int, ...], dtype=np.float32) -> np.ndarray:
    """A zero-filled array in a private anonymous memory map of its own: the OS commits a page when it is
    first written (reading an untouched page commits nothing), whatever the allocator would do with a
    request of that size. Pages of 2 MiB where the system has them (4 KiB otherwise: a fault for each)."""
    dtype = np.dtype(dtype)
    n = math.prod(shape)
    private = dict(flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS) if hasattr(mmap, "MAP_PRIVATE") else {}
    buf = mmap.mmap(-1, max(1, n * dtype.itemsize), **private)  # not shared: unread pages map the zero page
    try:  # 2 MiB pages where the system has them: 1/512 of the page faults, and fewer TLB misses
        buf.madvise(mmap.MADV_HUGEPAGE)
    except (AttributeError, OSError):  # not Linux, or a kernel without transparent huge pages
        pass
    return np.frombuffer(buf, dtype, count=n).reshape(shape)


def multi_index_arrays(n_columns: int) -> tuple[np.ndarray, np.ndarray]:
    """Zeroed multi_bits and multi_rank for a grid of n_columns (at least one word)."""
    words = max(1, -(-n_columns // 64))
    return np.zeros(words, np.int64), np.zeros(words, np.int32)


def empty_multi() -> dict:
    """The gap fields of a stock without undercuts."""
    bits, rank = multi_index_arrays(0)
    return dict(multi_bits=bits, multi_rank=rank, gap_ptr=np.zeros(1, np.int32), gap_lo=np.zeros(0, np.float32),
                gap_hi=np.zeros(0, np.float32))


def box(lo, hi, cell_mm: float | None = None, *, max_memory_mb: float | None = None) -> Stock:
    """An axis-aligned block from corner lo = (x, y, z) to hi (mm), its heights stored above z0 = its top.
    Columns whose centre falls outside the block (the last row/column when the size is not a multiple of
    the cell) are left empty."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    if lo.shape != (3,) or hi.shape != (3,) or not np.all(hi > lo):
        raise MillpostError(f"stock box {lo.tolist()}..{hi.tolist()}: needs 3 coordinates each and max > min")
    h = choose_cell(lo[:2], hi[:2], cell_mm, max_memory_mb)
    nx, ny = grid_shape(lo[:2], hi[:2], h)
    top = zeroed((ny, nx))
    zf = float(lo[2] - hi[2])
    xs = lo[0] + (np.arange(nx) + 0.5) * h
    ys = lo[1] + (np.arange(ny) + 0.5) * h
    top[:, xs > hi[0]] = zf
    top[ys > hi[1], :] = zf
    return Stock(float(lo[0]), float(lo[1]), h, zf, top, **empty_multi(), z0=float(hi[2]))
