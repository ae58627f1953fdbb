"""Time-domain milling forces: rotate the cutter through one period and sum elemental edge forces.

Elemental law shared by both models (per tooth, per axial disk of chip width db = dz/sin κ):

    dF_q = db · (Kc_q · h^p + Ke_q),  q ∈ {t, r, a},   h = f_z sin φ sin κ (+ runout, see below)

Mechanistic: p = 1 (Altintas linear edge-force model); Kienzle: Kc_q = k_c1.1 × ratio_q, Ke = 0,
p = 1 − m_c. Projection to the feed frame (φ clockwise from +y, Altintas):

    dF_x = −dF_t cos φ − (dF_r sin κ + dF_a cos κ) sin φ
    dF_y = +dF_t sin φ − (dF_r sin κ + dF_a cos κ) cos φ
    dF_z = dF_a sin κ − dF_r cos κ           dT = r · dF_t

Helix: tooth j at height z lags by z·tan β / R, so disks are subdivided until one disk lags at most one
angular step. Runout: tooth j cuts at radius R + r_j and removes what the m-th previous tooth left,
h_j = min_m (m f_z sin φ sin κ + r_j − r_{j−m}) (Schmitz & Smith); h ≤ 0 means the tooth is out of cut.
Without runout the loads repeat every tooth pitch, so one pitch is simulated; with runout a revolution.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

import numpy as np
from numba import njit, prange

from .._kernels import compiling


_EXACT_EVERY = 32  # angular steps between exact sin/cos (the rotation recurrence in between drifts ~1e-16 a step)


@njit(cache=True, parallel=True)
def _simulate(st, ex, b, z, dz, r, kappa, kc, ke, p, flutes, tan_helix, radius, runout, has_runout, fz,
              steps, periods):  # pragma: no cover - compiled
    n, k_slices = st.shape
    two_pi = 2.0 * math.pi
    pitch = two_pi / flutes
    dphi = pitch * periods / steps
    cd, sd = math.cos(dphi), math.sin(dphi)
    peaks = np.zeros((n, 4))     # |F_xy| total, |F_xy| shearing part, |F_xy| edge part, torque
    mean = np.zeros((n, 4))
    for i in prange(n):  # samples are independent: the result does not depend on the thread count
        acc = np.zeros((6, steps))   # per angular step: shear x, y; edge x, y; z; torque
        cutting = False
        for k in range(k_slices):
            if b[i, k] <= 0.0:
                continue
            cutting = True
            sk = math.sin(kappa[i, k])
            ck = math.cos(kappa[i, k])
            m = max(1, int(math.ceil(dz[i, k] * tan_helix / radius / dphi)))
            db = b[i, k] / m
            # per unit h^p (shearing) and per disk (edge): tangential, radial-plus-axial in plane, z
            ct, crad, cz = db * kc[0], db * (kc[1] * sk + kc[2] * ck), db * (kc[2] * sk - kc[1] * ck)
            et, erad, ez = db * ke[0], db * (ke[1] * sk + ke[2] * ck), db * (ke[2] * sk - ke[1] * ck)
            tq = r[i, k]
            for sub in range(m):
                zz = z[i, k] - 0.5 * dz[i, k] + (sub + 0.5) * dz[i, k] / m
                for j in range(flutes):
                    off = (j * pitch - zz * tan_helix / radius) % two_pi
                    # steps s whose angle (s + ½)dφ + off lies in [st, ex] modulo 2π: only those are visited
                    for shift in (-two_pi, 0.0, two_pi):
                        lo = st[i, k] - off + shift
                        hi = ex[i, k] - off + shift
                        s0 = max(0, int(math.ceil(lo / dphi - 0.5)))
                        s1 = min(steps - 1, int(math.floor(hi / dphi - 0.5)))
                        sp, cp = 0.0, 1.0
                        for s in range(s0, s1 + 1):
                            if (s - s0) % _EXACT_EVERY == 0:
                                ph = (s + 0.5) * dphi + off - shift
                                sp, cp = math.sin(ph), math.cos(ph)
                            h = fz[i] * sp * sk
                            if has_runout:
                                base = h
                                h = base + runout[j] - runout[(j - 1) % flutes]
                                for mm in range(2, flutes + 1):
                                    hm = mm * base + runout[j] - runout[(j - mm) % flutes]
                                    if hm < h:
                                        h = hm
                            if h > 0.0:
                                hp = h if p == 1.0 else h ** p
                                # shearing (∝ h^p) and edge parts kept apart for the linear peak bound
                                ft = ct * hp
                                rad = crad * hp
                                acc[0, s] += -ft * cp - rad * sp
                                acc[1, s] += ft * sp - rad * cp
                                acc[2, s] += -et * cp - erad * sp
                                acc[3, s] += et * sp - erad * cp
                                acc[4, s] += cz * hp + ez
                                acc[5, s] += tq * (ft + et)
                            sp, cp = sp * cd + cp * sd, cp * cd - sp * sd  # rotate by dφ
        if not cutting:
            continue
        for s in range(steps):
            fx = acc[0, s] + acc[2, s]
            fy = acc[1, s] + acc[3, s]
            peaks[i, 0] = max(peaks[i, 0], math.sqrt(fx * fx + fy * fy))
            peaks[i, 1] = max(peaks[i, 1], math.sqrt(acc[0, s] ** 2 + acc[1, s] ** 2))
            peaks[i, 2] = max(peaks[i, 2], math.sqrt(acc[2, s] ** 2 + acc[3, s] ** 2))
            peaks[i, 3] = max(peaks[i, 3], acc[5, s])
            mean[i, 0] += fx / steps
            mean[i, 1] += fy / steps
            mean[i, 2] += acc[4, s] / steps
            mean[i, 3] += acc[5, s] / steps
    return peaks, mean


def simulate(st, ex, b, z, dz, r, kappa, *, kc, ke, p: float, flutes: int, helix_deg: float, radius_mm: float,
             fz_mm, runout_mm=None, steps_per_rev: int = 360) -> tuple[np.ndarray, np.ndarray]:
    """Per sample: peaks (N, 4) = [max |F_xy| (N), max |F_xy| of the shearing part alone, max |F_xy| of the
    edge part alone, max torque (N·mm)] and the period average (N, 4) = [F_x, F_y, F_z (N), T (N·mm)].

    Arrays are (N, K) slices as in `Engagement` with arcs already clipped to [0, π] and b = dz/sin κ.
    kc (N/mm² per h^p), ke (N/mm): (3,) for t, r, a. runout_mm: (flutes,) radial offsets or None.
    steps_per_rev sets the angular step 2π/steps_per_rev.
    """
    n = st.shape[0]
    ro = np.zeros(flutes) if runout_mm is None else np.asarray(runout_mm, float)
    if ro.shape != (flutes,):
        raise ValueError(f"runout needs one offset per flute ({flutes}), got {ro.shape}")
    has_runout = bool(np.any(ro != 0))
    periods = flutes if has_runout else 1
    steps = max(8, int(math.ceil(steps_per_rev * periods / flutes)))
    fz = np.broadcast_to(np.asarray(fz_mm, float), (n,)).astype(float)
    tan_helix = math.tan(math.radians(helix_deg))
    # a sample that cuts nothing has no load; identical samples (a cut that does not change along a move)
    # are simulated once, and within `reusing_runs` once over all calls
    live = cutting_samples(np.asarray(b, float).reshape(n, -1))
    key = np.nan_to_num(np.column_stack([np.asarray(a, float).reshape(n, st.shape[1])[live]
                                         for a in (st, ex, b, z, dz, r, kappa)] + [fz[live]]), nan=-1e300)
    settings = (tuple(np.asarray(kc, float)), tuple(np.asarray(ke, float)), float(p), int(flutes), tan_helix,
                float(radius_mm), tuple(ro), steps, periods)
    peaks, mean = np.zeros((n, 4)), np.zeros((n, 4))
    if not live.size:
        return peaks, mean
    with compiling(_row_hash, _simulate):
        first, inverse = unique_rows(key)
        memo = _MEMO.get()
        memo = RunMemo(max_rows=0) if memo is None else memo
        new, pk, mn = memo.recall(settings, key[first])
        if new.size:
            f = lambda a: np.ascontiguousarray(np.asarray(a, dtype=float)[live[first[new]]])  # noqa: E731
            pk[new], mn[new] = _simulate(f(st), f(ex), f(b), f(z), f(dz), f(r), f(kappa), np.asarray(kc, float),
                                         np.asarray(ke, float), float(p), int(flutes), tan_helix, float(radius_mm),
                                         ro, has_runout, f(fz), steps, periods)
            memo.keep(key[first[new]], pk[new], mn[new])
    peaks[live], mean[live] = pk[inverse], mn[inverse]
    return peaks, mean


def cutting_samples(b: np.ndarray) -> np.ndarray:
    """Indices of the samples where some slice cuts: b (N, K) the slices' widths (mm) as `clipped_arcs`
    gives them, 0 where a slice does not cut (every load term of such a sample is 0)."""
    return np.flatnonzero(np.any(b > 0.0, axis=1))


class RunMemo:
    """The runs `simulate` made under one set of settings, by their input row bit for bit (the row's
    arcs, widths, heights, radii, κ per slice and f_z): a row met again gets the same numbers without a
    run (a steady cut repeats its engagement from chunk to chunk). Keeps at most `max_rows` rows
    (memory: ~0.5 KB a row of 8 slices); other settings start it afresh. A row whose hash collides with a
    kept row's is never recalled (its bits differ): it is run each time."""

    def __init__(self, max_rows: int = 50_000) -> None:
        self.max_rows = max_rows
        self._settings: tuple | None = None
        self._forget()

    def _forget(self, columns: int = 0) -> None:
        self._hash = np.empty(0, np.uint64)  # sorted row hashes (`_row_hash`) of the rows kept, and where each is
        self._slot = np.empty(0, np.intp)    # in `_rows` (as bits) and `_runs` ([peaks, mean]), filled in order
        # (memory: the pages of the rows not yet kept are never touched)
        self._rows, self._runs = np.empty((self.max_rows, columns), np.uint64), np.empty((self.max_rows, 8))

    def __len__(self) -> int:
        """The rows kept."""
        return len(self._hash)

    def recall(self, settings: tuple, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(new, peaks, mean) for the distinct input rows `rows` (M, columns): the indices of the rows
        never run, and (M, 4) peaks and means filled where a row was run before (zero elsewhere)."""
        bits = np.ascontiguousarray(rows, np.float64).view(np.uint64)
        if (settings, bits.shape[1]) != (self._settings, self._rows.shape[1]):
            self._settings = settings
            self._forget(bits.shape[1])
        runs, hit = np.zeros((len(rows), 8)), np.zeros(len(rows), bool)
        if len(self):  # a row is known when its hash and then all its bits match a kept row's
            h = _row_hash(bits)
            at = np.minimum(np.searchsorted(self._hash, h), len(self) - 1)
            slot = self._slot[at]
            hit = (self._hash[at] == h) & (self._rows[slot] == bits).all(axis=1)
            runs[hit] = self._runs[slot[hit]]
        return np.flatnonzero(~hit), runs[:, :4], runs[:, 4:]

    def keep(self, rows: np.ndarray, peaks: np.ndarray, mean: np.ndarray) -> None:
        """Remember the runs of these rows, never run before, of the settings of the last `recall` (up to
        `max_rows` in all)."""
        k = len(self)
        m = min(len(rows), self.max_rows - k)
        bits = np.ascontiguousarray(rows[:m], np.float64).view(np.uint64)
        self._rows[k:k + m], self._runs[k:k + m] = bits, np.column_stack([peaks, mean])[:m]
        h = np.concatenate([self._hash, _row_hash(bits)])
        order = np.argsort(h, kind="stable")
        self._hash, self._slot = h[order], np.concatenate([self._slot, np.arange(k, k + m)])[order]


_MEMO: ContextVar[RunMemo | None] = ContextVar("run_memo", default=None)


@contextmanager
def reusing_runs(max_rows: int = 50_000) -> Iterator[RunMemo]:
    """Within: `simulate` runs each distinct input row once over all its calls (`RunMemo` of at most
    max_rows rows), for the same numbers bit for bit (each row's run depends on that row alone)."""
    token = _MEMO.set(memo := RunMemo(max_rows))
    try:
        yield memo
    finally:
        _MEMO.reset(token)


@njit(cache=True)
def _row_hash(u):  # pragma: no cover - compiled
    """64-bit hash per row of a uint64 array: splitmix64's mixer folded over the columns."""
    out = np.empty(u.shape[0], np.uint64)
    for i in range(u.shape[0]):
        h = np.uint64(0x9E3779B97F4A7C15)
        for j in range(u.shape[1]):
            x = h ^ u[i, j]
            x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
            x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
            h = x ^ (x >> np.uint64(31))
        out[i] = h
    return out


def unique_rows(key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first, inverse) for the rows of a float array (N, M): one representative row index per distinct
    row, and per row the position of its representative in `first` (key[first][inverse] == key).
    Rows are told apart bit for bit: a 64-bit hash (splitmix64's mixer folded over the columns) groups
    them, and a row that differs from its group's representative (a hash collision) keeps an entry of
    its own, so the grouping is exact."""
    u = np.ascontiguousarray(key, dtype=np.float64).view(np.uint64).reshape(len(key), -1)
    _, first, inverse = np.unique(_row_hash(u), return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    clash = np.flatnonzero((u != u[first[inverse]]).any(axis=1))
    inverse[clash] = len(first) + np.arange(len(clash))
    return np.r_[first, clash], inverse
