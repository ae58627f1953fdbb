"""A seeded generator of measured runs for `millpost discover`, with one hidden effect (or none).

The job: straight passes in a box stock (slots, and side cuts along both long edges at varied depth, width,
feed and rpm) with one flat end mill; its material file holds the true mechanistic coefficients each
scaled by a random factor in [0.8, 1.2] (a nominal set ±20 % off); an ordinary job.toml.

The "measurement" is simulated here, independently of millpost's engagement and force code: for every log
row (100 Hz) the cutter's edge is swept around the circle (1° steps) on axial slices, each edge point is
tested against the box minus the swept volumes of the earlier passes (its own engagement, no height field),
and the mechanistic law (Altintas: dF_t = (K_tc h + K_te) dz, h = f_z sin φ, …) is integrated numerically
over the engaged points, N/(2π) per unit angle: the mean force and torque over a tooth period. Only the
motion (time, position, speed, acceleration of the tool) comes from millpost's controller model, which is
not what discover tests. Hidden effects are put into this simulation with physical strengths; noise is
white, a fraction (1–5 %) of each channel's RMS. The size effect is a Kienzle material (k(h) = k(h_ref)·
(h/h_ref)^(−m_c) in every direction, no separate edge force, m_c 0.15–0.35 as published for common
materials): what the job's linear edge-force law (K_c·h + K_e) misses of it once refitted is the curvature
of h^(1−m_c) over the job's chip thicknesses, f_z·sin φ with f_z over FZ_MM.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from millpost.config import dump_toml, load_description
from millpost.job import load_job
from millpost.measure import Log
from millpost.signals import simulate

TRUE = {"Ktc": 631.0, "Krc": 99.0, "Kac": 273.0, "Kte": 13.0, "Kre": 10.0, "Kae": 2.8}
TOOLS = ((6.0, 3), (10.0, 4), (8.0, 2))    # diameter (mm), flutes
BOX = (80.0, 80.0, 20.0)                   # length X, width Y, height (top at z = 0)
FZ_MM = (0.006, 0.15)
H_REF_MM = 0.05                            # reference chip thickness of the size effect (mm)
EDGE_FREE = {"Kte": 0.0, "Kre": 0.0, "Kae": 0.0}                      # feed per tooth range of a job: finishing to roughing
EFFECTS = ("none", "tool_wear", "size_effect", "deflection", "inertia", "sensor_lag", "spindle_no_load",
           "sensor_drift", "axis_friction", "runout")
KT_TO_MECH = {"Ktc": "Ktc_N_mm2", "Krc": "Krc_N_mm2", "Kac": "Kac_N_mm2", "Kte": "Kte_N_per_mm",
              "Kre": "Kre_N_per_mm", "Kae": "Kae_N_per_mm"}


@dataclass
class Pass:
    y_mm: float
    depth_mm: float
    feed_mm_min: float
    rpm: float


def passes(rng: np.random.Generator, diameter: float, flutes: int) -> list[Pass]:
    """Two or three slots (depth 0.2–1 D), then two side cuts along y = 0 (climb) and two along y = W
    (conventional), each a fresh strip of width 0.1–0.5 D and depth 0.4–1.5 D; every pass at its own
    speed (4000–10000 rpm, at least 200 mm/min where it can) and feed per tooth (FZ_MM, spread over the range)."""
    R = diameter / 2
    out = []
    for k in range(int(rng.integers(2, 4))):
        out.append(Pass(18.0 + 16.0 * k, rng.uniform(0.2, 1.0) * diameter, 0, 0))
    y0 = -R
    for _ in range(2):
        y0 += rng.uniform(0.1, 0.5) * diameter
        out.append(Pass(y0, rng.uniform(0.4, 1.5) * diameter, 0, 0))
    y1 = BOX[1] + R
    for _ in range(2):
        y1 -= rng.uniform(0.1, 0.5) * diameter
        out.append(Pass(y1, rng.uniform(0.4, 1.5) * diameter, 0, 0))
    # feeds per tooth spread over the whole range in every job (stratified, log scale), in random order
    levels = np.exp(np.log(FZ_MM[0]) + (np.arange(len(out)) + rng.uniform(0, 1, len(out))) / len(out)
                    * np.log(FZ_MM[1] / FZ_MM[0]))
    for p, fz in zip(out, rng.permutation(levels)):
        p.rpm = float(np.round(rng.uniform(min(max(4000.0, 200.0 / (fz * flutes)), 10000.0), 10000.0), -2))
        p.feed_mm_min = float(np.round(p.rpm * flutes * fz, -1))
        p.y_mm, p.depth_mm = round(p.y_mm, 3), round(p.depth_mm, 3)
    return out


def write_job(folder: Path, seed: int) -> tuple[Path, list[Pass], tuple[float, int], dict[str, float]]:
    """A job folder: program.nc, material.toml (nominal coefficients ±20 % off), job.toml."""
    rng = np.random.default_rng(seed)
    diameter, flutes = TOOLS[seed % len(TOOLS)]
    plan = passes(rng, diameter, flutes)
    R = diameter / 2
    lines = ["(discover test: straight passes in a box)", "G21 G90 G17 G94", "T1 M6", "G0 Z5"]
    for p in plan:
        lines += [f"S{p.rpm:.0f} M3", f"G0 X{-R - 3:.3f} Y{p.y_mm:.3f}", f"G1 Z{-p.depth_mm:.3f} F300",
                  f"G1 X{BOX[0] + R + 3:.3f} F{p.feed_mm_min:.0f}", "G0 Z5"]
    lines += ["M5", "M30"]
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "program.nc").write_text("\n".join(lines) + "\n")
    data, _ = load_description("materials", "al6061")
    nominal = {k: TRUE[k] * rng.uniform(0.8, 1.2) for k in TRUE}
    data["mechanistic"].update({KT_TO_MECH[k]: round(v, 3) for k, v in nominal.items()})
    data["name"] = "al6061-nominal"
    (folder / "material.toml").write_text(dump_toml(data))
    job = {"program": "program.nc", "material": "material.toml", "machine": "vmc-small",
           "stock": {"box": [[0, 0, -BOX[2]], [BOX[0], BOX[1], 0]], "cell_mm": 0.1},
           "tools": {"1": {"diameter_mm": diameter, "flutes": flutes, "shape": "flat", "helix_deg": 35,
                           "flute_length_mm": 2.5 * diameter, "stickout_mm": 4 * diameter}},
           "limits": {"ds_mm": 0.25}}
    (folder / "job.toml").write_text(dump_toml(job))
    return folder / "job.toml", plan, (diameter, flutes), nominal


def _removed(pts: np.ndarray, z: np.ndarray, done: list[tuple[float, float, float, float]]) -> np.ndarray:
    """Whether points (…, 2) at heights z lie inside the swept volume of an earlier pass (x from a to b at
    y, tool radius R, bottom at zb): within R of the segment in plan and above its bottom."""
    out = np.zeros(pts.shape[:-1], bool)
    for a, b, y, R, zb in done:
        dx = np.maximum(np.maximum(a - pts[..., 0], pts[..., 0] - b), 0.0)
        out |= (dx ** 2 + (pts[..., 1] - y) ** 2 < R * R) & (z >= zb)
    return out


def cutting_loads(xyz: np.ndarray, vel: np.ndarray, rpm: np.ndarray, diameter: float, flutes: int,
                  coef: dict[str, float], plan: list[Pass], *, size_m: float = 0.0, h_ref: float = H_REF_MM,
                  wear: np.ndarray | None = None, offset_xy: np.ndarray | None = None):
    """Mean force on the tool (n, 3, machine XYZ) and torque (n, N·m) per row by angle-domain integration.
    size_m: shearing coefficients × (h/h_ref)^(−m) per edge element; wear: factor per row on every
    coefficient; offset_xy: (n, 2) tool centre displacement (deflection)."""
    n = len(xyz)
    R = diameter / 2
    F = np.zeros((n, 3))
    T = np.zeros(n)
    speed = np.hypot(vel[:, 0], vel[:, 1])
    active = (xyz[:, 2] < -1e-6) & (speed > 1e-6) & (rpm > 0)
    phi = np.deg2rad(np.arange(0.5, 180.0, 1.0))          # front half: h = f_z sin φ > 0
    dphi = np.deg2rad(1.0)
    # pass k spans the rows whose y is its y (straight passes along +X)
    done: list = []
    for p in plan:
        rows = np.flatnonzero(active & (np.abs(xyz[:, 1] - p.y_mm) < 1e-6) & (np.abs(xyz[:, 2] + p.depth_mm) < 1e-6))
        if len(rows):
            c = xyz[rows, :2].copy()
            if offset_xy is not None:
                c += offset_xy[rows]
            d = vel[rows, :2] / speed[rows, None]
            nrm = np.column_stack([-d[:, 1], d[:, 0]])
            fz = speed[rows] * 60.0 / (flutes * rpm[rows])
            # axial layers between the depths of the earlier passes: the material is a z-prism within each,
            # so one slice per layer integrates the straight-fluted edge exactly
            levels = sorted({-p.depth_mm, 0.0, *(zb for *_, zb in done if -p.depth_mm < zb < 0)})
            for z0, z1 in zip(levels[:-1], levels[1:]):
                z, dz = 0.5 * (z0 + z1), z1 - z0
                pts = c[:, None, :] + R * (np.sin(phi)[None, :, None] * d[:, None, :]
                                           + np.cos(phi)[None, :, None] * nrm[:, None, :])
                inside = ((pts[..., 0] >= 0) & (pts[..., 0] <= BOX[0]) & (pts[..., 1] >= 0) & (pts[..., 1] <= BOX[1])
                          & (z >= -BOX[2]) & ~_removed(pts, np.full(pts.shape[:-1], z), done))
                h = fz[:, None] * np.sin(phi)[None, :]
                scale = (np.maximum(h, 1e-6) / h_ref) ** (-size_m) if size_m else 1.0
                w = wear[rows, None] if wear is not None else 1.0
                ft = w * (coef["Ktc"] * scale * h + coef["Kte"]) * dz
                fr = w * (coef["Krc"] * scale * h + coef["Kre"]) * dz
                fa = w * (coef["Kac"] * scale * h + coef["Kae"]) * dz
                k = flutes / (2 * np.pi) * dphi * inside
                fx = np.sum(k * (-ft * np.cos(phi) - fr * np.sin(phi)), 1)
                fy = np.sum(k * (ft * np.sin(phi) - fr * np.cos(phi)), 1)
                F[rows, :2] += fx[:, None] * d + fy[:, None] * nrm
                F[rows, 2] += np.sum(k * fa, 1)
                T[rows] += np.sum(k * ft, 1) * R / 1000.0
        done.append((-1e9, 1e9, p.y_mm, R, -p.depth_mm))   # the pass runs through the whole length
    return F, T


def lag(t: np.ndarray, x: np.ndarray, tau: float, substeps: int = 10) -> np.ndarray:
    """First-order lag τ ẏ = x − y, integrated on a grid `substeps` finer than the rows (x linear between)."""
    tf = np.linspace(t[0], t[-1], (len(t) - 1) * substeps + 1)
    xf = np.interp(tf, t, x)
    a = np.exp(-(tf[1] - tf[0]) / tau)
    y = np.empty_like(xf)
    y[0] = xf[0]
    for i in range(1, len(xf)):
        y[i] = a * y[i - 1] + (1 - a) * xf[i]
    return np.interp(t, tf, y)


@dataclass
class Run:
    job_path: Path
    log: Log
    effect: str
    truth: dict


def runout(tau, rpm, F, T, shear, vel, flutes: int, rng, truth: dict, substeps: int = 8):
    """Mean loads per row with the chip of each flute changed by runout: flute j sits ρ·cos(ψ − 2πj/N)
    further out, so its chip is f_z·sin φ + r_j − r_(j−1) and its shearing load (the `shear` part of F, T)
    scales by 1 + (r_j − r_(j−1))/f_z while it cuts; the log row is the mean over its interval of the
    flute in the cut (spindle angle ∫Ω dt, sub-steps per row)."""
    rho = truth["runout_mm"] = rng.uniform(0.004, 0.008)
    psi = rng.uniform(0, 2 * np.pi)
    r = rho * np.cos(psi - 2 * np.pi * np.arange(flutes) / flutes)
    delta = r - np.roll(r, 1)
    speed = np.hypot(vel[:, 0], vel[:, 1])
    fz = np.where(rpm > 0, speed * 60.0 / (flutes * np.maximum(rpm, 1.0)), 0.0)
    dt = np.gradient(tau)
    theta0 = np.cumsum(2 * np.pi * rpm / 60.0 * dt)
    factor = np.zeros(len(tau))
    for k in range(substeps):
        theta = theta0 + 2 * np.pi * rpm / 60.0 * dt * (k + 0.5) / substeps
        j = np.floor(theta * flutes / (2 * np.pi)).astype(np.int64) % flutes
        factor += np.maximum(1 + delta[j] / np.maximum(fz, 1e-9), 0.0) / substeps
    Fs, Ts = shear
    return F + Fs * (factor - 1)[:, None], T + Ts * (factor - 1)


def make_run(folder: Path, seed: int, effect: str, *, noise: float | None = None, rate_hz: float | None = None,
             signals_cache: dict | None = None) -> Run:
    """One measured run with `effect` hidden (or "none"), seeded; logged at rate_hz (default 100 Hz, and
    1 kHz for runout: once-per-revolution content needs several rows per revolution)."""
    rate_hz = rate_hz if rate_hz is not None else (1000.0 if effect == "runout" else 100.0)
    job_path, plan, (diameter, flutes), _ = write_job(folder, seed)
    rng = np.random.default_rng(1000 + seed)
    key = str(job_path)
    if signals_cache is not None and key in signals_cache:
        sig = signals_cache[key]
    else:
        sig = simulate(load_job(job_path))
        if signals_cache is not None:
            signals_cache[key] = sig
    drawn = rng.uniform(0.01, 0.05)          # drawn always, so that a given noise leaves the rest of the run as is
    noise = drawn if noise is None else noise
    offset = rng.uniform(-1.0, 3.0)
    tau = (rng.uniform(0, 1) + np.arange(int((sig.t_s[-1] + 1.0) * rate_hz))) / rate_hz - 0.5
    xyz = np.column_stack([np.interp(tau, sig.t_s, sig.xyz_mm[:, k]) for k in range(3)])
    vel = np.column_stack([np.interp(tau, sig.t_s, sig.axis_velocity_mm_s[:, k]) for k in range(3)])
    acc = np.column_stack([np.interp(tau, sig.t_s, sig.axis_accel_mm_s2[:, k]) for k in range(3)])
    # the straight cut rows: snap to the pass (interpolation between samples leaves y, z exact on a pass)
    rpm = sig.rpm[np.clip(np.searchsorted(sig.t_s, tau, side="right") - 1, 0, len(sig) - 1)]
    coef = dict(TRUE)
    truth: dict = {"effect": effect, "noise": noise, "offset_s": offset}
    kwargs: dict = {}
    if effect == "tool_wear":
        F0, _ = cutting_loads(xyz, vel, rpm, diameter, flutes, coef, plan)
        cutting = np.hypot(F0[:, 0], F0[:, 1]) > 1e-6
        dt = np.gradient(tau)
        length_m = np.cumsum(np.hypot(vel[:, 0], vel[:, 1]) * dt * cutting) / 1000.0
        rise = rng.uniform(0.3, 0.5)              # coefficients up 30–50 % by the end of the run
        kwargs["wear"] = 1 + rise * length_m / length_m[-1]
        truth["wear_per_m"] = rise / length_m[-1]
    elif effect == "size_effect":
        # a Kienzle material: k(h) = k(h_ref)·(h/h_ref)^(−m_c) in every direction and no separate edge force,
        # equal to the linear law at h_ref (k(h_ref) = K_c + K_e/h_ref); m_c 0.15–0.35, the published range
        # for common materials (ISO 513 / VDI 3323 tables: 0.17–0.30, aluminium 0.25)
        kwargs["size_m"] = truth["m"] = rng.uniform(0.15, 0.35)
        coef = {c: TRUE[c] + TRUE[e] / H_REF_MM for c, e in zip(("Ktc", "Krc", "Kac"), ("Kte", "Kre", "Kae"))} | EDGE_FREE
    F, T = cutting_loads(xyz, vel, rpm, diameter, flutes, coef, plan, **kwargs)
    if effect == "deflection":
        # a slender tool: the median in-plane force of the cuts bends it by 5–10 % of its diameter
        cut = np.hypot(F[:, 0], F[:, 1])
        C = truth["compliance_mm_per_N"] = rng.uniform(0.05, 0.1) * diameter / np.median(cut[cut > 1e-6])
        offset_xy = np.zeros((len(F), 2))
        for _ in range(8):     # the tool bends along the force on it (damped fixed point)
            offset_xy = 0.5 * (offset_xy + C * F[:, :2])
            F, T = cutting_loads(xyz, vel, rpm, diameter, flutes, coef, plan, offset_xy=offset_xy)
    if effect == "runout":   # the mean loads vary slowly: the shearing share on every 10th row, interpolated
        Fs, Ts = cutting_loads(xyz[::10], vel[::10], rpm[::10], diameter, flutes, coef | EDGE_FREE, plan)
        Fs = np.column_stack([np.interp(tau, tau[::10], Fs[:, k]) for k in range(3)])
        F, T = runout(tau, rpm, F, T, (Fs, np.interp(tau, tau[::10], Ts)), vel, flutes, rng, truth)
    omega = 2 * np.pi * rpm / 60.0
    power = T * omega
    work = -F                                              # force on the workpiece
    if effect == "inertia":
        m = truth["mass_kg"] = rng.uniform(40, 100)
        work = work - m * acc / 1000.0
    if effect == "spindle_no_load":
        c2 = truth["c2_W_per_krpm2"] = rng.uniform(4, 8)
        power = power + np.where(rpm > 0, c2 * (rpm / 1000) ** 2, 0.0)
    columns = {"t_s": tau + offset, "x_mm": xyz[:, 0], "y_mm": xyz[:, 1], "z_mm": xyz[:, 2], "spindle_rpm": rpm,
               "fx_N": work[:, 0], "fy_N": work[:, 1], "fz_N": work[:, 2], "spindle_power_W": power}
    if effect == "axis_friction":
        # axis currents: inertia + cutting force along the axis (+ the hidden friction), through K_t/ρ
        k_a, k_f = 0.004, 0.0025                           # A per mm/s², A per N
        for k, ax in enumerate("xy"):
            coul, visc = rng.uniform(0.3, 0.8), rng.uniform(0.002, 0.006)
            truth[f"coulomb_{ax}_A"], truth[f"viscous_{ax}_A_per_mm_s"] = coul, visc
            columns[f"i{ax}_A"] = (k_a * acc[:, k] + k_f * F[:, k] + coul * np.sign(np.round(vel[:, k], 6))
                                   + visc * vel[:, k])
    if effect == "sensor_lag":
        tl = truth["tau_s"] = rng.uniform(0.08, 0.3)
        for c in ("fx_N", "fy_N", "fz_N"):
            columns[c] = lag(tau, columns[c], tl)
    for c in [c for c in columns if c.endswith(("_N", "_W", "_A"))]:
        v = columns[c]
        rms = float(np.sqrt(np.mean(v * v)))
        if effect == "sensor_drift" and c in ("fx_N", "fy_N", "fz_N", "spindle_power_W"):
            d = truth[f"drift_{c}_per_s"] = rng.choice([-1, 1]) * rng.uniform(0.2, 0.4) * rms / tau[-1]
            v = v + d * (tau - tau[0])
        columns[c] = v + rng.normal(0.0, noise * rms, len(v))
    return Run(job_path, Log(columns, path=str(folder / "log.csv")), effect, truth)
