"""Scanline rasteriser: a closed triangle mesh to material intervals along vertical rays through the
cell centres (numba).

Each triangle is tested row by row against the cell centres of its XY projection with exact integer
edge functions (vertices snapped to 1/4096 of a cell) and a tie rule that gives a point on a shared edge
to exactly one of the two triangles. The triangle's plane gives z at the centre, clamped to the
triangle's z range (near-vertical triangles extrapolate badly). Up-facing triangles are where a ray
leaves material, down-facing ones where it enters. Heights are stored above the stock's z0 (see
`millpost.stock.grid`): a top left at 0 is never written, so its memory page is not committed.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .columns import is_multi, multi_index, ranks

SUB = 4096  # fixed-point subdivisions per cell
MULTI = np.uint8(128)  # flag in the per-column crossing count: the column enters material above the floor
UP = np.uint8(64)  # flag: an up-facing crossing was seen (the top holds one)
COUNT = np.uint8(63)  # the count's bits: it saturates there (a column crossing more is refused)
BUFFER_ROWS = 16  # grid rows buffered at a time (16 B a cell, 12 B a multi column, 5 B a crossing)


@njit(cache=True, inline="always")
def _inside(e: np.int64, dx: np.int64, dy: np.int64) -> bool:
    """Edge function e > 0 is inside; on the edge (e == 0) only one of two opposite edges wins."""
    if e > 0:
        return True
    if e < 0:
        return False
    return dy > 0 or (dy == 0 and dx < 0)


@njit(cache=True, inline="always")
def _in_triangle(ax, ay, bx, by, cx, cy, px, py) -> bool:
    return (_inside((bx - ax) * (py - ay) - (by - ay) * (px - ax), bx - ax, by - ay)
            and _inside((cx - bx) * (py - by) - (cy - by) * (px - bx), cx - bx, cy - by)
            and _inside((ax - cx) * (py - cy) - (ay - cy) * (px - cx), ax - cx, ay - cy))


@njit(cache=True)
def _triangle_cells(tri, x0, y0, h, nx, ny, z0, out_c, out_z, j_from, j_to):
    """Cells whose centre lies in the triangle's XY projection, on rows j_from..j_to-1 (j_from = -1:
    from the first), until out_c/out_z (at least nx long) would overflow: writes flat ids and z (rounded
    to float32, then less the stock's z0: the height it stores) and returns (count, up, next row or -1
    when done), up +1 for an up-facing triangle, -1 down-facing. On each row the inside cells are an
    interval: its ends are estimated from the edges, widened by a cell and trimmed with the exact test."""
    X = np.empty(3, np.int64)
    Y = np.empty(3, np.int64)
    for v in range(3):
        X[v] = np.int64(np.round((tri[v, 0] - x0) / h * SUB))
        Y[v] = np.int64(np.round((tri[v, 1] - y0) / h * SUB))
    area = (X[1] - X[0]) * (Y[2] - Y[0]) - (Y[1] - Y[0]) * (X[2] - X[0])
    if area == 0:
        return 0, 0, -1
    up = 1 if area > 0 else -1
    if area < 0:  # counter-clockwise order for the edge functions
        X[1], X[2] = X[2], X[1]
        Y[1], Y[2] = Y[2], Y[1]
    ax, ay, bx, by, cx, cy = X[0], Y[0], X[1], Y[1], X[2], Y[2]
    # plane z(x, y) in mm
    ux, uy, uz = tri[1, 0] - tri[0, 0], tri[1, 1] - tri[0, 1], tri[1, 2] - tri[0, 2]
    vx, vy, vz = tri[2, 0] - tri[0, 0], tri[2, 1] - tri[0, 1], tri[2, 2] - tri[0, 2]
    nxp, nyp, nzp = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    zmin = min(tri[0, 2], min(tri[1, 2], tri[2, 2]))
    zmax = max(tri[0, 2], max(tri[1, 2], tri[2, 2]))
    half = SUB // 2
    i0 = max(0, -((-(min(ax, min(bx, cx)) - half)) // SUB))
    i1 = min(nx - 1, (max(ax, max(bx, cx)) - half) // SUB)
    j0 = max(0, -((-(min(ay, min(by, cy)) - half)) // SUB))
    j1 = min(ny - 1, (max(ay, max(by, cy)) - half) // SUB)
    n = 0
    cap = out_c.shape[0]
    for j in range(max(j0, j_from), min(j1, j_to - 1) + 1):
        if n + (i1 - i0 + 1) > cap:
            return n, up, j
        py = j * SUB + half
        yc = y0 + (j + 0.5) * h
        # x range where all three edge functions are >= 0 on this row (floating estimate)
        xl, xh = -1e300, 1e300
        for e in range(3):
            ex0, ey0 = X[e], Y[e]
            dx, dy = X[(e + 1) % 3] - ex0, Y[(e + 1) % 3] - ey0
            if dy != 0:  # inside: dx·(py − ey0) − dy·(px − ex0) ≥ 0
                xe = ex0 + dx * (py - ey0) / dy
                if dy > 0:
                    xh = min(xh, xe)
                else:
                    xl = max(xl, xe)
            elif dx * (py - ey0) < 0:
                xl, xh = 1e300, -1e300
        if xl > xh + SUB:
            continue
        lo_i = max(i0, int(np.floor((max(xl, -1e18) - half) / SUB)) - 1)
        hi_i = min(i1, int(np.ceil((min(xh, 1e18) - half) / SUB)) + 1)
        while lo_i <= hi_i and not _in_triangle(ax, ay, bx, by, cx, cy, lo_i * SUB + half, py):
            lo_i += 1
        while hi_i >= lo_i and not _in_triangle(ax, ay, bx, by, cx, cy, hi_i * SUB + half, py):
            hi_i -= 1
        for i in range(lo_i, hi_i + 1):
            xc = x0 + (i + 0.5) * h
            z = tri[0, 2] - (nxp * (xc - tri[0, 0]) + nyp * (yc - tri[0, 1])) / nzp
            out_c[n] = j * nx + i
            out_z[n] = np.float64(np.float32(min(max(z, zmin), zmax))) - z0  # float32 z, then above z0
            n += 1
    return n, up, -1


@njit(cache=True, inline="always")
def _count_crossings(cells, zs, n, up, flat, count, z_floor, tol):
    """First pass over one batch of a triangle's cells: count crossings, raise the Z-map to up-facing
    ones (the first one seen replaces the zero the top starts with), flag columns entered above the
    floor. A top that keeps its value is not written (its page stays uncommitted)."""
    for k in range(n):
        c = cells[k]
        cnt = count[c] & COUNT
        if cnt < COUNT:
            count[c] = (count[c] & (MULTI | UP)) | np.uint8(cnt + 1)
        if up > 0:
            z = np.float32(zs[k])
            if (count[c] & UP) == 0 or z > flat[c]:
                if flat[c] != z:
                    flat[c] = z
                count[c] |= UP
        elif zs[k] > z_floor + tol:
            count[c] |= MULTI


@njit(cache=True)
def first_pass(tris, x0, y0, h, nx, ny, z0, z_floor, tol, top, count):
    """Z-map of the up-facing crossings and per-column crossing counts (top: zeros on entry); the
    MULTI bit marks columns that enter material above z_floor (an undercut or a raised bottom), UP
    those whose top holds an up-facing crossing."""
    cells = np.empty(BUFFER_ROWS * nx, np.int64)
    zs = np.empty(BUFFER_ROWS * nx, np.float64)
    flat = top.reshape(-1)
    for t in range(tris.shape[0]):
        j = -1
        while True:
            n, up, j = _triangle_cells(tris[t], x0, y0, h, nx, ny, z0, cells, zs, j, ny)
            _count_crossings(cells, zs, n, up, flat, count, z_floor, tol)
            if j < 0:
                break


@njit(cache=True)
def multi_gaps(tris, x0, y0, h, nx, ny, z0, z_floor, bits, rank, ptr, lo, hi, top):
    """Gaps and tops of the multi columns, BUFFER_ROWS rows of the grid at a time (only one band's
    crossings are held: 5 B each). On entry ptr[m + 1] is multi column m's crossing count (capped as
    in `first_pass`); on return ptr holds the CSR pointers of its gaps in lo/hi (top-down per column),
    top (flat) its top, and the number of gaps is returned."""
    nt = tris.shape[0]
    nm = ptr.shape[0] - 1
    band = min(BUFFER_ROWS, ny)
    cells = np.empty(band * nx, np.int64)
    zs = np.empty(band * nx, np.float64)
    # rows each triangle can touch (a cell centre row beyond its y extent cannot be inside it)
    t_lo = np.empty(nt, np.int64)
    t_hi = np.empty(nt, np.int64)
    for t in range(nt):
        ya = min(tris[t, 0, 1], min(tris[t, 1, 1], tris[t, 2, 1]))
        yb = max(tris[t, 0, 1], max(tris[t, 1, 1], tris[t, 2, 1]))
        t_lo[t] = int(math.floor((ya - y0) / h - 0.5))
        t_hi[t] = int(math.ceil((yb - y0) / h - 0.5))
    w = 0
    m0 = 0
    for ja in range(0, ny, band):
        jb = min(ny, ja + band)
        m1 = nm if jb == ny else multi_index(jb * nx, bits, rank)
        if m1 == m0:
            continue
        lptr = np.empty(m1 - m0 + 1, np.int64)
        lptr[0] = 0
        for m in range(m0, m1):
            lptr[m - m0 + 1] = lptr[m - m0] + ptr[m + 1]
        fill = lptr[:-1].copy()
        zc = np.empty(lptr[-1], np.float32)  # the stock's own precision
        up_c = np.empty(lptr[-1], np.int8)
        for t in range(nt):
            if t_hi[t] < ja or t_lo[t] >= jb:
                continue
            n, up, _ = _triangle_cells(tris[t], x0, y0, h, nx, ny, z0, cells, zs, ja, jb)
            for k in range(n):
                c = cells[k]
                if is_multi(c, bits):
                    q = multi_index(c, bits, rank) - m0
                    if fill[q] < lptr[q + 1]:
                        zc[fill[q]] = zs[k]
                        up_c[fill[q]] = up
                        fill[q] += 1
        m = m0
        for c in range(ja * nx, jb * nx):
            if is_multi(c, bits):
                ptr[m] = w
                w, t = _column_gaps(zc, up_c, lptr[m - m0], lptr[m - m0 + 1], lo, hi, w, z_floor)
                if top[c] != t:
                    top[c] = t
                m += 1
        m0 = m1
    ptr[nm] = w
    return w


@njit(cache=True)
def _column_gaps(zc, up_c, a, b, lo, hi, w, z_floor):
    """One column's crossings zc[a:b] (facing up_c) to its gaps lo/hi[w:] (top-down) and top: sort by
    z (at equal z entries, down-facing −1, first), walk up counting the inside depth; the material
    intervals it meets leave the gaps between them (and below the lowest, down to z_floor). Sorts
    zc/up_c[a:b] in place (insertion sort: a column holds fewer than COUNT). Returns (new w, top)."""
    for p in range(a + 1, b):
        z, u = zc[p], up_c[p]
        q = p
        while q > a and (zc[q - 1] > z or (zc[q - 1] == z and up_c[q - 1] > u)):
            zc[q] = zc[q - 1]
            up_c[q] = up_c[q - 1]
            q -= 1
        zc[q] = z
        up_c[q] = u
    start = w
    depth = 0
    below = np.float32(z_floor)  # top of the material below (the floor at first)
    z_in = np.float32(0.0)
    for k in range(a, b):
        if up_c[k] < 0:
            if depth == 0:
                z_in = zc[k]
            depth += 1
        elif depth > 0:
            depth -= 1
            if depth == 0 and zc[k] > z_in:
                if z_in > below:
                    lo[w] = below
                    hi[w] = z_in
                    w += 1
                below = zc[k]
    i, j = start, w - 1
    while i < j:
        lo[i], lo[j] = lo[j], lo[i]
        hi[i], hi[j] = hi[j], hi[i]
        i += 1
        j -= 1
    return w, below


@njit(cache=True)
def multi_columns(count, bits, rank, top, z_floor):
    """Mark in `bits` (zeroed; see `millpost._kernels.columns`) the columns that need gaps: crossing
    count other than 0 or 2, or MULTI set; fill `rank`; set the top of the columns without an up-facing
    crossing to z_floor. Returns ptr (int32, multi columns + 1) with each multi column's crossing count
    at ptr[m + 1], the sum of those counts, and a column whose count saturated (-1: none)."""
    full = -1
    for c in range(count.shape[0]):
        k = count[c]
        if (k & UP) == 0 and top[c] != z_floor:
            top[c] = z_floor
        if (k & COUNT) == COUNT:
            full = c
        if (k & MULTI) != 0 or ((k & COUNT) != 2 and (k & COUNT) != 0):
            bits[c >> 6] |= np.int64(1) << (c & 63)
    n = ranks(bits, rank)
    ptr = np.zeros(n + 1, np.int32)
    total = 0
    m = 0
    for c in range(count.shape[0]):
        if is_multi(c, bits):
            ptr[m + 1] = count[c] & COUNT
            total += ptr[m + 1]
            m += 1
    return ptr, total, full
