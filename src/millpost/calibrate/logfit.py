"""Fits from a measurement log aligned to the program it recorded (a calibration plan's, or any job's).

The log is aligned to the forward model (`millpost.measure.align`); every log row then has a program
time, hence a path sample: its engagement, feed per tooth, speed, axis kinematics. The planned moves say
which samples to use for what:

- cutting coefficients: samples of the plan's slot and step lines where the predicted engagement is the
  planned one and the speed the programmed one (steady), one observation per cut = the mean of the log
  rows nearest to its steady samples (force on the tool = −logged workpiece force; cutting power = logged
  spindle power − the no-load power at that speed);
- spindle no-load power (and current): log rows inside the idle dwells, after a spin-up allowance;
- axis drives: log rows on the axis-test strokes, with the controller model's axis velocity and
  acceleration at their program times.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import MillpostError
from ..forces import Measurements
from ..gcode import read_program
from ..gcode.interpret import Program
from ..job import Job, load_job
from ..measure import Alignment, Log, align
from ..measure.alignment import TOLERANCE_MM
from ..signals import Signals, simulate
from .coefficients import PRIOR_SPREAD, Fit, fit_models
from .machine_fit import AxisDrive, fit_idle_power, fit_spindle_current
from .plan import PlannedMove, read_plan

SPIN_UP_S = 1.0    # idle dwell rows this long after the speed change are left out


def steady_samples(signals: Signals, moves: list[PlannedMove], *, kinds=("slot", "step"), tol: float = 0.02,
                   erode: int = 2) -> np.ndarray:
    """Samples on the planned lines of `kinds` whose predicted engagement (ap, ae) and speed are the
    planned ones and whose predicted force is the line's median within `tol`, keeping only runs of such
    samples shrunk by `erode` at both ends."""
    ok = np.zeros(len(signals), bool)
    for m in moves:
        if m.kind not in kinds:
            continue
        on = signals.line == m.line
        ae_plan = min(m.ae_mm, m.diameter_mm)
        ok |= _steady_load(signals, on & (np.abs(signals.ap_mm - m.ap_mm) <= tol * m.ap_mm)
                           & (np.abs(signals.ae_mm - ae_plan) <= tol * ae_plan)
                           & (np.abs(signals.speed_mm_s * 60.0 - m.feed_mm_min) <= tol * m.feed_mm_min), tol)
    for _ in range(erode):
        ok[1:-1] &= ok[:-2] & ok[2:]
        ok[[0, -1]] = False
    return ok


def steady_job_samples(signals: Signals, *, tol: float = 0.02, erode: int = 2, minimum: int = 10) -> np.ndarray:
    """In any program: per source line, the cutting samples whose ap, ae, speed and predicted force are the
    line's median ones within `tol` (the steady stretch of the line's cut), runs shrunk by `erode` at both ends, lines
    with at least `minimum` such samples."""
    ok = np.zeros(len(signals), bool)
    cutting = signals.ap_mm > 0
    for line in np.unique(signals.line[cutting]):
        on = cutting & (signals.line == line)
        near = on.copy()
        for q in (signals.ap_mm, signals.ae_mm, signals.speed_mm_s):
            mid = float(np.median(q[on]))
            near &= np.abs(q - mid) <= tol * mid
        ok |= _steady_load(signals, near, tol)
    for _ in range(erode):
        ok[1:-1] &= ok[:-2] & ok[2:]
        ok[[0, -1]] = False
    for line in np.unique(signals.line[ok]):
        if np.count_nonzero(ok & (signals.line == line)) < minimum:
            ok &= signals.line != line
    return ok


def _steady_load(signals: Signals, on: np.ndarray, tol: float) -> np.ndarray:
    """The samples of `on` (one line) whose predicted force on the tool is within `tol` of their median and
    that lie at least a tool diameter along the path from where the line's cut starts and ends: entering
    and leaving the stock, the width across the feed is already (or still) the full one, but the engaged
    arcs are not."""
    if not on.any():
        return on
    mag = np.linalg.norm(signals.force_tool_N, axis=1)
    mid = float(np.median(mag[on]))
    line = signals.line[np.flatnonzero(on)[0]]
    cut = np.flatnonzero((signals.line == line) & (signals.ap_mm > 0))
    diameter = 2.0 * float(np.max(signals.engagement.r_mm[cut])) if signals.engagement is not None else 0.0
    s = signals.s_mm
    inner = (s >= s[cut[0]] + diameter) & (s <= s[cut[-1]] - diameter)
    return on & inner & (np.abs(mag - mid) <= tol * mid)


@dataclass
class Observations:
    """One observation per steady cut: the sample standing for it (its engagement, feed per tooth,
    speed), the measured means over the cut (force on the tool machine XYZ, cutting power), its tool, and
    how many log rows went into it."""

    index: np.ndarray
    measurements: Measurements
    tools: list
    rows: np.ndarray


def observations(log: Log, alignment: Alignment, signals: Signals, job: Job, use: np.ndarray,
                 idle_W=None, tol: float = 0.02) -> Observations:
    """Mean logged force and power over each steady cut: the used samples grouped by source line (a cut
    is a line of the plan), averaged over all the log rows nearest to them. Means over whole cuts are what
    the average-force method fits; samples within a cut share its disturbances (runout, material), so
    they are not independent observations. idle_W(rpm) → no-load power (W) to subtract (default: the job
    machine's)."""
    j = alignment.samples(signals)
    keep = (j >= 0) & use[np.maximum(j, 0)]
    fz_log = np.full(len(log), np.nan)
    if np.isfinite(alignment.speed_mm_s).any():   # the feed per tooth the machine ran: the log's own speed
        flutes = np.array([job.tools[int(t)].flutes if int(t) in job.tools else 1 for t in signals.tool])
        jj = np.maximum(j, 0)
        with np.errstate(invalid="ignore", divide="ignore"):
            fz_log = alignment.speed_mm_s * 60.0 / (flutes[jj] * signals.rpm[jj])
        keep &= _steady(fz_log, signals.line[jj], keep, tol)
    lines = np.unique(signals.line[use])
    group = np.full(len(signals), -1)
    group[use] = np.searchsorted(lines, signals.line[use])
    g = group[j[keep]]
    counts = np.bincount(g, minlength=len(lines))
    found = np.flatnonzero(counts >= 3)
    if len(found) < 3:
        raise MillpostError(f"{log.path}: only {len(found)} steady cuts covered by the log; is it the log of "
                            "this program, and does it cover the cuts?")
    # the sample standing for each cut: the middle of its steady samples
    index = np.array([np.flatnonzero(group == k)[len(np.flatnonzero(group == k)) // 2] for k in found])

    def mean_of(values: np.ndarray) -> np.ndarray:
        v = values[keep]
        ok = np.isfinite(v)
        s = np.bincount(g[ok], weights=v[ok], minlength=len(lines))
        c = np.bincount(g[ok], minlength=len(lines))
        with np.errstate(invalid="ignore", divide="ignore"):
            return (s / c)[found]

    def mean(column: str) -> np.ndarray:
        return mean_of(log[column])

    force = None
    if all(log.has(c) for c in ("fx_N", "fy_N", "fz_N")):
        force = -np.column_stack([mean(c) for c in ("fx_N", "fy_N", "fz_N")])   # on the tool
    power = None
    if log.has("spindle_power_W"):
        rpm = signals.rpm[index]
        idle = idle_W(rpm) if idle_W is not None else job.machine.spindle.idle_power_at_W(rpm)
        power = mean("spindle_power_W") - idle
    if force is None and power is None:
        raise MillpostError(f"{log.path}: no force (fx_N, fy_N, fz_N) or spindle_power_W columns to fit")
    tools = [job.tools[int(t)] for t in signals.tool[index]]
    fz = signals.fz_mm[index]
    if np.isfinite(fz_log[keep]).any():
        fz = np.where(np.isfinite(mean_of(fz_log)), mean_of(fz_log), fz)
    meas = Measurements(fz_mm=fz, rpm=signals.rpm[index], force_N=force, power_W=power)
    return Observations(index, meas, tools, counts[found])


def _steady(fz_mm: np.ndarray, line: np.ndarray, keep: np.ndarray, tol: float) -> np.ndarray:
    """Rows whose logged feed per tooth is within `tol` of the median of their line's kept rows (the
    machine's own steady stretch: its accelerations, holds and override, not the model's)."""
    out = np.zeros(len(fz_mm), bool)
    for value in np.unique(line[keep]):
        on = keep & (line == value) & np.isfinite(fz_mm)
        if on.any():
            mid = float(np.median(fz_mm[on]))
            out |= on & (np.abs(fz_mm - mid) <= tol * mid)
    return out


def idle_windows(signals: Signals, program: Program, moves: list[PlannedMove]) -> list[tuple[float, float, float]]:
    """(rpm, program time start, end) of the planned idle dwells, spin-up left out."""
    out = []
    dwells = {e.line: e for e in program.events if e.kind == "dwell"}
    for m in moves:
        if m.kind != "idle" or m.line not in dwells:
            continue
        before = signals.t_s[signals.move < dwells[m.line].move]
        t0 = float(before[-1]) if len(before) else 0.0
        if m.dwell_s > SPIN_UP_S:
            out.append((m.rpm, t0 + SPIN_UP_S, t0 + m.dwell_s))
    return out


def fit_idle(log: Log, alignment: Alignment, windows) -> dict:
    """No-load power points (idle_rpm, idle_power_W) from the idle dwells ({} when the log has no spindle
    power inside them)."""
    tau = alignment.tau_s
    rpm = np.full(len(log), np.nan)
    for n, a, b in windows:
        rpm[(tau >= a) & (tau <= b)] = n
    inside = np.isfinite(rpm) & np.isfinite(log["spindle_power_W"])
    if not inside.any():
        return {}
    speeds, power = fit_idle_power(rpm[inside], log["spindle_power_W"][inside])
    out = {"idle_rpm": speeds, "idle_power_W": power}
    return out


def fit_axes(log: Log, alignment: Alignment, signals: Signals, moves: list[PlannedMove],
             terms=("inertia", "coulomb", "viscous")) -> dict[str, AxisDrive]:
    """Per axis with a logged current (ix_A, iy_A, iz_A): the drive model fitted on the axis-test strokes
    of that axis, kinematics from the controller model at the rows' program times."""
    j = alignment.samples(signals)
    out = {}
    for k, axis in enumerate("xyz"):
        col = f"i{axis}_A"
        lines = {m.line for m in moves if m.kind == "axis" and m.axis == axis}
        if not log.has(col) or not lines:
            continue
        on = (j >= 0) & np.isin(signals.line[np.maximum(j, 0)], list(lines))
        if on.sum() < 10:
            continue
        tau = alignment.tau_s[on]
        vs = signals.axis_velocity_mm_s[:, k]
        v = np.interp(tau, signals.t_s, vs)
        a = np.interp(tau, signals.t_s, signals.axis_accel_mm_s2[:, k])
        # where the axis stops or reverses the friction's sign (and stiction) is undetermined: rows between
        # samples that do not both move the same way are left out
        before = np.clip(np.searchsorted(signals.t_s, tau) - 1, 0, len(signals) - 2)
        moving = (np.sign(vs[before]) == np.sign(vs[before + 1])) & (vs[before] != 0)
        out[axis] = AxisDrive(terms).fit(v[moving], a[moving], log[col][on][moving])
    return out


@dataclass
class LogFit:
    """Everything fitted from one log against a plan folder."""

    alignment: Alignment
    cutting: Fit | None
    idle: dict
    axes: dict[str, AxisDrive]
    notes: list[str]


def fit_log(target, log: Log, base=None, *, axis_terms=("inertia", "coulomb", "viscous"),
            progress=None, prior_spread: float = PRIOR_SPREAD, tolerance_mm: float = TOLERANCE_MM) -> LogFit:
    """Align `log` to a job's program and fit what the log holds: cutting coefficients (forces and/or
    spindle power), spindle no-load power and current, axis drives. target: the folder `calibrate plan`
    wrote (job.toml and plan.csv: the planned cuts, idle dwells and axis strokes are used), or any job
    (folder or .toml: its steady stretches of cut, see `steady_job_samples`; cutting coefficients only).
    base: the material to start from, the prior (default: the job's; prior_spread its relative 1σ);
    tolerance_mm: the alignment's (a log off the program's path is refused, `MisalignedLog`). progress: as
    `millpost.optimize`'s (the engagement run reports through it)."""
    target = Path(target)
    job = load_job(target)
    plan_file = job.path.parent / "plan.csv"
    moves = read_plan(plan_file) if plan_file.exists() else []
    program = read_program(job.program, job.reader_options())
    signals = simulate(job, program=program, progress=progress)
    alignment = align(log, signals, tolerance_mm=tolerance_mm)
    notes: list[str] = list(alignment.notes)
    idle: dict = {}
    windows = idle_windows(signals, program, moves)
    if windows and log.has("spindle_power_W"):
        idle = fit_idle(log, alignment, windows)
    idle_fn = None
    if idle:
        idle_fn = lambda rpm: np.interp(rpm, idle["idle_rpm"], idle["idle_power_W"])  # noqa: E731
    elif log.has("spindle_power_W"):
        notes.append("no idle dwells in the plan" + (" covered by the log" if windows else "") +
                     ": the machine file's no-load power is subtracted")
    if log.has("spindle_current_A") and log.has("spindle_power_W"):
        # shaft torque P/ω against current wherever the spindle turns (idle and cutting)
        j = alignment.samples(signals)
        rpm = np.where(j >= 0, signals.rpm[np.maximum(j, 0)], 0.0)
        on = rpm > 0
        if on.sum() >= 3:
            kt, i0 = fit_spindle_current(log["spindle_power_W"][on] / (2 * np.pi * rpm[on] / 60.0),
                                         log["spindle_current_A"][on])
            idle.update(kt_Nm_per_A=kt, idle_current_A=i0)
    cutting = None
    steady = steady_samples(signals, moves) if moves else steady_job_samples(signals)
    if not moves:
        notes.append(f"no plan beside {job.path}: the job's steady stretches of cut are fitted")
    if steady.any() and (log.has("spindle_power_W") or log.has("fx_N")):
        obs = observations(log, alignment, signals, job, steady, idle_fn)
        cutting = fit_models(signals.engagement.select(obs.index), obs.measurements, obs.tools,
                             base or job.material, source=log.path, prior_spread=prior_spread)
    axes = fit_axes(log, alignment, signals, moves, axis_terms)
    return LogFit(alignment, cutting, idle, axes, notes)
