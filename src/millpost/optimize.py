"""End to end: a job's program → engagement → loads → one convex feed schedule → the program with new feeds.

The limits the schedule obeys, each a constraint object of `millpost.schedule` built here from the
machine, tool and material:

- feed: the user's and the machine's maximum feed; axis velocity and acceleration; junction speed
  at corners (the controller's junction deviation); optional path jerk;
- cutting_force: the peak in-plane force per revolution under the tool's breaking force divided by
  its safety factor (tool beam, load at the tip: the weakest case);
- deflection: (tool compliance at the tip + the softer of the X/Y axes) × peak force ≤ limit;
- power and torque: the spindle's curve at the programmed rpm (clamped to the spindle's range, as
  controllers do, and reported);
- chip_load: the maximum chip thickness h_max = f_z·max sin φ·sin κ of the engaged arc between the
  material's minimum chip (edge radius: no rubbing; a soft floor) and its maximum chip load;
- current: per axis, inertia (moving mass and reflected rotor inertia) plus cutting force plus
  friction under the drive's current limit; current_slew: di/dt under (V_bus − R·I − K_e·ω)/L.

Cycle times are always the controller model's (`millpost.controller`), before and after, and against
the honest baseline: per tool, the highest single constant feed that exceeds no limit anywhere.
When the solver fails, the programmed feeds are kept and the summary says why.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from . import controller, engagement
from .emit import FeedPlan, whole_compensated_moves, write_feeds
from .errors import MillpostError
from .gcode import read_program
from .gcode.interpret import Program
from .job import Job
from .progress import Progress, resolve, stage
from .schedule import (AxisAcceleration, AxisVelocity, Centripetal, ChipLoad, CurrentSlew, FeedLimit, Junction, MotorCurrent,
                       PathGrid, PathJerk, ScheduleOptions, SpeedLoad, schedule_samples)
from .schedule.assemble import merged_bounds
from .schedule.feeds import SLOWEST_FEED_MM_MIN, emission_limit, piecewise_feeds, split_toolpath
from .schedule.rows import SpeedBounds
from .toolpath import RAPID, Samples
from .tools.beam import ToolBeam

V_SLOWEST = SLOWEST_FEED_MM_MIN / 60.0  # mm/s: the slowest feed the emitted program states

# which limit names count as which physical effect in the summary's "binding"
EFFECTS = {"axis_velocity": "inertia", "axis_acceleration": "inertia", "centripetal": "inertia", "junction": "inertia",
           "jerk": "inertia",
           "feed": "feed", "cutting_force": "cutting force", "deflection": "deflection", "power": "power",
           "torque": "power", "current": "current", "cutting_current": "current", "current_slew": "current",
           "chip_load_max": "chip load",
           "chip_load_min": "chip-load floor"}


@dataclass
class Result:
    """What `optimize` did: the emitted text, the summary (JSON-ready) and per-sample arrays."""

    text: str
    summary: dict
    samples: Samples
    trace: dict = field(default_factory=dict)


def machine_controller(job: Job) -> controller.ControllerModel:
    ax = [job.machine.axes[a] for a in "xyz"]
    return controller.ControllerModel(
        max_rate_mm_s=tuple(a.vmax_mm_min / 60.0 for a in ax), accel_mm_s2=tuple(a.amax_mm_s2 for a in ax),
        junction_deviation_mm=job.machine.controller.junction_deviation_mm,
        block_rate_hz=job.machine.controller.block_rate_Hz)


def _max_sin(eng) -> np.ndarray:
    """Per sample: the largest sin φ·sin κ over the engaged arcs (0 where nothing cuts)."""
    st, ex = eng.phi_st, eng.phi_ex
    cuts = np.isfinite(st) & np.isfinite(ex) & (eng.dz_mm > 0)
    s = np.where((st <= np.pi / 2) & (ex >= np.pi / 2), 1.0, np.maximum(np.sin(np.nan_to_num(st)),
                                                                         np.sin(np.nan_to_num(ex))))
    return np.where(cuts, s * np.sin(eng.kappa), 0.0).max(axis=1, initial=0.0)


def spindle_rpm(job: Job, programmed_rpm: np.ndarray) -> np.ndarray:
    """The speed the spindle turns at (rpm): the programmed S clamped to the machine's range."""
    return np.clip(programmed_rpm, job.machine.spindle.rpm_min, job.machine.spindle.rpm_max)


