"""Measured runs for `millpost discover` made without millpost's motion or forces: the jobs of
`discover_runs.write_job` (slots and side cuts in a box at spread feeds, depths, widths and speeds, a
nominal material ±20 % off the true coefficients), run by the independent generator
(`independent_log.generate`: its own program reader, exact-stop trapezoid motion, swept-stock engagement,
per-tooth force integration, its own clock) with one hidden effect or none, logged at 100 Hz with
positions, forces and spindle power, white noise 1–5 % of each channel's RMS."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from discover_runs import BOX, TRUE, Run, write_job
from independent_log import Mill, generate
from millpost.measure import Log

CHANNELS = ("x_mm", "y_mm", "z_mm", "fx_N", "fy_N", "fz_N", "spindle_power_W")


def make_run(folder: Path, seed: int, effect: str, channels: tuple[str, ...] = CHANNELS) -> Run:
    job_path, _, (diameter, flutes), _ = write_job(folder, seed)
    rng = np.random.default_rng(2000 + seed)
    mill = Mill(diameter_mm=diameter, flutes=flutes, helix_deg=35, flute_length_mm=2.5 * diameter,
                K=tuple(TRUE[k] for k in ("Ktc", "Krc", "Kac", "Kte", "Kre", "Kae")), idle_W=(0.0, 0.0),
                accel_mm_s2=float(rng.uniform(300, 900)), rapid_mm_min=float(rng.uniform(4000, 9000)),
                slice_mm=0.25)
    g = generate((folder / "program.nc").read_text(), ((0.0, 0.0, -BOX[2]), (BOX[0], BOX[1], 0.0)), mill,
                 rate_hz=100.0, epoch_s=float(rng.uniform(-100, 100)), noise=0.0, noise_N=0.0,
                 noise_rms=float(rng.uniform(0.01, 0.05)), hidden=effect, seed=seed, channels=channels)
    return Run(job_path, Log(g.columns, path=str(folder / "log.csv")), effect, g.truth)
