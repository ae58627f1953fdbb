"""Cutter engagement per path sample: what the force model needs to know about the cut; `simulate`,
which steps a tool through a `millpost.stock.Stock` along resampled toolpath samples; and `engage`, the
stage that resamples a program's path, steps its tools from the first known position and applies the
safety gates on the cut.

Conventions (Altintas): x = feed direction, y = in-plane normal to the left of x, z = tool axis.
Immersion angle φ is measured clockwise from +y (the cutter turns clockwise seen from the spindle),
so a tooth enters at φ_st and leaves at φ_ex; up-milling starts at 0, down-milling ends at π, a full
slot spans [0, π]. The tool is cut into K axial slices; each slice carries its own engaged arc. A slice is
engaged where more than half of it holds material, so a step in the stock inside the axial depth (a wall
whose top is lower on one side: a pocket's earlier level, a stepped wall, a restart) would fall mid-slice
and give that slice the wrong arc: the flat levels the flank meets inside the depth are slice boundaries,
the slices shared among the bands between them; without such a level the slices are ap/K each.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from ._kernels import compiling
from ._kernels import engage as _k
from .errors import CrashError, MillpostError
from .gcode import check_program
from .gcode.convert import SourceBlocks
from .gcode.interpret import Program
from .progress import Progress, reporting, resolve
from .safety import check_cut, check_size
from .toolpath import RAPID, Samples
from .tools import Tool
from .tools.cutter import CONE_SHAPES


@dataclass
class Engagement:
    """Per sample (N) and axial slice (K). Lengths mm, angles rad, volumes mm³.

    phi_st, phi_ex: (N, K) outermost engaged immersion interval of the slice (nan when the slice
        does not cut). dz_mm: (N, K) axial thickness of the slice's engaged part (0 when not cutting).
    z_mm: (N, K) slice mid-height above the tool tip (slices need not be equal: see above). r_mm: (N, K) cutting radius of the slice.
    kappa: (N, K) axial immersion angle of the edge (π/2 on a cylindrical flank; < π/2 on a ball or
        corner radius), so chip thickness is h = f_z·sin φ·sin κ; when every tool is flat, a read-only
        view of the one value π/2.
    feed_dir: (N, 3) unit feed direction (the x of the convention) in machine coordinates.
    ap_mm, ae_mm: (N,) axial depth and radial width of cut. volume_mm3: (N,) material removed on the
    step ending at the sample; area_mm2 = volume / step length (the cross-section the feed sweeps).

    From `simulate` also (None otherwise): arc_rad (N, K) engaged angular measure of each slice
    (≤ phi_ex − phi_st when the arc has gaps); step_mm (N,) path length of the step;
    descending (N,) the step moves down (its area comes from the removed cells, not the ring);
    move, line (N,) the toolpath move and source line of each sample; depth_mm (N,) the depth of
    material the step meets below its old top, not clipped to the flute length (ap_mm is).
    end_engaged (N, J) float32: the tool's end on a descending step, per radial bin j of J equal bins over
    [0, R]: the share of the circle at that radius where the end edges cut a full axial feed (0 where
    the step does not descend). descent (N,): −dz/ds of the step (0 level or rising, 1 a plunge), so the
    end's axial feed per tooth is f_z·descent. look_ahead_mm (N,): how far ahead along the path each
    sample's ring was taken (its engagement is the one the tool meets that much later). On a step with no horizontal motion (a plunge, a drill)
    the flank sweeps no new material: its slices are not engaged (the end carries the whole cut).
    near_stock (N,) bool: a feed step that cuts nothing lies in the shell of `simulate`'s clearance c
    around the stock as loaded (what the stock model may have got wrong; the surfaces the program has
    cut since are known exactly): the tool grown by c (radius R + c, tip c lower, whatever its shape)
    meets the original stock and its tip disc (radius R) is not inside it, so air over a pocket's
    floor or a faced top is not near (None when no clearance was asked for). Read from the original
    tops' range per block of ~0.5 mm: it errs towards near, by up to a block's diagonal.
    below_top (N,) bool: a feed sample whose tool tip is below the top of the stock as loaded within the
    tool's radius (from the original tops' highest per block of ~0.5 mm: errs towards below by up to a
    block's width beside the stock), or that goes down below the stock's highest top anywhere: where a
    move there cuts nothing, it is in space the program cut before (or beside the stock as modelled),
    which a restart from a later line, a skipped operation or a broken tool leaves uncut.
    edge_ratio (N,): the feed at the cutting edge over the feed of the tool centre (1 on straight moves;
    `edge_feed_ratio`): the flank's chip and loads are those of the centre's feed per tooth times it.
    swept_air (N,) bool: a near_stock sample that is known air all the same: its step, and the next
    step unless that one is not near, lie wholly in space the program's earlier feed steps swept with
    the tool (at or below it, whatever the stock model says; None when no clearance was asked). Read
    from a field of the lowest tool surface that covered each whole cell of ~R/12 (`simulate`): it errs
    towards unknown, by up to a cell's diagonal and half a step.
    """

    phi_st: np.ndarray
    phi_ex: np.ndarray
    dz_mm: np.ndarray
    z_mm: np.ndarray
    r_mm: np.ndarray
    kappa: np.ndarray
    feed_dir: np.ndarray
    ap_mm: np.ndarray
    ae_mm: np.ndarray
    volume_mm3: np.ndarray
    area_mm2: np.ndarray
    arc_rad: np.ndarray | None = None
    step_mm: np.ndarray | None = None
    descending: np.ndarray | None = None
    move: np.ndarray | None = None
    line: np.ndarray | None = None
    depth_mm: np.ndarray | None = None
    end_engaged: np.ndarray | None = None
    descent: np.ndarray | None = None
    look_ahead_mm: np.ndarray | None = None
    near_stock: np.ndarray | None = None
    swept_air: np.ndarray | None = None
    below_top: np.ndarray | None = None
    edge_ratio: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.ap_mm)

    @property
    def edge(self) -> np.ndarray:
        """(N,) `edge_ratio`, 1 where it was not computed (a cut given, not stepped)."""
        return np.ones(len(self)) if self.edge_ratio is None else self.edge_ratio

    @classmethod
    def concatenate(cls, parts: "list[Engagement]") -> "Engagement":
        """Samples of several engagements one after another (optional fields kept where all have them)."""
        def cat(name: str):
            values = [getattr(p, name) for p in parts]
            return None if any(v is None for v in values) else np.concatenate(values)
        return cls(**{name: cat(name) for name in cls.__dataclass_fields__})

    def per_sample(self) -> "Engagement":
        """The same engagement with what is reported once the loads are computed: ap, ae, volume, area
        and feed direction; the per-slice arrays become (N, 0) and the optional per-step fields None
        (~0.6 KB a sample less)."""
        n = len(self)
        return replace(self, **{name: np.empty((n, 0)) for name in _PER_SLICE},  # not views: freed
                       **dict.fromkeys(("arc_rad", "step_mm", "descending", "move", "line", "depth_mm",
                                        "end_engaged", "descent")))

    def select(self, index) -> "Engagement":
        """The samples at `index` (a slice, mask or index array)."""
        return Engagement(**{name: None if getattr(self, name) is None else getattr(self, name)[index]
                             for name in self.__dataclass_fields__})

    @classmethod
    def uniform(cls, phi_st, phi_ex, ap_mm: float, radius_mm: float, *, slices: int = 1,
                kappa: float = np.pi / 2, feed_dir=(1.0, 0.0, 0.0)) -> "Engagement":
        """A flank cut with the same arc on every slice: N samples from arrays phi_st, phi_ex.

        Used by `millpost calc`, by heuristics and in tests, where the cut is given, not simulated.
        ae follows from the arc for a cylindrical flank: ae = R·(cos φ_st − cos φ_ex).
        """
        phi_st = np.atleast_1d(np.asarray(phi_st, float))
        phi_ex = np.atleast_1d(np.asarray(phi_ex, float))
        n = len(phi_st)
        dz = ap_mm / slices
        full = lambda v: np.full((n, slices), v, float)  # noqa: E731
        ae = radius_mm * (np.cos(phi_st) - np.cos(phi_ex))
        area = ae * ap_mm
        return cls(
            phi_st=np.repeat(phi_st[:, None], slices, 1), phi_ex=np.repeat(phi_ex[:, None], slices, 1),
            dz_mm=full(dz), z_mm=np.tile((np.arange(slices) + 0.5) * dz, (n, 1)), r_mm=full(radius_mm),
            kappa=full(kappa), feed_dir=np.tile(np.asarray(feed_dir, float), (n, 1)),
            ap_mm=np.full(n, ap_mm), ae_mm=ae, volume_mm3=np.full(n, np.nan), area_mm2=area)


_PER_SLICE = ("phi_st", "phi_ex", "dz_mm", "z_mm", "r_mm", "kappa")
END_BINS = 8  # radial bins of the tool's end (Engagement.end_engaged)
EDGE_RATIO_MAX = 5.0  # the edge's feed over the centre's at most: (ρ + R)/ρ at ρ = R/4 (`edge_feed_ratio`)
KAPPA_ROWS = 4096  # samples per chunk of the κ computation (its temporaries: ~0.5 MB each at K = 8)


def _tool_params(tool: Tool) -> tuple[int, float, float, float, float]:
    """(shape code, R, corner radius, cone tip radius, tan of cone half angle) for the kernel."""
    if tool.shape in ("ball", "bull"):
        return _k.CORNER, tool.radius_mm, tool.corner_radius, 0.0, 1.0
    if tool.shape in CONE_SHAPES:
        return _k.CHAMFER, tool.radius_mm, 0.0, 0.5 * tool.tip_diameter_mm, math.tan(math.radians(0.5 * tool.tip_angle_deg))
    return _k.FLAT, tool.radius_mm, 0.0, 0.0, 1.0


def _kappa(tool: Tool, z_mm: np.ndarray) -> np.ndarray:
    """Axial immersion angle κ: angle between the tool axis and the cutting surface normal at
    height z (π/2 on a cylindrical flank, 0 at a ball tip), from the profile slope dr/dz."""
    eps = 1e-5
    zl = np.maximum(z_mm - eps, 0.0)
    zh = zl + 2 * eps
    return np.arctan2(zh - zl, tool.radius_at(zh) - tool.radius_at(zl))


def _lowpass(x: np.ndarray, fresh: np.ndarray, sigma: float) -> np.ndarray:
    """Zero-phase Gaussian low-pass (σ in samples) within each continuous run of samples: the kernel
    exp(−i²/2σ²), normalised, over |i| ≤ 4σ (rounded), each run extended by its end values (as
    scipy.ndimage.gaussian_filter1d with mode "nearest", without its ~6 MB import)."""
    if sigma <= 0 or len(x) == 0:
        return x
    r = int(4.0 * sigma + 0.5)
    w = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    w /= w.sum()
    out = x.copy()
    starts = np.flatnonzero(fresh).tolist() + [len(x)]
    for a, b in zip(starts[:-1], starts[1:]):
        if b - a > 1:
            out[a:b] = np.convolve(np.pad(x[a:b], r, mode="edge"), w, mode="valid")
    return out


def _ring_frames(xyz: np.ndarray, s: np.ndarray, fresh: np.ndarray, look_ahead: float) -> np.ndarray:
    """(n, 4) ring centre (x, y) and feed direction (x, y) per sample: the path point `look_ahead`
    mm further along the path and the direction of the step there (following arcs and polyline
    corners rather than the tangent line); past the end of a continuous run, straight on."""
    n = len(xyz)
    d = np.diff(xyz[:, :2], axis=0, prepend=xyz[:1, :2])
    ln = np.hypot(d[:, 0], d[:, 1])
    ok = (ln > 1e-12) & ~fresh
    idx = np.maximum.accumulate(np.where(ok, np.arange(n), -1))
    first = int(np.argmax(ok)) if ok.any() else -1
    dirs = np.tile([1.0, 0.0], (n, 1))
    if first >= 0:
        src = np.where(idx >= 0, idx, first)
        dirs = d[src] / ln[src, None]
    starts = np.flatnonzero(fresh)
    run_last = np.append(starts[1:] - 1, n - 1)[np.cumsum(fresh) - 1]
    target = s + look_ahead
    j = np.minimum(np.searchsorted(s, target, side="left"), run_last)
    beyond = target > s[j]
    jm = np.maximum(j - 1, 0)
    span = s[j] - s[jm]
    u = np.where(span > 0, (target - s[jm]) / np.where(span > 0, span, 1.0), 1.0)
    centre = xyz[jm, :2] + u[:, None] * (xyz[j, :2] - xyz[jm, :2])
    centre[beyond] = xyz[j[beyond], :2] + (target - s[j])[beyond, None] * dirs[j[beyond]]
    return np.ascontiguousarray(np.column_stack([centre, dirs[j]]))


def path_radius(tangent: np.ndarray, curvature: np.ndarray) -> np.ndarray:
    """(N,) radius (mm) of the horizontal projection of the path, |t_xy|³ / |t_xy × k_xy| from the unit
    tangent t and curvature vector k = d²q/ds² (a helix's radius; an arc in a vertical plane does not
    curve it): positive on a left turn (the centre to the left of the feed), negative on a right one,
    inf on a straight."""
    t, k = np.asarray(tangent, float)[:, :2], np.asarray(curvature, float)[:, :2]
    tn = np.hypot(t[:, 0], t[:, 1])
    cross = t[:, 0] * k[:, 1] - t[:, 1] * k[:, 0]
    turning = (np.abs(cross) > 1e-9) & (tn > 1e-9)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(turning, np.sign(cross) * tn**3 / np.abs(cross), np.inf)


def edge_feed_ratio(phi_st: np.ndarray, phi_ex: np.ndarray, r_mm: np.ndarray, tangent: np.ndarray,
                    curvature: np.ndarray) -> np.ndarray:
    """(N,) feed at the cutting edge over the feed of the tool centre, per sample.

    On a path that curves in the horizontal plane with radius ρ about a centre O, the cutter's edge
    point at distance r_e from O moves past the workpiece r_e/ρ times as fast as the centre, so its
    feed per tooth, and the chip, is the centre's times r_e/ρ: on an inside (concave) arc the edge
    generating the wall is at ρ + R and cuts thicker chips than the centre's feed says, on an outside
    (convex) arc at ρ − R, thinner. This is the circular-interpolation rule of the tool makers,
    v_f,centre = v_f,edge·(D_m − D_c)/D_m inside and ·(D_m + D_c)/D_m outside (Sandvik Coromant,
    Metalcutting technical guide, milling: circular interpolation; Harvey Performance, "Circular
    Interpolation: Machining Circular Tool Paths"); the stepping's wider engaged arc on an inside arc
    (a_e = (D_m² − D_w²)/(4(D_m − D_c)) in the same guide) is the other half of that rule.

    The edge point of a slice is the end of its engaged arc that generates the surface (the end farther
    from φ = π/2, where the edge meets the wall; on a slot the farther of the two from O), in the feed
    frame of Altintas (x the feed, y to its left, φ clockwise from +y: p = r(sin φ, cos φ)); O lies at
    y_O = ±ρ (left on a left turn), ρ the `path_radius` (an arc in a vertical plane does not curve the
    horizontal feed: 1). The largest ratio over the slices; 1 where nothing cuts. On an orbit tighter
    than a quarter of the tool's radius (a helical bore barely larger than the tool) the rule grows
    without bound (r_e/ρ → ∞ as ρ → 0) while a tooth's chip stays bounded (the rigid tool moves f_z per
    tooth): the ratio is taken at ρ = R/4 there, `EDGE_RATIO_MAX`."""
    signed = path_radius(tangent, curvature)
    out = np.ones(len(signed))
    rows = np.flatnonzero(np.isfinite(signed))
    if not len(rows):
        return out
    rho = np.abs(signed[rows])
    y_o = signed[rows][:, None]
    st, ex, r = phi_st[rows], phi_ex[rows], r_mm[rows]
    cuts = np.isfinite(st) & np.isfinite(ex) & (r > 0)
    st, ex = np.clip(np.nan_to_num(st), 0.0, np.pi), np.clip(np.nan_to_num(ex), 0.0, np.pi)
    r_st = np.sqrt(np.maximum(r * r + y_o * y_o - 2.0 * r * y_o * np.cos(st), 0.0))
    r_ex = np.sqrt(np.maximum(r * r + y_o * y_o - 2.0 * r * y_o * np.cos(ex), 0.0))
    c_st, c_ex = np.abs(np.cos(st)), np.abs(np.cos(ex))
    r_e = np.where(c_st > c_ex + 1e-9, r_st, np.where(c_ex > c_st + 1e-9, r_ex, np.maximum(r_st, r_ex)))
    ratio = np.where(cuts, r_e / rho[:, None], 0.0).max(axis=1, initial=0.0)
    out[rows] = np.where(cuts.any(axis=1), np.minimum(ratio, EDGE_RATIO_MAX), 1.0)
    return out


def simulate(stock, tool: Tool | Mapping[int, Tool], samples: Samples, *, slices: int = 8,
             ring_samples: int = 180, look_ahead_mm: float | None = None, smooth_steps: float = 1.0,
             progress: Progress | bool | None = None, start: int | None = None,
             clearance_mm: float | None = None) -> Engagement:
    """Step the tool(s) through `stock` (cut in place) along `samples` and return the engagement.

    tool: one Tool, or tools by number (samples.tool picks one; a change restarts the footprint).
    slices: K axial slices over each step's axial depth (boundaries at the stock's levels inside it, else
    ap/K each; z_mm, dz_mm per slice). ring_samples: coarse immersion
    samples over [0, π] (transitions are then refined by bisection to 1/256 of that spacing).
    look_ahead_mm: how far ahead along the path the ring is sampled (default max(2·step, √(R·cell)),
    so that material at the tangent ends of the arc is not yet cut by the current step); the
    reported engagement is thus the one the tool meets that distance later.
    smooth_steps: σ (in samples) of the zero-phase Gaussian low-pass applied to area and ae, which
    damps the cell-quantisation noise at a bandwidth tied to the step.
    Rapids that would remove material raise CrashError naming the source line. start: the first
    sample whose position is known (`known_start`); the samples before it start
    from an unknown position and are neither cut nor checked (default: the first feed move's).
    progress: a `millpost.progress` callback (stages "compile kernels" on the first run, "engagement"
    in steps), or True/False/None as `millpost.progress.resolve` reads it. clearance_mm: c of
    `Engagement.near_stock` (mm; None: not computed).
    """
    n = len(samples)
    if slices < 1 or ring_samples < 4:
        raise MillpostError("simulate: slices must be >= 1 and ring_samples >= 4")
    origin = np.array([0.0, 0.0, stock.z0])  # the kernels work in the stock's heights (above its z0)
    path = _Path.of(samples, origin, start)
    runs = _tool_runs(samples, tool, path.skip)
    K, M = int(slices), int(ring_samples)
    nan = lambda *shape: np.full(shape, np.nan)  # noqa: E731
    out = dict(phi_st=nan(n, K), phi_ex=nan(n, K), dz=np.zeros((n, K)), zmid=np.zeros((n, K)),
               rad=np.zeros((n, K)), arc=np.zeros((n, K)), ap=np.zeros(n), ae=np.zeros(n), vol=np.zeros(n),
               area=np.zeros(n), feed=np.zeros((n, 3)), desc=np.zeros(n, bool), depth=np.zeros(n),
               end=np.zeros((n, END_BINS), np.float32), near=np.zeros(n, bool), swept=np.zeros(n, bool))
    # the clearance's snapshot of the stock as loaded: its tops' range per block of ~0.5 mm (at least
    # 4 × 4 columns: an eighth of the grid's size at most)
    clear = -1.0 if clearance_mm is None else float(clearance_mm)
    B = max(4, round(0.5 / stock.cell_mm))
    omax, omin = _k.block_range(stock.top.reshape(-1), stock.nx, stock.ny, B, stock.z_floor)
    ahead = _step_runs(stock, samples, path, runs, out, K, M, look_ahead_mm, clear, (omax, omin, B), resolve(progress))
    # under the tool's footprint, or going down below the stock's highest top anywhere (beside it too: a
    # blank larger than modelled, a restart that left a neighbouring cut undone)
    xyz, rapid, zmax = path.xyz, path.rapid, float(omax.max())
    below = _below_original(xyz, ~rapid, runs, omax, B, stock) | (out["desc"] & ~rapid & (xyz[:, 2] < zmax - 1e-6))
    # a flat end mill's flank is a cylinder: κ = π/2 at every height (`_kappa` gives exactly that), one
    # read-only value for all the (N, K) (memory: ~50 MB at 760 k samples); a profiled tool's per slice
    if all(t.shape == "flat" for _, _, t in runs):
        kappa = np.broadcast_to(np.pi / 2, (n, K))
    else:
        kappa = np.full((n, K), np.pi / 2)
        for a, b, t in runs:
            for c0 in range(a, b, KAPPA_ROWS):  # in chunks: the profile's temporaries stay small
                kappa[c0:min(b, c0 + KAPPA_ROWS)] = _kappa(t, out["zmid"][c0:min(b, c0 + KAPPA_ROWS)])
    steps = path.steps
    dz_step = np.concatenate([[0.0], np.diff(xyz[:, 2])]) if n else np.zeros(0)
    with np.errstate(divide="ignore", invalid="ignore"):
        descent = np.where(out["desc"] & (steps > 0), -dz_step / np.where(steps > 0, steps, 1.0), 0.0)
    plunge = out["desc"] & (descent > 1.0 - 1e-9)
    out["phi_st"][plunge], out["phi_ex"][plunge], out["dz"][plunge], out["arc"][plunge] = np.nan, np.nan, 0.0, 0.0
    out["ae"][plunge] = 0.0
    # a near step in swept space is known air when the step after it is too, or is not near: the tool
    # then reaches no space near the stock that it has not cleared itself at the speed raised there
    unknown_next = np.append(out["near"][1:] & ~out["swept"][1:], False)
    fresh = path.fresh
    return Engagement(
        phi_st=out["phi_st"], phi_ex=out["phi_ex"], dz_mm=out["dz"], z_mm=out["zmid"], r_mm=out["rad"],
        kappa=kappa, feed_dir=out["feed"], ap_mm=out["ap"], ae_mm=_lowpass(out["ae"], fresh, smooth_steps),
        volume_mm3=out["vol"], area_mm2=_lowpass(out["area"], fresh, smooth_steps), arc_rad=out["arc"],
        step_mm=steps, descending=out["desc"], move=np.asarray(samples.move), line=np.asarray(samples.line),
        depth_mm=out["depth"], end_engaged=out["end"], descent=descent, look_ahead_mm=ahead,
        near_stock=out["near"] if clearance_mm is not None else None, below_top=below,
        # the path's curvature at the sample itself: the move whose feed runs there
        edge_ratio=edge_feed_ratio(out["phi_st"], out["phi_ex"], out["rad"], samples.tangent, samples.curvature),
        swept_air=out["near"] & out["swept"] & ~unknown_next if clearance_mm is not None else None)


@dataclass(frozen=True)
class _Path:
    """The samples as the kernels step them: positions above the stock's z0 (mm), step lengths and arc
    length (mm), where the tool's footprint restarts (`fresh`: a new segment or tool), rapids, and the
    first sample whose position is known (`skip`: the samples before it are neither cut nor checked)."""

    xyz: np.ndarray
    steps: np.ndarray
    s_mm: np.ndarray
    fresh: np.ndarray
    rapid: np.ndarray
    skip: int

    @classmethod
    def of(cls, samples: Samples, origin: np.ndarray, start: int | None) -> "_Path":
        n = len(samples)
        xyz = np.asarray(samples.xyz_mm, dtype=np.float64) - origin
        steps = np.concatenate([[0.0], np.linalg.norm(np.diff(xyz, axis=0), axis=1)]) if n else np.zeros(0)
        tool_no = np.asarray(samples.tool)
        fresh = np.asarray(samples.segment_start, bool).copy()
        if n:
            fresh[0] = True
            fresh[1:] |= tool_no[1:] != tool_no[:-1]
        rapid = np.asarray(samples.kind) == RAPID
        # the leading rapids start wherever the machine stands (the reader assumes a start point for the
        # axes not yet programmed): they are neither cut nor checked; the path starts after them
        skip = (int(np.argmax(~rapid)) if not rapid.all() else n) if n else 0
        if start is not None:
            skip = min(max(int(start), 0), n)
        if skip < n:
            fresh[skip] = True
        s_mm = np.concatenate([[0.0], np.cumsum(steps[1:])]) if n else np.zeros(0)
        return cls(xyz, steps, s_mm, fresh, rapid, skip)


def _tool_runs(samples: Samples, tool: Tool | Mapping[int, Tool], skip: int) -> list[tuple[int, int, Tool]]:
    """The runs of one tool from sample `skip` on: (first, end, tool)."""
    n, tool_no = len(samples), np.asarray(samples.tool)
    tools = tool if isinstance(tool, Mapping) else None
    bounds = sorted({skip, n, *(int(b) for b in np.flatnonzero(np.diff(tool_no)) + 1 if b > skip)})
    runs = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        t = tools.get(int(tool_no[a])) if tools is not None else tool
        if t is None:
            raise MillpostError(f"line {int(samples.line[a])}: tool T{int(tool_no[a])} is not described")
        runs.append((a, b, t))
    return runs


def _step_runs(stock, samples: Samples, path: _Path, runs: list, out: dict, K: int, M: int,
               look_ahead_mm: float | None, clear: float, blocks: tuple, report: Progress) -> np.ndarray:
    """Step each run's tool through the stock (cut in place), filling `out`'s per-sample columns; in chunks
    for the progress display. blocks: the stock's tops' (max, min) per block of B columns, and B. Returns
    the look-ahead (mm) per sample."""
    n, xyz, fresh, rapid = len(samples), path.xyz, path.fresh, path.rapid
    omax, omin, B = blocks
    top, zmax = stock.top.reshape(-1), float(omax.max())
    prev_f = np.array([1.0, 0.0])
    moving = path.steps[path.steps > 0]
    ds = float(np.median(moving)) if len(moving) else 0.0
    swept, sweep_grid = _swept_field(stock, max((t.radius_mm for _, _, t in runs), default=1.0), clear)
    report("engagement", 0, n)  # started: its bar's clock runs from here
    chunk = 50_000
    ahead = np.zeros(n)
    for a, b, t in runs:
        shape, R, rc, r_tip, tan_half = _tool_params(t)
        la = look_ahead_mm if look_ahead_mm is not None else max(2 * ds, math.sqrt(R * stock.cell_mm))
        ring_at = _ring_frames(xyz[a:b], path.s_mm[a:b], fresh[a:b], la)
        ahead[a:b] = la
        for c0 in range(a, b, chunk):
            c1 = min(b, c0 + chunk)
            with reporting(report), compiling(_k.run):
                bad = _k.run(xyz[a:b], fresh[a:b], rapid[a:b], c0 - a, c1 - a, prev_f, top, stock.nx, stock.ny,
                             stock.x0, stock.y0, stock.cell_mm, stock.z_floor, stock.n_multi > 0, stock.multi_bits,
                             stock.multi_rank, stock.gap_ptr, stock.gap_lo, stock.gap_hi, shape, R, rc, r_tip, tan_half,
                             t.flute_len, K, M, ring_at, shape != _k.FLAT, 1e-3, clear, zmax, omax, omin, B,
                             swept, *sweep_grid, *(v[a:b] for v in out.values()))
            if bad != _k.OK:
                bad += a
                raise CrashError(int(samples.line[bad]), xyz[bad] + np.array([0.0, 0.0, stock.z0]))
            report("engagement", c1, n)
    return ahead


def _below_original(xyz: np.ndarray, feed: np.ndarray, runs: list, omax: np.ndarray, B: int, stock) -> np.ndarray:
    """(n,) bool: a feed sample whose tool tip is below the original stock's top somewhere within its
    radius R (the blocks' top maxima `omax` of B × B columns, over the square of blocks within R of
    the axis: it errs towards below, by up to a block's width beside the stock). xyz: heights above
    stock.z0, as the tops."""
    from scipy.ndimage import maximum_filter
    w = B * stock.cell_mm
    nbx, nby = -(-stock.nx // B), -(-stock.ny // B)
    tops = omax.reshape(nby, nbx)
    out = np.zeros(len(xyz), bool)
    for a, b, t in runs:
        reach = math.ceil(t.radius_mm / w)
        grown = maximum_filter(tops, size=2 * reach + 1, mode="constant", cval=stock.z_floor)
        bi = np.floor((xyz[a:b, 0] - stock.x0) / w).astype(np.int64)
        bj = np.floor((xyz[a:b, 1] - stock.y0) / w).astype(np.int64)
        over = (bi >= -reach) & (bi < nbx + reach) & (bj >= -reach) & (bj < nby + reach)
        top_at = grown[np.clip(bj, 0, nby - 1), np.clip(bi, 0, nbx - 1)]
        out[a:b] = feed[a:b] & over & (xyz[a:b, 2] < top_at - 1e-6)
    return out


def _swept_field(stock, radius_mm: float, clear: float) -> tuple[np.ndarray, tuple[int, int, float, float, float]]:
    """The swept field `simulate` fills (float32 heights, +inf: not swept) and its grid (nx, ny, x0, y0,
    cell mm): cells of R/12 for the largest tool radius R, at least two stock cells (so it holds at most a
    byte per stock column, a fifth of the stock's own memory), over the stock's grid and the band
    2R + c + a cell around it where a tool can be near the stock; one cell when no clearance was asked."""
    if clear < 0:
        return np.full(1, np.inf, np.float32), (1, 1, 0.0, 0.0, 1.0)
    w = max(2.0 * stock.cell_mm, radius_mm / 12.0)
    margin = 2.0 * radius_mm + clear + w
    nx = math.ceil((stock.nx * stock.cell_mm + 2.0 * margin) / w)
    ny = math.ceil((stock.ny * stock.cell_mm + 2.0 * margin) / w)
    return np.full(nx * ny, np.inf, np.float32), (nx, ny, stock.x0 - margin, stock.y0 - margin, w)


def resample(program: Program, ds_mm: float, allow: Iterable[str], notes: list[str], *,
             stage: str = "optimize") -> Samples:
    """The program's path resampled every `ds_mm` (mm) after the ``large`` gate
    (`millpost.safety.check_size`)."""
    check_size(program, ds_mm, allow, notes, stage=stage)
    return program.toolpath.resample(ds_mm)


def known_start(program: Program, samples: Samples) -> int:
    """The first sample whose position is known: the end of the first move by which every axis has
    been named in a block (the reader assumes a start for the others), or the first feed move's
    first sample if that comes earlier, and not before the first tool is loaded when any is."""
    tp = program.toolpath
    if not len(samples):
        return 0
    blocks = SourceBlocks(program)
    named: set[str] = set()
    known = len(tp)
    for i in range(len(tp)):
        if tp.kind[i] != RAPID:
            break
        block = blocks[int(tp.line[i])]
        for w in block.words if block is not None else ():
            if w.letter in "XYZ@^":
                named.update("XY" if w.letter in "@^" else w.letter)
        if named >= {"X", "Y", "Z"}:
            known = i
            break
    move = np.asarray(samples.move)
    first_feed = np.flatnonzero(np.asarray(samples.kind) != RAPID)
    start = len(samples) if not len(first_feed) else int(first_feed[0])
    if known < len(tp):
        start = min(start, max(int(np.searchsorted(move, known, side="right")) - 1, 0))
    loaded = np.flatnonzero(np.asarray(samples.tool) >= 0)
    if len(loaded):
        start = max(start, int(loaded[0]))
    return start


def _check_tools(program: Program, tools: Tool | Mapping[int, Tool], stock_top_mm: float) -> None:
    """Every feed move runs with a tool the job describes. A program that cuts (a feed move below the
    stock top, Z mm) before any T word selects a tool can only run with the job's only tool
    (`ReaderOptions.for_tools`); with several, say what to write."""
    if isinstance(tools, Tool):
        return
    tp = program.toolpath
    fed = tp.kind != RAPID
    described = ", ".join(f"[tools.{n}]" for n in sorted(tools)) or "none"
    unloaded = fed & (tp.tool < 0) & (np.minimum(tp.start[:, 2], tp.end[:, 2]) < stock_top_mm)
    if unloaded.any():
        line = int(tp.line[np.argmax(unloaded)])
        raise MillpostError(f"{program.path}:{line}: the program cuts before any T word selects a tool; the job "
                            f"describes {described}: write `T<n> M6` (e.g. T{min(tools, default=1)} M6) before "
                            "this line, or describe only the tool it uses (a job with one [tools.N] table has "
                            "that tool loaded)")
    missing = fed & (tp.tool >= 0) & ~np.isin(tp.tool, list(tools))
    if missing.any():
        k = int(np.argmax(missing))
        empty = " (T0 is the empty spindle on LinuxCNC)" if tp.tool[k] == 0 else ""
        raise MillpostError(f"{program.path}:{int(tp.line[k])}: tool T{int(tp.tool[k])} cuts{empty} but the job "
                            f"has no [tools.{int(tp.tool[k])}] (it describes {described})")


def engage(program: Program, stock, tools: Tool | Mapping[int, Tool], ds_mm: float, allow: Iterable[str],
           *, stage: str = "optimize", slices: int = 8, progress: Progress | bool | None = None,
           clearance_mm: float | None = None) -> tuple[Samples, Engagement, list[str]]:
    """The engagement stage: check the program (`millpost.gcode.check_program`) and that every feed move
    runs with a described tool, resample every `ds_mm` (mm; ``large`` gate), step the tools through `stock`
    (cut in place; ``rapid`` gate from the first known position) and check the cut (``no-cut``,
    ``below-stock``, ``flute-length``). clearance_mm: see `simulate`. Returns the samples, the engagement
    and the warnings/notes the gates left."""
    notes: list[str] = []
    bounds = stock.bounds()
    check_program(program)
    _check_tools(program, tools, float(bounds[1][2]))
    samples = resample(program, ds_mm, allow, notes, stage=stage)
    try:
        eng = simulate(stock, tools, samples, slices=slices, progress=progress,
                                  start=known_start(program, samples), clearance_mm=clearance_mm)
    except CrashError as exc:
        on_line = np.flatnonzero(program.toolpath.line == exc.line)
        inch = bool(len(on_line) and program.move_inch[on_line[0]])
        raise CrashError(exc.line, exc.xyz, file=program.path, inch=inch) from None
    check_cut(program, bounds, tools, samples, eng, allow, notes)
    return samples, eng, notes
