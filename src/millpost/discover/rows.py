"""The log rows discover works on: each row's measured channels beside what the forward model says about
the tool at that instant (engagement, feed per tooth, speed, axis kinematics) and the base model's
regressors for every channel.

Base model per channel (linear in its parameters, refitted on the log):
- fx_N, fy_N, fz_N (force on the workpiece) and spindle_power_W: the mechanistic cutting law with six
  coefficients K_tc, K_rc, K_ac (N/mm²), K_te, K_re, K_ae (N/mm) shared by all of them (the average force
  over a tooth period is affine in f_z: F = f_z·G·K_c + E·K_e, `millpost.forces.mechanistic.regressors`,
  rotated to machine XYZ; power = torque·ω) + a zero offset per channel; spindle power also carries the
  machine file's no-load power P_idle(n) as a fixed term;
- spindle_current_A: a gain on the forward model's current + an offset;
- ix_A, iy_A, iz_A (axis motor current): inertia k_a·a + the cutting force along the axis through the
  drive's A per N, k_f·F = Σ_j (k_f·K_j)·regressor_j (the cutting law's six regressors, each product a
  parameter of the channel: linear, and free of the nominal coefficients' ±20 % error, which a single
  gain on the forward model's force would carry) + an offset (friction is a candidate effect, not part
  of the base).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..engagement import Engagement
from ..errors import MillpostError
from ..forces.base import to_machine
from ..forces.mechanistic import COEF_NAMES, regressors
from ..job import Job
from ..measure import Alignment, Log
from ..measure.alignment import STILL_MM_S, rate
from ..signals import Signals

FORCE = ("fx_N", "fy_N", "fz_N")
CUTTING = FORCE + ("spindle_power_W",)
CURRENTS = ("ix_A", "iy_A", "iz_A")
CHANNELS = CUTTING + ("spindle_current_A",) + CURRENTS
AGREE = 0.05                # the log's path speed within this of the model's (+ 2 STILL_MM_S): the model's timing holds
OPEN_ROWS = 2               # ... and where it does not, only in runs of 2·OPEN_ROWS + 1 rows or more
GAP_RAD = np.deg2rad(0.5)   # an engaged arc with a gap wider than this is two arcs (see `exit_zone`)


@dataclass
class Cuts:
    """The cutting path samples behind the rows, so that an effect can evaluate the cutting law again on a
    changed engagement (a bent tool's narrower cut, a chip-thickness-dependent coefficient).

    sample: (n, 2) per log row, the two cutting samples around the tool's engagement (indices into the
    arrays below, −1 where that sample does not cut) and weight (n,) the second's share (the row is
    interpolated between them); engagement, flutes, fz_mm (feed per tooth, mm) and omega_rad_s (spindle speed) of the cutting
    samples; fz_scale: per row, the feed per tooth the machine ran (from the log's own path speed) over the
    model's there (None: the model's)."""

    sample: np.ndarray
    weight: np.ndarray
    engagement: Engagement
    flutes: np.ndarray
    fz_mm: np.ndarray
    omega_rad_s: np.ndarray
    fz_scale: np.ndarray | None = None   # per row: the feed per tooth the log shows over the model's

    def regressors(self, engagement: Engagement | None = None) -> tuple[np.ndarray, np.ndarray]:
        """G, E (m, 4, 3) of the cutting law per cutting sample (feed frame, force on the tool and torque;
        `millpost.forces.mechanistic.regressors`) on `engagement` (default the simulated one)."""
        return regressors(self.engagement if engagement is None else engagement, self.flutes)

    def channels(self, G: np.ndarray, E: np.ndarray) -> dict[str, np.ndarray]:
        """Per log row and cutting channel, the (n, 6) columns of the six coefficients (K_tc, K_rc, K_ac
        × f_z·G, K_te, K_re, K_ae × E): forces on the workpiece (−, rotated to machine XYZ, N) and spindle
        power (torque × ω, W); zero on rows that do not cut."""
        m = len(self.fz_mm)
        per = {c: np.zeros((m + 1, 6)) for c in CUTTING}     # the last row: not cutting
        fd = self.engagement.feed_dir
        for k in range(3):
            shear = -to_machine(fd, self.fz_mm[:, None] * G[:, :3, k])
            edge = -to_machine(fd, E[:, :3, k])
            for a, c in enumerate(FORCE):
                per[c][:m, k], per[c][:m, 3 + k] = shear[:, a], edge[:, a]
            per["spindle_power_W"][:m, k] = self.fz_mm * G[:, 3, k] / 1000.0 * self.omega_rad_s
            per["spindle_power_W"][:m, 3 + k] = E[:, 3, k] / 1000.0 * self.omega_rad_s
        at = np.where(self.sample >= 0, self.sample, m)
        w = self.weight[:, None]
        out = {c: (1 - w) * v[at[:, 0]] + w * v[at[:, 1]] for c, v in per.items()}
        if self.fz_scale is not None:   # the shearing share is proportional to the feed per tooth
            for v in out.values():
                v[:, :3] *= self.fz_scale[:, None]
        return out


@dataclass
class Rows:
    """n log rows (time order) with their measured channels and per-row features.

    t_s: log time (s); measured: channel → (n,) values (nan: missing); cut: channel → (n, 6) regressors of
    the cutting law for fx_N, fy_N, fz_N, spindle_power_W (zeros where the tool does not cut), present
    whether or not the channel is logged (effects use the force magnitude); columns: channel → {name: (n,)}
    channel-own base columns; fixed: channel → (n,) fixed base term. features: rpm, fz_mm, ae_mm, ap_mm,
    diameter_mm, cut_length_m (engaged path so far, per tool), velocity_mm_s (n, 3), accel_mm_s2 (n, 3);
    cuts: the cutting samples behind the rows (for effects that change the engagement or the law). use:
    the rows fits and scores use: not where the tool leaves the material (`exit_zone`), nor just before
    a cut (`entry_zone`), nor the first
    look-ahead of a cut, where the tool already cuts but the sample behind it did not (`engaged_between`)."""

    t_s: np.ndarray
    measured: dict[str, np.ndarray]
    cut: dict[str, np.ndarray]
    columns: dict[str, dict[str, np.ndarray]]
    fixed: dict[str, np.ndarray]
    features: dict[str, np.ndarray] = field(default_factory=dict)
    index: np.ndarray | None = None   # the log rows these are (into the whole log)
    use: np.ndarray | None = None     # rows the fits and scores use (default all)
    cuts: Cuts | None = None          # the cutting samples behind the rows (None: no program)

    def __len__(self) -> int:
        return len(self.t_s)

    @property
    def channels(self) -> list[str]:
        return list(self.measured)

    @property
    def dt_s(self) -> float:
        return float(np.median(np.diff(self.t_s))) if len(self.t_s) > 1 else 1.0


def from_log(log: Log, alignment: Alignment, signals: Signals, job: Job) -> Rows:
    """The rows of `log` inside the program (by the alignment), each with its nearest path sample."""
    j_all = alignment.samples(signals)
    inside = np.flatnonzero(j_all >= 0)
    if len(inside) < 50:
        raise MillpostError(f"{log.path}: only {len(inside)} log rows fall inside the program after alignment "
                            f"({alignment.method}, offset {alignment.offset_s:.3f} s)")
    j = j_all[inside]
    tau = alignment.tau_s[inside]
    ka, kb, w = engaged_between(signals, tau)
    # the axis kinematics at each row's instant, linear in time between the path samples around it (the
    # nearest sample would move a rapid's acceleration step by up to half a sample interval)
    velocity, accel = (np.column_stack([np.interp(tau, signals.t_s, v[:, k]) for k in range(3)])
                       for v in (signals.axis_velocity_mm_s, signals.axis_accel_mm_s2))
    je = np.where(w < 0.5, ka, kb)
    fz_scale = None
    if alignment.method == "position":
        # where the machine ran at another speed than the model (its own accelerations, a hold, an override),
        # the feed per tooth and axis kinematics the log's own speed gives; elsewhere the model's
        speed = alignment.speed_mm_s[inside]
        model_speed = np.interp(tau, signals.t_s, signals.speed_mm_s)
        other = ~(np.abs(speed - model_speed) <= AGREE * model_speed + 2 * STILL_MM_S)
        # runs of at least 2·OPEN_ROWS + 1 rows: not a few rows at a corner, where a derivative of the log's
        # positions smears the speed's step
        core = other.copy()
        for k in range(1, OPEN_ROWS + 1):
            core &= np.roll(other, k) & np.roll(other, -k)
        other = core.copy()
        for k in range(1, OPEN_ROWS + 1):
            other |= np.roll(core, k) | np.roll(core, -k)
        if other.any():   # there the axes move along the path's tangent at the log's speed
            a = np.clip(np.floor(alignment.place[inside]).astype(int), 0, len(signals) - 2)
            step = signals.xyz_mm[a + 1] - signals.xyz_mm[a]
            tangent = step / np.maximum(np.linalg.norm(step, axis=1), 1e-12)[:, None]
            velocity = np.where(other[:, None], tangent * speed[:, None], velocity)
            accel = np.where(other[:, None], tangent * rate(log.t_s[inside], speed)[:, None], accel)
        with np.errstate(invalid="ignore", divide="ignore"):
            fz_scale = np.where(other & (model_speed > 0), speed / np.where(model_speed > 0, model_speed, 1.0), 1.0)
        fz_scale = np.clip(np.nan_to_num(fz_scale, nan=1.0), 0.0, 3.0)
    measured = {c: np.asarray(log[c][inside], float) for c in CHANNELS if log.has(c)}
    if not measured:
        raise MillpostError(f"{log.path}: no channel discover can use (has {', '.join(log.columns)}; "
                            f"usable: {', '.join(CHANNELS)})")
    n_s = len(signals)
    cutting = signals.ap_mm > 1e-9
    flutes = np.ones(n_s)
    diameter = np.zeros(n_s)
    for number in np.unique(signals.tool[cutting]):
        tool = job.tools[int(number)]
        on = signals.tool == number
        flutes[on], diameter[on] = tool.flutes, tool.diameter_mm
    idx = np.flatnonzero(cutting)
    position = np.full(n_s, -1)
    position[idx] = np.arange(len(idx))
    cuts = Cuts(np.column_stack([position[ka], position[kb]]), w, signals.engagement.select(idx), flutes[idx],
                signals.fz_mm[idx], 2 * np.pi * signals.rpm[idx] / 60.0, fz_scale)
    cut = cuts.channels(*cuts.regressors())
    # engaged path length so far per tool (m): wear grows with it
    ds = np.diff(signals.s_mm, prepend=signals.s_mm[0]) * cutting
    length = np.zeros(n_s)
    for number in np.unique(signals.tool):
        on = signals.tool == number
        length[on] = np.cumsum(ds[on]) / 1000.0
    n = len(j)
    ones = np.ones(n)
    columns: dict[str, dict[str, np.ndarray]] = {}
    fixed: dict[str, np.ndarray] = {}
    for c in measured:
        columns[c] = {"offset": ones}
        if c == "spindle_power_W":
            fixed[c] = job.machine.spindle.idle_power_at_W(signals.rpm[j])
        elif c == "spindle_current_A":
            columns[c]["gain"] = np.nan_to_num(signals.spindle_current_A[j])
        elif c in CURRENTS:
            k = CURRENTS.index(c)
            columns[c]["inertia_A_per_m_s2"] = accel[:, k] / 1000.0
            for name, col in zip(COEF_NAMES, cut[FORCE[k]].T):   # k_f·K per coefficient: A per (N/mm², N/mm)
                columns[c][f"cut_{name}"] = col
    exiting = exit_zone(signals, diameter)
    features = {"rpm": signals.rpm[j], "fz_mm": signals.fz_mm[je] * (1.0 if fz_scale is None else fz_scale),
                "ae_mm": signals.ae_mm[je],
                "ap_mm": signals.ap_mm[je], "diameter_mm": diameter[je], "cut_length_m": length[je],
                "velocity_mm_s": velocity, "accel_mm_s2": accel}
    use = ~exiting[je] & ~entry_zone(signals)[j] & (cutting[j] == cutting[ka]) & (cutting[j] == cutting[kb])
    return Rows(np.asarray(log.t_s[inside], float), measured, cut, columns, fixed, features, inside, use, cuts)


def engaged_between(signals: Signals, tau_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tool's engagement at program times tau_s as the two path samples around it and the weight of
    the second (ka, kb, w): the engagement of a sample is the one the tool meets `look_ahead_mm` further
    along the path (taken ahead so that the current step's own cells do not cut the arc's tangent ends),
    so the tool's own at path position s is that of the path at s − look-ahead, interpolated linearly in
    path length between the samples (a nearest sample would shift the rising force of a cut's entry by
    up to half a step)."""
    s = signals.s_mm
    s_row = np.interp(tau_s, signals.t_s, s)
    ahead = signals.engagement.look_ahead_mm
    target = s_row - (np.interp(s_row, s, ahead) if ahead is not None else 0.0)
    ka = np.clip(np.searchsorted(s, target, side="right") - 1, 0, max(len(s) - 2, 0))
    kb = np.minimum(ka + 1, len(s) - 1)
    step = s[kb] - s[ka]
    w = np.where(step > 0, np.clip((target - s[ka]) / np.where(step > 0, step, 1.0), 0.0, 1.0), 0.0)
    return ka, kb, w


