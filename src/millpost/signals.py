"""The forward model: what the sensors of a machine running a program should read.

Program + job + the speed the controller executes → per path sample, and on the controller's time base:

- force on the tool F_tool (N, machine XYZ): the force model's mean over a tooth period at the feed per
  tooth f_z = v / (flutes · n) of the centre (`fz_mm`) times the edge's ratio on arcs
  (`Engagement.edge_ratio`: the flank's edge runs faster than the centre on an inside arc), rotated from the feed frame to machine axes, plus where the tool moves
  down the thrust and torque of its end edges (`millpost.forces.endcut`); the force on the workpiece
  (what a table dynamometer reads) is −F_tool;
- spindle: cutting torque T_c and power P_c = T_c ω; the spindle's total power P_c + P_idle(n) and its
  output current √(I₀² + (T/K_t)²), T = T_c + P_idle/ω, from the machine's spindle description;
- each axis's motor current from the drive model (`Axis.demand`): inertia (moving mass, reflected rotor)
  + Coulomb and viscous friction + the cutting force along the axis, at the axis velocity and
  acceleration of `axis_motion` (t·v and t·a + κ·v² along the path). The feed axes move the
  tool: the drive pushes against F_tool, so the cutting share is −F_tool along the axis;
- deflection: the tool's lateral deflection at the load point (two-segment cantilever, `ToolBeam`) under
  the in-plane mean force, and the machine's per axis F_tool / k_axis.

Time: the controller model (`millpost.controller`) gives the instant the tool passes each sample; dwells
(G4) are added where they run. Everything else the controller does (tool changes, spindle ramp-up) is
not in the time base: `millpost.measure.align` finds the offset of a real log.

Use `simulate(job)` for a whole job, or `predict(job, samples, eng, speed)` when the samples, their
engagement and the executed speed are already at hand (optimize's replay check).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from enum import Enum

import numpy as np

from . import controller, engagement
from .engagement import Engagement
from .errors import MillpostError
from .forces import LinearLoads
from .forces.endcut import EndCut
from .gcode import read_program
from .gcode.interpret import Program
from .job import Job
from .progress import Progress, reporting, resolve
from .safety import check_spindle, spindle_off_message
from .toolpath import RAPID, Samples
from .tools.beam import ToolBeam


class Load(Enum):
    """The signal a load limit bounds (`millpost.limits.Limit.load`), and how the optimize trace and the job
    report show it: (the trace column of its value, of its bound (None: the column is a ratio to it), the
    report's label); a load the report does not plot has no columns. DEFLECTION: the tool's and the
    machine's lateral deflection under the peak force; CHIP: the thickest chip per tooth; DRIVE_CURRENT: the
    drives' current (the trace: the largest axis motor current over its drive's limit)."""

    PEAK_FORCE = ("peak_force_N", "peak_force_limit_N", "cutting force")
    POWER = ("power_W", "power_limit_W", "power")
    DEFLECTION = ("deflection_mm", "deflection_limit_mm", "deflection")
    CHIP = ("chip_mm", "chip_limit_mm", "chip load")
    DRIVE_CURRENT = ("current_ratio", None, "drive current")
    TORQUE = (None, None, "torque")
    THRUST = (None, None, "thrust")

    @property
    def column(self) -> str | None:
        return self.value[0]

    @property
    def bound_column(self) -> str | None:
        return self.value[1]

    @property
    def label(self) -> str:
        return self.value[2]

    @classmethod
    def plotted(cls) -> list["Load"]:
        """The loads the trace holds, in the report's order."""
        return [load for load in cls if load.column is not None]


