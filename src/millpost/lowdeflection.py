"""Zero-normal-force engagement: the radial width at which the mean cutting force normal to the feed vanishes.

A structure much slower than the tooth passing (a robot arm, a machine's frame) follows the mean force
of a cut, not its ripple. Along a wall, the mean force normal to the feed moves the tool into or off the
wall, so the wall comes out wrong by that force over the structure's stiffness; the force along the feed
only delays the tool along its path. Choosing the width at which the mean normal force is zero removes
the first error: the robot-milling strategy of cutting against the feed (conventional milling) at the
engagement where the mean force orthogonal to the feed vanishes, which gave 30 % less deviation from the
desired geometry than the usual cuts there.

Sign convention (`forces.given_cut`, Altintas): a straight cut along +X, feed frame x = feed,
y = in-plane normal to the left of the feed; the cutter turns clockwise seen from the spindle and the
tooth angle φ runs clockwise from +y, chip h = f_z sin φ. Conventional (up) milling engages φ ∈ [0, φ_s]
on the +y side: the tooth meets the finished wall with a zero chip and its edge there moves along the
feed, i.e. against the work's feed ("against the feed"); climb (down) milling engages [π − φ_s, π] on
the −y side. Forces are those on the tool.

Mean forces per tooth period of a flat end mill, N teeth, depth a (Altintas, *Manufacturing Automation*,
2nd ed., ch. 2), conventional:

    F̄_y = (N a f_z / 8π)[K_tc (2φ_s − sin 2φ_s) − K_rc (1 − cos 2φ_s)]
          + (N a / 2π)[K_te (1 − cos φ_s) − K_re sin φ_s]

Each bracket is negative for a thin cut (the radial force pushes the tool off the wall) and positive for a
slot (the tangential force pulls it in), with one sign change each: the shearing root (φ_s ≈ 3 K_rc / 2 K_tc
for small ratios) and the edge root φ_s = 2 atan(K_re / K_te); the root of the sum lies between them, nearer
the edge root at thin chips. So conventional milling has a root whenever K_rc or K_re > 0. Climb milling
changes both minus signs to plus: F̄_y > 0 at every width, no root (the tool is always pushed off the wall).
The root here is found on the model's own mean force (any force model, any tool shape), not on this formula.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from .errors import MillpostError
from .forces import given_cut, immersion
from .machine import Machine
from .tools.beam import ToolBeam
from .tools.cutter import Tool

SCAN_WIDTHS = 48        # geometric grid of widths (1e-4 D .. D) on which the sign changes are looked for
ROOT_TOLERANCE = 1e-6   # a root's |mean normal force| at most this × |mean feed force| (else a jump of the feed)


@dataclass(frozen=True)
class MeanDeflection:
    """Static deflection (mm) under the mean force of a straight cut beside a wall. normal: toward the wall
    (> 0 the tool bends into the material and overcuts, < 0 it leaves material); feed: along the feed
    (< 0 the tool lags). tool_*: the tool as a beam, at the load point (mid-depth); machine_*: the axes'
    stiffness (feed along X, normal along Y), None without a machine."""

    tool_normal_mm: float
    tool_feed_mm: float
    machine_normal_mm: float | None = None
    machine_feed_mm: float | None = None

    @classmethod
    def of(cls, force_feed_N: float, force_normal_N: float, tool: Tool, ap_mm: float,
           machine: Machine | None = None) -> "MeanDeflection":
        """From the mean force along the feed and toward the wall (N) of a cut at depth ap_mm."""
        c = float(ToolBeam.of(tool).compliance_mm_per_N(ap_mm))
        if machine is None:
            return cls(c * force_normal_N, c * force_feed_N)
        dx, dy, _ = machine.deflection_mm([force_feed_N, force_normal_N, 0.0])
        return cls(c * force_normal_N, c * force_feed_N, float(dy), float(dx))


def toward_wall(force_y_N, climb: bool):
    """The feed-frame normal force F_y (N) as a force toward the wall: the wall is at +y in conventional
    milling, at −y in climb milling."""
    return force_y_N if not climb else -np.asarray(force_y_N)


@dataclass(frozen=True)
class ZeroNormalForce:
    """The width ae_mm (mm) at which the mean force normal to the feed vanishes, for feed per tooth fz_mm
    and depth ap_mm. engagement_deg: immersion angle of the full-radius edge. F_feed_N: the mean force
    left along the feed (on the tool, < 0 against the feed); F_normal_N: the residual normal force (root
    tolerance). deflection: under the mean force."""

    ae_mm: float
    fz_mm: float
    ap_mm: float
    climb: bool
    engagement_deg: float
    F_feed_N: float
    F_normal_N: float
    deflection: MeanDeflection


def zero_normal_force(tool: Tool, model, *, fz_mm: float | Callable[[np.ndarray], np.ndarray], ap_mm: float,
                      climb: bool = False, machine: Machine | None = None) -> ZeroNormalForce:
    """Root in ae ∈ (0, D] of the model's mean normal force (the module docstring): the sign changes on a
    geometric grid of widths from 10⁻⁴ D, in order, each solved by Brent's method; the first whose normal
    force is within `ROOT_TOLERANCE` of the feed force is the root. fz_mm: a feed per tooth (mm), or a
    function of the widths (array, mm) giving one per width (a feed that follows the width, nan where no
    feed is feasible: a feed that jumps makes a sign change that is no root). Refuses when the mean normal
    force has no root: no sign change (climb milling; a model without radial force), or none among the
    widths with a feasible feed."""
    d = tool.diameter_mm
    feed = fz_mm if callable(fz_mm) else (lambda ae: np.full(len(ae), float(fz_mm)))

    def force(ae: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        fz = np.asarray(feed(ae), float)
        ok = np.isfinite(fz) & (fz > 0)
        f = np.full((len(ae), 3), np.nan)
        if ok.any():
            eng = given_cut(tool, ae[ok], np.full(ok.sum(), ap_mm), climb=climb)
            f[ok] = model.predict(eng, fz[ok], 1000.0, tool, peaks=False).force_feed_N
        return f[:, 0], toward_wall(f[:, 1], climb), fz

    def normal(ae: float) -> float:
        value = float(force(np.array([ae]))[1][0])
        if not math.isfinite(value):
            raise MillpostError(f"no feasible feed per tooth at width {ae:.6g} mm while solving for zero normal force")
        return value

    widths = d * np.geomspace(1e-4, 1.0, SCAN_WIDTHS)
    _, fn, _ = force(widths)
    changes = np.flatnonzero(np.isfinite(fn[:-1]) & np.isfinite(fn[1:]) & (np.sign(fn[:-1]) != np.sign(fn[1:])))
    for k in changes:
        ae = brentq(normal, widths[k], widths[k + 1], xtol=1e-12 * d, rtol=4 * np.finfo(float).eps)
        fx, fy, fz = (float(v[0]) for v in force(np.array([ae])))
        if abs(fy) <= ROOT_TOLERANCE * abs(fx):
            st, ex = immersion(ae, d, climb=climb)
            return ZeroNormalForce(ae_mm=float(ae), fz_mm=fz, ap_mm=ap_mm, climb=climb,
                                   engagement_deg=math.degrees(ex - st), F_feed_N=fx, F_normal_N=fy,
                                   deflection=MeanDeflection.of(fx, fy, tool, ap_mm, machine))
    side = "climb" if climb else "conventional"
    feasible = np.isfinite(fn)
    if len(changes):
        raise MillpostError(f"the mean force normal to the feed changes sign only where the feed per tooth jumps "
                            f"(near ae = {', '.join(f'{widths[k]:.4g}' for k in changes)} mm): no root")
    if not feasible.all():
        span = (f"{widths[feasible].min():.4g}–{widths[feasible].max():.4g} mm" if feasible.any() else "none")
        raise MillpostError(f"no radial width with a feasible feed makes the mean force normal to the feed zero "
                            f"in {side} milling (widths with a feed: {span} of (0, {d:g}] mm)")
    raise MillpostError(f"no radial width in (0, {d:g}] mm makes the mean force normal to the feed zero in "
                        f"{side} milling with this tool and force model (normal force from "
                        f"{np.nanmin(fn):.4g} to {np.nanmax(fn):.4g} N toward the wall, no sign change"
                        f"{'; climb milling pushes the tool off the wall at every width' if climb else ''}"
                        "; conventional milling needs a radial force coefficient > 0)")