def build_limits(job: Job, samples: Samples, eng) -> tuple[list, dict]:
    """Constraint objects for the whole resampled program, and the per-sample loads they came from
    (force/power/torque as affine functions of the path speed in mm/s)."""
    n = len(samples)
    m = job.machine
    ax = [m.axes[a] for a in "xyz"]
    amax = tuple(a.amax_mm_s2 for a in ax)
    feed_max = m.feed_max_mm_min
    if job.limits["feed_max_mm_min"]:
        feed_max = min(feed_max, float(job.limits["feed_max_mm_min"]))
    limits: list = [FeedLimit(feed_max / 60.0), AxisVelocity(tuple(a.vmax_mm_min / 60.0 for a in ax)),
                    AxisAcceleration(amax), Centripetal(amax), Junction(amax, m.controller.junction_deviation_mm)]
    if job.limits.get("jerk_mm_s3"):
        limits.append(PathJerk(float(job.limits["jerk_mm_s3"])))
    model = job.material.force_model(job.limits["model"])
    cutting = samples.kind != RAPID
    engaged = eng.ap_mm > 1e-9
    spin = samples.rpm > 0
    if np.any(engaged & ~spin):
        k = int(np.flatnonzero(engaged & ~spin)[0])
        raise MillpostError(f"{job.program}:{samples.line[k]}: the tool cuts material with the spindle off")
    loads = {key: np.zeros(n) for key in ("peak_a", "peak_b", "power_a", "power_b", "torque_a", "torque_b")}
    loads["force_a"], loads["force_b"] = np.zeros((n, 3)), np.zeros((n, 3))
    rpm = np.where(spin, spindle_rpm(job, samples.rpm), 1.0)
    k_xy = min(m.axes["x"].stiffness_N_per_mm, m.axes["y"].stiffness_N_per_mm)
    peak_limit, defl_per_N = np.full(n, np.inf), np.zeros(n)
    fz_hi, fz_lo = np.full(n, np.inf), np.zeros(n)
    sin_max = _max_sin(eng)
    for number in np.unique(samples.tool[cutting]):
        tool = job.tools.get(int(number))
        if tool is None:
            line = int(samples.line[np.flatnonzero(cutting & (samples.tool == number))[0]])
            raise MillpostError(f"{job.program}:{line}: tool T{number} cuts but the job has no [tools.{number}]")
        idx = np.flatnonzero(samples.tool == number)
        # Kienzle is concave in the feed: its tangent at the programmed feed bounds it from above
        ll = model.linear_loads(eng.select(idx), tool, rpm[idx],
                                feed_ref_mm_min=np.nan_to_num(samples.feed_mm_min[idx], nan=100.0))
        for key in ("peak", "power", "torque", "force"):
            loads[f"{key}_a"][idx] = getattr(ll, f"{key}_a") * 60.0  # per mm/min → per mm/s
            loads[f"{key}_b"][idx] = getattr(ll, f"{key}_b")
        beam = ToolBeam.of(tool, safety_factor=job.limits["tool_safety_factor"] or None)
        peak_limit[idx] = beam.breaking_force_N(eng.ap_mm[idx])  # the cut's depth sets the lever arm
        defl_per_N[idx] = beam.compliance_mm_per_N(eng.ap_mm[idx], at_tip=True) + 1.0 / k_xy
        h_min, h_max = job.material.min_chip_mm(tool.edge_radius_mm), job.material.chip_load_mm(tool.diameter_mm)[1]
        cut_here = idx[sin_max[idx] > 0]
        fz_hi[cut_here] = h_max / sin_max[cut_here]
        fz_lo[cut_here] = h_min / sin_max[cut_here]
        limits.append(ChipLoad(tool.flutes, rpm, np.where(samples.tool == number, fz_lo, 0.0),
                               np.where(samples.tool == number, fz_hi, np.inf), name="chip_load"))
    loads["unavoidable"] = {}
    v_hold = np.nan_to_num(samples.feed_mm_min, nan=0.0) / 60.0
    for name, a, b, bound in (
            ("cutting_force", loads["peak_a"], loads["peak_b"], peak_limit),
            ("deflection", loads["peak_a"] * defl_per_N, loads["peak_b"] * defl_per_N,
             np.full(n, float(job.limits["deflection_mm"]))),
            ("power", loads["power_a"], loads["power_b"], np.where(spin, m.spindle.power_available_W(rpm), np.inf)),
            ("torque", loads["torque_a"], loads["torque_b"], np.where(spin, m.spindle.torque_Nm(rpm), np.inf))):
        # Where the cut exceeds the bound at any feed a program can state (its edge forces alone: the
        # depth or width of cut, not the feed, is at fault), feeding slower cannot help: never feed
        # faster than programmed there, and report those samples rather than crawl.
        over = a * V_SLOWEST + b > bound
        loads["unavoidable"][name] = over
        limits.append(SpeedLoad(a, b, np.where(over, a * v_hold + b, bound), name=name))
    rho = np.array([a.rho_m_per_rad for a in ax])
    mass = tuple(a.moving_mass_kg + a.motor.rotor_inertia_kgm2 / r**2 for a, r in zip(ax, rho))
    kf = tuple(a.motor.kt_Nm_per_A * a.efficiency / r for a, r in zip(ax, rho))
    current = tuple(a.motor.current_limit_A for a in ax)
    friction = np.array([a.friction_coulomb_N for a in ax])
    viscous = np.array([a.friction_viscous_N_s_per_mm for a in ax])
    # Cutting force, friction and drag must leave the drive the current for the controller's own
    # acceleration (it ramps at a_max whatever the F words say): per axis
    # |F_b| + f_c + (|F_a| + c_v·|t|)·v ≤ k_f·I_max − m·a_max (N at the carriage), a conservative
    # speed cap; where no programmable feed meets it the cut is unavoidable as above.
    capacity = np.asarray(kf) * np.asarray(current) - np.asarray(mass) * np.asarray(amax) * 1e-3
    static = np.abs(loads["force_b"]) + friction
    slope = np.abs(loads["force_a"]) + viscous * np.abs(samples.tangent)
    stalled = (static + slope * V_SLOWEST >= capacity).any(axis=1) & engaged
    loads["unavoidable"]["cutting_current"] = stalled
    for k in range(3):
        limits.append(SpeedLoad(slope[:, k], static[:, k], np.where(stalled, slope[:, k] * v_hold + static[:, k],
                                                                    capacity[k]), name="cutting_current"))
    # The cutting share of the current is taken at each sample's speed cap (the speed-only limits
    # above), the endpoint of larger magnitude of the force over [0, cap]: linear rows, no √b term.
    v_cap = np.minimum(_static_caps(samples, limits), feed_max / 60.0)
    at_cap = loads["force_a"] * v_cap[:, None] + loads["force_b"]
    drive_force = -np.where(np.abs(at_cap) > np.abs(loads["force_b"]), at_cap, loads["force_b"])
    drive_force[stalled] = 0.0  # inertia only there: no feed satisfies the cutting share (reported)
    limits.append(MotorCurrent(mass, kf, current, tuple(friction), tuple(viscous), cut_beta=drive_force))
    limits.append(CurrentSlew(mass, kf, current, tuple(a.motor.resistance_ohm for a in ax),
                              tuple(a.motor.inductance_H for a in ax), tuple(a.motor.ke_V_s_per_rad for a in ax),
                              min(a.motor.bus_voltage_V for a in ax), tuple(1.0 / (r * 1000.0) for r in rho)))
    return limits, loads


