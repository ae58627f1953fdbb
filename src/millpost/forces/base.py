"""What every force model returns, and the geometry they share.

Frames: the *feed frame* of Altintas (x = feed, y = in-plane normal to the left of x, z = tool axis up)
and machine XYZ. With a vertical tool the feed frame is the machine frame turned about Z by the
heading of the horizontal feed direction (a pure plunge keeps heading +X).

Loads are averages over a tooth period unless named `peak_*` (maximum over a revolution).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..engagement import Engagement
from ..errors import MillpostError
from ..tools.cutter import Tool
from .timedomain import simulate


class NotFittedError(MillpostError):
    """A fitted model was used before `fit` (or before coefficients were given)."""


def feed_frame(feed_dir: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations whose columns are the feed-frame axes x, y, z in machine coordinates."""
    d = np.asarray(feed_dir, float).reshape(-1, 3)
    h = np.hypot(d[:, 0], d[:, 1])
    c = np.where(h > 1e-12, d[:, 0] / np.where(h > 0, h, 1), 1.0)
    s = np.where(h > 1e-12, d[:, 1] / np.where(h > 0, h, 1), 0.0)
    R = np.zeros((len(d), 3, 3))
    R[:, 0, 0], R[:, 1, 0] = c, s          # x: horizontal feed heading
    R[:, 0, 1], R[:, 1, 1] = -s, c         # y = z × x (left of the feed)
    R[:, 2, 2] = 1.0
    return R


def to_machine(feed_dir: np.ndarray, vec_feed: np.ndarray) -> np.ndarray:
    """Rotate (N, 3) vectors from the feed frame to machine XYZ."""
    return np.einsum("nij,nj->ni", feed_frame(feed_dir), vec_feed)


def to_feed(feed_dir: np.ndarray, vec_machine: np.ndarray) -> np.ndarray:
    """Rotate (N, 3) vectors from machine XYZ into the feed frame."""
    return np.einsum("nji,nj->ni", feed_frame(feed_dir), vec_machine)


def immersion(ae_mm: float, diameter_mm: float, *, climb: bool = True) -> tuple[float, float]:
    """Entry and exit angles (rad, Altintas) of a straight flank cut of width ae.

    Climb (down) milling leaves at π, conventional (up) milling enters at 0; ae ≥ D is a slot.
    """
    phi_s = float(np.arccos(1.0 - 2.0 * min(ae_mm / diameter_mm, 1.0)))
    return (np.pi - phi_s, np.pi) if climb else (0.0, phi_s)


def given_cut(tool: Tool, ae_mm, ap_mm, *, climb: bool = True, slices: int | None = None) -> Engagement:
    """Engagement of straight cuts along +X beside a vertical wall: width ae (≥ D is a slot), depth ap.
    ae_mm and ap_mm are scalars or arrays (one sample per pair).

    Each axial slice at height z cuts with its own radius r(z) (corner radius, ball, chamfer): the wall sits
    R − ae from the axis, so the slice engages ae_z = r(z) − (R − ae) and its arc spans
    arccos(1 − ae_z/r(z)). Axial immersion κ(z) = atan2(1, dr/dz) (π/2 on the cylinder).
    slices: axial slices (default 8 on a flat end mill, whose slices are alike, 24 along a profile).
    """
    if slices is None:
        slices = 8 if tool.shape == "flat" else 24
    ae, ap = np.broadcast_arrays(np.atleast_1d(np.asarray(ae_mm, float)), np.atleast_1d(np.asarray(ap_mm, float)))
    if not (np.all(ae > 0) and np.all(ap > 0)):
        raise MillpostError(f"a cut needs ae > 0 and ap > 0 mm, got ae={ae_mm}, ap={ap_mm}")
    n = len(ae)
    dz = (ap / slices)[:, None] * np.ones((1, slices))
    z = (np.arange(slices) + 0.5)[None, :] * dz
    r = tool.radius_at(z)
    eps = 1e-4 * tool.diameter_mm
    z_lo = np.maximum(z - eps, 0.0)
    kappa = np.arctan2(1.0, (tool.radius_at(z + eps) - tool.radius_at(z_lo)) / (z + eps - z_lo))
    ae_c = np.minimum(ae, tool.diameter_mm)
    ae_z = np.clip(r - (tool.radius_mm - ae_c)[:, None], 0.0, 2 * r)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi_s = np.arccos(np.clip(1.0 - ae_z / np.where(r > 0, r, 1.0), -1.0, 1.0))
    cutting = (ae_z > 0) & (r > 0)
    st = np.where(cutting, np.pi - phi_s if climb else 0.0, np.nan)
    ex = np.where(cutting, np.pi if climb else phi_s, np.nan)
    return Engagement(phi_st=st, phi_ex=ex, dz_mm=np.where(cutting, dz, 0.0), z_mm=z, r_mm=r, kappa=kappa,
                      feed_dir=np.tile([1.0, 0.0, 0.0], (n, 1)), ap_mm=ap.copy(), ae_mm=ae_c,
                      volume_mm3=np.full(n, np.nan), area_mm2=np.sum(ae_z * dz, axis=1))


