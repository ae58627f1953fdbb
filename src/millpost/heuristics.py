"""Roughing parameters (axial depth, radial width, spindle speed, feed) from machining heuristics.

The variables a realtime feed cannot change quickly are chosen here, before CAM. For a tool, a material
and a machine, every candidate (ae, ap, rpm) gets the largest feed per tooth that keeps all limits, and
the candidate with the highest material removal rate wins. The limits, with their sources:

- surface speed window of the tool/material pair (material file; Tungaloy, Amana, Machinery's Handbook
  table) and the spindle's speed range → rpm window;
- chip load with radial chip thinning: f_z = h_target · RCTF(ae), RCTF = D / (2 sqrt(ae (D − ae))) for
  ae < D/2 (machinecalcs.com radial chip thinning; PHYSICS.md §3.1), h_target the middle of the material's
  chip-load range at this diameter (Tungaloy catalogue; PHYSICS.md §3.3) — keeps the real maximum chip on
  target as ae shrinks;
- minimum chip: h_max ≥ h_min = ratio · edge radius, else the edge rubs (Cheng 2018; PHYSICS.md §3.4);
- tool beam: deflection under the peak in-plane force ≤ max deflection (0.025 mm default, Ingersoll's
  0.001 in), peak force ≤ breaking force / safety factor (PHYSICS.md §4);
- spindle power (hence torque) at the chosen rpm (machine spindle curve, §5.3);
- axis thrust: the feed-direction force within what the X drive can push at that speed (§5.2);
- feed range: the machine's maximum feed, the user's min/max traversal rate, and a cap on the dynamic
  range between corners and open passes (the reference's 100 mm/s: above it, acceleration at corners
  dominates and the programmed feed is never reached);
- chatter (with the tool tip's FRF, `Limits.frf`): ap ≤ a_lim, the zero-order stability lobes' limiting
  depth at the cut's speed and immersion (`stability.chatter_limit`; Altintas & Budak 1995). The speeds
  searched are then `CHATTER_SPEEDS` spread over the window (a lobe's pocket is a few % wide), and
  unstable candidates are dropped before their feed is solved;
- among candidates within `tie_tolerance` of the best removal rate, the fastest feed wins (the
  reference's preference for fast, light passes over slow, heavy ones). With an FRF, only the candidates
  within `CHATTER_TIE` (3 %) of the best removal rate at the highest lobe take part (a_lim at their
  width and speed, counted up to `SAFE_MARGIN` = 1.25 × their depth): a speed near a pocket's top
  rather than on a lobe's flank, where a small error in the FRF or the speed tips the cut into chatter;
  at one speed the deepest stable cut, so that `chatter` binds when it decides the depth.

With a strategy (adaptive, slot, profile, face, low-deflection) the search keeps to a machinist's rules
for it, from the material file's `[strategies]` table with their sources: the radial width range of
adaptive clearing, profiling and facing, the deepest full-width slot (chips must leave a closed slot),
the deepest facing pass. low-deflection mills conventionally at the width where the mean force normal
to the feed vanishes for the tool, force model and the cut's own feed (`millpost.lowdeflection`), so a
compliant structure is not pushed into or off the wall. Entry moves are never fed like the cut: the
ramp feed is the full-width ramp at the material's steepest ramp angle under the same limits, and at
most `ramp_feed_ratio` of the cutting feed; the plunge feed takes the axial feed per tooth f_ax = `plunge_fz_ratio` · h_target on the
whole end edge (no chip thinning there), lowered where the end-edge torque M = z·k_c(h)·h·R²/2 (Kienzle,
k_c = k_c1.1·h^−m_c, the bottom edges as a 180° drill) exceeds the spindle's torque, and never above
the ramp feed. The answer names the rules that bind, as it names the physical limits.

Loads come from the same models as `millpost calc` (`evaluate_cut`), so an independent `calc` of the
answer satisfies every limit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import product

import math

import numpy as np

from .cut import evaluate_cut
from .errors import MillpostError
from .forces import Kienzle, Mechanistic, chip_thinning_factor, given_cut, immersion
from .lowdeflection import MeanDeflection, toward_wall, zero_normal_force
from .machine import Machine
from .materials import STRATEGIES, STRATEGY_KINDS, Material, Strategy
from .progress import Progress, silent
from .tools.beam import ToolBeam
from .stability.chatter_limit import ChatterLimit
from .stability.frf import ToolTipFRF
from .tools.cutter import Tool


SEARCH_STEPS_PER_REV = 90    # coarse angular resolution while searching; the answer is re-solved at full
ZERO_NORMAL_GRIDS = ((8, 4), (5, 3), (5, 3))   # low-deflection (depths, speeds) grids: whole ranges, then finer
FIXED_POINT_ROUNDS = 12      # secant rounds of the low-deflection width before the bracketing solve
CHATTER_SPEEDS = 61          # speeds of the first search grid with an FRF (geometric: ~2 % apart over 3:1)
CHATTER_TIE = 0.03           # with an FRF: removal rates this close count as equal, the higher lobe wins
SAFE_MARGIN = 1.25           # ... counted up to this × the cut's depth (a choice: higher buys nothing here)


@dataclass(frozen=True)
class Limits:
    """User limits. max_deflection_mm: tool deflection at the cut. safety_factor: on the tool's bending
    strength (None: chosen from the geometry). feed_min/max_mm_min: traversal rate range (max None: the
    machine's). dynamic_range_mm_s: largest feed change between corners and open passes. chip_load_mm:
    target maximum chip thickness (None: the material's guidance). frf: the tool tip's FRF (None: no
    chatter limit)."""

    max_deflection_mm: float = 0.025
    safety_factor: float | None = None
    feed_min_mm_min: float = 0.0
    feed_max_mm_min: float | None = None
    dynamic_range_mm_s: float = 100.0
    chip_load_mm: float | None = None
    frf: ToolTipFRF | None = None

    def __post_init__(self) -> None:
        if self.max_deflection_mm <= 0 or self.dynamic_range_mm_s <= 0 or self.feed_min_mm_min < 0:
            raise MillpostError("limits must be positive (deflection, dynamic range) and feed_min >= 0")


@dataclass(frozen=True)
class Recommendation:
    """Chosen cut and its predicted loads (mm, rpm, mm/min, mm³/min, N, N·m, W). `binding` names the
    limits and strategy rules at their bound (ratio ≥ 0.999); `ratios` gives every limit's load over its
    bound. ramp_feed_mm_min: along a full-width ramp at the material's ramp angle; plunge_feed_mm_min:
    straight down (both below the cutting feed). climb: climb (down) milling, else conventional;
    engagement_deg: immersion angle; mean_deflection: tool and machine under the mean force, normal to
    the wall and along the feed. a_lim_mm: the chatter limit's depth at the cut (None without an FRF)."""

    ap_mm: float
    ae_mm: float
    rpm: float
    fz_mm: float
    feed_mm_min: float
    mrr_mm3_min: float
    h_max_mm: float
    chip_target_mm: float
    vc_m_min: float
    F_avg_N: tuple[float, float, float]
    F_peak_N: float
    deflection_mm: float
    break_ratio: float
    torque_Nm: float
    power_W: float
    ramp_feed_mm_min: float
    plunge_feed_mm_min: float
    binding: tuple[str, ...]
    climb: bool
    engagement_deg: float
    mean_deflection: MeanDeflection
    ratios: dict[str, float] = field(default_factory=dict)
    strategy: str | None = None
    a_lim_mm: float | None = None


@dataclass(frozen=True)
class _Setup:
    tool: Tool
    material: Material
    machine: Machine
    limits: Limits
    model: Mechanistic | Kienzle
    search_model: Mechanistic | Kienzle
    beam: ToolBeam
    chip_target_mm: float
    h_min_mm: float
    rpm_lo: float
    rpm_hi: float
    rpm_hi_reason: str
    feed_cap_mm_min: float
    feed_cap_reason: str
    ap_max_mm: float
    strategy: str | None
    ae_range_mm: tuple[float, float]
    ap_range_mm: tuple[float, float]
    kind: Strategy
    chatter: ChatterLimit | None


def rpm_range(tool: Tool, material: Material, machine: Machine) -> tuple[float, float, str]:
    """(lo, hi, what sets hi) of the spindle speed (rpm): the material's surface-speed window for the
    tool (n = 1000 v_c / (π D)) within the spindle's range ("surface_speed" or "spindle_rpm"); a
    window the spindle cannot reach gives its nearest end."""
    vc_lo, vc_hi = material.rpm_window(tool.diameter_mm, tool.material)
    lo, hi = max(vc_lo, machine.spindle.rpm_min), min(vc_hi, machine.spindle.rpm_max)
    hi_reason = "surface_speed" if vc_hi <= machine.spindle.rpm_max else "spindle_rpm"
    if lo > hi:   # the spindle cannot reach the window: run at the nearest end it can
        lo = hi = machine.spindle.rpm_max if vc_lo > machine.spindle.rpm_max else machine.spindle.rpm_min
        hi_reason = "spindle_rpm"
    return lo, hi, hi_reason


def _setup(tool: Tool, material: Material, machine: Machine, limits: Limits, model: str,
           strategy: str | None = None) -> _Setup:
    lo, hi, hi_reason = rpm_range(tool, material, machine)
    caps = {"machine_feed": machine.feed_max_mm_min, "dynamic_range": 60.0 * limits.dynamic_range_mm_s}
    if limits.feed_max_mm_min is not None:
        caps["feed_max"] = limits.feed_max_mm_min
    reason = min(caps, key=caps.get)
    target = limits.chip_load_mm or float(np.mean(material.chip_load_mm(tool.diameter_mm)))
    d, ap_max = tool.diameter_mm, min(tool.flute_len, tool.stickout)
    ae_range, ap_hi, kind = (0.02 * d, d), ap_max, Strategy()
    if strategy is not None:
        if strategy not in STRATEGIES:
            raise MillpostError(f"unknown strategy {strategy!r}; known: {', '.join(STRATEGIES)}")
        rules, kind = material.strategies, STRATEGY_KINDS[strategy]
        ae_range = tuple(f * d for f in rules.ae_range_D(strategy))
        if rules.ap_max_D(strategy) is not None:
            ap_hi = min(ap_max, rules.ap_max_D(strategy) * d)
    chatter = (ChatterLimit(limits.frf, material, d, tool.flutes, kind.climb) if limits.frf is not None
               else None)
    return _Setup(tool, material, machine, limits, material.force_model(model),
                  material.force_model(model, steps_per_rev=SEARCH_STEPS_PER_REV),
                  ToolBeam.of(tool, safety_factor=limits.safety_factor), target,
                  material.min_chip_mm(tool.edge_radius_mm, tool.diameter_mm), lo, hi, hi_reason, caps[reason], reason,
                  ap_max, strategy, ae_range, (min(0.05 * d, 0.5 * ap_hi), ap_hi), kind, chatter)


def _load_ratios(s: _Setup, eng, fz: np.ndarray, rpm: np.ndarray, ap: np.ndarray, *,
                 search: bool = False) -> dict[str, np.ndarray]:
    """Each force-dependent limit's load over its bound (≤ 1 is feasible) at feed per tooth fz."""
    loads = (s.search_model if search else s.model).predict(eng, fz, rpm, s.tool)
    comp = s.beam.compliance_mm_per_N(ap)
    brk = s.beam.breaking_force_N(ap)
    avail = s.machine.spindle.power_available_W(rpm)
    feed_mm_s = fz * s.tool.flutes * rpm / 60.0
    thrust = s.machine.axes["x"].max_thrust_N(feed_mm_s)
    return {
        "deflection": loads.peak_force_xy_N * comp / s.limits.max_deflection_mm,
        "breakage": loads.peak_force_xy_N / brk,
        "spindle_power": np.where(avail > 0, loads.power_W / np.where(avail > 0, avail, 1), np.inf),
        "axis_thrust": np.where(thrust > 0, np.abs(loads.force_N[:, 0]) / np.where(thrust > 0, thrust, 1), np.inf),
    }


def _best_fz(s: _Setup, ae: np.ndarray, ap: np.ndarray, rpm: np.ndarray, *, search: bool = False,
            iterations: int = 14) -> np.ndarray:
    """Largest feasible feed per tooth per candidate (nan when none keeps the minimum chip and feed range).

    Start at the chip-load/feed cap; where a load limit is exceeded there, solve max ratio(f_z) = 1 on the
    bracket [0, cap]: every ratio grows with f_z (peak |f_z A(φ) + B(φ)| is convex, power affine, the
    axis thrust falls with speed), so five bisections (the thrust ratio jumps where the drive runs out of
    voltage) and then Illinois regula falsi (the force ratios are nearly affine) converge. The feasible end
    of the bracket is returned.
    """
    eng = given_cut(s.tool, ae, ap, climb=s.kind.climb)
    rctf = chip_thinning_factor(ae, s.tool.diameter_mm)
    per_fz = s.tool.flutes * rpm
    top = np.minimum(s.chip_target_mm * rctf, s.feed_cap_mm_min / per_fz)
    bottom = np.maximum(s.h_min_mm * rctf, s.limits.feed_min_mm_min / per_fz)

    def excess(fz):
        ratios = _load_ratios(s, eng, fz, rpm, ap, search=search)
        return np.minimum(np.max(np.stack(list(ratios.values())), axis=0), 1e6) - 1.0

    g_hi = excess(top)
    todo = g_hi > 0
    lo, hi = np.where(todo, 0.0, top), top.copy()
    g_lo = np.full(len(top), -1.0)
    for it in range(iterations):
        if not todo.any():
            break
        if it < 5:
            x = 0.5 * (lo + hi)
        else:
            denom = g_hi - g_lo
            x = np.where(denom > 0, (lo * g_hi - hi * g_lo) / np.where(denom > 0, denom, 1.0), 0.5 * (lo + hi))
        x = np.where(todo, x, lo)
        x = np.clip(x, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
        g = excess(x)
        left = todo & (g <= 0)
        right = todo & (g > 0)
        g_hi = np.where(left, 0.5 * g_hi, g_hi)          # Illinois: halve the stale end
        g_lo = np.where(right, 0.5 * g_lo, g_lo)
        lo, g_lo = np.where(left, x, lo), np.where(left, g, g_lo)
        hi, g_hi = np.where(right, x, hi), np.where(right, g, g_hi)
        todo &= (hi - lo) > (1e-3 if search else 1e-7) * hi
    return np.where((lo >= bottom) & (lo > 0) & (top >= bottom), lo, np.nan)


def _grid(lo: float, hi: float, n: int) -> np.ndarray:
    """Geometric grid: light cuts (small ae, ap), where fast passes live, get as fine a grid as heavy ones."""
    return np.unique(np.geomspace(lo, hi, n)) if hi > lo else np.array([hi])


def _search(s: _Setup, ae_fixed, ap_fixed, rpm_fixed, tie_tolerance: float) -> tuple[float, float, float, float]:
    """Geometric grid over (ae, ap, rpm) with the coarse search model, four finer grids around the best so
    far, then the best dozen candidates re-solved with the full model (`_choose`); f_z is always the
    largest feasible."""
    full = [(v, v) if v else rng for v, rng in
            ((ae_fixed, s.ae_range_mm), (ap_fixed, s.ap_range_mm), (rpm_fixed, (s.rpm_lo, s.rpm_hi)))]
    ranges = list(full)
    seen: dict[tuple[float, float, float], float] = {}
    first = (20, 16, 4 if s.chatter is None else CHATTER_SPEEDS)
    for sizes in (first, (7, 7, 4), (7, 7, 3), (7, 7, 3), (7, 7, 3)):
        axes = [_grid(lo, hi, n) for (lo, hi), n in zip(ranges, sizes)]
        A, P, N = (g.ravel() for g in np.meshgrid(*axes, indexing="ij"))
        if s.chatter is not None:  # and at each width and speed the deepest stable cut
            A, P, N = _with_stable_depths(s, A, P, N, ranges[1])
        mrr, _ = _removal_rates(s, A, P, N, search=True)
        seen.update({(a, p, n): m for a, p, n, m in zip(A, P, N, mrr) if m > 0})
        if not seen:
            raise _no_cut(s, full, first)
        centre = max(seen, key=seen.get)
        ratios = [(hi / lo) ** (1 / max(n - 1, 1)) for (lo, hi), n in zip(ranges, sizes)]
        ranges = [(max(f[0], c / q), min(f[1], c * q)) for f, c, q in zip(full, centre, ratios)]
    return _choose(s, seen, tie_tolerance)


def _with_stable_depths(s: _Setup, A: np.ndarray, P: np.ndarray, N: np.ndarray, ap_range: tuple[float, float]
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The candidates plus, at each of their (ae, rpm), ap = a_lim where it lies within `ap_range` (so that
    the chatter limit, when it decides, is met at its bound as the others are)."""
    pairs = np.unique(np.stack([A, N], axis=1), axis=0)
    deepest = s.chatter.a_lim_mm(pairs[:, 0], pairs[:, 1])
    ok = (deepest >= ap_range[0]) & (deepest <= ap_range[1])
    return (np.concatenate([A, pairs[ok, 0]]), np.concatenate([P, deepest[ok]]), np.concatenate([N, pairs[ok, 1]]))


def _removal_rates(s: _Setup, A: np.ndarray, P: np.ndarray, N: np.ndarray, *, search: bool,
                   iterations: int = 14) -> tuple[np.ndarray, np.ndarray]:
    """Per candidate (ae, ap, rpm) the removal rate (mm³/min; −1 where no feed keeps every limit or the
    cut chatters) and its largest feasible feed per tooth (nan there)."""
    fz = np.full(len(A), np.nan)
    stable = np.ones(len(A), bool) if s.chatter is None else s.chatter.ratio(A, P, N) <= 1.0
    if stable.any():
        fz[stable] = _best_fz(s, A[stable], P[stable], N[stable], search=search, iterations=iterations)
    return np.where(np.isfinite(fz), given_cut(s.tool, A, P).area_mm2 * fz * s.tool.flutes * N, -1.0), fz


def _choose(s: _Setup, seen: dict[tuple[float, float, float], float], tie_tolerance: float
            ) -> tuple[float, float, float, float]:
    """The best dozen candidates of the search (with an FRF also the dozen of highest lobe within
    `CHATTER_TIE` of the best, `_lobe_height`) re-solved with the full model; among those within the tie
    of the best removal rate the fastest feed wins. With an FRF only the candidates within `CHATTER_TIE`
    of the best rate at the highest lobe take part."""
    top = sorted(seen, key=seen.get, reverse=True)[:12]
    if s.chatter is not None:
        close = [k for k in seen if seen[k] >= (1 - CHATTER_TIE) * seen[top[0]]]
        lobe = _lobe_height(s, *np.array(close).T)
        top = list(dict.fromkeys(top + [close[i] for i in np.lexsort(([-seen[k] for k in close], -lobe))[:12]]))
    A, P, N = (np.array(v) for v in zip(*top))
    mrr, fz = _removal_rates(s, A, P, N, search=False, iterations=30)
    if mrr.max() <= 0:
        raise MillpostError("no cut keeps every limit (minimum chip, feed range, tool, spindle); relax a limit")
    if s.chatter is not None:  # the highest lobe among the near-equal, then as without
        lobe = _lobe_height(s, A, P, N)
        near = mrr >= (1 - CHATTER_TIE) * mrr.max()
        mrr = np.where(near & (lobe >= np.max(lobe[near])), mrr, -1.0)
    feed = fz * s.tool.flutes * N
    near = mrr >= (1 - tie_tolerance) * mrr.max()
    i = int(np.argmax(np.where(near, feed, -1.0)))
    return float(A[i]), float(P[i]), float(N[i]), float(fz[i])


def _lobe_height(s: _Setup, A: np.ndarray, P: np.ndarray, N: np.ndarray) -> np.ndarray:
    """How high the lobes stand at each candidate's width and speed: a_lim (mm), counted up to
    `SAFE_MARGIN` × its depth (a lobe that far above the cut is high enough)."""
    return np.minimum(s.chatter.a_lim_mm(A, N), SAFE_MARGIN * P)


def _no_cut(s: _Setup, full: list[tuple[float, float]], sizes: tuple[int, int, int]) -> MillpostError:
    """Why no candidate keeps every limit: with an FRF, when no depth searched is stable, the deepest
    stable one (the highest a_lim over the widths and ten times as many speeds as searched); else the
    general refusal."""
    general = MillpostError("no cut keeps every limit (minimum chip, feed range, tool, spindle"
                            f"{', chatter' if s.chatter is not None else ''}); relax a limit")
    if s.chatter is None:
        return general
    ae, rpm = np.meshgrid(_grid(*full[0], sizes[0]), _grid(*full[2], 10 * sizes[2]), indexing="ij")
    a_lim = s.chatter.a_lim_mm(ae.ravel(), rpm.ravel())
    k = int(np.argmax(a_lim))
    if a_lim[k] >= full[1][0]:
        return general
    return MillpostError(
        f"no stable cut: the chatter limit (zero-order lobes of the FRF) is at most {a_lim[k]:.3g} mm deep over "
        f"{full[2][0]:.0f}–{full[2][1]:.0f} rpm and ae {full[0][0]:.3g}–{full[0][1]:.3g} mm "
        f"(at {rpm.ravel()[k]:.0f} "
        f"rpm, ae {ae.ravel()[k]:.3g} mm), shallower than the {full[1][0]:.3g} mm searched: ap ≤ "
        f"{a_lim[k]:.3g} mm would be stable (--ap), or a stiffer tool set-up")


def recommend(tool: Tool, material: Material, machine: Machine, limits: Limits = Limits(), *,
              model: str = "mechanistic", ae_mm: float | None = None, ap_mm: float | None = None,
              rpm: float | None = None, tie_tolerance: float = 0.005, strategy: str | None = None) -> Recommendation:
    """Best roughing cut for the tool, material and machine (ae, ap, rpm may be fixed by the caller),
    within the material's rules for `strategy` (adaptive, slot, profile, face, low-deflection; None: the
    physics only). low-deflection chooses ae itself (zero mean normal force, `_zero_normal_search`)."""
    s = _setup(tool, material, machine, limits, model, strategy)
    if s.kind.width == "zero_normal_force" and ae_mm is not None:
        raise MillpostError(f"fixed ae_mm = {ae_mm:g} conflicts with {strategy}, which chooses the width "
                            "(where the mean force normal to the feed vanishes); leave ae free")
    for name, value, lo, hi in (("ae_mm", ae_mm, 0.0, tool.diameter_mm), ("ap_mm", ap_mm, 0.0, s.ap_max_mm),
                                ("rpm", rpm, machine.spindle.rpm_min, machine.spindle.rpm_max)):
        if value is not None and not lo < value <= hi:
            raise MillpostError(f"fixed {name} = {value:g} is outside ({lo:g}, {hi:g}] for this tool and machine")
    for name, value, (lo, hi) in (("ae_mm", ae_mm, s.ae_range_mm), ("ap_mm", ap_mm, s.ap_range_mm)):
        if strategy is not None and value is not None and not lo * (1 - 1e-9) <= value <= hi * (1 + 1e-9):
            raise MillpostError(f"fixed {name} = {value:g} is outside {strategy}'s range [{lo:.4g}, {hi:.4g}] mm "
                                f"for this tool in {material.name} ({material.strategies.source.split(';')[0]})")
    if s.kind.width == "zero_normal_force":
        return _describe(s, *_zero_normal_search(s, ap_mm, rpm, tie_tolerance))
    return _describe(s, *_search(s, ae_mm, ap_mm, rpm, tie_tolerance))


def _zero_normal_search(s: _Setup, ap_fixed, rpm_fixed, tie_tolerance: float) -> tuple[float, float, float, float]:
    """(ae, ap, rpm, fz) of the best cut whose mean normal force vanishes at its own feed. At a fixed depth
    and speed the width is a 1-D fixed point (the root moves with f_z through the edge forces, f_z with the
    width through chip thinning), solved by `_roots`. The depth and speed are then chosen among such roots
    by removal rate as in `_search`: a geometric grid of (ap, rpm), finer grids around the best so far
    (`ZERO_NORMAL_GRIDS`), the best dozen by `_choose`."""
    try:
        free = zero_normal_force(s.tool, s.model, fz_mm=s.chip_target_mm, ap_mm=ap_fixed or s.ap_range_mm[1],
                                 climb=s.kind.climb)
    except MillpostError as exc:
        raise MillpostError(f"{s.strategy} with the {s.model.name} model of {s.material.name}: {exc}") from None
    full = [(v, v) if v else rng for v, rng in ((ap_fixed, s.ap_range_mm), (rpm_fixed, (s.rpm_lo, s.rpm_hi)))]
    ranges, seen, misses = list(full), {}, {}
    for sizes in ZERO_NORMAL_GRIDS:
        done = set(misses) | {key[1:] for key in seen}
        todo = [c for c in product(*(_grid(lo, hi, k) for (lo, hi), k in zip(ranges, sizes))) if c not in done]
        if todo:
            P, N = (np.array(v) for v in zip(*todo))
            A, _ = _roots(s, free.ae_mm, P, N)
            mrr, _ = _removal_rates(s, np.nan_to_num(A, nan=free.ae_mm), P, N, search=False, iterations=30)
            for a, p, n, m in zip(A, P, N, mrr):
                if np.isfinite(a) and m > 0:
                    seen[(a, p, n)] = m
                else:
                    misses[(p, n)] = _why_no_feed(s, free.ae_mm, p, n) if np.isnan(a) else "chatter"
        if not seen:
            raise _no_zero_normal_cut(s, free, full, misses)
        _, *centre = max(seen, key=seen.get)
        steps = [(hi / lo) ** (1 / max(k - 1, 1)) for (lo, hi), k in zip(ranges, sizes)]
        ranges = [(max(f[0], c / q), min(f[1], c * q)) for f, c, q in zip(full, centre, steps)]
    return _choose(s, seen, tie_tolerance)


def _roots(s: _Setup, ae0: float, P: np.ndarray, N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per depth P and speed N the width (mm) where the mean normal force vanishes with the largest feasible
    feed per tooth at that width, and that feed (nan where no width with a feasible feed has a root).
    The width is the fixed point of T(ae) = the root at f_z = `_best_fz`(ae), solved from ae0 for all
    candidates at once by the secant method on T(ae) − ae (a plain iteration of T may cycle where the feed
    falls steeply with the width), until T moves ae by ≤ 10⁻⁹ D; a candidate that does not settle in
    `FIXED_POINT_ROUNDS` (or has no feed on the way) gets the bracketing solve of g(ae) = normal force at ae
    with the feed at ae (`zero_normal_force` with the feed as a function of the width)."""
    d = s.tool.diameter_mm
    ae, fz = np.full(len(P), ae0), np.full(len(P), np.nan)
    last, h_last = np.full(len(P), np.nan), np.full(len(P), np.nan)
    todo = np.ones(len(P), bool)
    for _ in range(FIXED_POINT_ROUNDS):
        fz[todo] = _best_fz(s, ae[todo], P[todo], N[todo], iterations=30)
        todo &= np.isfinite(fz)
        mapped = ae.copy()
        for i in np.flatnonzero(todo):
            mapped[i] = zero_normal_force(s.tool, s.model, fz_mm=fz[i], ap_mm=P[i], climb=s.kind.climb).ae_mm
        h = mapped - ae
        settled = todo & (np.abs(h) <= 1e-9 * d)
        ae[settled], todo[settled] = mapped[settled], False
        dx, dh = ae - last, h - h_last
        ok = np.isfinite(dh) & (dx != 0) & (dh != 0)
        slope = np.where(ok, dh / np.where(ok, dx, 1.0), -1.0)   # first round: ae ← T(ae)
        last, h_last = ae.copy(), h
        ae[todo] = np.clip(ae[todo] - h[todo] / slope[todo], 1e-4 * d, d)
        if not todo.any():
            break
    todo |= np.isnan(fz)
    for i in np.flatnonzero(todo):   # a jumping or infeasible feed: the bracketing solve
        def best(w: np.ndarray, i: int = i) -> np.ndarray:
            return _best_fz(s, w, np.full(len(w), P[i]), np.full(len(w), N[i]), iterations=30)
        try:
            root = zero_normal_force(s.tool, s.model, fz_mm=best, ap_mm=P[i], climb=s.kind.climb)
            ae[i], fz[i] = root.ae_mm, root.fz_mm
        except MillpostError:
            ae[i] = fz[i] = np.nan
    return ae, fz


def _why_no_feed(s: _Setup, ae: float, ap: float, n: float) -> str:
    """The limits that leave no feed per tooth at width ae, depth ap, speed n: the feed cap below the minimum
    chip, or the loads at the smallest feed the minimum chip allows."""
    rctf, per_fz = chip_thinning_factor(ae, s.tool.diameter_mm), s.tool.flutes * n
    floors = {"minimum chip": s.h_min_mm * rctf, "feed_min": s.limits.feed_min_mm_min / per_fz}
    floor = max(floors, key=floors.get)
    caps = {"chip_load": s.chip_target_mm * rctf, s.feed_cap_reason: s.feed_cap_mm_min / per_fz}
    cap = min(caps, key=caps.get)
    if caps[cap] < floors[floor]:
        return f"{cap} allows f_z ≤ {caps[cap]:.3g} mm, {floor} needs ≥ {floors[floor]:.3g} mm"
    eng = given_cut(s.tool, np.array([ae]), np.array([ap]), climb=s.kind.climb)
    ratios = _load_ratios(s, eng, np.array([floors[floor]]), np.array([n]), np.array([ap]))
    over = ", ".join(f"{k} {float(v[0]):.3g}× its bound" for k, v in ratios.items() if v[0] > 1)
    return f"at the smallest f_z the {floor} allows ({floors[floor]:.3g} mm): {over or 'no load over its bound'}"


def _no_zero_normal_cut(s: _Setup, free, full: list[tuple[float, float]], misses: dict) -> MillpostError:
    """Why no depth and speed searched has a feasible cut at the zero-normal-force width: the limits met at
    the shallowest depth (slowest and fastest speed), at the model's root width for the chip target."""
    ap = min(k[0] for k in misses)
    speeds = sorted(n for a, n in misses if a == ap)
    why = "; ".join(dict.fromkeys(f"{n:.0f} rpm: {misses[(ap, n)]}" for n in (speeds[0], speeds[-1])))
    return MillpostError(
        f"{s.strategy}: no feasible feed at the width where the mean force normal to the feed vanishes "
        f"(ae ≈ {free.ae_mm:.3g} mm at the chip target, engagement {free.engagement_deg:.1f}°) for any depth "
        f"{full[0][0]:.3g}–{full[0][1]:.3g} mm and speed {full[1][0]:.0f}–{full[1][1]:.0f} rpm; at ap "
        f"{ap:.3g} mm, {why}; relax that limit or use another strategy")


def _describe(s: _Setup, ae: float, ap: float, n: float, fz: float) -> Recommendation:
    climb = s.kind.climb
    res = evaluate_cut(s.tool, s.model, ae_mm=ae, ap_mm=ap, rpm=n, fz_mm=fz, climb=climb, machine=s.machine,
                       safety_factor=s.limits.safety_factor)
    eng = given_cut(s.tool, np.array([ae]), np.array([ap]), climb=climb)
    load_ratios = _load_ratios(s, eng, np.array([fz]), np.array([n]), np.array([ap]))
    ratios = {k: float(v[0]) for k, v in load_ratios.items()}
    ratios["chip_load"] = float(res.h_max_mm) / s.chip_target_mm
    ratios[s.feed_cap_reason] = res.feed_mm_min / s.feed_cap_mm_min
    ratios[s.rpm_hi_reason] = n / s.rpm_hi
    ratios["max_depth"] = ap / s.ap_max_mm
    a_lim = None if s.chatter is None else float(s.chatter.a_lim_mm(ae, n))
    if a_lim is not None:
        ratios["chatter"] = ap / a_lim
    ratios["slot"] = min(ae, s.tool.diameter_mm) / s.tool.diameter_mm
    if s.strategy is not None and s.kind.width == "range" and s.ae_range_mm[0] < s.ae_range_mm[1]:
        ratios[f"{s.strategy}_width_max"] = ae / s.ae_range_mm[1]
        ratios[f"{s.strategy}_width_min"] = s.ae_range_mm[0] / ae
    if s.strategy is not None and s.ap_range_mm[1] < s.ap_max_mm:
            ratios[f"{s.strategy}_depth_max"] = ap / s.ap_range_mm[1]
    binding = tuple(sorted(k for k, v in ratios.items() if v >= 0.999))
    ramp_feed, plunge_feed = _entry_feeds(s, ap, n, res.feed_mm_min)
    st, ex = immersion(ae, s.tool.diameter_mm, climb=climb)
    mean = MeanDeflection.of(res.F_avg_N[0], float(toward_wall(res.F_avg_N[1], climb)), s.tool, ap, s.machine)
    return Recommendation(
        ap_mm=ap, ae_mm=ae, rpm=n, fz_mm=fz, feed_mm_min=res.feed_mm_min, mrr_mm3_min=res.mrr_mm3_min,
        h_max_mm=float(res.h_max_mm), chip_target_mm=s.chip_target_mm, vc_m_min=res.vc_m_min, F_avg_N=res.F_avg_N,
        F_peak_N=res.F_peak_N, deflection_mm=res.deflection_mm, break_ratio=res.break_ratio,
        torque_Nm=res.torque_Nm, power_W=res.power_W, ramp_feed_mm_min=ramp_feed, plunge_feed_mm_min=plunge_feed,
        binding=binding, climb=climb, engagement_deg=math.degrees(ex - st), mean_deflection=mean, ratios=ratios,
        strategy=s.strategy, a_lim_mm=a_lim)


def _entry_feeds(s: _Setup, ap: float, n: float, feed_mm_min: float) -> tuple[float, float]:
    """Ramp and plunge feeds (mm/min) for the cut at depth ap and speed n (see the module docstring)."""
    rules, d, z = s.material.strategies, s.tool.diameter_mm, s.tool.flutes
    ramp_ap = min(ap, math.pi * d * math.tan(math.radians(rules.ramp_angle_deg)))
    ramp = _best_fz(s, np.array([d]), np.array([ramp_ap]), np.array([n]), iterations=40)[0]
    ramp_feed = min(float(ramp * z * n) if np.isfinite(ramp) else 0.0, rules.ramp_feed_ratio * feed_mm_min)
    k = s.material.kienzle
    torque_Nmm = float(s.machine.spindle.torque_Nm(n)) * 1e3
    h_torque = (2 * torque_Nmm / (z * k.kc11_N_mm2 * (d / 2) ** 2)) ** (1 / (1 - k.mc))
    h = min(rules.plunge_fz_ratio * s.chip_target_mm, h_torque)
    plunge_feed = min(h * z * n if h >= s.h_min_mm else 0.0, ramp_feed)
    return ramp_feed, plunge_feed


def sweep_ae(tool: Tool, material: Material, machine: Machine, limits: Limits = Limits(), *,
             model: str = "mechanistic", widths_mm: np.ndarray | None = None,
             strategy: str | None = None, progress: Progress = silent) -> list[Recommendation]:
    """The best cut at each radial width (MRR against ae): why the recommendation chose its width
    (over the strategy's width range when one is given)."""
    s = _setup(tool, material, machine, limits, model, strategy)
    if widths_mm is not None:
        widths = widths_mm
    else:
        d, (lo, hi) = tool.diameter_mm, s.ae_range_mm
        widths = np.linspace(max(lo, 0.02 * d), hi, 20) if strategy else np.linspace(0.05, 1.0, 20) * d
    out = []
    for k, ae in enumerate(widths):
        try:
            out.append(_describe(s, *_search(s, float(ae), None, None, 0.005)))
        except MillpostError:
            pass
        progress("sweep ae", k + 1, len(widths))
    return out