def _plan_from_fragments(program: Program, fragments) -> FeedPlan:
    plan = FeedPlan.programmed(program)
    by_move: dict[int, list] = {}
    for f in fragments:
        by_move.setdefault(f.move, []).append(f)
    for mv, frs in by_move.items():
        frs.sort(key=lambda f: f.u_start)
        if len(frs) == 1:
            plan.feed_mm_min[mv] = frs[0].feed_mm_min
        else:
            plan.feed_mm_min[mv] = min(f.feed_mm_min for f in frs)
            plan.fragments[mv] = [(f.u_end, f.feed_mm_min) for f in frs]
    return plan


def _static_caps(samples: Samples, limits: list) -> np.ndarray:
    """Per sample the highest speed (mm/s) that the speed-only limits allow (loads, chip, feed; not the
    controller's own axis rates, corners and arcs)."""
    grid = PathGrid.from_samples(samples)
    caps = [blk for lim in limits for blk in lim.blocks(grid) if isinstance(blk, SpeedBounds)
            and blk.name not in ("axis_velocity", "junction", "centripetal")]
    return np.sqrt(merged_bounds(caps, len(samples))[1])


def baseline_feeds(program: Program, samples: Samples, limits: list) -> tuple[np.ndarray, dict]:
    """The honest baseline: per tool one constant feed (mm/min), the highest that exceeds no
    speed-only limit anywhere that tool cuts (what a careful CAM user would program)."""
    tp = program.toolpath
    cap = _static_caps(samples, limits) * 60.0
    feeds = tp.feed_mm_min.copy()
    per_tool = {}
    for number in np.unique(tp.tool[tp.kind != RAPID]):
        sel = (samples.tool == number) & (samples.kind != RAPID)
        f = float(np.floor(cap[sel].min())) if sel.any() else math.nan
        per_tool[int(number)] = f
        feeds[(tp.tool == number) & (tp.kind != RAPID)] = f
    return feeds, per_tool


