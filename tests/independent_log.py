"""An independent log generator: what a mill and its sensors record while running a simple G-code
program, computed without any of millpost's code (reader, controller, engagement, forces, signals).

- Program: its own reader of G0/G1/G4, X/Y/Z/F/S, M3/M5 in absolute millimetres (what `calibrate plan`
  writes), one move per motion line.
- Motion: exact stop at the end of every move, a trapezoidal speed profile of its own acceleration and
  rapid rate, a feed override, feed holds (the tool stops mid-move, waits, goes on).
- Engagement: a box of stock minus the volumes swept by the earlier moves (a flat end mill of radius R
  removes everything within R of its axis above its tip), tested at every tooth point: no height field,
  no arcs in closed form.
- Forces: per tooth and axial slice, the linear edge-force law on the chip thickness h = f_z·(f̂·û)
  (û the tooth's outward radial unit, f̂ the feed direction), integrated over the flutes and the helix
  at the instant of every sub-sample; the logger averages its sample interval (anti-alias boxcar).
  Force on the tool: −dF_t along the tooth's velocity (clockwise spindle seen from above), −dF_r along
  û, +dF_a along +Z; the log holds the force on the workpiece, its negative.
- Spindle: torque ΣdF_t·R, power T·ω plus a no-load power a + b·n, current √(I₀² + (T/K_t)²).
- Axis currents: i = k_a·a + k_c·sgn v + k_v·v − k_f·F_tool,axis (+ a constant gravity load on Z).
- The log: its own clock (epoch, rate, jitter), rows dropped at random, rows only while feeding, a part
  of the program only; seeded noise. Hidden effects a model may lack are switched on by name
  (`HIDDEN`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

HIDDEN = ("none", "tool_wear", "size_effect", "deflection", "inertia", "sensor_lag", "spindle_no_load",
          "sensor_drift")
H_REF_MM = 0.05     # reference chip thickness of the size effect (mm)


@dataclass(frozen=True)
class Move:
    """One program move: kind rapid/feed/dwell, start and end (mm), feed (mm/min), spindle (rpm), the
    program line, dwell seconds."""

    kind: str
    start: tuple[float, float, float]
    end: tuple[float, float, float]
    feed_mm_min: float
    rpm: float
    line: int
    dwell_s: float = 0.0


def read_moves(text: str) -> list[Move]:
    """The moves of a program in absolute millimetres (G0, G1, G4 P seconds; S, M3, M5)."""
    pos, feed, rpm, on, motion = (0.0, 0.0, 0.0), 0.0, 0.0, False, "G0"
    out = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        code = re.sub(r"\(.*?\)|;.*$", "", raw).upper()
        words = dict()
        gs = []
        for letter, value in re.findall(r"([A-Z])\s*([-+]?\d*\.?\d+)", code):
            if letter == "G":
                gs.append(float(value))
            elif letter == "M":
                m = int(float(value))
                on = True if m in (3, 4) else False if m in (5, 2, 30) else on
            else:
                words[letter] = float(value)
        if "S" in words:
            rpm = words["S"]
        if "F" in words:
            feed = words["F"]
        for g in gs:
            if g in (0.0, 1.0):
                motion = f"G{int(g)}"
            elif g == 4.0:
                out.append(Move("dwell", pos, pos, 0.0, rpm if on else 0.0, lineno, words.get("P", 0.0)))
        if any(k in words for k in "XYZ") and 4.0 not in gs:
            end = tuple(words.get(a, p) for a, p in zip("XYZ", pos))
            if end != pos:
                out.append(Move("rapid" if motion == "G0" else "feed", pos, end, feed, rpm if on else 0.0, lineno))
            pos = end
    return out


@dataclass
class Mill:
    """The machine the log comes from: its motion, cutter, material law, spindle and drives."""

    accel_mm_s2: float = 450.0
    rapid_mm_min: float = 5000.0
    override: float = 1.0
    diameter_mm: float = 6.0
    flutes: int = 3
    helix_deg: float = 35.0
    flute_length_mm: float = 16.0
    K: tuple[float, ...] = (631.0, 99.0, 273.0, 13.0, 10.0, 2.8)   # Ktc Krc Kac N/mm², Kte Kre Kae N/mm
    idle_W: tuple[float, float] = (60.0, 0.025)                     # a + b·n (W, W/rpm)
    kt_Nm_per_A: float = 0.7
    idle_current_A: float = 1.5
    # k_a A/(mm/s²), k_c A, k_v A/(mm/s), k_f A/N
    drive: tuple[float, float, float, float] = (0.002, 0.35, 0.004, 0.004)
    gravity_z_A: float = 0.0
    slices: int = 12
    slice_mm: float = 0.1
    sub_samples: int = 16


@dataclass
class Segment:
    move: int
    line: int
    kind: str
    t0: float
    p0: np.ndarray
    p1: np.ndarray
    v_mm_s: float
    a_mm_s2: float
    rpm: float
    dwell_s: float = 0.0

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.p1 - self.p0))

    @property
    def duration(self) -> float:
        if self.kind == "dwell":
            return self.dwell_s
        L, v, a = self.length, self.v_mm_s, self.a_mm_s2
        if L <= v * v / a:
            return 2 * np.sqrt(L / a)
        return L / v + v / a

    def state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(distance along, speed, acceleration) at times t since the segment's start."""
        L, v, a = self.length, self.v_mm_s, self.a_mm_s2
        if self.kind == "dwell" or L == 0:
            z = np.zeros_like(t)
            return z, z, z
        vp = min(v, np.sqrt(L * a))
        ta = vp / a
        T = self.duration
        t = np.clip(t, 0, T)
        s = np.where(t < ta, 0.5 * a * t * t, np.where(t > T - ta, L - 0.5 * a * (T - t) ** 2, 0.5 * a * ta * ta
                                                         + vp * (t - ta)))
        sp = np.where(t < ta, a * t, np.where(t > T - ta, a * (T - t), vp))
        acc = np.where(t < ta, a, np.where(t > T - ta, -a, 0.0))
        return s, sp, acc