def exit_zone(signals: Signals, diameter_mm: np.ndarray) -> np.ndarray:
    """Samples within one tool radius of the end of a run of cutting samples: where the tool leaves the
    material. There the material left in front of the tool can lie on two separate arcs of its circle
    (a sliver at both flanks when a slot runs out of the stock), which the engagement's one entry/exit
    arc per slice takes as the whole span between them: the forward model overstates the force there, so
    discover leaves these rows out of its fits and scores (they keep their predictions)."""
    cutting = signals.ap_mm > 1e-9
    out = np.zeros(len(signals), bool)
    if not cutting.any():
        return out
    edges = np.diff(np.concatenate([[0], cutting.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    for a, b in zip(starts, ends):
        s_end = signals.s_mm[b - 1]
        out[a:b] = s_end - signals.s_mm[a:b] < 0.5 * diameter_mm[a:b]
    eng = signals.engagement
    if eng is not None and eng.arc_rad is not None:
        # the material in front already split in two: the engaged measure falls short of the interval
        span = np.nan_to_num(eng.phi_ex - eng.phi_st)
        out |= np.any(span - eng.arc_rad > GAP_RAD, axis=1)
    return out


def entry_zone(signals: Signals) -> np.ndarray:
    """Samples within one look-ahead (or one step) before a run of cutting samples: the tool may already
    touch the stock there (the stepping takes a cell as cut only once the tool covers its centre, and an
    entering cutter's first fraction of a millimetre already meets a wide arc of a flat face), but the
    model has no engagement for them: discover leaves these rows out of its fits and scores."""
    cutting = signals.ap_mm > 1e-9
    out = np.zeros(len(signals), bool)
    ahead = signals.engagement.look_ahead_mm if signals.engagement is not None else None
    s = signals.s_mm
    starts = np.flatnonzero(np.diff(np.concatenate([[0], cutting.astype(np.int8)])) == 1)
    for a in starts[starts > 0]:
        margin = max(float(ahead[a]) if ahead is not None else 0.0, s[a] - s[a - 1])
        k = a
        while k > 0 and not cutting[k - 1] and s[a] - s[k - 1] <= margin:
            k -= 1
        out[k:a] = True
    return out


def from_axis_arrays(t_s, velocity_mm_s, accel_mm_s2, currents: dict[str, np.ndarray]) -> Rows:
    """Rows of axis drive logs without a program (e.g. a drive's own velocity, acceleration and current
    feedback): velocity and acceleration (n, 3) per row, currents keyed ix_A/iy_A/iz_A."""
    t = np.asarray(t_s, float)
    v, a = np.asarray(velocity_mm_s, float), np.asarray(accel_mm_s2, float)
    n = len(t)
    columns = {c: {"offset": np.ones(n), "inertia_A_per_m_s2": a[:, CURRENTS.index(c)] / 1000.0}
               for c in currents}
    zeros = np.zeros(n)
    return Rows(t, {c: np.asarray(i, float) for c, i in currents.items()}, {c: np.zeros((n, 6)) for c in CUTTING},
                columns, {}, {"rpm": zeros, "fz_mm": zeros, "ae_mm": zeros, "ap_mm": zeros, "diameter_mm": zeros,
                              "cut_length_m": zeros, "velocity_mm_s": v, "accel_mm_s2": a})


COEFS = COEF_NAMES