@dataclass
class Signals:
    """Predicted signals per path sample (N samples). Units in the names; forces are means over a tooth
    period. peak_force_xy_N is nan unless asked for (`peaks=True`: a time-domain run per sample)."""

    t_s: np.ndarray               # (N,) time at which the tool passes the sample
    s_mm: np.ndarray              # (N,) arc length
    xyz_mm: np.ndarray            # (N, 3) tool tip, program frame
    line: np.ndarray              # (N,) source line
    move: np.ndarray              # (N,) toolpath move
    tool: np.ndarray              # (N,) tool number
    kind: np.ndarray              # (N,) RAPID/FEED/ARC_CW/ARC_CCW
    speed_mm_s: np.ndarray        # (N,) executed path speed
    rpm: np.ndarray               # (N,) spindle speed (0: off)
    fz_mm: np.ndarray             # (N,) feed per tooth
    ap_mm: np.ndarray             # (N,) axial depth of cut (0: not cutting)
    ae_mm: np.ndarray             # (N,) radial width of cut
    force_tool_N: np.ndarray      # (N, 3) on the tool, machine XYZ
    peak_force_xy_N: np.ndarray   # (N,) largest in-plane |F| over a revolution
    torque_Nm: np.ndarray         # (N,) cutting torque
    cutting_power_W: np.ndarray   # (N,) cutting power T_c ω
    spindle_power_W: np.ndarray   # (N,) cutting + no-load power
    spindle_current_A: np.ndarray  # (N,) VFD output current (nan without the spindle's K_t)
    axis_velocity_mm_s: np.ndarray  # (N, 3)
    axis_accel_mm_s2: np.ndarray    # (N, 3)
    axis_current_A: np.ndarray      # (N, 3) motor current of X, Y, Z
    tool_deflection_mm: np.ndarray     # (N,) lateral, at the load point
    machine_deflection_mm: np.ndarray  # (N, 3): the machine's compliance times the force on the tool
    engagement: Engagement | None = None  # the engagement the loads came from (for fits and discover)

    def __len__(self) -> int:
        return len(self.t_s)

    @property
    def force_workpiece_N(self) -> np.ndarray:
        """(N, 3) force on the workpiece (what a table dynamometer reads): −F_tool."""
        return -self.force_tool_N

    def log_columns(self) -> dict[str, np.ndarray]:
        """The predicted signals under the column names of the measurement log format
        (`millpost.measure.log`): t_s, positions, line, spindle, workpiece force, axis currents."""
        fw = self.force_workpiece_N
        return {"t_s": self.t_s, "x_mm": self.xyz_mm[:, 0], "y_mm": self.xyz_mm[:, 1], "z_mm": self.xyz_mm[:, 2],
                "line": self.line.astype(float), "spindle_rpm": self.rpm, "fx_N": fw[:, 0], "fy_N": fw[:, 1],
                "fz_N": fw[:, 2], "spindle_power_W": self.spindle_power_W,
                "spindle_current_A": self.spindle_current_A, "ix_A": self.axis_current_A[:, 0],
                "iy_A": self.axis_current_A[:, 1], "iz_A": self.axis_current_A[:, 2]}

    def select(self, index) -> "Signals":
        """The samples at `index` (slice, mask or index array)."""
        def pick(value):
            return None if value is None else value.select(index) if isinstance(value, Engagement) else value[index]
        return Signals(**{f.name: pick(getattr(self, f.name)) for f in fields(self)})

    def sample_at(self, t_s) -> np.ndarray:
        """Index of the sample the tool has last passed at each time (s; clipped to the program)."""
        return np.clip(np.searchsorted(self.t_s, np.asarray(t_s, float), side="right") - 1, 0, len(self) - 1)


def running_rpm(job: Job, programmed_rpm: np.ndarray) -> np.ndarray:
    """The speed the spindle turns at (rpm): the programmed S clamped to the machine's range, 0 when off."""
    sp = job.machine.spindle
    r = np.asarray(programmed_rpm, float)
    return np.where(r > 0, np.clip(r, sp.rpm_min, sp.rpm_max), 0.0)


def controller_model(job: Job) -> controller.ControllerModel:
    """The job machine's own planner (`ControllerModel.from_machine`: grbl's or LinuxCNC's, its axis
    rates and accelerations, junction deviation or blend tolerance, block rate, command times): the
    one model that times programs and decides corner speeds for optimize, replay and the signals."""
    return controller.ControllerModel.from_machine(job.machine)