def timeline(moves: list[Move], mill: Mill, holds: dict[int, tuple[float, float]] | None = None) -> list[Segment]:
    """Segments on the machine's clock: every move exact-stop; holds {move: (fraction, seconds)} stop that
    move part way and wait."""
    holds = holds or {}
    out, t = [], 0.0
    for k, m in enumerate(moves):
        p0, p1 = np.array(m.start, float), np.array(m.end, float)
        if m.kind == "dwell":
            seg = Segment(k, m.line, "dwell", t, p0, p0, 0.0, 1.0, m.rpm, m.dwell_s)
            out.append(seg)
            t += seg.duration
            continue
        v = (mill.rapid_mm_min if m.kind == "rapid" else min(m.feed_mm_min * mill.override, mill.rapid_mm_min)) / 60
        parts = [(p0, p1)]
        if k in holds:
            f, wait = holds[k]
            pm = p0 + f * (p1 - p0)
            parts = [(p0, pm), None, (pm, p1)]
        for part in parts:
            if part is None:
                seg = Segment(k, m.line, "dwell", t, pm, pm, 0.0, 1.0, m.rpm, wait)
            else:
                seg = Segment(k, m.line, m.kind, t, part[0], part[1], v, mill.accel_mm_s2, m.rpm)
            out.append(seg)
            t += seg.duration
    return out


@dataclass
class Stock:
    box: tuple[tuple[float, float, float], tuple[float, float, float]]
    cuts: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)   # earlier tool sweeps

    def material(self, q: np.ndarray, radius: float, before: int) -> np.ndarray:
        """Whether points q (…, 3) are stock left by the first `before` sweeps."""
        lo, hi = np.array(self.box[0]), np.array(self.box[1])
        inside = np.all((q >= lo) & (q <= hi), axis=-1)
        q_lo, q_hi = q.reshape(-1, 3).min(0) - radius, q.reshape(-1, 3).max(0) + radius
        for p0, p1 in self.cuts[:before]:
            if (np.any(np.minimum(p0, p1)[:2] > q_hi[:2]) or np.any(np.maximum(p0, p1)[:2] < q_lo[:2])
                    or min(p0[2], p1[2]) > q_hi[2]):
                continue
            d = p1[:2] - p0[:2]
            L2 = float(d @ d)
            rel = q[..., :2] - p0[:2]
            u = np.clip((rel @ d) / L2, 0, 1) if L2 > 0 else np.zeros(q.shape[:-1])
            near = np.sum((rel - u[..., None] * d) ** 2, axis=-1) <= radius * radius
            # the tip's height where the sweep passes closest (exact for level moves and plunges)
            zt = np.minimum(p0[2], p1[2]) if L2 == 0 else p0[2] + u * (p1[2] - p0[2])
            inside &= ~(near & (q[..., 2] >= zt))
        return inside


