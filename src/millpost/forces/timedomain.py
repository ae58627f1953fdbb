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

import numpy as np
from numba import njit


@njit(cache=True)
def _simulate(st, ex, b, z, dz, r, kappa, kc, ke, p, flutes, tan_helix, radius, runout, has_runout, fz,
              steps, periods):  # pragma: no cover - compiled
    n, k_slices = st.shape
    two_pi = 2.0 * math.pi
    pitch = two_pi / flutes
    dphi = pitch * periods / steps
    peaks = np.zeros((n, 4))     # |F_xy| total, |F_xy| shearing part, |F_xy| edge part, torque
    mean = np.zeros((n, 4))
    acc = np.zeros((6, steps))   # per angular step: shear x, y; edge x, y; z; torque
    for i in range(n):
        acc[:, :] = 0.0
        for k in range(k_slices):
            if b[i, k] <= 0.0:
                continue
            sk = math.sin(kappa[i, k])
            ck = math.cos(kappa[i, k])
            m = max(1, int(math.ceil(dz[i, k] * tan_helix / radius / dphi)))
            db = b[i, k] / m
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
                        for s in range(s0, s1 + 1):
                            ph = (s + 0.5) * dphi + off - shift
                            sp = math.sin(ph)
                            h = fz[i] * sp * sk
                            if has_runout:
                                base = h
                                h = base + runout[j] - runout[(j - 1) % flutes]
                                for mm in range(2, flutes + 1):
                                    hm = mm * base + runout[j] - runout[(j - mm) % flutes]
                                    if hm < h:
                                        h = hm
                            if h <= 0.0:
                                continue
                            hp = h if p == 1.0 else h ** p
                            cp = math.cos(ph)
                            # shearing (∝ h^p) and edge parts kept apart for the linear peak bound
                            ft = db * kc[0] * hp
                            rad = db * hp * (kc[1] * sk + kc[2] * ck)
                            et = db * ke[0]
                            erad = db * (ke[1] * sk + ke[2] * ck)
                            acc[0, s] += -ft * cp - rad * sp
                            acc[1, s] += ft * sp - rad * cp
                            acc[2, s] += -et * cp - erad * sp
                            acc[3, s] += et * sp - erad * cp
                            acc[4, s] += db * ((kc[2] * hp + ke[2]) * sk - (kc[1] * hp + ke[1]) * ck)
                            acc[5, s] += r[i, k] * (ft + et)
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
    # identical samples (a cut that does not change along a move) are simulated once
    key = np.column_stack([np.asarray(a, float).reshape(n, st.shape[1]) for a in (st, ex, b, z, dz, r, kappa)] + [fz])
    key = np.nan_to_num(key, nan=-1e300)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    f = lambda a: np.ascontiguousarray(np.asarray(a, dtype=float)[first])  # noqa: E731
    peaks, mean = _simulate(f(st), f(ex), f(b), f(z), f(dz), f(r), f(kappa), np.asarray(kc, float),
                            np.asarray(ke, float), float(p), int(flutes), math.tan(math.radians(helix_deg)),
                            float(radius_mm), ro, has_runout, f(fz), steps, periods)
    inverse = inverse.reshape(-1)
    return peaks[inverse], mean[inverse]