def replay(samples: Samples, limits: list, loads: dict, v_mm_s: np.ndarray, job: Job) -> dict:
    """Largest value/bound of every limit over the cutting samples at the executed speeds."""
    grid = PathGrid.from_samples(samples)
    cut = samples.kind != RAPID
    out: dict[str, float] = {}
    v = v_mm_s
    for lim in limits:
        if isinstance(lim, SpeedLoad):
            value = lim.alpha * v + lim.beta
            with np.errstate(divide="ignore", invalid="ignore"):  # 0/0 off the cut: masked below
                ratio = value / np.broadcast_to(np.asarray(lim.limit, float), value.shape)
            keep = cut & ~loads["unavoidable"].get(lim.name, np.zeros(len(v), bool))
            out[lim.name] = max(out.get(lim.name, 0.0), float(np.nanmax(np.where(keep, ratio, 0.0), initial=0)))
        elif isinstance(lim, (FeedLimit, AxisVelocity, ChipLoad)):
            for blk in lim.blocks(grid):
                if isinstance(blk, SpeedBounds):
                    with np.errstate(divide="ignore", invalid="ignore"):
                        r = np.where(cut & (blk.b_hi > 0), v / np.sqrt(blk.b_hi), 0.0)
                    out[blk.name] = max(out.get(blk.name, 0.0), float(np.nanmax(r, initial=0.0)))
    # motor current from the executed speed profile: a = v dv/ds along the path
    ds = np.gradient(samples.s_mm)
    a_path = v * np.gradient(v) / np.where(ds > 0, ds, 1.0)
    worst = 0.0
    for k, name in enumerate("xyz"):
        axis = job.machine.axes[name]
        vel = samples.tangent[:, k] * v
        acc = samples.tangent[:, k] * a_path + samples.curvature[:, k] * v**2
        cut_force = -(loads["force_a"][:, k] * v + loads["force_b"][:, k])
        d = axis.demand(vel, acc, cut_force_N=cut_force)
        keep = cut & ~loads["unavoidable"]["cutting_current"]
        worst = max(worst, float(np.max(np.abs(d.current_A[keep]), initial=0.0)) / axis.motor.current_limit_A)
    out["current"] = worst
    return out


def optimize(job: Job, *, progress: Progress | bool | None = None, options: ScheduleOptions | None = None) -> Result:
    """Run the whole post step on a job and return the new program and its summary. progress: a
    `millpost.progress` callback, or True/False/None (bars on stderr: always, never, on a terminal)."""
    t_start = time.perf_counter()
    report = resolve(progress)
    with stage(report, "read program"):
        program = read_program(job.program, job.reader_options())
        samples = program.toolpath.resample(float(job.limits["ds_mm"]))
    with stage(report, "stock"):
        stock = job.stock()
    eng = engagement.simulate(stock, dict(job.tools), samples, progress=report)
    with stage(report, "forces, schedule, emit"):
        result = schedule_program(job, program, samples, eng, options)
    result.summary["total_s"] = round(time.perf_counter() - t_start, 3)
    return result