def chip_thinning_factor(ae_mm, diameter_mm: float):
    """Radial chip thinning factor RCTF = f_z / h_max: D / (2·sqrt(ae·(D − ae))) for ae < D/2, else 1.
    Scalar in, float out; array in, array out."""
    ae = np.asarray(ae_mm, float)
    d = diameter_mm
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(ae >= 0.5 * d, 1.0, d / (2.0 * np.sqrt(ae * (d - ae))))
    return float(f) if f.ndim == 0 else f


def max_chip_mm(fz_mm: float, ae_mm: float, diameter_mm: float, kappa: float = np.pi / 2) -> float:
    """Largest uncut chip thickness h_max = f_z·sin κ / RCTF (mm)."""
    return fz_mm * np.sin(kappa) / chip_thinning_factor(ae_mm, diameter_mm)


def mean_chip_mm(fz_mm, phi_st, phi_ex, kappa=np.pi / 2):
    """Mean chip thickness over the engaged arc h_m = f_z sin κ (cos φ_st − cos φ_ex)/(φ_ex − φ_st) (mm)."""
    phi_st, phi_ex = np.asarray(phi_st, float), np.asarray(phi_ex, float)
    return fz_mm * np.sin(kappa) * (np.cos(phi_st) - np.cos(phi_ex)) / (phi_ex - phi_st)


def clipped_arcs(engagement: Engagement) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Entry/exit clipped to [0, π] (chip thickness f_z sin φ is ≤ 0 outside) and the slice width
    b = dz / sin κ (mm) of slices that cut; non-cutting slices get an empty arc and b = 0."""
    st = np.clip(np.nan_to_num(engagement.phi_st, nan=0.0), 0.0, np.pi)
    ex = np.clip(np.nan_to_num(engagement.phi_ex, nan=0.0), 0.0, np.pi)
    ex = np.maximum(ex, st)
    cutting = np.isfinite(engagement.phi_st) & np.isfinite(engagement.phi_ex) & (engagement.dz_mm > 0)
    sk = np.maximum(np.sin(engagement.kappa), 1e-6)
    b = np.where(cutting, engagement.dz_mm / sk, 0.0)
    return st, ex, b


def tool_arrays(tool, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(flutes, radius_mm), each (N,), of one Tool for all samples or a sequence of N Tools (one per
    sample: a fit over cuts with several tools)."""
    tools = [tool] * n if isinstance(tool, Tool) else list(tool)
    if len(tools) != n:
        raise MillpostError(f"one tool per sample needed: {len(tools)} tools for {n} samples")
    return (np.array([t.flutes for t in tools], float), np.array([t.radius_mm for t in tools], float))


def rpm_array(rpm, n: int) -> np.ndarray:
    r = np.broadcast_to(np.asarray(rpm, float), (n,)).astype(float)
    if np.any(r <= 0):
        raise MillpostError("spindle speed must be > 0 rpm for a cutting load")
    return r


@dataclass(frozen=True)
class Measurements:
    """Measured averages per sample for fitting. fz_mm, rpm: (N,) or scalar. force_N: (N, 3) average
    force on the tool in machine XYZ (nan where not measured). power_W: (N,) cutting power (spindle
    power minus the air-cut baseline), nan where not measured. Give either or both."""

    fz_mm: np.ndarray
    rpm: np.ndarray
    force_N: np.ndarray | None = None
    power_W: np.ndarray | None = None


@dataclass(frozen=True)
class Loads:
    """Predicted loads per sample at the given feed. Forces are those the cut exerts on the tool.

    force_feed_N: (N, 3) average over a tooth period in the feed frame. force_N: (N, 3) the same in
    machine XYZ. peak_force_xy_N: (N,) largest in-plane |F| over a revolution (bends the tool).
    torque_Nm, power_W: (N,) average spindle torque and cutting power. peak_torque_Nm: (N,).
    """

    force_feed_N: np.ndarray
    force_N: np.ndarray
    peak_force_xy_N: np.ndarray
    torque_Nm: np.ndarray
    peak_torque_Nm: np.ndarray
    power_W: np.ndarray


