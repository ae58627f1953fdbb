"""Scanline rasteriser: a closed triangle mesh to material intervals along vertical rays through the
cell centres (numba).

Each triangle is tested row by row against the cell centres of its XY projection with exact integer
edge functions (vertices snapped to 1/4096 of a cell) and a tie rule that gives a point on a shared edge
to exactly one of the two triangles. The triangle's plane gives z at the centre, clamped to the
triangle's z range (near-vertical triangles extrapolate badly). Up-facing triangles are where a ray
leaves material, down-facing ones where it enters.
"""

from __future__ import annotations

import numpy as np
from numba import njit

SUB = 4096  # fixed-point subdivisions per cell
MULTI = np.uint8(128)  # flag bit in the per-column crossing count
BUFFER_ROWS = 64  # rows of a triangle's cells buffered at a time (memory: 16 B per cell)


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
def _triangle_cells(tri, x0, y0, h, nx, ny, out_c, out_z, j_from):
    """Cells whose centre lies in the triangle's XY projection, row by row from row j_from (-1: the
    first), until out_c/out_z (at least nx long) would overflow: writes flat ids and z and returns
    (count, up, next row or -1 when done), up +1 for an up-facing triangle, -1 down-facing. On each
    row the inside cells are an interval: its ends are estimated from the edges, widened by a cell
    and trimmed with the exact test."""
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
    for j in range(max(j0, j_from), j1 + 1):
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
            out_z[n] = min(max(z, zmin), zmax)
            n += 1
    return n, up, -1


@njit(cache=True, inline="always")
def _count_crossings(cells, zs, n, up, flat, count, z_floor, tol):
    """First pass over one batch of a triangle's cells: count crossings, raise the Z-map to up-facing
    ones, flag columns entered above the floor."""
    for k in range(n):
        c = cells[k]
        cnt = count[c] & 127
        if cnt < 127:
            count[c] = (count[c] & MULTI) | np.uint8(cnt + 1)
        if up > 0:
            if zs[k] > flat[c]:
                flat[c] = zs[k]
        elif zs[k] > z_floor + tol:
            count[c] |= MULTI


@njit(cache=True)
def first_pass(tris, x0, y0, h, nx, ny, z_floor, tol, top, count):
    """Z-map of the up-facing crossings and per-column crossing counts; the MULTI bit marks columns
    that enter material above z_floor (an undercut or a raised bottom)."""
    cells = np.empty(BUFFER_ROWS * nx, np.int64)
    zs = np.empty(BUFFER_ROWS * nx, np.float64)
    flat = top.reshape(-1)
    for t in range(tris.shape[0]):
        j = -1
        while True:
            n, up, j = _triangle_cells(tris[t], x0, y0, h, nx, ny, cells, zs, j)
            _count_crossings(cells, zs, n, up, flat, count, z_floor, tol)
            if j < 0:
                break


@njit(cache=True)
def second_pass(tris, x0, y0, h, nx, ny, multi_ids, ptr, zc, up_c):
    """Collect every crossing (z, facing) of the multi columns into CSR slots."""
    cells = np.empty(BUFFER_ROWS * nx, np.int64)
    zs = np.empty(BUFFER_ROWS * nx, np.float64)
    fill = ptr[:-1].copy()
    for t in range(tris.shape[0]):
        j = -1
        while True:
            n, up, j = _triangle_cells(tris[t], x0, y0, h, nx, ny, cells, zs, j)
            for k in range(n):
                m = np.searchsorted(multi_ids, cells[k])
                if m < multi_ids.shape[0] and multi_ids[m] == cells[k] and fill[m] < ptr[m + 1]:
                    zc[fill[m]] = zs[k]
                    up_c[fill[m]] = up
                    fill[m] += 1
            if j < 0:
                break


@njit(cache=True)
def intervals_from_crossings(ptr, zc, up_c, out_ptr, lo, hi):
    """Per column: sort crossings by z (entries before exits at equal z), walk up counting inside
    depth, emit non-empty intervals top-down. Returns the number of intervals written."""
    w = 0
    for m in range(ptr.shape[0] - 1):
        a, b = ptr[m], ptr[m + 1]
        out_ptr[m] = w
        key = np.empty(b - a, np.float64)
        for k in range(a, b):
            key[k - a] = zc[k]
        order = np.argsort(key, kind="mergesort")
        # stable sort by z; at equal z put entries (down-facing, -1) first
        n = b - a
        for p in range(1, n):
            q = p
            while q > 0 and zc[a + order[q]] == zc[a + order[q - 1]] and up_c[a + order[q]] < up_c[a + order[q - 1]]:
                order[q], order[q - 1] = order[q - 1], order[q]
                q -= 1
        start = w
        depth = 0
        z_in = 0.0
        for p in range(n):
            k = a + order[p]
            if up_c[k] < 0:
                if depth == 0:
                    z_in = zc[k]
                depth += 1
            elif depth > 0:
                depth -= 1
                if depth == 0 and zc[k] > z_in:
                    lo[w] = z_in
                    hi[w] = zc[k]
                    w += 1
        # reverse this column's intervals to top-down order
        i, j = start, w - 1
        while i < j:
            lo[i], lo[j] = lo[j], lo[i]
            hi[i], hi[j] = hi[j], hi[i]
            i += 1
            j -= 1
    out_ptr[ptr.shape[0] - 1] = w
    return w


@njit(cache=True)
def multi_columns(count):
    """Flat ids of the columns that need intervals: crossing count other than 0 or 2, or MULTI set."""
    n = 0
    for c in range(count.shape[0]):
        k = count[c]
        if (k & MULTI) != 0 or ((k & 127) != 2 and k != 0):
            n += 1
    ids = np.empty(n, np.int64)
    n = 0
    for c in range(count.shape[0]):
        k = count[c]
        if (k & MULTI) != 0 or ((k & 127) != 2 and k != 0):
            ids[n] = c
            n += 1
    return ids


@njit(cache=True)
def tops_from_intervals(flat, multi_ids, out_ptr, hi, z_floor):
    """Z-map of the multi columns: the top of their first (highest) interval, z_floor when empty."""
    for m in range(multi_ids.shape[0]):
        flat[multi_ids[m]] = hi[out_ptr[m]] if out_ptr[m + 1] > out_ptr[m] else z_floor
