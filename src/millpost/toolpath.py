"""Toolpath: the moves of a program as numpy arrays (mm, program frame), and resampling by arc length.

One row per motion (rapid, feed line, arc). Each row keeps the source line and block so every later
result maps back to the program. Arcs are helices in general: a circle in the active plane
(G17 XY, G18 ZX, G19 YZ) plus linear motion along the plane normal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RAPID, FEED, ARC_CW, ARC_CCW = 0, 1, 2, 3
KIND_NAMES = ("rapid", "feed", "arc_cw", "arc_ccw")
# (first, second, normal) axis indices of each plane: G17 XY, G18 ZX, G19 YZ (LinuxCNC convention).
PLANE_AXES = ((0, 1, 2), (2, 0, 1), (1, 2, 0))


def segments_per_move(length_mm: np.ndarray, ds_mm: float) -> np.ndarray:
    """Segments `Toolpath.resample` cuts each move of nonzero length into (float: inf-safe for the
    sample-count estimate): at most ds_mm long, and at least two (see `resample`)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return np.maximum(np.ceil(np.asarray(length_mm, float) / ds_mm - 1e-9), 2.0)


@dataclass
class Toolpath:
    """Moves as arrays, all lengths in mm in the program's coordinate frame.

    kind: int8 RAPID/FEED/ARC_CW/ARC_CCW. start, end: (n, 3). center: (n, 3) arc centre (the
    normal-axis component equals the start's); nan for lines. plane: int8 index into PLANE_AXES.
    turns: int32 extra full turns of an arc (P word − 1). feed_mm_min: programmed feed (nan for
    rapids; for G93 inverse time it is the equivalent mm/min), as the program's F words have it: the
    reader's and the writer's unit; everything after the reader takes `feed_mm_s`. rpm: spindle speed
    (0 when off). tool: tool number (−1 before the first change). line: 1-based source line. block:
    0-based block.
    """

    kind: np.ndarray
    start: np.ndarray
    end: np.ndarray
    center: np.ndarray
    plane: np.ndarray
    turns: np.ndarray
    feed_mm_min: np.ndarray
    rpm: np.ndarray
    tool: np.ndarray
    line: np.ndarray
    block: np.ndarray

    def __len__(self) -> int:
        return len(self.kind)

    @property
    def feed_mm_s(self) -> np.ndarray:
        """The programmed feed per move in mm/s (nan for rapids): the unit of every stage after the reader."""
        return self.feed_mm_min / 60.0

    @classmethod
    def empty(cls) -> "Toolpath":
        z3 = np.zeros((0, 3))
        return cls(np.zeros(0, np.int8), z3, z3.copy(), z3.copy(), np.zeros(0, np.int8),
                   np.zeros(0, np.int32), np.zeros(0), np.zeros(0), np.zeros(0, np.int32),
                   np.zeros(0, np.int32), np.zeros(0, np.int32))

    def subset(self, mask: np.ndarray) -> "Toolpath":
        return Toolpath(**{k: getattr(self, k)[mask] for k in self.__dataclass_fields__})

    # --- arc geometry -------------------------------------------------------------------------
    def _arc_params(self) -> tuple[np.ndarray, ...]:
        """Per move: in-plane radius at start, start angle, signed sweep (rad), normal travel, plane axes."""
        n = len(self)
        ax = np.array(PLANE_AXES)[self.plane.astype(int)]  # (n, 3)
        rows = np.arange(n)
        s1, s2 = self.start[rows, ax[:, 0]], self.start[rows, ax[:, 1]]
        e1, e2 = self.end[rows, ax[:, 0]], self.end[rows, ax[:, 1]]
        c1, c2 = self.center[rows, ax[:, 0]], self.center[rows, ax[:, 1]]
        r0 = np.hypot(s1 - c1, s2 - c2)
        a0 = np.arctan2(s2 - c2, s1 - c1)
        a1 = np.arctan2(e2 - c2, e1 - c1)
        ccw = self.kind == ARC_CCW
        sweep = np.where(ccw, (a1 - a0) % (2 * np.pi), -((a0 - a1) % (2 * np.pi)))
        # a zero sweep on an arc is a full circle
        full = np.isclose(sweep, 0.0, atol=1e-12)
        sweep = np.where(full, np.where(ccw, 2 * np.pi, -2 * np.pi), sweep)
        sweep = sweep + np.sign(sweep) * 2 * np.pi * self.turns
        r1 = np.hypot(e1 - c1, e2 - c2)
        dn = self.end[rows, ax[:, 2]] - self.start[rows, ax[:, 2]]
        return r0, r1, a0, sweep, dn, ax

    def axis_shares(self) -> np.ndarray:
        """(N, 3) per move the largest share |t_i| of each axis in its unit tangent anywhere along it: a
        line's |Δ_i| / L; on an arc the in-plane share s = √(1 − (Δn/L)²) times the largest |sin θ| (first
        plane axis) or |cos θ| (second) over the swept angles θ of the radius (1 where the sweep passes the
        point where the tangent lies along that axis), plus a spiral's |dr/ds| (an end radius a little off
        the start's turns the tangent), and the normal travel |Δn| / L (a helix). The
        controller runs a move at most at min_i vmax_i / share_i."""
        L = self.lengths()
        with np.errstate(divide="ignore", invalid="ignore"):
            out = np.where(L[:, None] > 0, np.abs(self.end - self.start) / L[:, None], 0.0)
        arc = np.flatnonzero((self.kind >= ARC_CW) & (L > 0))
        if len(arc):
            r0, r1, a0, sweep, dn, ax = self.subset(arc)._arc_params()
            normal = np.abs(dn) / L[arc]
            radial = np.abs(r1 - r0) / L[arc]  # a spiral's (end radius a little off the start's): dr/ds
            s = np.sqrt(np.maximum(1.0 - normal**2, 0.0))
            lo, hi = np.minimum(a0, a0 + sweep), np.maximum(a0, a0 + sweep)

            def largest(f, at: float) -> np.ndarray:  # max |f| over [lo, hi], |f| = 1 at `at` + kπ
                passes = np.ceil((lo - at) / np.pi) <= np.floor((hi - at) / np.pi)
                return np.where(passes, 1.0, np.maximum(np.abs(f(lo)), np.abs(f(hi))))

            rows = np.arange(len(arc))
            share = np.zeros((len(arc), 3))
            # the tangent is ∝ (−sin θ, cos θ), turned by a spiral's dr/ds (bounded by adding it)
            share[rows, ax[:, 0]] = np.minimum(s * largest(np.sin, np.pi / 2) + radial, 1.0)
            share[rows, ax[:, 1]] = np.minimum(s * largest(np.cos, 0.0) + radial, 1.0)
            share[rows, ax[:, 2]] = normal
            out[arc] = share
        return out

    def lengths(self) -> np.ndarray:
        """Path length of each move (mm); helices as helices (radius varying linearly if the
        programmed end radius differs slightly from the start radius)."""
        L = np.linalg.norm(self.end - self.start, axis=1)
        arc = self.kind >= ARC_CW
        if arc.any():
            r0, r1, _, sweep, dn, _ = self.subset(arc)._arc_params()
            rm = 0.5 * (r0 + r1)
            L[arc] = np.hypot(rm * np.abs(sweep), dn)
        return L

    def bbox(self) -> np.ndarray:
        """[[xmin, ymin, zmin], [xmax, ymax, zmax]] of the swept path including arc extremes (mm)."""
        if len(self) == 0:
            return np.full((2, 3), np.nan)
        pts = [self.start, self.end]
        arc = np.flatnonzero(self.kind >= ARC_CW)
        if len(arc):
            sub = self.subset(arc)
            r0, r1, a0, sweep, dn, ax = sub._arc_params()
            for q in range(4):  # quadrant angles 0, 90, 180, 270 degrees
                ang = q * np.pi / 2
                # is angle ang within the swept interval (starting at a0, signed sweep)?
                rel = np.where(sweep >= 0, (ang - a0) % (2 * np.pi), (a0 - ang) % (2 * np.pi))
                hit = (rel <= np.abs(sweep) + 1e-12)
                if not hit.any():
                    continue
                frac = np.clip(rel / np.maximum(np.abs(sweep), 1e-300), 0, 1)
                r = r0 + (r1 - r0) * frac
                p = sub.start.copy()
                rows = np.arange(len(sub))
                p[rows, ax[:, 0]] = sub.center[rows, ax[:, 0]] + r * np.cos(ang)
                p[rows, ax[:, 1]] = sub.center[rows, ax[:, 1]] + r * np.sin(ang)
                p[rows, ax[:, 2]] = sub.start[rows, ax[:, 2]] + dn * frac
                pts.append(p[hit])
        allp = np.concatenate(pts)
        return np.array([allp.min(axis=0), allp.max(axis=0)])

    def points(self, move: np.ndarray, u: np.ndarray, derivatives: bool = False):
        """Points at fraction u ∈ [0, 1] of path length along moves `move` (mm).

        With derivatives=True also returns the unit tangent dq/ds and curvature vector d²q/ds² (1/mm).
        """
        move = np.asarray(move)
        u = np.asarray(u, dtype=float)
        st, en = self.start[move], self.end[move]
        p = st + (en - st) * u[:, None]
        L = self.lengths()[move] if derivatives else None
        if derivatives:
            with np.errstate(invalid="ignore", divide="ignore"):
                t = (en - st) / L[:, None]
            t = np.nan_to_num(t)
            k = np.zeros_like(p)
        arc = self.kind[move] >= ARC_CW
        if arc.any():
            idx = np.flatnonzero(arc)
            sub = self.subset(move[idx])
            r0, r1, a0, sweep, dn, ax = sub._arc_params()
            uu = u[idx]
            r = r0 + (r1 - r0) * uu
            ang = a0 + sweep * uu
            rows = np.arange(len(idx))
            q = sub.start.copy()
            q[rows, ax[:, 0]] = sub.center[rows, ax[:, 0]] + r * np.cos(ang)
            q[rows, ax[:, 1]] = sub.center[rows, ax[:, 1]] + r * np.sin(ang)
            q[rows, ax[:, 2]] = sub.start[rows, ax[:, 2]] + dn * uu
            p[idx] = q
            if derivatives:
                Ls = L[idx]
                dth = sweep / Ls  # dθ/ds
                dr = (r1 - r0) / Ls
                dn_ds = dn / Ls
                tq = np.zeros_like(q)
                kq = np.zeros_like(q)
                c, s = np.cos(ang), np.sin(ang)
                tq[rows, ax[:, 0]] = dr * c - r * s * dth
                tq[rows, ax[:, 1]] = dr * s + r * c * dth
                tq[rows, ax[:, 2]] = dn_ds
                kq[rows, ax[:, 0]] = -2 * dr * s * dth - r * c * dth**2
                kq[rows, ax[:, 1]] = 2 * dr * c * dth - r * s * dth**2
                t[idx] = tq
                k[idx] = kq
        if derivatives:
            return p, t, k
        return p

    def resample(self, ds_mm: float, kinds: tuple[int, ...] = (RAPID, FEED, ARC_CW, ARC_CCW)) -> "Samples":
        """Samples at most ds_mm apart along every move of the given kinds, each move's end included.

        Sample 0 is the start of the first selected move; every sample k > 0 ends a segment that
        belongs to move `move[k]`. Moves of zero length contribute no sample. Every other move gets at
        least two segments: a move may start and end at a stop (a rapid on either side, a reversal, an
        exact-stop corner), and the schedule, which holds the acceleration constant between samples,
        needs a sample inside it to speed up and brake again (one segment from rest to rest never moves).
        """
        if ds_mm <= 0:
            raise ValueError("ds_mm must be > 0")
        sel = np.flatnonzero(np.isin(self.kind, kinds))
        L = self.lengths()[sel]
        keep = L > 1e-9
        sel, L = sel[keep], L[keep]
        if len(sel) == 0:
            return Samples.empty()
        nseg = segments_per_move(L, ds_mm).astype(np.int64)
        move = np.repeat(sel, nseg)
        first = np.repeat(np.cumsum(nseg) - nseg, nseg)
        j = np.arange(len(move)) - first + 1
        u = j / np.repeat(nseg, nseg)
        p, t, k = self.points(move, u, derivatives=True)
        p0, t0, k0 = self.points(sel[:1], np.zeros(1), derivatives=True)
        seg_len = np.repeat(L / nseg, nseg)
        s = np.concatenate([[0.0], np.cumsum(seg_len)])
        # a jump between selected moves that are not contiguous (e.g. rapids left out) marks a break
        starts = self.start[sel]
        ends_prev = np.concatenate([self.start[sel[:1]], self.end[sel[:-1]]])
        gap = np.linalg.norm(starts - ends_prev, axis=1) > 1e-6
        brk = np.zeros(len(move) + 1, bool)
        brk[np.cumsum(np.concatenate([[0], nseg[:-1]]))[gap]] = True
        moves = np.concatenate([sel[:1], move])
        return Samples(
            s_mm=s,
            xyz_mm=np.concatenate([p0, p]),
            tangent=np.concatenate([t0, t]),
            curvature=np.concatenate([k0, k]),
            move=moves,
            line=self.line[moves],
            kind=self.kind[moves],
            feed_mm_s=self.feed_mm_s[moves],
            rpm=self.rpm[moves],
            tool=self.tool[moves],
            segment_start=brk,
        )


