"""Stability lobes (zero-order and semi-discretisation) against closed forms, published examples and an
independent time-domain integration of the milling delay equation.

Zero-order oracle (derived; symmetric single-mode tool, slotting, k = 2e4 N/mm, ζ = 0.02, f_n = 1000 Hz,
N = 4, K_t = 767.01 N/mm², K_r = 0.22008): the eigenvalues of the slot's directional matrix are
λ = π(−K_r ± i), so Λ = −1/(λ G) and a_lim = 2k / (N K_t · g(r)) with
g(r) = [K_r (r² − 1) + 2ζr] / [(1 − r²)² + (2ζr)²]; the minimum is at the r maximising g. Its lobes lie at
n = 60 ω_c / (N (ε + 2kπ)), ω_c = 2π f_c, ε = π − 2 atan(Λ_I/Λ_R). Values: a_lim,min = 0.5164 mm at f_c = 1001.97 Hz,
lobe speeds 27953.8, 9774.4, 5922.6, 4248.5 rpm.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from millpost.stability.frf import Mode, ToolTipFRF
from millpost.stability.lobes import zero_order_limit_mm

K, ZETA, FN, N4, KT, KR = 2e4, 0.02, 1000.0, 4, 767.01, 0.22008
SLOT = dict(phi_st_rad=0.0, phi_ex_rad=math.pi)


def zoa_slot_closed_form() -> tuple[float, float, list[float]]:
    """(a_lim,min mm, f_c Hz, lobe speeds rpm k = 0..3) of the symmetric single-mode slot, in closed form."""
    g = lambda r: (KR * (r * r - 1) + 2 * ZETA * r) / ((1 - r * r) ** 2 + (2 * ZETA * r) ** 2)
    r = minimize_scalar(lambda r: -g(r), bounds=(1.0, 1.1), method="bounded", options={"xatol": 1e-12}).x
    a_min = 2 * K / (N4 * KT * g(r))
    G = 1 / (K * (1 - r * r + 2j * ZETA * r))
    lam = -1 / (math.pi * (-KR + 1j) * G)        # the critical root (the other one gives ~52 mm)
    eps = math.pi - 2 * math.atan(lam.imag / lam.real)
    fc = r * FN
    return a_min, fc, [60 * 2 * math.pi * fc / (N4 * (eps + 2 * k * math.pi)) for k in range(4)]


def test_zero_order_slot_matches_closed_form():
    a_min, fc, speeds = zoa_slot_closed_form()
    assert a_min == pytest.approx(0.5164, abs=1e-4) and fc == pytest.approx(1001.97, abs=0.01)
    assert speeds == pytest.approx([27953.8, 9774.4, 5922.6, 4248.5], rel=1e-4)
    frf = ToolTipFRF.symmetric(Mode(FN, ZETA, K))
    rpm = np.linspace(3500, 40000, 6000)
    a = zero_order_limit_mm(frf, kt_N_per_mm2=KT, kr=KR, flutes=N4, rpm=rpm, **SLOT)
    assert a.min() == pytest.approx(a_min, rel=0.03)
    for s in speeds:  # each lobe's minimum: its depth within 3 %, its speed within 2 %
        near = np.abs(rpm - s) < 0.15 * s
        i = np.argmin(np.where(near, a, np.inf))
        assert a[i] == pytest.approx(a_min, rel=0.03)
        assert rpm[i] == pytest.approx(s, rel=0.02)
    # between two lobes the limit rises well above the minimum (a stable pocket)
    assert a[(rpm > 12000) & (rpm < 27000)].max() > 3 * a_min
