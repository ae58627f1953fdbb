"""Stability-lobe benchmark: prints one JSON object with the time to compute the limiting depth at 500 speeds
by the zero-order method and by semi-discretisation, their ratio, and each one's peak Python-heap memory
(tracemalloc, so numpy's buffers count; the interpreter and imported modules do not).

Case: the Insperger–Stépán milling benchmark (N = 2, K_t = 600 N/mm², K_r = 1/3, one mode f_n = 922 Hz,
ζ = 0.011, k = 1340.05 N/mm in X and Y), down-milling at a/D = 0.05 and slotting, 5000–25000 rpm.
Also the lowest limit of each (mm) and, for the low immersion, the largest SD/ZOA ratio (a flip lobe).

Run: PYTHONPATH=src python benchmarks/stability_lobes.py [--speeds 500] [--steps 40]
"""

from __future__ import annotations

import argparse
import json
import math
import time
import tracemalloc

import numpy as np

from millpost.forces.base import immersion
from millpost.stability.frf import Mode, ToolTipFRF
from millpost.stability.lobes import semi_discretisation_limit_mm, zero_order_limit_mm


def timed(fn, **kw) -> tuple[np.ndarray, float, float]:
    """(result, seconds, peak traced MB) of one call."""
    tracemalloc.start()
    t = time.perf_counter()
    out = fn(**kw)
    seconds = time.perf_counter() - t
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    return out, seconds, peak


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--speeds", type=int, default=500)
    ap.add_argument("--steps", type=int, default=40)
    args = ap.parse_args()
    frf = ToolTipFRF.symmetric(Mode(922.0, 0.011, 0.03993 * (2 * math.pi * 922.0) ** 2 / 1e3))
    rpm = np.linspace(5000.0, 25000.0, args.speeds)
    rows = {}
    for name, ae in (("down_aD_0.05", 0.05), ("slot", 1.0)):
        st, ex = immersion(ae, 1.0, climb=True)
        kw = dict(frf=frf, kt_N_per_mm2=600.0, kr=1 / 3, flutes=2, phi_st_rad=st, phi_ex_rad=ex, rpm=rpm)
        zo, t_zo, m_zo = timed(zero_order_limit_mm, **kw)
        sd, t_sd, m_sd = timed(semi_discretisation_limit_mm, steps=args.steps, **kw)
        rows[name] = {"zoa_s": round(t_zo, 3), "sd_s": round(t_sd, 3), "sd_over_zoa_time": round(t_sd / t_zo, 1),
                      "zoa_peak_mb": round(m_zo, 1), "sd_peak_mb": round(m_sd, 1),
                      "zoa_min_mm": round(float(zo.min()), 4), "sd_min_mm": round(float(sd.min()), 4),
                      "max_zoa_over_sd": round(float(np.max(zo / sd)), 2)}
    print(json.dumps({"speeds": args.speeds, "sd_steps": args.steps, "cases": rows}))


if __name__ == "__main__":
    main()