@dataclass
class Samples:
    """Points along a toolpath at arc length s (mm).

    xyz_mm: position; tangent: unit dq/ds; curvature: d²q/ds² (1/mm), so axis velocity is
    tangent·v and axis acceleration tangent·a + curvature·v². move/line/kind/feed_mm_s/rpm/tool:
    the move each sample ends (sample 0: the first move); feed_mm_s: its programmed feed (mm/s).
    segment_start: True where the path jumps (the sample does not continue the previous one), so
    consumers restart there.
    """

    s_mm: np.ndarray
    xyz_mm: np.ndarray
    tangent: np.ndarray
    curvature: np.ndarray
    move: np.ndarray
    line: np.ndarray
    kind: np.ndarray
    feed_mm_s: np.ndarray
    rpm: np.ndarray
    tool: np.ndarray
    segment_start: np.ndarray

    def __len__(self) -> int:
        return len(self.s_mm)

    def select(self, index) -> "Samples":
        """The samples at `index` (a slice: views; a mask or index array: copies)."""
        return Samples(**{k: getattr(self, k)[index] for k in self.__dataclass_fields__})

    @classmethod
    def empty(cls) -> "Samples":
        z, z3 = np.zeros(0), np.zeros((0, 3))
        zi = np.zeros(0, np.int32)
        return cls(z, z3, z3.copy(), z3.copy(), zi, zi.copy(), np.zeros(0, np.int8), z.copy(), z.copy(),
                   zi.copy(), np.zeros(0, bool))