def schedule_program(job: Job, program: Program, samples: Samples, eng,
                     options: ScheduleOptions | None = None) -> Result:
    """From the engagement on: limits, schedule, emitted text, cycle times and the replay check.
    (Split from `optimize` so that tests can give engagements of known geometry.)"""
    tp = program.toolpath
    ds = float(job.limits["ds_mm"])
    limits, loads = build_limits(job, samples, eng)
    t0 = time.perf_counter()
    sched = schedule_samples(samples, limits, options or ScheduleOptions())
    solver_s = time.perf_counter() - t0
    model = machine_controller(job)
    before = controller.execute(tp, model)
    base_feeds, base_per_tool = baseline_feeds(program, samples, limits)
    baseline = controller.execute(tp, model, base_feeds)
    failed = [s for _, _, s in sched.segments if not s.status.ok]
    if failed:
        plan = FeedPlan.programmed(program)
        emitted_tp = tp
        status = "fallback_programmed_feeds"
        message = "; ".join(f"{s.status.value}: {s.message}" for s in failed[:3])
    else:
        # F words never exceed the axis rates either (the controller would clamp them, but an emitted
        # feed must not ask for more than the machine can do); ramps and corners stay the controller's
        fragments = whole_compensated_moves(program, piecewise_feeds(
            samples, emission_limit(samples, limits, sched, ("axis_acceleration", "junction", "jerk"))))
        plan = _plan_from_fragments(program, fragments)
        emitted_tp = split_toolpath(tp, fragments)
        status, message = "solved", ""
    text = write_feeds(program, plan)
    after = controller.execute(emitted_tp, model)
    executed = np.interp(samples.s_mm, *_speed_profile(emitted_tp, after, ds))
    ratios = replay(samples, limits, loads, executed, job)
    binding = _binding_fractions(samples, sched)
    cut = samples.kind != RAPID
    summary = {
        "program": str(job.program), "output": str(job.output), "status": status, "message": message,
        "samples": int(len(samples)), "cutting_samples": int(cut.sum()),
        "cycle_time_before_s": round(before.time_s, 3), "cycle_time_after_s": round(after.time_s, 3),
        "cycle_time_baseline_s": round(baseline.time_s, 3),
        "improvement_vs_baseline": round(1.0 - after.time_s / baseline.time_s, 4) if baseline.time_s else None,
        "improvement_vs_programmed": round(1.0 - after.time_s / before.time_s, 4) if before.time_s else None,
        "baseline_feed_mm_min": base_per_tool,
        "solver_s": round(solver_s, 3),
        "removed_volume_mm3": round(float(np.nansum(eng.volume_mm3)), 3),
        "limits": {k: round(v, 4) for k, v in sorted(ratios.items())},
        "binding": binding,
        "chip_floor_unmet_samples": int(sum(int(np.sum(s.floor_unmet)) for _, _, s in sched.segments)),
        "unavoidable_samples": {k: int(np.sum(v & cut)) for k, v in loads["unavoidable"].items() if np.any(v & cut)},
        "notes": program.notes + _rpm_notes(job, program),
    }
    trace = {"s_mm": samples.s_mm, "x": samples.xyz_mm[:, 0], "y": samples.xyz_mm[:, 1], "z": samples.xyz_mm[:, 2],
             "line": samples.line, "tool": samples.tool, "ap_mm": eng.ap_mm, "ae_mm": eng.ae_mm,
             "area_mm2": eng.area_mm2, "feed_programmed_mm_min": samples.feed_mm_min,
             "feed_schedule_mm_min": sched.feed_mm_s * 60.0, "feed_executed_mm_min": executed * 60.0,
             "peak_force_N": np.where(cut, loads["peak_a"] * executed + loads["peak_b"], 0.0),
             "power_W": np.where(cut, loads["power_a"] * executed + loads["power_b"], 0.0)}
    # 1 where the cut exceeds that limit at any feed (held at the programmed feed and reported)
    trace.update({f"unavoidable_{k}": v.astype(np.int8) for k, v in sorted(loads["unavoidable"].items())})
    return Result(text, summary, samples, trace)


def _rpm_notes(job: Job, program: Program) -> list[str]:
    tp = program.toolpath
    on = (tp.rpm > 0) & (tp.kind != RAPID)
    out = []
    for rpm in np.unique(tp.rpm[on]):
        used = float(spindle_rpm(job, rpm))
        if used != rpm:
            line = int(tp.line[np.flatnonzero(on & (tp.rpm == rpm))[0]])
            out.append(f"{job.program}:{line}: S{rpm:g} is outside the spindle's range "
                       f"{job.machine.spindle.rpm_min:g}–{job.machine.spindle.rpm_max:g} rpm; "
                       f"the controller runs it at {used:g} rpm and the loads are computed there")
    return out


def _speed_profile(tp, execution, ds: float) -> tuple[np.ndarray, np.ndarray]:
    """(s, v) of an executed program on its own resampling, to interpolate at any arc length."""
    s2 = tp.resample(ds)
    return s2.s_mm, execution.speed_at_samples(s2)


def _binding_fractions(samples: Samples, sched) -> dict[str, float]:
    """Fraction of cutting time each physical effect binds (time weights ds / v)."""
    total = 0.0
    acc: dict[str, float] = {}
    for lo, hi, s in sched.segments:
        v = s.feed_mm_s
        dt = np.zeros(hi - lo)
        with np.errstate(divide="ignore", invalid="ignore"):  # trapezoid: interval time 2·Δs/(v₀+v₁)
            dt[1:] = np.where(v[1:] + v[:-1] > 0, 2 * np.diff(samples.s_mm[lo:hi]) / (v[1:] + v[:-1]), 0.0)
        total += float(dt.sum())
        for name, w in zip(s.binding.astype(str), dt):
            if name:
                effect = EFFECTS.get(name, name)
                acc[effect] = acc.get(effect, 0.0) + float(w)
    return {k: round(v / total, 4) for k, v in sorted(acc.items())} if total > 0 else {}