def time_base(program: Program, samples: Samples, execution: controller.Execution) -> np.ndarray:
    """Time (s) at each sample: the controller's motion time plus the dwells that ran before it."""
    t = execution.time_at_samples(samples)
    dwells = sorted((e.move, float(e.value)) for e in program.events if e.kind == "dwell" and float(e.value) > 0)
    if not dwells:
        return t
    at, secs = np.array(dwells).T
    before = np.concatenate([[0.0], np.cumsum(secs)])   # dwell time run before move m: those with move ≤ m
    return t + before[np.searchsorted(at, samples.move, side="right")]


def step_times_s(s_mm: np.ndarray, speed_mm_s: np.ndarray) -> np.ndarray:
    """Time (s) of the step ending at each sample (0 for the first) at path speeds v (mm/s) at the
    samples: Δs·2/(v₀ + v₁), exact when the speed changes at constant acceleration; 0 where both ends
    stand still."""
    v = np.asarray(speed_mm_s, float)
    dt = np.zeros(len(v))
    with np.errstate(divide="ignore", invalid="ignore"):
        dt[1:] = np.where(v[1:] + v[:-1] > 0, 2 * np.diff(s_mm) / (v[1:] + v[:-1]), 0.0)
    return dt


def axis_motion(samples: Samples, speed_mm_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(velocity mm/s, acceleration mm/s²), each (N, 3), of the axes at path speed v (mm/s) per sample:
    t·v and t·a + κ·v², t the path tangent, κ the curvature vector and a = v dv/ds = ½ d(v²)/ds (exact
    on a constant-acceleration ramp, where v² is linear in s)."""
    v = np.asarray(speed_mm_s, float)
    a_path = 0.5 * np.gradient(v**2, samples.s_mm) if len(v) > 1 else np.zeros(len(v))
    return samples.tangent * v[:, None], samples.tangent * a_path[:, None] + samples.curvature * (v**2)[:, None]


def predict(job: Job, samples: Samples, eng: Engagement, speed_mm_s: np.ndarray, *, time_s: np.ndarray | None = None,
            peaks: bool = False, loads: LinearLoads | None = None) -> Signals:
    """Signals per sample at the executed path speed (mm/s, per sample). time_s: the time base (default:
    the cumulative `step_times_s`, for callers without a controller execution).
    peaks: also the peak in-plane force per revolution (a time-domain run; slower).
    loads: the cutting loads as affine functions a·v + b of the path speed v (mm/s) per sample
    (`millpost.limits.JobLimits.loads`, the schedule's linearisation, exact for the mechanistic model and an upper bound for the concave Kienzle
    and end-cutting laws); without them the force model and the end-cutting model at the feed per tooth."""
    n = len(samples)
    v = np.asarray(speed_mm_s, float)
    if v.shape != (n,):
        raise MillpostError(f"predict needs one speed per sample ({n}), got shape {v.shape}")
    m = job.machine
    rpm = running_rpm(job, samples.rpm)
    engaged = eng.ap_mm > 1e-9
    if np.any(engaged & (rpm <= 0)):
        k = int(np.flatnonzero(engaged & (rpm <= 0))[0])
        raise MillpostError(spindle_off_message(str(job.program), int(samples.line[k])))
    model = job.material.force_model(job.settings.model)
    end_model = EndCut.from_material(job.material)
    force = np.zeros((n, 3))
    torque, peak = np.zeros(n), np.full(n, np.nan)
    fz = np.zeros(n)
    tool_defl = np.zeros(n)
    cutting = (samples.kind != RAPID) & engaged
    if loads is not None:
        force = loads.force_at(v)
        torque, peak = loads.torque_a * v + loads.torque_b, loads.peak_a * v + loads.peak_b
    for number in np.unique(samples.tool[cutting]):
        tool = job.tools.get(int(number))
        if tool is None:
            line = int(samples.line[np.flatnonzero(cutting & (samples.tool == number))[0]])
            raise MillpostError(f"{job.program}:{line}: tool T{number} cuts but the job has no [tools.{number}]")
        idx = np.flatnonzero(cutting & (samples.tool == number))
        fz[idx] = v[idx] * 60.0 / (tool.flutes * rpm[idx])
        if loads is None:
            eng_t = eng.select(idx)
            got = model.predict(eng_t, fz[idx] * eng_t.edge, rpm[idx], tool, peaks=peaks)  # the edge's feed
            force[idx], torque[idx], peak[idx] = got.force_N, got.torque_Nm, got.peak_force_xy_N
            if end_model is not None:  # the end's thrust (+Z on the tool) and torque where it moves down
                thrust, end_torque = end_model.predict(eng_t, fz[idx], tool)
                force[idx, 2] += thrust
                torque[idx] += end_torque
        beam = ToolBeam.of(tool, safety_factor=job.settings.tool_safety_factor)
        tool_defl[idx] = beam.compliance_mm_per_N(eng.ap_mm[idx]) * np.hypot(force[idx, 0], force[idx, 1])
    omega = 2 * np.pi * rpm / 60.0
    idle = m.spindle.idle_power_at_W(rpm)
    with np.errstate(divide="ignore", invalid="ignore"):
        shaft_torque = torque + np.where(omega > 0, idle / np.where(omega > 0, omega, 1.0), 0.0)
    spindle_current = np.where(rpm > 0, m.spindle.current_A(shaft_torque), 0.0)
    vel, acc = axis_motion(samples, v)
    current = np.zeros((n, 3))
    for k, name in enumerate("xyz"):
        current[:, k] = m.axes[name].demand(vel[:, k], acc[:, k], cut_force_N=-force[:, k]).current_A
    if time_s is None:
        time_s = np.cumsum(step_times_s(samples.s_mm, v))
    return Signals(
        t_s=np.asarray(time_s, float), s_mm=samples.s_mm, xyz_mm=samples.xyz_mm, line=samples.line,
        move=samples.move, tool=samples.tool, kind=samples.kind, speed_mm_s=v, rpm=rpm, fz_mm=fz,
        ap_mm=np.where(engaged, eng.ap_mm, 0.0), ae_mm=np.where(engaged, eng.ae_mm, 0.0), force_tool_N=force,
        peak_force_xy_N=peak, torque_Nm=torque, cutting_power_W=torque * omega, spindle_power_W=torque * omega + idle,
        spindle_current_A=spindle_current, axis_velocity_mm_s=vel, axis_accel_mm_s2=acc, axis_current_A=current,
        tool_deflection_mm=tool_defl, machine_deflection_mm=m.deflection_mm(force), engagement=eng)


def simulate(job: Job, feed_mm_s: np.ndarray | None = None, *, program: Program | None = None,
             peaks: bool = False, progress: Progress | bool | None = None) -> Signals:
    """The whole job: read the program, resample at the job's ds_mm, step the tools through the stock,
    run the controller model (feed_mm_s overrides the programmed feed per move, mm/s) and predict."""
    program = program or read_program(job.program, job.reader_options())
    samples = program.toolpath.resample(job.settings.ds_mm)
    if len(samples) == 0:
        raise MillpostError(f"{job.program}: the program has no motion")
    report = resolve(progress)
    with reporting(report):  # the controller kernel's first compile too
        eng = engagement.simulate(job.stock(), dict(job.tools), samples, progress=report)
        samples = check_spindle(program, samples, eng, job.spindle_rpm, job.allow, [])  # a hand-switched spindle
        execution = controller.execute(program.toolpath, controller_model(job), feed_mm_s)
    return predict(job, samples, eng, execution.speed_at_samples(samples),
                   time_s=time_base(program, samples, execution), peaks=peaks)
