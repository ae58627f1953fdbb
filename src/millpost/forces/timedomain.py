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
def _simulate(st, ex, b, z, dz, r, kappa, kc, ke, p, flutes, tan_helix, radius, runout, fz,
              steps, periods):  # pragma: no cover - compiled
    n, k_slices = st.shape
    pitch = 2.0 * math.pi / flutes
    span = pitch * periods
    dphi = span / steps
    peak_fxy = np.zeros(n)
    peak_t = np.zeros(n)
    mean = np.zeros((n, 4))
    for i in range(n):
        for s in range(steps):
            phi0 = (s + 0.5) * dphi
            fx = 0.0
            fy = 0.0
            fzz = 0.0
            tq = 0.0
            for k in range(k_slices):
                if b[i, k] <= 0.0:
                    continue
                sk = math.sin(kappa[i, k])
                ck = math.cos(kappa[i, k])
                lag_span = dz[i, k] * tan_helix / radius
                m = max(1, int(math.ceil(lag_span / dphi)))
                db = b[i, k] / m
                for sub in range(m):
                    zz = z[i, k] - 0.5 * dz[i, k] + (sub + 0.5) * dz[i, k] / m
                    for j in range(flutes):
                        ph = (phi0 + j * pitch - zz * tan_helix / radius) % (2.0 * math.pi)
                        if ph < st[i, k] or ph > ex[i, k]:
                            continue
                        base = fz[i] * math.sin(ph) * sk
                        h = base + runout[j] - runout[(j - 1) % flutes]
                        for mm in range(2, flutes + 1):
                            hm = mm * base + runout[j] - runout[(j - mm) % flutes]
                            if hm < h:
                                h = hm
                        if h <= 0.0:
                            continue
                        hp = h ** p
                        ft = db * (kc[0] * hp + ke[0])
                        fr = db * (kc[1] * hp + ke[1])
                        fa = db * (kc[2] * hp + ke[2])
                        sp = math.sin(ph)
                        cp = math.cos(ph)
                        rad = fr * sk + fa * ck
                        fx += -ft * cp - rad * sp
                        fy += ft * sp - rad * cp
                        fzz += fa * sk - fr * ck
                        tq += r[i, k] * ft
            fxy = math.sqrt(fx * fx + fy * fy)
            if fxy > peak_fxy[i]:
                peak_fxy[i] = fxy
            if tq > peak_t[i]:
                peak_t[i] = tq
            mean[i, 0] += fx / steps
            mean[i, 1] += fy / steps
            mean[i, 2] += fzz / steps
            mean[i, 3] += tq / steps
    return peak_fxy, peak_t, mean


def simulate(st, ex, b, z, dz, r, kappa, *, kc, ke, p: float, flutes: int, helix_deg: float, radius_mm: float,
             fz_mm, runout_mm=None, steps_per_rev: int = 360) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Peak in-plane |F| (N), peak torque (N·mm) and period-averaged [F_x, F_y, F_z, T] (N, N·mm) per sample.

    Arrays are (N, K) slices as in `Engagement` with arcs already clipped to [0, π] and b = dz/sin κ.
    kc (N/mm² per h^p), ke (N/mm): (3,) for t, r, a. runout_mm: (flutes,) radial offsets or None.
    steps_per_rev sets the angular step 2π/steps_per_rev.
    """
    n = st.shape[0]
    ro = np.zeros(flutes) if runout_mm is None else np.asarray(runout_mm, float)
    if ro.shape != (flutes,):
        raise ValueError(f"runout needs one offset per flute ({flutes}), got {ro.shape}")
    periods = flutes if np.any(ro != 0) else 1
    steps = max(8, int(math.ceil(steps_per_rev * periods / flutes)))
    fz = np.broadcast_to(np.asarray(fz_mm, float), (n,)).astype(float)
    f = lambda a: np.ascontiguousarray(a, dtype=float)  # noqa: E731
    return _simulate(f(st), f(ex), f(b), f(z), f(dz), f(r), f(kappa), f(kc), f(ke), float(p), int(flutes),
                     math.tan(math.radians(helix_deg)), float(radius_mm), ro, fz, steps, periods)