def tool_loads(mill: Mill, stock: Stock, before: int, centre: np.ndarray, feed_dir: np.ndarray, fz: np.ndarray,
               angle: np.ndarray, K: np.ndarray, size_m: float = 0.0, bend: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """Force on the tool (M, 3) N and torque (M,) N·m at tool tips `centre` (M, 3), feed unit `feed_dir`
    (3,), feed per tooth fz (M,), rotation angle `angle` (M,) of flute 0 at the tip; K (M, 6) coefficients.
    size_m: the shearing coefficients × (h/H_REF_MM)^(−size_m) per edge element (a Kienzle material);
    bend: (M, 2) the tool's lateral displacement (mm): its edge cuts where the bent tool is (the chip
    thickness stays the feed's)."""
    R = mill.diameter_mm / 2
    M = len(centre)
    # slices over the flutes up to the stock's top (an exact depth where the top bounds the cut)
    top = float(np.clip(stock.box[1][2] - centre[:, 2].min(), 1e-6, mill.flute_length_mm))
    slices = max(mill.slices, int(np.ceil(top / mill.slice_mm)))
    dz = top / slices
    z = (np.arange(slices) + 0.5) * dz
    lag = z * np.tan(np.radians(mill.helix_deg)) / R
    teeth = 2 * np.pi * np.arange(mill.flutes) / mill.flutes
    psi = angle[:, None, None] + teeth[None, :, None] + lag[None, None, :]          # (M, N, L)
    u = np.stack([np.cos(psi), np.sin(psi), np.zeros_like(psi)], -1)
    vel = np.stack([np.sin(psi), -np.cos(psi), np.zeros_like(psi)], -1)             # clockwise from above
    q = centre[:, None, None, :] + R * u
    if bend is not None:
        q[..., :2] += bend[:, None, None, :]
    q[..., 2] = centre[:, None, None, 2] + z[None, None, :]
    f_h = np.array([feed_dir[0], feed_dir[1], 0.0])
    norm = np.linalg.norm(f_h)
    proj = (u @ (f_h / norm)) if norm > 1e-9 else np.zeros(psi.shape)
    h = fz[:, None, None] * proj
    cut = (h > 0) & stock.material(q, R, before)
    h = np.where(cut, h, 0.0)
    k = K[:, None, None, :]
    hs = h * (np.maximum(h, 1e-6) / H_REF_MM) ** (-size_m) if size_m else h
    Ft = np.where(cut, k[..., 0] * hs + k[..., 3], 0.0) * dz
    Fr = np.where(cut, k[..., 1] * hs + k[..., 4], 0.0) * dz
    Fa = np.where(cut, k[..., 2] * hs + k[..., 5], 0.0) * dz
    F = -Ft[..., None] * vel - Fr[..., None] * u
    F[..., 2] += Fa
    return F.reshape(M, -1, 3).sum(1), Ft.reshape(M, -1).sum(1) * R / 1000.0


@dataclass
class Generated:
    columns: dict[str, np.ndarray]
    truth: dict
    segments: list[Segment]


def _strength(hidden: str, mill: Mill, rng: np.random.Generator) -> dict:
    """The hidden effect's physical size, drawn: wear +30–50 % by the end; m_c 0.15–0.35 (published for
    common materials); a tool bent by 5–10 % of its diameter at a typical load; a 40–100 kg table; a
    0.08–0.3 s sensor lag; 4–8 W per krpm² of drag."""
    if hidden == "tool_wear":
        return {"rise": rng.uniform(0.3, 0.5)}
    if hidden == "size_effect":
        return {"m": rng.uniform(0.15, 0.35)}
    if hidden == "deflection":   # at the force of a slot 0.5 D deep at f_z 0.05 mm
        Ktc, Krc, _, Kte, Kre, _ = mill.K
        ap, fz, N = 0.5 * mill.diameter_mm, 0.05, mill.flutes
        typical = np.hypot(N * ap * Ktc * fz / 4 + N * ap * Kte / np.pi, N * ap * Krc * fz / 4 + N * ap * Kre / np.pi)
        return {"compliance_mm_per_N": rng.uniform(0.05, 0.1) * mill.diameter_mm / typical}
    if hidden == "inertia":
        return {"mass_kg": rng.uniform(40, 100)}
    if hidden == "sensor_lag":
        return {"tau_s": rng.uniform(0.08, 0.3)}
    if hidden == "spindle_no_load":
        return {"c2_W_per_krpm2": rng.uniform(4, 8)}
    return {}


def generate(text: str, box, mill: Mill, *, rate_hz: float = 250.0, epoch_s: float = 1234.5, jitter: float = 0.1,
             drop: float = 0.0, holds: dict[int, tuple[float, float]] | None = None, feeding_only: bool = False,
             lines: tuple[int, int] | None = None, noise: float = 0.02, noise_N: float = 1.0, noise_rms: float = 0.0,
             position_noise_mm: float = 0.002, hidden: str = "none", seed: int = 0,
             channels: tuple[str, ...] = ("x_mm", "y_mm", "z_mm", "fx_N", "fy_N", "fz_N", "spindle_power_W",
                                          "spindle_current_A", "ix_A", "iy_A", "iz_A")) -> Generated:
    """A log of the program `text` run on `mill` in a stock `box` (see the module docstring). lines:
    (first, last) program lines the log covers (a partial log); hidden: one of HIDDEN (its size drawn,
    `_strength`; in .truth). Noise: each row × (1 + noise·N(0, 1)) + N(0, σ), σ = noise_N for forces and
    noise × the channel's RMS for the others, plus noise_rms × the channel's RMS for all."""
    if hidden not in HIDDEN:
        raise ValueError(hidden)
    rng = np.random.default_rng(seed)
    truth: dict = {"hidden": hidden, **_strength(hidden, mill, rng)}
    moves = read_moves(text)
    segs = timeline(moves, mill, holds)
    stock = Stock(box, [(s.p0, s.p1) for s in segs if s.kind != "dwell"])
    sweep_index = np.cumsum([s.kind != "dwell" for s in segs]) - np.array([s.kind != "dwell" for s in segs])
    end = segs[-1].t0 + segs[-1].duration
    dt = 1.0 / rate_hz
    t = np.arange(0.0, end, dt) + rng.uniform(0, dt)
    t = t + rng.uniform(-jitter, jitter, len(t)) * dt * 0.5
    t = np.sort(t[(t >= 0) & (t < end)])
    starts = np.array([s.t0 for s in segs])
    which = np.searchsorted(starts, t, side="right") - 1
    n = len(t)
    xyz, speed, acc3, vel3 = np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3))
    force, torque, rpm = np.zeros((n, 3)), np.zeros(n), np.zeros(n)
    K0 = np.array(mill.K, float)
    S = mill.sub_samples
    for k, seg in enumerate(segs):
        rows = np.flatnonzero(which == k)
        rpm[rows] = seg.rpm
        if seg.kind == "dwell" or seg.length == 0:
            xyz[rows] = seg.p0
            continue
        direction = (seg.p1 - seg.p0) / seg.length
        s, v, a = seg.state(t[rows] - seg.t0)
        xyz[rows] = seg.p0 + s[:, None] * direction
        speed[rows], vel3[rows], acc3[rows] = v, v[:, None] * direction, a[:, None] * direction
        if seg.rpm <= 0 or not len(rows):
            continue
        # the logger's boxcar over the sample interval before each row, by one sub-sample at a random
        # instant in each of S equal parts of it (evenly spaced ones would alias with the tooth passing)
        tt = (t[rows, None] - seg.t0 - dt * (np.arange(S) + rng.uniform(0, 1, (len(rows), S))) / S).ravel()
        ss, vv, _ = seg.state(tt)
        centre = seg.p0 + ss[:, None] * direction
        omega = 2 * np.pi * seg.rpm / 60
        fz = vv * 60 / (mill.flutes * seg.rpm)
        K = np.tile(K0, (len(tt), 1))
        size_m = 0.0
        if hidden == "size_effect":   # a Kienzle material: no edge force, k(h) = k(h_ref)·(h/h_ref)^(−m)
            size_m = truth["m"]
            K[:, :3] += K[:, 3:] / H_REF_MM
            K[:, 3:] = 0.0
        lo, hi = np.array(box[0]) - mill.diameter_mm, np.array(box[1]) + mill.diameter_mm
        near = np.all((centre >= lo) & (centre <= hi), axis=1) & (centre[:, 2] < box[1][2])
        F = np.zeros((len(tt), 3))
        T = np.zeros(len(tt))
        if near.any():
            phase = -omega * tt[near] + rng.uniform(0, 2 * np.pi)
            args = (mill, stock, int(sweep_index[k]), centre[near], direction, fz[near], phase, K[near], size_m)
            F[near], T[near] = tool_loads(*args)
            if hidden == "deflection":   # the tool bends along the force on it (damped fixed point)
                bend = np.zeros((int(near.sum()), 2))
                for _ in range(4):
                    bend = 0.5 * (bend + truth["compliance_mm_per_N"] * F[near, :2])
                    F[near], T[near] = tool_loads(*args, bend=bend)
        force[rows] = F.reshape(len(rows), S, 3).mean(1)
        torque[rows] = T.reshape(len(rows), S).mean(1)
    omega = 2 * np.pi * rpm / 60
    engaged = np.linalg.norm(force, axis=1) > 1e-6
    if hidden == "tool_wear":   # every coefficient × (1 + rise·L/L_end), L the engaged path so far
        length = np.cumsum(speed * np.diff(t, prepend=t[0]) * engaged)
        wear = 1 + truth["rise"] * length / max(length[-1], 1e-9)
        force, torque = force * wear[:, None], torque * wear
    idle = np.where(rpm > 0, mill.idle_W[0] + mill.idle_W[1] * rpm, 0.0)
    if hidden == "spindle_no_load":   # a drag the machine file lacks, growing with the square of the speed
        idle = idle + truth["c2_W_per_krpm2"] * (rpm / 1000) ** 2
    power = torque * omega + idle
    shaft = np.where(omega > 0, power / np.where(omega > 0, omega, 1), 0.0)
    current = np.where(rpm > 0, np.sqrt(mill.idle_current_A ** 2 + (shaft / mill.kt_Nm_per_A) ** 2), 0.0)
    ka, kc, kv, kf = mill.drive
    axis_i = ka * acc3 + kc * np.sign(np.round(vel3, 9)) + kv * vel3 - kf * force
    axis_i[:, 2] += mill.gravity_z_A
    work = -force
    if hidden == "inertia":   # the dynamometer moves with the table and reads the workpiece's m·a too
        work = work - truth["mass_kg"] * acc3 / 1000.0
    if hidden == "sensor_lag":   # a first-order lag of the force sensor
        alpha = 1 - np.exp(-np.diff(t, prepend=t[0]) / truth["tau_s"])
        for i in range(1, n):
            work[i] = work[i - 1] + alpha[i] * (work[i] - work[i - 1])
    if hidden == "sensor_drift":   # the zeros of forces and power drift linearly with time
        for c, v in (("fx_N", work[:, 0]), ("fy_N", work[:, 1]), ("fz_N", work[:, 2]), ("spindle_power_W", power)):
            r = float(np.sqrt(np.mean(v * v)))
            d = truth[f"drift_{c}_per_s"] = rng.choice([-1, 1]) * rng.uniform(0.2, 0.4) * r / (t[-1] - t[0])
            v += d * (t - t[0])
    rms = lambda v: float(np.sqrt(np.mean(v * v))) if len(v) else 0.0  # noqa: E731
    clean = {"x_mm": xyz[:, 0], "y_mm": xyz[:, 1], "z_mm": xyz[:, 2], "fx_N": work[:, 0], "fy_N": work[:, 1],
             "fz_N": work[:, 2], "spindle_power_W": power, "spindle_current_A": current, "ix_A": axis_i[:, 0],
             "iy_A": axis_i[:, 1], "iz_A": axis_i[:, 2]}
    keep = np.ones(n, bool)
    if feeding_only:
        keep &= np.array([segs[w].kind == "feed" for w in which])
    if lines is not None:
        line = np.array([segs[w].line for w in which])
        keep &= (line >= lines[0]) & (line <= lines[1])
    if drop:
        keep &= rng.uniform(size=n) >= drop
    cols = {"t_s": epoch_s + t[keep]}
    for c in channels:
        v = clean[c][keep]
        if c.endswith("_mm"):
            cols[c] = v + rng.normal(0, position_noise_mm, len(v))
        else:
            cols[c] = v * (1 + noise * rng.standard_normal(len(v))) + rng.normal(
                0, (noise_N if c.startswith("f") else noise * rms(v)) + noise_rms * rms(v), len(v))
    truth.update({"K": K0, "rows": int(keep.sum()), "program_end_s": end,
                  "line": np.array([segs[w].line for w in which])[keep], "t_machine_s": t[keep]})
    return Generated(cols, truth, segs)
