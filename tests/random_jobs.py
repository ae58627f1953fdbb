"""Seeded random jobs for the end-to-end safety check (tests and `benchmarks/random_jobs.py`).

A random job is a short G-code program (lines, arcs in the XY plane, helical arcs, plunges, rapid
repositioning, feed changes), a random tool, one of the built-in materials and machines, random user
limits, and a random engagement per move (radial arc from an up-, down-milling or slotting cut and an
axial depth, air cuts included), given directly instead of simulated, so that every kind of cut is
reached quickly. `run_job` goes through the same code as `millpost optimize` from the engagement on.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from millpost.engagement import Engagement
from millpost.gcode import read_text
from millpost.job import Job
from millpost.machine import Machine
from millpost.materials import Material
from millpost.optimize import Result, schedule_program
from millpost.settings import JobSettings
from millpost.toolpath import RAPID
from millpost.tools import Tool

MATERIALS = ["al6061", "al7075", "steel1045", "ss304", "ti6al4v", "brass", "pom", "mdf", "plywood"]
MACHINES = ["benchtop-belt", "hobby-router", "vmc-small"]
_CACHE: dict[tuple[str, str], object] = {}


def _builtin(kind, name):
    if (kind.__name__, name) not in _CACHE:
        _CACHE[kind.__name__, name] = kind.load(name)
    return _CACHE[kind.__name__, name]


def random_program(rng: np.random.Generator) -> str:
    """A program of 2 to 7 moves after the plunge, within ±20 mm, at programmed feeds of 100–3000 mm/min."""
    rpm = int(rng.uniform(3000, 18000))
    feed = float(rng.uniform(100, 3000))
    out = ["G21 G90 G17 G94", "T1 M6", f"S{rpm} M3", "G0 X0 Y0 Z5", f"G1 Z-1 F{feed:.0f}"]
    p = np.zeros(2)
    z = -1.0
    for _ in range(rng.integers(2, 8)):
        u = rng.random()
        if u < 0.15:  # lift, reposition, plunge
            p = rng.uniform(-20, 20, 2)
            z = -rng.uniform(0.2, 3.0)
            out += ["G0 Z5", f"G0 X{p[0]:.3f} Y{p[1]:.3f}", f"G1 Z{z:.3f} F{rng.uniform(50, 500):.0f}"]
            continue
        fword = f" F{rng.uniform(100, 3000):.0f}" if rng.random() < 0.3 else ""
        if u < 0.5:  # arc (helical sometimes) of 0.3–6 rad about a centre 1–10 mm away
            r = rng.uniform(1.0, 10.0)
            a0 = rng.uniform(0, 2 * math.pi)
            c = p + r * np.array([math.cos(a0), math.sin(a0)])
            cw = rng.random() < 0.5
            sweep = rng.uniform(0.3, 6.0)
            a1 = a0 + math.pi + (-sweep if cw else sweep)
            e = c + r * np.array([math.cos(a1), math.sin(a1)])
            zword = ""
            if rng.random() < 0.3:
                z -= rng.uniform(0.0, 0.5)
                zword = f" Z{z:.3f}"
            ij = c - p
            out.append(f"{'G2' if cw else 'G3'} X{e[0]:.3f} Y{e[1]:.3f}{zword} I{ij[0]:.3f} J{ij[1]:.3f}{fword}")
            # the controller ends the arc on its own radius: keep p on the written numbers
            p = np.round(e, 3)
        else:
            d = rng.normal(size=2)
            p = np.round(p + d / np.linalg.norm(d) * rng.uniform(0.5, 15.0), 3)
            out.append(f"G1 X{p[0]:.3f} Y{p[1]:.3f}{fword}")
    out += ["G0 Z5", "M5", "M30"]
    return "\n".join(out) + "\n"


def random_tool(rng: np.random.Generator) -> Tool:
    d = float(rng.choice([1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0, 12.0, 16.0]))
    shape = str(rng.choice(["flat", "flat", "ball", "bull"]))
    corner = d * rng.uniform(0.05, 0.25) if shape == "bull" else 0.0
    flute = d * rng.uniform(1.5, 4.0)
    return Tool(diameter_mm=d, flutes=int(rng.integers(1, 5)), shape=shape, corner_radius_mm=corner,
                helix_deg=float(rng.uniform(0, 45)), flute_length_mm=flute,
                stickout_mm=flute + d * rng.uniform(0.5, 3.0), material=str(rng.choice(["carbide", "hss"])),
                number=1)


def random_engagement(rng: np.random.Generator, samples, tool: Tool) -> Engagement:
    """Per move one cut: air (none, always on rapids), slot, up- or down-milling at ae/D in 0.02–1,
    axial depth 0.05–2 D."""
    R = tool.radius_mm
    moves = np.unique(samples.move)
    slices = int(rng.integers(1, 5))
    parts, order = [], []
    for m in moves:
        idx = np.flatnonzero(samples.move == m)
        ae = rng.uniform(0.02, 1.0) * 2 * R
        phi = math.acos(max(-1.0, 1 - ae / R))
        kind = 3 if samples.kind[idx[0]] == RAPID else rng.integers(0, 4)
        st, ex = {0: (0.0, math.pi), 1: (0.0, phi), 2: (math.pi - phi, math.pi), 3: (math.nan, math.nan)}[kind]
        ap = rng.uniform(0.05, 2.0) * tool.diameter_mm
        e = Engagement.uniform(np.full(len(idx), st), np.full(len(idx), ex), ap, R, slices=slices)
        if kind == 3:
            e.dz_mm[:] = 0.0
            e.ae_mm[:] = 0.0
            e.area_mm2[:] = 0.0
            e.ap_mm[:] = 0.0
        parts.append(e)
        order.append(idx)
    eng = Engagement.concatenate(parts)
    eng = eng.select(np.argsort(np.concatenate(order), kind="stable"))
    t = samples.tangent.copy()
    t[:, 2] = 0.0
    n = np.linalg.norm(t, axis=1, keepdims=True)
    eng.feed_dir = np.where(n > 1e-9, t / np.where(n > 1e-9, n, 1.0), [1.0, 0.0, 0.0])
    return eng


def random_job(rng: np.random.Generator) -> tuple[Job, str]:
    settings = {"deflection_mm": float(rng.choice([0.01, 0.025, 0.05, 0.1])),
                "lower": "all",  # every limit enforced: the replay checks them all
                "ds_mm": float(rng.uniform(0.15, 0.5)), "model": str(rng.choice(["mechanistic", "kienzle"]))}
    if rng.random() < 0.3:
        settings["feed_max_mm_min"] = float(rng.uniform(200, 4000))
    if rng.random() < 0.2:
        settings["jerk_mm_s3"] = float(rng.uniform(2e3, 2e5))
    job = Job(path=Path("random/job.toml"), program=Path("random/program.nc"), output=Path("random/out.nc"),
              material=_builtin(Material, str(rng.choice(MATERIALS))),
              machine=_builtin(Machine, str(rng.choice(MACHINES))), tools={1: random_tool(rng)},
              stock_box=((-50.0, -50.0, -10.0), (50.0, 50.0, 0.0)), settings=JobSettings(**settings),
              allow=frozenset({"slower", "overload"}))  # random cuts are often too heavy: the schedule, not the refusal, is tested
    return job, random_program(rng)


def run_job(seed: int) -> tuple[Job, Engagement, Result]:
    """Random job number `seed` through limits, schedule, emission, controller replay and the limit check."""
    rng = np.random.default_rng(seed)
    job, text = random_job(rng)
    program = read_text(text, "random.nc")
    samples = program.toolpath.resample(job.settings.ds_mm)
    eng = random_engagement(rng, samples, job.tools[1])
    return job, eng, schedule_program(job, program, samples, eng, trace=True)