@dataclass(frozen=True)
class LinearLoads:
    """Loads as affine functions of the path feed v (mm/s) per sample: load(v) = a·v + b.

    force_a, force_b: (N, 3) machine-XYZ average force, N/(mm/s) and N. peak_a, peak_b: (N,) an upper
    bound of the peak in-plane |F| per revolution. torque_a/b (N·m), power_a/b (W): (N,).
    `exact` is True when the affine form is the model itself (mechanistic); otherwise (Kienzle) every
    quantity is the tangent at `feed_ref_mm_min` of a concave law, hence an upper bound for all v ≥ 0
    that is exact at the reference.

    For a convex scheduler: ‖F_xy(v)‖ = ‖a_xy·v + b_xy‖ ≤ F_max is a second-order cone in v (the vector
    tangent is a valid bound because all components share one exponent); tool deflection is
    compliance·‖F_xy‖ with compliance = ToolBeam.of(tool).compliance_mm_per_N(engagement.ap_mm) per sample,
    so δ ≤ δ_max is the same cone with F_max = δ_max / compliance (on the peak: peak_a·v + peak_b ≤ F_max is
    one linear row); torque and power are one linear row each.
    """

    force_a: np.ndarray
    force_b: np.ndarray
    peak_a: np.ndarray
    peak_b: np.ndarray
    torque_a: np.ndarray
    torque_b: np.ndarray
    power_a: np.ndarray
    power_b: np.ndarray
    exact: bool
    feed_ref_mm_min: np.ndarray | None = None

    @classmethod
    def per_minute(cls, **arrays) -> "LinearLoads":
        """The loads from slopes per mm/min of feed (the models' chip per tooth f_z = v/(z·n) of a spindle
        at n rpm), stored per mm/s: each `*_a` × 60."""
        return cls(**{k: v * 60.0 if k.endswith("_a") else v for k, v in arrays.items()})

    @classmethod
    def zeros(cls, n: int) -> "LinearLoads":
        """No load at any of n samples (to be filled per tool); `exact` False: a sum of exact and tangent
        laws is only an upper bound."""
        z = {f"{key}_{ab}": np.zeros(n) for key in ("peak", "torque", "power") for ab in "ab"}
        return cls(force_a=np.zeros((n, 3)), force_b=np.zeros((n, 3)), **z, exact=False)

    def select(self, index) -> "LinearLoads":
        """The loads of some samples (an index or a slice)."""
        arrays = {f.name: getattr(self, f.name)[index] for f in fields(self) if f.name.endswith(("_a", "_b"))}
        ref = None if self.feed_ref_mm_min is None else self.feed_ref_mm_min[index]
        return LinearLoads(**arrays, exact=self.exact, feed_ref_mm_min=ref)

    def force_at(self, feed_mm_s) -> np.ndarray:
        """(N, 3) average force (N) at feed v (mm/s, scalar or (N,))."""
        v = np.asarray(feed_mm_s, float)
        return self.force_a * (v[..., None] if v.ndim else v) + self.force_b


def assemble_loads(engagement: Engagement, tool: Tool, avg: np.ndarray, fz: np.ndarray, rpm, *, kc, ke, p: float,
                   runout_mm=None, steps_per_rev: int = 360, peaks: bool = True) -> Loads:
    """`Loads` from the closed-form averages avg (N, 4) = [F_x, F_y, F_z (feed frame, N), T (N·mm)] plus,
    when `peaks`, a time-domain run of the elemental law (kc, ke, p) for the peaks per revolution."""
    omega = 2 * np.pi * rpm_array(rpm, len(engagement)) / 60.0
    if peaks:
        st, ex, b = clipped_arcs(engagement)
        pk, _ = simulate(st, ex, b, engagement.z_mm, engagement.dz_mm, engagement.r_mm, engagement.kappa,
                         kc=kc, ke=ke, p=p, flutes=tool.flutes, helix_deg=tool.helix_deg,
                         radius_mm=tool.radius_mm, fz_mm=fz, runout_mm=runout_mm, steps_per_rev=steps_per_rev)
    else:
        pk = np.full((len(engagement), 4), np.nan)
    torque = avg[:, 3] / 1000.0
    return Loads(force_feed_N=avg[:, :3], force_N=to_machine(engagement.feed_dir, avg[:, :3]),
                 peak_force_xy_N=pk[:, 0], torque_Nm=torque, peak_torque_Nm=pk[:, 3] / 1000.0,
                 power_W=torque * omega)
