"""Stepping kernel (numba): move a rotationally symmetric cutter through the stock sample by sample.

Per step (sample k, tool tip p_k, coming from p_{k-1}):

1. Footprint update: every column under the tool is cut down to the tool surface
   z_tip + height(r). Only columns that can still lose material are visited: for a flat end mill
   moving level or up, the crescent outside the previous disk; for other shapes, the half-plane
   of columns nearer the new centre than the old one; the full disk when descending or starting.
   Removed volume (column length × cell area) and the axial depth ap (deepest column cut) follow.
2. Ring sampling of the updated stock on a ring centred a look-ahead distance further along the
   path (so the thin fresh crescent near the arc's tangent ends is not yet cut), at K axial slices over
   [0, ap] (`_layout`: the flat stock levels the flank's ring meets inside the depth are slice
   boundaries, else ap/K each): material inside slice k along the vertical line at
   immersion φ ∈ [0, π] (Altintas: φ clockwise from +y = left of feed, x = feed) decides whether
   the slice is engaged there (more than half the slice filled). Coarse samples find the arcs,
   bisection places each transition; the swept cross-section ∫ r sin φ · m(φ) dφ follows.
3. End band (descending feed steps only, read before the cut): per radial bin of the tool's end, the
   share of its columns whose band [surface, surface + drop] just above the new tool surface holds
   material: where the end edges cut a full axial feed (`_end_band`).
4. Clearance (feed steps that cut nothing): whether the tool is in the shell of width c around the
   stock as loaded (`_near_original`): the tool grown by c (radius R + c, tip c lower) meets the
   original stock and its tip disc is not inside it, read from a coarse snapshot of the original
   column tops (per block of columns their maximum and minimum, `block_range`). And whether such a
   step lies in space the tool itself has swept (`_in_swept`), read from a coarse swept field that
   every feed step lowers (`_sweep_record`): per cell the lowest tool surface that covered it whole.

Tool shapes: 0 flat, 1 corner radius (ball when rc = R, bull otherwise), 2 chamfer or drill (a cone).
These closed forms mirror `millpost.tools.Tool.height_at` / `radius_at` (tests check they agree).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .columns import gap_overlap, is_multi, multi_index

FLAT, CORNER, CHAMFER = 0, 1, 2
OK = -1
BAND, WEDGE, CAP = 0, 1, 2  # parts of a level sweep (see _region); CAP is also any disk
BISECT = 8  # transition refinement: coarse step / 2**8
LEVEL_TOL = 0.01  # stock levels closer than this fraction of ap (to each other, to the tip or to ap) are one
PLATEAU_MM = 1e-6  # adjacent ring heights this close are a flat level


@njit(cache=True, inline="always", error_model="numpy")
def surface_height(r, shape, R, rc, r_tip, tan_half):
    """Height of the cutting surface above the tip at radius r ≤ R (mm)."""
    if shape == CORNER:
        x = r - (R - rc)
        if x <= 0.0:
            return 0.0
        return rc - math.sqrt(max(rc * rc - x * x, 0.0))
    if shape == CHAMFER:
        return max(r - r_tip, 0.0) / tan_half
    return 0.0


@njit(cache=True, inline="always", error_model="numpy")
def profile_radius(z, shape, R, rc, r_tip, tan_half):
    """Cutting radius at height z ≥ 0 above the tip (mm)."""
    if shape == CORNER:
        d = rc - z
        if d <= 0.0:
            return R
        return (R - rc) + math.sqrt(max(rc * rc - d * d, 0.0))
    if shape == CHAMFER:
        return min(r_tip + z * tan_half, R)
    return R


@njit(cache=True, inline="always", error_model="numpy")
def _flank_foot(shape, R, rc, r_tip, tan_half):
    """Height above the tip (mm) from which the cutting radius is R (the vertical flank's foot)."""
    if shape == CORNER:
        return rc
    if shape == CHAMFER:
        return (R - r_tip) / tan_half
    return 0.0


@njit(cache=True, error_model="numpy")
def _profile_integral(za, zb, shape, R, rc, r_tip, tan_half):
    """∫ r(z) dz over [za, zb] (mm²), composite Simpson on 32 intervals."""
    n = 32
    w = (zb - za) / n
    s = profile_radius(za, shape, R, rc, r_tip, tan_half) + profile_radius(zb, shape, R, rc, r_tip, tan_half)
    for i in range(1, n):
        s += (4.0 if i % 2 else 2.0) * profile_radius(za + i * w, shape, R, rc, r_tip, tan_half)
    return s * w / 3.0


@njit(cache=True, inline="always", error_model="numpy")
def _is_multi(c, has_multi, bits):
    return has_multi and is_multi(c, bits)


@njit(cache=True, error_model="numpy")
def _cut_multi(c, zc, top, zf, bits, rank, ptr, lo, hi):
    """Cut multi column c (top above zc) down to zc: its top drops to zc, or to the bottom of the gap
    zc falls in (the gaps themselves do not change); returns the removed length."""
    t = top[c]
    nt = np.float32(max(zc, zf))
    m = multi_index(c, bits, rank)
    rem = (t - nt) - gap_overlap(m, nt, t, ptr, lo, hi)
    for k in range(ptr[m], ptr[m + 1]):
        if lo[k] < nt <= hi[k]:
            nt = lo[k]
            break
    top[c] = nt
    return rem


@njit(cache=True, error_model="numpy")
def _above(c, zc, top, zf, has_multi, bits, rank, ptr, lo, hi):
    """Length of material above zc in column c (mm), without cutting (a column cut down to the
    floor zf holds none)."""
    t = top[c]
    if zc >= t or t <= zf:
        return 0.0
    za = max(zc, zf)
    if _is_multi(c, has_multi, bits):
        return t - za - gap_overlap(multi_index(c, bits, rank), za, t, ptr, lo, hi)
    return t - za


@njit(cache=True, inline="always", error_model="numpy")
def _column(c, zc, pz, cut, top, zf, has_multi, bits, rank, ptr, lo, hi, tol):
    """One column under the tool surface at zc (tool tip at pz): cut it down (cut) and return
    (height removed, axial depth reached, False), or only test it and return (0, 0, whether
    material stands above zc by more than tol: a crash for a rapid)."""
    t = top[c]
    if zc >= t:
        return 0.0, 0.0, False
    if not cut:
        return 0.0, 0.0, _above(c, zc, top, zf, has_multi, bits, rank, ptr, lo, hi) > tol
    if _is_multi(c, has_multi, bits):
        r = _cut_multi(c, zc, top, zf, bits, rank, ptr, lo, hi)
    else:
        top[c] = max(zc, zf)
        r = t - top[c]
    return r, (t - pz if r > 0.0 else 0.0), False


@njit(cache=True, inline="always", error_model="numpy")
def _tool_z(kind, dx, dy, fx, fy, pz, shape, R, rc, r_tip, tan_half):
    """Height (mm) of the tool surface over a column at (dx, dy) from the axis point (tip at pz):
    radial distance, or for a BAND the distance across the sweep direction f; inf beyond R."""
    d = abs(dy * fx - dx * fy) if kind == BAND else math.sqrt(dx * dx + dy * dy)
    if d > R:
        return math.inf
    return pz if shape == FLAT else pz + surface_height(d, shape, R, rc, r_tip, tan_half)


@njit(cache=True, inline="always", error_model="numpy")
def _cut_row(row, i0, i1, kind, cx, dy, fx, fy, pz, x0, h, shape, R, rc, r_tip, tan_half, top, zf):
    """Columns row+i0..row+i1 of a stock without undercuts cut down to the tool: (removed, depth)."""
    if shape == FLAT and kind == CAP:
        return _cut_level(row, i0, i1, pz, top, zf)
    rem = 0.0
    ap = 0.0
    for i in range(i0, i1 + 1):
        zc = _tool_z(kind, x0 + (i + 0.5) * h - cx, dy, fx, fy, pz, shape, R, rc, r_tip, tan_half)
        c = row + i
        t = top[c]
        if zc < t:
            nt = max(zc, zf)
            top[c] = nt
            if t > nt:
                rem += t - nt
                ap = max(ap, t - pz)
    return rem, ap


@njit(cache=True, inline="always", error_model="numpy")
def _cut_level(row, i0, i1, pz, top, zf):
    """`_cut_row` for a flat end over a row span inside its disk: every column is cut to the same
    height max(pz, zf), without a radius test (branch-free, so the loop vectorises)."""
    zc = max(pz, zf)
    rem = 0.0
    ap = 0.0
    for i in range(row + i0, row + i1 + 1):
        t = top[i]
        nt = min(t, zc)
        top[i] = nt
        rem += t - nt
        ap = max(ap, t - pz if t > nt else 0.0)
    return rem, ap


@njit(cache=True, inline="always", error_model="numpy")
def _visit_row(row, i0, i1, kind, cx, dy, fx, fy, pz, cut, x0, h, shape, R, rc, r_tip, tan_half, top, zf,
               has_multi, bits, rank, ptr, lo, hi, tol, rem, ap):
    """One row of columns under the tool: cut (or, for a rapid, check) them. Adds to the removed
    length sum `rem` and the deepest cut below the old top `ap`; returns (rem, ap, crash). The common
    case — cutting a stock without undercuts — runs in its own loop: gap code in the same loop,
    even never run, makes it ~20× slower."""
    if cut and not has_multi:
        r, a = _cut_row(row, i0, i1, kind, cx, dy, fx, fy, pz, x0, h, shape, R, rc, r_tip, tan_half, top, zf)
        return rem + r, max(ap, a), False
    for i in range(i0, i1 + 1):
        zc = _tool_z(kind, x0 + (i + 0.5) * h - cx, dy, fx, fy, pz, shape, R, rc, r_tip, tan_half)
        r, depth, crash = _column(row + i, zc, pz, cut, top, zf, has_multi, bits, rank, ptr, lo, hi, tol)
        if crash:
            return rem, ap, True
        rem += r
        ap = max(ap, depth)
    return rem, ap, False


@njit(cache=True, inline="always", error_model="numpy")
def _material(c, za, zb, top, zf, has_multi, bits, rank, ptr, lo, hi):
    """Material length of column c inside [za, zb] (mm); c < 0 is outside the grid (air)."""
    if c < 0:
        return 0.0
    if _is_multi(c, has_multi, bits):
        za, zb = max(zf, za), min(np.float64(top[c]), zb)
        if zb <= za:
            return 0.0
        return zb - za - gap_overlap(multi_index(c, bits, rank), za, zb, ptr, lo, hi)
    return max(min(top[c], zb) - max(zf, za), 0.0)


@njit(cache=True, error_model="numpy")
def _end_band(px, py, pz, drop, R, shape, rc, r_tip, tan_half, top, nx, ny, x0, y0, h, zf, has_multi, bits, rank,
              ptr, lo, hi, out):
    """The tool's end on a descending step (tip now at pz, `drop` mm lower than before): per radial bin
    j of [0, R] (J = len(out) equal bins), the mean over the bin's columns of the material fraction in
    the band [z_s, z_s + drop] just above the tool surface z_s = pz + height(r). That is the share of
    the circle at radius r where the end edges cut a full axial feed (1 when drilling on or re-entering
    the own bottom, 0 over a hole, partial while the tip enters a surface). Read only (before cutting)."""
    J = out.shape[0]
    cnt = np.zeros(J)
    acc = np.zeros(J)  # in float64 whatever out's precision
    j0 = int(math.ceil((py - R - y0) / h - 0.5))
    j1 = int(math.floor((py + R - y0) / h - 0.5))
    for j in range(j0, j1 + 1):
        dy = y0 + (j + 0.5) * h - py
        w2 = R * R - dy * dy
        if w2 < 0.0:
            continue
        w = math.sqrt(w2)
        ia = int(math.ceil((px - w - x0) / h - 0.5))
        ib = int(math.floor((px + w - x0) / h - 0.5))
        for i in range(ia, ib + 1):
            dx = x0 + (i + 0.5) * h - px
            d = math.sqrt(dx * dx + dy * dy)
            b = min(int(d / R * J), J - 1)
            cnt[b] += 1.0
            if 0 <= i < nx and 0 <= j < ny:  # columns off the grid are air
                zs = pz + surface_height(d, shape, R, rc, r_tip, tan_half)
                m = _material(j * nx + i, zs, zs + drop, top, zf, has_multi, bits, rank, ptr, lo, hi)
                acc[b] += min(m / drop, 1.0)
    for b in range(J):
        out[b] = acc[b] / cnt[b] if cnt[b] > 0 else 0.0


@njit(cache=True, error_model="numpy")
def block_range(top, nx, ny, B, zf):
    """Maximum and minimum of the column tops (mm) per block of B × B columns (row-major blocks)."""
    nbx, nby = (nx + B - 1) // B, (ny + B - 1) // B
    hi = np.full(nbx * nby, np.float32(zf), np.float32)
    lo = np.full(nbx * nby, np.float32(np.inf), np.float32)
    for j in range(ny):
        row, base = j * nx, (j // B) * nbx
        for bi in range(nbx):  # a block's span of the row in one loop (no division per column: 2-4x faster)
            m, n = hi[base + bi], lo[base + bi]
            for c in range(row + bi * B, row + min(nx, bi * B + B)):
                m = max(m, top[c])
                n = min(n, top[c])
            hi[base + bi], lo[base + bi] = m, n
    return hi, lo


@njit(cache=True, error_model="numpy")
def _near_original(px, py, pz, R, c, omax, omin, B, nx, ny, x0, y0, h, zf):
    """Whether a tool of radius R (mm) with its tip at (px, py, pz) lies in the shell of width c (mm)
    around the original stock: (a) the tool grown by c (radius R + c, tip c lower, a cylinder) meets
    it, and (b) its tip disc (radius R at pz) is not inside it (not every column within R of the axis
    held material above pz). omax/omin: the original tops' maximum/minimum per block of B × B columns
    (`block_range`); a block is read whole, so both answers err towards near: by up to a block's
    diagonal beside the stock, and inside it within a block of its edge."""
    w = B * h
    nbx, nby = (nx + B - 1) // B, (ny + B - 1) // B
    rc = R + c
    zc = max(pz - c, zf)  # a column at the floor holds no material
    zt = max(pz, zf)
    meets = False
    inside = px - R >= x0 and px + R <= x0 + nx * h and py - R >= y0 and py + R <= y0 + ny * h
    bi0 = min(max(int(math.floor((px - rc - x0) / w)), 0), nbx - 1)
    bi1 = min(max(int(math.floor((px + rc - x0) / w)), 0), nbx - 1)
    bj0 = min(max(int(math.floor((py - rc - y0) / w)), 0), nby - 1)
    bj1 = min(max(int(math.floor((py + rc - y0) / w)), 0), nby - 1)
    for bj in range(bj0, bj1 + 1):
        ddy = max(y0 + bj * w - py, 0.0, py - y0 - min((bj + 1) * B, ny) * h)
        for bi in range(bi0, bi1 + 1):
            ddx = max(x0 + bi * w - px, 0.0, px - x0 - min((bi + 1) * B, nx) * h)
            d2 = ddx * ddx + ddy * ddy
            b = bj * nbx + bi
            if d2 <= rc * rc and omax[b] > zc:
                meets = True
            if d2 < R * R and not omin[b] > zt:
                inside = False
    return meets and not inside


@njit(cache=True, inline="always", error_model="numpy")
def _up32(z):
    """z as the nearest float32 not below it (the swept field's storage: rounding up errs towards
    unknown; a tool height rounded the same way compares equal to its own record)."""
    v = np.float32(z)
    if v < z:
        v = np.nextafter(v, np.float32(np.inf))
    return v


@njit(cache=True, inline="always", error_model="numpy")
def _covered(px, py, R, ya, yb, sx0, W):
    """Span (first, last) of the cells of W mm on the row [ya, yb] that lie wholly inside the disc of
    radius R at (px, py): those whose farthest corner is within R (empty: first > last)."""
    dy = max(abs(ya - py), abs(yb - py))
    if dy > R:
        return 1, 0
    w = math.sqrt(R * R - dy * dy)
    return int(math.ceil((px - w - sx0) / W)), int(math.floor((px + w - sx0) / W)) - 1


@njit(cache=True, error_model="numpy")
def _sweep_record(px, py, pz, qx, qy, skip_q, R, shape, rc, r_tip, tan_half, swept, snx, sny, sx0, sy0, W):
    """Lower the swept field under the tool at tip (px, py, pz): each cell of W × W mm wholly inside the
    tool's disc takes the lower of its value and the tool surface's height at the cell's farthest point
    from the axis (the tool occupied everything above that, over the whole cell). skip_q: a flat end
    not descending from the disc at (qx, qy), whose wholly covered cells hold no more than pz already:
    only the cells outside it are visited."""
    j0 = max(0, int(math.floor((py - R - sy0) / W)))
    j1 = min(sny - 1, int(math.floor((py + R - sy0) / W)))
    for j in range(j0, j1 + 1):
        ya, yb = sy0 + j * W, sy0 + (j + 1) * W
        a, b = _covered(px, py, R, ya, yb, sx0, W)
        a, b = max(a, 0), min(b, snx - 1)
        a1, b1 = 1, 0  # a second range when the disc at q splits the row
        if skip_q:
            qa, qb = _covered(qx, qy, R, ya, yb, sx0, W)
            if qa <= qb:
                a, b, a1, b1 = a, min(b, qa - 1), max(a, qb + 1), b
        dy = max(abs(ya - py), abs(yb - py))
        row = j * snx
        for seg in range(2):
            lo_i, hi_i = (a, b) if seg == 0 else (a1, b1)
            for i in range(lo_i, hi_i + 1):
                z = pz
                if shape != FLAT:
                    dx = max(abs(sx0 + i * W - px), abs(sx0 + (i + 1) * W - px))
                    z += surface_height(min(math.sqrt(dx * dx + dy * dy), R), shape, R, rc, r_tip, tan_half)
                v = _up32(z)
                if v < swept[row + i]:
                    swept[row + i] = v


@njit(cache=True, error_model="numpy")
def _in_swept(px, py, pz, qx, qy, qz, R, shape, rc, r_tip, tan_half, swept, snx, sny, sx0, sy0, W):
    """Whether the tool's sweep from tip q to tip p lies in space the swept field knows as cleared: every
    cell meeting the disc of radius R + L/2 about the step's midpoint (L its horizontal length; the disc
    holds the tool's whole sweep) has a swept height no higher than the tool's lowest surface over it,
    min(qz, pz) + height(d − L/2) with d the cell's nearest distance to the midpoint (both rounded up
    to float32, `_up32`: within a float32 step, < 0.1 µm in 1 m). Cells off the field are not known."""
    mx, my = 0.5 * (px + qx), 0.5 * (py + qy)
    half = 0.5 * math.sqrt((px - qx) * (px - qx) + (py - qy) * (py - qy))
    rr = R + half
    zlow = min(pz, qz)
    if mx - rr < sx0 or my - rr < sy0 or mx + rr > sx0 + snx * W or my + rr > sy0 + sny * W:
        return False
    j0 = max(0, int(math.floor((my - rr - sy0) / W)))
    j1 = min(sny - 1, int(math.floor((my + rr - sy0) / W)))
    for j in range(j0, j1 + 1):
        dy = max(sy0 + j * W - my, 0.0, my - sy0 - (j + 1) * W)
        if dy > rr:
            continue
        w = math.sqrt(rr * rr - dy * dy)
        i0 = max(0, int(math.floor((mx - w - sx0) / W)))
        i1 = min(snx - 1, int(math.floor((mx + w - sx0) / W)))
        row = j * snx
        for i in range(i0, i1 + 1):
            z = zlow
            if shape != FLAT:
                dx = max(sx0 + i * W - mx, 0.0, mx - sx0 - (i + 1) * W)
                d = max(math.sqrt(dx * dx + dy * dy) - half, 0.0)
                z += surface_height(min(d, R), shape, R, rc, r_tip, tan_half)
            if not swept[row + i] <= _up32(z):
                return False
    return True


@njit(cache=True, error_model="numpy")
def _footprint(px, py, pz, qx, qy, mode, cut, R, shape, rc, r_tip, tan_half, top, nx, ny, x0, y0, h, zf,
               has_multi, bits, rank, ptr, lo, hi, tol, spans, rows, spans_at_q):
    """Update (cut=True) or check (cut=False) the columns under the tool at tip (px, py, pz).

    mode 0: full disk; 1: crescent outside the disk at (qx, qy); 2: half-plane nearer to p than q.
    Returns (removed length sum, deepest cut below the old top, crash) in mm.
    spans (ny, 2), rows (2,): each call leaves there the disk's column span (unclipped, empty when
    the row has no centre inside) on its rows rows[0]..rows[1]; with spans_at_q they hold the disk at
    q (the previous step's call), whose spans mode 1 then reads instead of recomputing them.
    """
    rem = 0.0
    ap = 0.0
    # in cell units: column i's centre is at u = i, row j's at v = j; the disk's radius is Rc
    Rc = R / h
    Rc2 = Rc * Rc
    u, v = (px - x0) / h - 0.5, (py - y0) / h - 0.5
    uq, vq = (qx - x0) / h - 0.5, (qy - y0) / h - 0.5
    j0 = max(0, int(math.ceil(v - Rc)))
    j1 = min(ny - 1, int(math.floor(v + Rc)))
    A = 2.0 * (qx - px)
    q_rows0, q_rows1 = rows[0], rows[1]
    rows[0], rows[1] = j0, j1
    for j in range(j0, j1 + 1):
        yc = y0 + (j + 0.5) * h
        dy = yc - py
        w2 = Rc2 - (j - v) * (j - v)
        qa, qb = 1, 0
        if mode == 1:
            if spans_at_q:
                if q_rows0 <= j <= q_rows1:
                    qa, qb = spans[j, 0], spans[j, 1]
            else:
                wq2 = Rc2 - (j - vq) * (j - vq)
                if wq2 >= 0.0:
                    wq = math.sqrt(wq2)
                    qa = int(math.ceil(uq - wq))
                    qb = int(math.floor(uq + wq))
        if w2 < 0.0:
            spans[j, 0], spans[j, 1] = 1, 0
            continue
        w = math.sqrt(w2)
        ia, ib = int(math.ceil(u - w)), int(math.floor(u + w))
        spans[j, 0], spans[j, 1] = ia, ib
        ia, ib = max(0, ia), min(nx - 1, ib)
        # up to two index ranges [a0, b0], [a1, b1] to visit on this row
        a0, b0, a1, b1 = ia, ib, 1, 0
        if mode == 1:
            if qa <= qb:  # outside the disk at q (an empty span leaves the whole row)
                a0, b0 = ia, min(ib, qa - 1)
                a1, b1 = max(ia, qb + 1), ib
        elif mode == 2:
            # columns with |c - p|² < |c - q|²  <=>  x·A < B
            B = (qx * qx - px * px) + (qy * qy - py * py) - 2.0 * yc * (qy - py)
            if A == 0.0:
                if not (B > 0.0):
                    continue
            else:
                xb = (B / A - x0) / h - 0.5
                if A > 0.0:
                    b0 = min(ib, int(math.ceil(xb)) - 1)
                else:
                    a0 = max(ia, int(math.floor(xb)) + 1)
        for seg in range(2):
            lo_i, hi_i = (a0, b0) if seg == 0 else (a1, b1)
            rem, ap, crash = _visit_row(j * nx, lo_i, hi_i, CAP, px, dy, 0.0, 0.0, pz, cut, x0, h, shape, R, rc,
                                        r_tip, tan_half, top, zf, has_multi, bits, rank, ptr, lo, hi, tol, rem, ap)
            if crash:
                return rem, ap, True
    return rem, ap, False


@njit(cache=True, error_model="numpy")
def _ring_cells(cx, cy, fx, fy, r, M, sin_t, cos_t, x0, y0, h, nx, ny, bilinear, cells, wts):
    """Columns (and bilinear weights) under M + 1 ring points at immersion φ_i (sin/cos tables)."""
    for i in range(M + 1):
        _point_cells_sc(cx, cy, fx, fy, r, sin_t[i], cos_t[i], x0, y0, h, nx, ny, bilinear, cells, wts, i)


@njit(cache=True, inline="always", error_model="numpy")
def _point_cells(cx, cy, fx, fy, r, phi, x0, y0, h, nx, ny, bilinear, cells, wts, i):
    _point_cells_sc(cx, cy, fx, fy, r, math.sin(phi), math.cos(phi), x0, y0, h, nx, ny, bilinear, cells, wts, i)


@njit(cache=True, inline="always", error_model="numpy")
def _point_cells_sc(cx, cy, fx, fy, r, s, c, x0, y0, h, nx, ny, bilinear, cells, wts, i):
    # x = feed (fx, fy), y = left normal (-fy, fx); point = centre + r (sin φ x + cos φ y)
    px = cx + r * (s * fx - c * fy)
    py = cy + r * (s * fy + c * fx)
    if bilinear:
        u = (px - x0) / h - 0.5
        v = (py - y0) / h - 0.5
        iu = int(math.floor(u))
        iv = int(math.floor(v))
        wts[i, 0] = u - iu
        wts[i, 1] = v - iv
        for q in range(4):
            ii = iu + (q & 1)
            jj = iv + (q >> 1)
            cells[i, q] = jj * nx + ii if (0 <= ii < nx and 0 <= jj < ny) else -1
    else:
        ii = int(math.floor((px - x0) / h))
        jj = int(math.floor((py - y0) / h))
        cells[i, 0] = jj * nx + ii if (0 <= ii < nx and 0 <= jj < ny) else -1


@njit(cache=True, inline="always", error_model="numpy")
def _ring_height(cells, wts, i, bilinear, top, zf):
    """Height-field top under ring point i (bilinear between the four cell centres, or the cell's);
    z_floor outside the grid."""
    if not bilinear:
        c = cells[i, 0]
        return top[c] if c >= 0 else zf
    wx, wy = wts[i, 0], wts[i, 1]
    c0, c1, c2, c3 = cells[i, 0], cells[i, 1], cells[i, 2], cells[i, 3]
    v0 = top[c0] if c0 >= 0 else zf
    v1 = top[c1] if c1 >= 0 else zf
    v2 = top[c2] if c2 >= 0 else zf
    v3 = top[c3] if c3 >= 0 else zf
    return (1 - wy) * ((1 - wx) * v0 + wx * v1) + wy * ((1 - wx) * v2 + wx * v3)


@njit(cache=True, inline="always", error_model="numpy")
def _plain_material(cells, wts, i, za, zb, bilinear, top, zf):
    """Material length in [za, zb] under ring point i of a stock without undercuts: the slice's
    share of [z_floor, H]."""
    return max(min(_ring_height(cells, wts, i, bilinear, top, zf), zb) - max(zf, za), 0.0)


@njit(cache=True, inline="always", error_model="numpy")
def _ring_material(cells, wts, i, za, zb, bilinear, top, zf, has_multi, bits, rank, ptr, lo, hi):
    if not has_multi:
        return _plain_material(cells, wts, i, za, zb, bilinear, top, zf)
    if not bilinear:
        return _material(cells[i, 0], za, zb, top, zf, has_multi, bits, rank, ptr, lo, hi)
    wx, wy = wts[i, 0], wts[i, 1]
    m00 = _material(cells[i, 0], za, zb, top, zf, has_multi, bits, rank, ptr, lo, hi)
    m10 = _material(cells[i, 1], za, zb, top, zf, has_multi, bits, rank, ptr, lo, hi)
    m01 = _material(cells[i, 2], za, zb, top, zf, has_multi, bits, rank, ptr, lo, hi)
    m11 = _material(cells[i, 3], za, zb, top, zf, has_multi, bits, rank, ptr, lo, hi)
    return (1 - wy) * ((1 - wx) * m00 + wx * m10) + wy * ((1 - wx) * m01 + wx * m11)


@njit(cache=True, inline="always", error_model="numpy")
def _ring_values(cells, wts, M, za, zb, bilinear, grid, mat):
    """mat[i] = material length in [za, zb] under ring point i, i = 0..M. Stock without undercuts
    has a loop of its own: gap code in the loop, even never run, makes it several times slower."""
    top, nx, ny, x0, y0, h, zf, has_multi, bits, rank, ptr, lo, hi = grid
    if not has_multi:
        for i in range(M + 1):
            mat[i] = _plain_material(cells, wts, i, za, zb, bilinear, top, zf)
    else:
        for i in range(M + 1):
            mat[i] = _ring_material(cells, wts, i, za, zb, bilinear, top, zf, has_multi, bits, rank, ptr, lo, hi)


@njit(cache=True, error_model="numpy")
def _bisect(a, b, a_on, cx, cy, fx, fy, r, za, zb, half, x0, y0, h, nx, ny, bilinear, pc, pw,
            top, zf, has_multi, bits, rank, ptr, lo, hi):
    """Transition angle between a (engaged == a_on) and b (the opposite state)."""
    for _ in range(BISECT):
        mid = 0.5 * (a + b)
        _point_cells(cx, cy, fx, fy, r, mid, x0, y0, h, nx, ny, bilinear, pc, pw, 0)
        on = _ring_material(pc, pw, 0, za, zb, bilinear, top, zf, has_multi, bits, rank, ptr, lo, hi) > half
        if on == a_on:
            a = mid
        else:
            b = mid
    return 0.5 * (a + b)



@njit(cache=True, error_model="numpy")
def _bisect_heights(a, b, a_on, tree, known, cx, cy, fx, fy, r, za, zb, half, x0, y0, h, nx, ny, bilinear, pc, pw,
                    top, zf):
    """`_bisect` on stock without undercuts, the ring height at each bisection point kept in `tree`
    (node 1 the midpoint of [a, b], nodes 2n and 2n + 1 those of node n's lower and upper halves;
    `known` marks the ones read): another slice bisecting the same [a, b] reads each point once."""
    node = 1
    for _ in range(BISECT):
        mid = 0.5 * (a + b)
        if not known[node]:
            _point_cells(cx, cy, fx, fy, r, mid, x0, y0, h, nx, ny, bilinear, pc, pw, 0)
            tree[node] = _ring_height(pc, pw, 0, bilinear, top, zf)
            known[node] = True
        on = max(min(tree[node], zb) - max(zf, za), 0.0) > half
        if on == a_on:
            a = mid
            node = 2 * node + 1
        else:
            b = mid
            node = 2 * node
    return 0.5 * (a + b)


@njit(cache=True, inline="always", error_model="numpy")
def _clip(lo, hi, a, b):
    """Narrow [lo, hi] to the x with a·x + b >= 0."""
    if a > 1e-15:
        return max(lo, -b / a), hi
    if a < -1e-15:
        return lo, min(hi, -b / a)
    if b < 0.0:
        return 1.0, 0.0
    return lo, hi



@njit(cache=True, error_model="numpy")
def _region(kind, qx, qy, pz, ex, ey, fx, fy, Ls, cut, R, shape, rc, r_tip, tan_half, top, nx, ny, x0, y0, h, zf,
            has_multi, bits, rank, ptr, lo, hi, tol):
    """Cut (or check) the part of a level tool sweep at height pz (tip) that one step adds.

    BAND: the straight sweep from q along unit f for Ls mm, columns whose foot on the segment lies
    inside it, cut to the tool surface at their lateral distance (exact for a level move).
    WEDGE: at a joint q between a previous direction e and the new f, the columns within R of q
    beyond the previous sweep's end and before the new one's start.
    CAP: the front half disk at q (f forward), where a run of level steps ends.
    Returns (removed length sum, deepest cut below the old top, crash) in mm.
    """
    rem = 0.0
    ap = 0.0
    ylo = qy - R
    yhi = qy + R
    if kind == BAND:
        ylo = min(qy, qy + Ls * fy) - R
        yhi = max(qy, qy + Ls * fy) + R
    j0 = max(0, int(math.ceil((ylo - y0) / h - 0.5)))
    j1 = min(ny - 1, int(math.floor((yhi - y0) / h - 0.5)))
    for j in range(j0, j1 + 1):
        yc = y0 + (j + 0.5) * h
        dy = yc - qy
        xl, xh = -1e300, 1e300
        if kind == BAND:
            # 0 <= (c - q)·f <= Ls and -R <= (c - q)×f <= R
            xl, xh = _clip(xl, xh, fx, dy * fy - qx * fx)
            xl, xh = _clip(xl, xh, -fx, Ls - dy * fy + qx * fx)
            xl, xh = _clip(xl, xh, -fy, R + dy * fx + qx * fy)
            xl, xh = _clip(xl, xh, fy, R - dy * fx - qx * fy)
        else:
            w2 = R * R - dy * dy
            if w2 < 0.0:
                continue
            w = math.sqrt(w2)
            xl, xh = qx - w, qx + w
            if kind == WEDGE:
                xl, xh = _clip(xl, xh, ex, dy * ey - qx * ex)  # (c - q)·e >= 0
                xl, xh = _clip(xl, xh, -fx, -dy * fy + qx * fx)  # (c - q)·f <= 0
            else:
                xl, xh = _clip(xl, xh, fx, dy * fy - qx * fx)
        if xl > xh:
            continue
        i0 = max(0, int(math.ceil((xl - x0) / h - 0.5)))
        i1 = min(nx - 1, int(math.floor((xh - x0) / h - 0.5)))
        rem, ap, crash = _visit_row(j * nx, i0, i1, kind, qx, dy, fx, fy, pz, cut, x0, h, shape, R, rc, r_tip,
                                    tan_half, top, zf, has_multi, bits, rank, ptr, lo, hi, tol, rem, ap)
        if crash:
            return rem, ap, True
    return rem, ap, False


@njit(cache=True, error_model="numpy")
def _level_step(k, n, xyz, fresh, shape):
    """Step k is a level, horizontal move of a non-flat tool (swept as bands, wedges and caps)."""
    if k < 1 or k >= n or fresh[k] or shape == FLAT:
        return False
    dx, dy = xyz[k, 0] - xyz[k - 1, 0], xyz[k, 1] - xyz[k - 1, 1]
    return abs(xyz[k, 2] - xyz[k - 1, 2]) <= 1e-9 and dx * dx + dy * dy > 1e-24


@njit(cache=True, error_model="numpy")
def _ring_slice(k, s, cx, cy, fx, fy, r, za, dzs, flank, rint, M, sin_t, cos_t, cells, wts, pc, pw, mat, g,
                bilinear, grid, phi_st, phi_ex, dz, arc):
    """One axial slice with its own ring (cells already placed): outermost engaged arc refined by
    bisection, engaged measure, and its swept cross-section ∫ sin φ g(φ) dφ, g = r·(material in the
    slice) on a vertical flank, else the slice's ∫ r dz where engaged (the column at the mid radius
    does not measure material at the other heights of a sloped edge). Returns (area, ae)."""
    top, nx, ny, x0, y0, h, zf, has_multi, bits, rank, ptr, lo, hi = grid
    zb = za + dzs
    half = 0.5 * dzs
    dphi = math.pi / M
    area = 0.0
    i_s, i_e, n_on = -1, -1, 0
    mmax = 0.0
    _ring_values(cells, wts, M, za, zb, bilinear, grid, mat)
    for i in range(M + 1):
        m = mat[i]
        on = m > half
        g[i] = r * m if flank else (rint if on else 0.0)
        if i > 0:
            area += 0.5 * dphi * (sin_t[i - 1] * g[i - 1] + sin_t[i] * g[i])
        if on:
            n_on += 1
            mmax = max(mmax, m)
            if i_s < 0:
                i_s = i
            i_e = i
    if i_s < 0:
        return area, 0.0
    st, ex = _ends(i_s, i_e, M, cx, cy, fx, fy, r, za, zb, half, pc, pw, bilinear, grid)
    cos_st, cos_ex = math.cos(st), math.cos(ex)
    area += _split(i_s, i_e, M, cos_st, cos_ex, g, sin_t, cos_t)
    phi_st[k, s] = st
    phi_ex[k, s] = ex
    dz[k, s] = mmax
    arc[k, s] = ex - st - dphi * ((i_e - i_s + 1) - n_on)
    return area, r * (cos_st - cos_ex)


@njit(cache=True, error_model="numpy")
def _ring_flank(k, s0, K, cx, cy, fx, fy, R, pz, layout, M, sin_t, cos_t, pc, pw, H, cnt, gs, tree, known, bilinear,
                grid, phi_st, phi_ex, dz, arc):
    """Slices s0..K-1 on the vertical flank (radius R) of single-interval stock, from one ring of
    column tops H(φ) (read by `_slices`): slice s is engaged where H > its mid-height, so the engaged
    sets are nested and one pass finds every slice's coarse ends. layout: `_layout`'s (uniform, dzs,
    zr, th). Returns (area, ae). Work arrays: tree, known (2, 2**BISECT) float and bool (see below)."""
    top, nx, ny, x0, y0, h, zf, has_multi, bits, rank, ptr, lo, hi = grid
    uniform, dzs, zr, th = layout
    dphi = math.pi / M
    zbase = pz + zr[s0]
    nk = K - s0
    T = nk * dzs if uniform else zr[K] - zr[s0]
    area = 0.0
    hmax = -1e300
    base = max(zbase, zf)
    m_prev = 0.0
    for i in range(M + 1):
        Hi = H[i]
        hmax = max(hmax, Hi)
        if uniform:
            cnt[i] = min(max(int(math.floor((Hi - zbase) / dzs + 0.5)), 0), nk)
        else:  # the slices whose mid-height Hi exceeds
            c = 0
            while c < nk and Hi - (pz + zr[s0 + c]) > 0.5 * th[s0 + c]:
                c += 1
            cnt[i] = c
        m = min(max(Hi - base, 0.0), T)
        if i > 0:
            area += 0.5 * dphi * R * (sin_t[i - 1] * m_prev + sin_t[i] * m)
        m_prev = m
    first, last = 0, M
    ae = 0.0
    # heights met by the bisections at the start and at the exit, shared by the slices whose coarse
    # transition lies in the same interval (on a vertical wall, all of them)
    held0, held1 = -1, -1  # the coarse interval each tree belongs to
    st_c, cos_st, ex_c, cos_ex = 0.0, 1.0, math.pi, -1.0  # the last ends and their cosines (often shared)
    for j in range(nk):
        while first <= last and cnt[first] <= j:
            first += 1
        while last >= first and cnt[last] <= j:
            last -= 1
        if first > last:
            break
        s = s0 + j
        za = zbase + j * dzs if uniform else pz + zr[s]
        t = th[s]
        zb = za + t
        if first != held0:  # another coarse interval: its tree of heights starts empty
            held0 = first
            known[0, :] = False
        if last != held1:
            held1 = last
            known[1, :] = False
        half = 0.5 * t
        st = 0.0 if first == 0 else _bisect_heights((first - 1) * dphi, first * dphi, False, tree[0], known[0], cx, cy,
                                                    fx, fy, R, za, zb, half, x0, y0, h, nx, ny, bilinear, pc, pw, top, zf)
        ex = math.pi if last == M else _bisect_heights(last * dphi, (last + 1) * dphi, True, tree[1], known[1], cx, cy,
                                                       fx, fy, R, za, zb, half, x0, y0, h, nx, ny, bilinear, pc, pw, top,
                                                       zf)
        # this slice's share of the trapezoid in the two end intervals, replaced by the exact split
        for i in (first - 1, first, last, last + 1):
            if 0 <= i <= M:
                gs[i] = R * min(max(H[i] - max(za, zf), 0.0), t)
        if st != st_c:
            st_c, cos_st = st, math.cos(st)
        if ex != ex_c:
            ex_c, cos_ex = ex, math.cos(ex)
        area += _split(first, last, M, cos_st, cos_ex, gs, sin_t, cos_t)
        off = 0
        for i in range(first, last + 1):
            off += cnt[i] <= j
        phi_st[k, s] = st
        phi_ex[k, s] = ex
        dz[k, s] = min(max(hmax - za, 0.0), t)
        arc[k, s] = ex - st - dphi * off
        ae = max(ae, R * (cos_st - cos_ex))
    return area, ae


@njit(cache=True, error_model="numpy")
def _ring_levels(H, ring, z_lo, ap, pz, lv):
    """The flat stock levels the ring meets inside the step's axial depth above z_lo, as heights above the
    tip (mm) sorted into lv; returns their count. A level is a height in (z_lo + tol, ap − tol),
    tol = LEVEL_TOL·ap, that a ring point shares (within PLATEAU_MM) with the next ring point and with
    the stock one cell in and one cell out along its radius: flat around it, not the ramp interpolation
    draws across a step nor a sloped wall read along its contour. Levels within tol of one another are one.
    ring: (cx, cy, fx, fy, R, M, sin_t, cos_t, pc, pw, bilinear, grid) of the ring H was read on."""
    cx, cy, fx, fy, R, M, sin_t, cos_t, pc, pw, bilinear, grid = ring
    top, nx, ny, x0, y0, h, zf, has_multi, bits, rank, ptr, lo, hi = grid
    tol = LEVEL_TOL * ap
    n = 0
    for i in range(1, M + 1):
        z = H[i] - pz
        if z <= z_lo + tol or z >= ap - tol or abs(H[i] - H[i - 1]) > PLATEAU_MM:
            continue
        flat = True
        for r in (R - h, R + h):
            _point_cells_sc(cx, cy, fx, fy, r, sin_t[i], cos_t[i], x0, y0, h, nx, ny, bilinear, pc, pw, 0)
            flat = flat and abs(_ring_height(pc, pw, 0, bilinear, top, zf) - H[i]) <= PLATEAU_MM
        if not flat:
            continue
        j = 0
        while j < n and lv[j] < z - tol:
            j += 1
        if j < n and lv[j] <= z + tol:
            continue
        for q in range(n, j, -1):
            lv[q] = lv[q - 1]
        lv[j] = z
        n += 1
    return n


@njit(cache=True, error_model="numpy")
def _drop_levels(lv, n, keep, ap):
    """Keep `keep` of the n sorted levels in lv (mm above the tip, inside (0, ap)): repeatedly drop the
    one nearest a neighbouring level or an end of [0, ap] (the thinnest band it bounds merges with the
    next). Returns the count kept."""
    while n > keep:
        best, j_best = math.inf, 0
        for j in range(n):
            below = lv[j - 1] if j > 0 else 0.0
            above = lv[j + 1] if j + 1 < n else ap
            d = min(lv[j] - below, above - lv[j])
            if d < best:
                best, j_best = d, j
        for q in range(j_best, n - 1):
            lv[q] = lv[q + 1]
        n -= 1
    return n


@njit(cache=True, error_model="numpy")
def _layout(H, ring, z_lo, pz, ap, K, lv, zr, th, zm):
    """The K axial slices of a step of depth ap (mm) whose ring of column tops is H (`_ring_levels`' ring):
    the stock levels met inside (z_lo, ap) (at most K − 1, `_drop_levels`) placed as boundaries by
    `_place`. Returns (uniform, ap/K)."""
    return _place(lv, _drop_levels(lv, _ring_levels(H, ring, z_lo, ap, pz, lv), K - 1, ap), ap, K, zr, th, zm)


@njit(cache=True, error_model="numpy")
def _place(lv, n, ap, K, zr, th, zm):
    """K axial slices over [0, ap] (mm) with the n sorted levels lv (mm above the tip, n < K) as boundaries,
    so no slice holds a step: boundaries zr (K + 1), thicknesses th (K) and mid-heights zm (K). The bands
    between levels share the slices, at least one each, each further slice going to the band whose slices
    are thickest; within a band the slices are equal. With no level: ap/K each, computed as they always
    were (s·ap/K, (s + ½)·ap/K). Returns (uniform, ap/K)."""
    dzs = ap / K
    if n == 0:
        for s in range(K + 1):
            zr[s] = s * dzs
        for s in range(K):
            th[s] = dzs
            zm[s] = (s + 0.5) * dzs
        return True, dzs
    per = np.ones(n + 1, np.int64)
    for _ in range(K - n - 1):
        best, b_best = -1.0, 0
        for b in range(n + 1):
            lo_b = lv[b - 1] if b > 0 else 0.0
            hi_b = lv[b] if b < n else ap
            if (hi_b - lo_b) / per[b] > best:
                best, b_best = (hi_b - lo_b) / per[b], b
        per[b_best] += 1
    s = 0
    for b in range(n + 1):
        lo_b = lv[b - 1] if b > 0 else 0.0
        hi_b = lv[b] if b < n else ap
        for j in range(per[b]):
            zr[s] = lo_b + j * ((hi_b - lo_b) / per[b])
            s += 1
    zr[K] = ap
    for s in range(K):
        th[s] = zr[s + 1] - zr[s]
        zm[s] = zr[s] + 0.5 * th[s]
    return False, dzs


@njit(cache=True, error_model="numpy")
def _ends(i_s, i_e, M, cx, cy, fx, fy, r, za, zb, half, pc, pw, bilinear, grid):
    """Outer ends of the engaged arc from the first/last engaged coarse samples, by bisection."""
    top, nx, ny, x0, y0, h, zf, has_multi, bits, rank, ptr, lo, hi = grid
    dphi = math.pi / M
    st = 0.0 if i_s == 0 else _bisect((i_s - 1) * dphi, i_s * dphi, False, cx, cy, fx, fy, r, za, zb, half, x0,
                                      y0, h, nx, ny, bilinear, pc, pw, top, zf, has_multi, bits, rank, ptr, lo, hi)
    ex = math.pi if i_e == M else _bisect(i_e * dphi, (i_e + 1) * dphi, True, cx, cy, fx, fy, r, za, zb, half,
                                          x0, y0, h, nx, ny, bilinear, pc, pw, top, zf, has_multi, bits, rank,
                                          ptr, lo, hi)
    return st, ex


@njit(cache=True, error_model="numpy")
def _split(i_s, i_e, M, cos_st, cos_ex, g, sin_t, cos_t):
    """Area correction for the two end intervals: the trapezoid of g·sin φ there is replaced by g
    of the off sample before st / after ex and of the on sample inside, integrated exactly (given
    cos st and cos ex)."""
    dphi = math.pi / M
    d = 0.0
    if i_s > 0:
        i = i_s - 1
        d += (g[i] * (cos_t[i] - cos_st) + g[i + 1] * (cos_st - cos_t[i + 1])
              - 0.5 * dphi * (sin_t[i] * g[i] + sin_t[i + 1] * g[i + 1]))
    if i_e < M:
        i = i_e
        d += (g[i] * (cos_t[i] - cos_ex) + g[i + 1] * (cos_ex - cos_t[i + 1])
              - 0.5 * dphi * (sin_t[i] * g[i] + sin_t[i + 1] * g[i + 1]))
    return d


@njit(cache=True, error_model="numpy")
def _level_sweep(k, xyz, fresh, rapid, shape, px, py, pz, qx, qy, fx, fy, dxy, args):
    """The material a level step k removes, as (cells' removed height sum, ap mm, crash): its band,
    the wedge at its start (when the previous step was a band of the same kind), and its front cap
    when no such band follows."""
    n = xyz.shape[0]
    rem, ap, crash = _region(BAND, qx, qy, pz, 0.0, 0.0, fx, fy, dxy, not rapid[k], *args)
    if not crash and _level_step(k - 1, n, xyz, fresh, shape) and rapid[k - 1] == rapid[k]:
        ex, ey = xyz[k - 1, 0] - xyz[k - 2, 0], xyz[k - 1, 1] - xyz[k - 2, 1]
        le = math.sqrt(ex * ex + ey * ey)
        r2, a2, crash = _region(WEDGE, qx, qy, pz, ex / le, ey / le, fx, fy, 0.0, not rapid[k], *args)
        rem += r2
        ap = max(ap, a2)
    if not crash and not (_level_step(k + 1, n, xyz, fresh, shape) and rapid[k + 1] == rapid[k]):
        r2, a2, crash = _region(CAP, px, py, pz, 0.0, 0.0, fx, fy, 0.0, not rapid[k], *args)
        rem += r2
        ap = max(ap, a2)
    return rem, ap, crash


@njit(cache=True, error_model="numpy")
def _slices(k, ap, K, M, cx, cy, gx, gy, pz, shape, R, rc, r_tip, tan_half, bilinear, grid, work, zmid, rad,
            phi_st, phi_ex, dz, arc):
    """Sample k's K axial slices over the depth ap (mm), placed by `_layout` from the column tops on the
    ring of radius R centred (cx, cy), feed direction (gx, gy) (the levels the vertical flank meets; below
    its foot the slices' own rings are narrower): each slice's engaged arc (rows k of
    phi_st, phi_ex, dz, arc, zmid, rad written in place; rad at the slice's mid-height), and the step's
    chip cross-section (sum of the slices' ring areas, mm²) and radial engagement a_e (mm).
    Slices on the vertical flank (r = R) share that ring; below it each slice has its own.
    work: the scratch arrays (sin_t, cos_t, cells, wts, pc, pw, mat, cnt, g, tree, known, H, lv, zr, th)."""
    sin_t, cos_t, cells, wts, pc, pw, mat, cnt, g, tree, known, H, lv, zr, th = work
    top, nx, ny, x0, y0, h, zf, has_multi, bits, rank, ptr, lo, hi = grid
    z_lo = _flank_foot(shape, R, rc, r_tip, tan_half)
    if z_lo < ap:  # the flank reaches into the depth: its ring's tops (the levels; `_ring_flank` reads them)
        _ring_cells(cx, cy, gx, gy, R, M, sin_t, cos_t, x0, y0, h, nx, ny, bilinear, cells, wts)
        for i in range(M + 1):
            H[i] = _ring_height(cells, wts, i, bilinear, top, zf)
        ring = (cx, cy, gx, gy, R, M, sin_t, cos_t, pc, pw, bilinear, grid)
        uniform, dzs = _layout(H, ring, z_lo, pz, ap, K, lv, zr, th, zmid[k])
    else:
        uniform, dzs = _place(lv, 0, ap, K, zr, th, zmid[k])
    area = 0.0
    ae = 0.0
    s0 = K
    while s0 > 0 and profile_radius(zr[s0 - 1], shape, R, rc, r_tip, tan_half) == R:
        s0 -= 1
    for s in range(K):
        rad[k, s] = profile_radius(zmid[k, s], shape, R, rc, r_tip, tan_half)
    for s in range(s0 if not has_multi else K):
        r = rad[k, s]
        _ring_cells(cx, cy, gx, gy, r, M, sin_t, cos_t, x0, y0, h, nx, ny, bilinear, cells, wts)
        flank = s >= s0
        rint = r * th[s] if flank else _profile_integral(zr[s], zr[s + 1], shape, R, rc, r_tip, tan_half)
        da, de = _ring_slice(k, s, cx, cy, gx, gy, r, pz + zr[s], th[s], flank, rint, M, sin_t, cos_t,
                             cells, wts, pc, pw, mat, g, bilinear, grid, phi_st, phi_ex, dz, arc)
        area += da
        ae = max(ae, de)
    if s0 < K and not has_multi:
        da, de = _ring_flank(k, s0, K, cx, cy, gx, gy, R, pz, (uniform, dzs, zr, th), M, sin_t, cos_t, pc, pw,
                             H, cnt, g, tree, known, bilinear, grid, phi_st, phi_ex, dz, arc)
        area += da
        ae = max(ae, de)
    return area, ae


@njit(cache=True, error_model="numpy")
def run(xyz, fresh, rapid, k0, k1, prev_f, top, nx, ny, x0, y0, h, zf, has_multi, bits, rank, ptr, lo, hi,
        shape, R, rc, r_tip, tan_half, flute, K, M, ring_at, bilinear, crash_tol, clear, zmax, omax, omin, B,
        swept, snx, sny, sx0, sy0, W,
        phi_st, phi_ex, dz, zmid, rad, arc, ap_o, ae_o, vol_o, area_o, feed_o, desc_o, depth_o, end_o, near_o,
        swept_o):
    """Step samples k0..k1-1. fresh[k]: sample k does not continue from k-1 (start, jump, tool change).
    ring_at[k] = (x, y, fx, fy): centre and feed direction of sample k's ring (the path point a
    look-ahead distance further on). Outputs are written in place (rows k); returns OK or the index
    of a rapid that hits material. prev_f: (2,) feed direction carried across calls (in place).
    depth_o[k]: the depth of material the step meets, before ap is clipped to the flute length.
    feed_o[k, :2]: the ring's feed direction (the rest of the row is left as it is).
    end_o[k]: the end's radial engagement of a descending feed step (`_end_band`). near_o[k]: a feed
    step that cuts nothing lies within `clear` mm of the original stock (`_near_original` with its
    tops' block maxima omax and minima omin of B × B columns; zmax: the highest original top); not
    computed when clear < 0. swept (snx × sny cells of W mm from (sx0, sy0), in place): the swept field,
    the lowest height the feed steps' tool surface has covered over each whole cell (`_sweep_record`,
    kept when clear >= 0); swept_o[k]: a near step lies in space it knows as cleared (`_in_swept`)."""
    dphi = math.pi / M
    sin_t = np.sin(np.arange(M + 1) * dphi)
    cos_t = np.cos(np.arange(M + 1) * dphi)
    cells = np.empty((M + 1, 4), np.int64)
    wts = np.empty((M + 1, 2), np.float64)
    pc = np.empty((1, 4), np.int64)
    pw = np.empty((1, 2), np.float64)
    mat = np.empty(M + 1, np.float64)
    g = np.empty(M + 1, np.float64)
    cnt = np.empty(M + 1, np.int64)
    spans = np.empty((ny, 2), np.int64)
    rows = np.zeros(2, np.int64)
    spans_k = -2  # the last sample whose disk spans are in `spans`
    tree = np.empty((2, 1 << BISECT))
    known = np.zeros((2, 1 << BISECT), np.bool_)
    H = np.empty(M + 1, np.float64)
    lv = np.empty(M + 1, np.float64)
    zr = np.empty(K + 1, np.float64)
    th = np.empty(K, np.float64)
    fx, fy = prev_f[0], prev_f[1]
    for k in range(k0, k1):
        px, py, pz = xyz[k, 0], xyz[k, 1], xyz[k, 2]
        mode = 0
        step = 0.0
        dxy = 0.0
        descending = False
        if not fresh[k]:
            qx, qy, qz = xyz[k - 1, 0], xyz[k - 1, 1], xyz[k - 1, 2]
            ddx, ddy, ddz = px - qx, py - qy, pz - qz
            dxy = math.sqrt(ddx * ddx + ddy * ddy)
            step = math.sqrt(dxy * dxy + ddz * ddz)
            if dxy > 1e-12:
                fx, fy = ddx / dxy, ddy / dxy
            descending = ddz < -1e-9
            if not descending and dxy < 2.0 * R:
                mode = 1 if shape == FLAT else 2
        else:
            qx, qy, qz = px, py, pz
        gx, gy = ring_at[k, 2], ring_at[k, 3]
        feed_o[k, 0], feed_o[k, 1] = gx, gy
        desc_o[k] = descending
        if descending and not rapid[k]:
            _end_band(px, py, pz, -ddz, R, shape, rc, r_tip, tan_half, top, nx, ny, x0, y0, h, zf, has_multi, bits,
                      rank, ptr, lo, hi, end_o[k])
        n = xyz.shape[0]
        if _level_step(k, n, xyz, fresh, shape):
            args = (R, shape, rc, r_tip, tan_half, top, nx, ny, x0, y0, h, zf, has_multi, bits, rank, ptr, lo, hi,
                    crash_tol)
            rem, ap, crash = _level_sweep(k, xyz, fresh, rapid, shape, px, py, pz, qx, qy, fx, fy, dxy, args)
        else:
            rem, ap, crash = _footprint(px, py, pz, qx, qy, mode, not rapid[k], R, shape, rc, r_tip, tan_half,
                                        top, nx, ny, x0, y0, h, zf, has_multi, bits, rank, ptr, lo, hi, crash_tol,
                                        spans, rows, spans_k == k - 1)
            spans_k = k
        if crash:
            prev_f[0], prev_f[1] = fx, fy
            return k
        vol_o[k] = rem * h * h
        depth_o[k] = ap
        ap = min(ap, flute)
        ap_o[k] = ap
        if clear >= 0.0 and not rapid[k] and pz - clear < zmax:  # higher, no near step could use its record
            if ap <= 1e-6:
                near_o[k] = _near_original(px, py, pz, R, clear, omax, omin, B, nx, ny, x0, y0, h, zf)
                if near_o[k]:  # before this step is recorded: what the tool swept until it got here
                    swept_o[k] = _in_swept(px, py, pz, qx, qy, qz, R, shape, rc, r_tip, tan_half, swept, snx, sny,
                                           sx0, sy0, W)
            skip_q = shape == FLAT and not fresh[k] and pz >= qz and not rapid[k - 1]
            _sweep_record(px, py, pz, qx, qy, skip_q, R, shape, rc, r_tip, tan_half, swept, snx, sny, sx0, sy0, W)
        if ap <= 1e-6 or step == 0.0:
            area_o[k] = vol_o[k] / step if step > 0.0 else 0.0
            continue
        grid = (top, nx, ny, x0, y0, h, zf, has_multi, bits, rank, ptr, lo, hi)
        work = (sin_t, cos_t, cells, wts, pc, pw, mat, cnt, g, tree, known, H, lv, zr, th)
        area, ae_o[k] = _slices(k, ap, K, M, ring_at[k, 0], ring_at[k, 1], gx, gy, pz, shape, R, rc, r_tip,
                                tan_half, bilinear, grid, work, zmid, rad, phi_st, phi_ex, dz, arc)
        if descending:
            area_o[k] = vol_o[k] / step
        else:
            area_o[k] = area * dxy / step
    prev_f[0], prev_f[1] = fx, fy
    return OK
