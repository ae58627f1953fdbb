"""The machine: feed axes with their drives and motors, the spindle, the motion controller.

Axis drive model (PHYSICS.md §5.1–5.2). Transmission ρ = travel per motor radian: lead/(2π·gear) for a
ball screw, pulley radius/gear for a belt. With axis force F_axis (N) along the motion:

    F_axis = m a + F_c sgn v + c v + F_cut          (moving mass, Coulomb, viscous, cutting load)
    T = J_rotor a/ρ + F_axis ρ / η                  (N·m; η divides in both directions: conservative)
    i = T / K_t,   di/dt = (J_rotor j/ρ + (m j + c a + dF_cut/dt) ρ/η) / K_t
    V = R i + L di/dt + K_e ω,   ω = v/ρ,   di/dt_max = (V_bus − R i − K_e ω) / L

SI inside the formulas (m, rad, kg·m²); the API takes mm, mm/s, mm/s², N.
Spindle (§5.3): constant torque up to base_rpm, constant power above: T = P/ω_base, then P/ω.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .config import Table, is_number, load_description

DRIVES = ("ballscrew", "belt")
CONTROLLERS = ("grbl", "linuxcnc", "fanuc", "mach3", "generic")


@dataclass(frozen=True)
class Motor:
    """Motor electrical and mechanical constants (SI). ke defaults to kt (consistent SI DC/BLDC units)."""

    kt_Nm_per_A: float
    resistance_ohm: float
    inductance_H: float
    bus_voltage_V: float
    current_limit_A: float
    rotor_inertia_kgm2: float
    ke_V_s_per_rad: float


@dataclass(frozen=True)
class AxisDemand:
    """What a motion asks of an axis drive, per sample: torque N·m, current A, di/dt A/s, voltage V,
    motor speed rad/s, and whether current and voltage stay within the drive's limits."""

    torque_Nm: np.ndarray
    current_A: np.ndarray
    di_dt_A_s: np.ndarray
    voltage_V: np.ndarray
    omega_rad_s: np.ndarray
    within_current: np.ndarray
    within_voltage: np.ndarray


@dataclass(frozen=True)
class Axis:
    """One linear feed axis. Lengths mm, mass kg, forces N, speeds mm/min, accelerations mm/s²."""

    name: str
    moving_mass_kg: float
    drive: str
    lead_mm: float
    pulley_radius_mm: float
    gear_ratio: float
    efficiency: float
    motor: Motor
    friction_coulomb_N: float
    friction_viscous_N_s_per_mm: float
    stiffness_N_per_mm: float
    vmax_mm_min: float
    amax_mm_s2: float

    @property
    def vmax_mm_s(self) -> float:
        """The axis rate in mm/s (the machine file's vmax_mm_min)."""
        return self.vmax_mm_min / 60.0

    @property
    def rho_m_per_rad(self) -> float:
        """Travel per motor radian (m/rad)."""
        per_turn = self.lead_mm / (2 * math.pi) if self.drive == "ballscrew" else self.pulley_radius_mm
        return per_turn / self.gear_ratio / 1000.0

    def demand(self, velocity_mm_s, accel_mm_s2, *, cut_force_N=0.0, jerk_mm_s3=0.0,
               cut_force_rate_N_s=0.0) -> AxisDemand:
        """Torque, current, di/dt and voltage for a motion sample (arrays broadcast together).

        cut_force_N: cutting force along the axis opposing the motion (N, positive loads the motor when
        moving forward). jerk and cut-force rate enter di/dt only.
        """
        v, a = np.asarray(velocity_mm_s, float) / 1000.0, np.asarray(accel_mm_s2, float) / 1000.0
        j = np.asarray(jerk_mm_s3, float) / 1000.0
        rho, eta, m = self.rho_m_per_rad, self.efficiency, self.motor
        c_visc = self.friction_viscous_N_s_per_mm * 1000.0        # N·s/m
        f_axis = self.moving_mass_kg * a + self.friction_coulomb_N * np.sign(v) + c_visc * v + cut_force_N
        torque = m.rotor_inertia_kgm2 * a / rho + f_axis * rho / eta
        dforce = self.moving_mass_kg * j + c_visc * a + cut_force_rate_N_s
        dtorque = m.rotor_inertia_kgm2 * j / rho + dforce * rho / eta
        current = torque / m.kt_Nm_per_A
        di_dt = dtorque / m.kt_Nm_per_A
        omega = v / rho
        volts = m.resistance_ohm * current + m.inductance_H * di_dt + m.ke_V_s_per_rad * omega
        return AxisDemand(torque, current, di_dt, volts, omega,
                          np.abs(current) <= m.current_limit_A * (1 + 1e-12),
                          np.abs(volts) <= m.bus_voltage_V * (1 + 1e-12))

    def max_thrust_N(self, velocity_mm_s) -> np.ndarray:
        """Steady thrust available at a speed: min(K_t I_max, K_t (V − K_e ω)/R) η/ρ, less friction (N)."""
        m = self.motor
        v = np.abs(np.asarray(velocity_mm_s, float))
        omega = v / 1000.0 / self.rho_m_per_rad
        torque = np.minimum(m.kt_Nm_per_A * m.current_limit_A,
                            m.kt_Nm_per_A * (m.bus_voltage_V - m.ke_V_s_per_rad * omega) / m.resistance_ohm)
        friction = self.friction_coulomb_N + self.friction_viscous_N_s_per_mm * v
        return np.maximum(torque, 0.0) * self.efficiency / self.rho_m_per_rad - friction


@dataclass(frozen=True)
class Spindle:
    """Spindle speed range (rpm) and rated power (W); constant torque below base_rpm, constant power above.

    Optional, for predicting what a VFD reports (`millpost calibrate fit` measures them): the no-load
    power at speeds idle_rpm (bearings, windage, motor losses; interpolated, held flat outside), and the
    output current I = √(I₀² + (T/K_t)²) with the magnetising (no-load) current I₀ and the torque-producing
    part T/K_t in quadrature (field-oriented view of an induction motor; T the shaft torque, N·m).
    """

    rpm_min: float
    rpm_max: float
    power_W: float
    base_rpm: float
    idle_rpm: tuple[float, ...] = ()
    idle_power_W: tuple[float, ...] = ()
    kt_Nm_per_A: float | None = None
    idle_current_A: float = 0.0

    def idle_power_at_W(self, rpm) -> np.ndarray:
        """No-load spindle power (W) at a speed: 0 where not measured, and 0 when the spindle is off."""
        n = np.asarray(rpm, float)
        if not self.idle_rpm:
            return np.zeros_like(n)
        return np.where(n > 0, np.interp(n, self.idle_rpm, self.idle_power_W), 0.0)

    def current_A(self, torque_Nm) -> np.ndarray:
        """Output current (A) at a shaft torque (N·m); nan when the spindle's K_t is not given."""
        t = np.asarray(torque_Nm, float)
        if self.kt_Nm_per_A is None:
            return np.full_like(t, np.nan)
        return np.hypot(self.idle_current_A, t / self.kt_Nm_per_A)

    def torque_Nm(self, rpm) -> np.ndarray:
        """Available torque at a speed (N·m); 0 outside the speed range."""
        n = np.asarray(rpm, float)
        t = self.power_W / (2 * np.pi * np.maximum(n, self.base_rpm) / 60.0)
        return np.where((n >= self.rpm_min) & (n <= self.rpm_max), t, 0.0)

    def power_available_W(self, rpm) -> np.ndarray:
        return self.torque_Nm(rpm) * 2 * np.pi * np.asarray(rpm, float) / 60.0


@dataclass(frozen=True)
class Controller:
    """Motion controller: kind (which sets the planner model, `controller.Planner.of_kind`: grbl's for
    grbl, LinuxCNC's for the others, and only LinuxCNC's canon merges naive-CAM feeds), junction
    deviation (mm, grbl's cornering rule), block rate (blocks/s), corner blending tolerance (mm,
    LinuxCNC's G64 P; 0: none, the planner's own bound), and the time (s) the machine stands still for
    a tool change, a spindle start (to speed), coolant and any other command that waits for the motion
    to end (spindle stop or speed, tool length...)."""

    kind: str
    junction_deviation_mm: float
    block_rate_Hz: float
    blend_tolerance_mm: float = 0.0
    tool_change_s: float = 0.0
    spindle_start_s: float = 0.0
    coolant_s: float = 0.0
    command_s: float = 0.0


@dataclass(frozen=True)
class Machine:
    name: str
    description: str
    axes: dict[str, Axis]
    spindle: Spindle
    controller: Controller
    source: str
    # the machine's compliance between tool and table (mm/N, 3×3 in machine XYZ, symmetric positive
    # definite: cross-coupling a robot arm or a gantry has), from the file's compliance_mm_per_N; None:
    # the axes in series, diagonal 1/k per axis
    compliance_mm_per_N: tuple[tuple[float, float, float], ...] | None = None

    @classmethod
    def load(cls, name_or_path: str | Path) -> "Machine":
        data, file = load_description("machines", name_or_path)
        return cls.from_dict(data, file=file)

    @classmethod
    def from_dict(cls, data: dict, *, file: str | None = None) -> "Machine":
        t = Table(data, "", file)
        name, description, source = t.string("name"), t.string("description", ""), t.string("source")
        axes_t = t.table("axes")
        axes = {}
        for key in ("x", "y", "z"):
            axes[key] = _axis(axes_t.table(key), key)
        axes_t.done()
        s = t.table("spindle")
        rpm_min = s.number("rpm_min", ge=0)
        rpm_max = s.number("rpm_max", gt=rpm_min)
        idle_rpm = s.numbers("idle_rpm", (), ge=0)
        idle_power = s.numbers("idle_power_W", (), ge=0, length=len(idle_rpm) if idle_rpm else None)
        if len(idle_power) != len(idle_rpm) or any(np.diff(idle_rpm) <= 0):
            raise s.fail("idle_rpm", list(idle_rpm), "needs rising speeds, one idle_power_W for each")
        spindle = Spindle(rpm_min, rpm_max, s.number("power_W", gt=0),
                          s.number("base_rpm", rpm_max, gt=0, le=rpm_max), idle_rpm, idle_power,
                          s.number("kt_Nm_per_A", None, gt=0), s.number("idle_current_A", 0.0, ge=0))
        s.done()
        c = t.table("controller")
        controller = Controller(c.string("kind", "generic", choices=CONTROLLERS),
                                c.number("junction_deviation_mm", 0.01, gt=0),
                                c.number("block_rate_Hz", 1000.0, gt=0),
                                c.number("blend_tolerance_mm", 0.0, ge=0),
                                c.number("tool_change_s", 0.0, ge=0),
                                c.number("spindle_start_s", 0.0, ge=0),
                                c.number("coolant_s", 0.0, ge=0),
                                c.number("command_s", 0.0, ge=0))
        c.done()
        compliance = _compliance(t)
        t.done()
        return cls(name, description, axes, spindle, controller, source, compliance)

    @property
    def feed_max_mm_min(self) -> float:
        """Fastest feed along any horizontal direction both X and Y can follow (mm/min)."""
        return min(self.axes["x"].vmax_mm_min, self.axes["y"].vmax_mm_min)

    @property
    def feed_cap_mm_min(self) -> float:
        """Highest F word millpost writes (mm/min): the feed with every axis at its maximum rate,
        sqrt(Σ vmax_k²). The controller clamps each axis to its own rate (as it does a programmed F
        above it), so a move runs at min_k vmax_k/|t_k|, never faster than this in any direction."""
        return math.sqrt(sum(self.axes[a].vmax_mm_min ** 2 for a in "xyz"))

    @property
    def feed_cap_mm_s(self) -> float:
        """`feed_cap_mm_min` in mm/s."""
        return self.feed_cap_mm_min / 60.0

    @property
    def compliance_matrix(self) -> np.ndarray:
        """(3, 3) compliance C (mm/N): the file's matrix, else diag(1/k_x, 1/k_y, 1/k_z)."""
        if self.compliance_mm_per_N is not None:
            return np.array(self.compliance_mm_per_N, float)
        return np.diag([1.0 / self.axes[a].stiffness_N_per_mm for a in "xyz"])

    @property
    def lateral_compliance_mm_per_N(self) -> float:
        """The largest deflection per newton of a force in the XY plane (mm/N): the largest eigenvalue of
        the compliance's XY block (1/min(k_x, k_y) for axes in series); a bound on |δ_xy| / |F_xy| in any
        direction."""
        return float(np.linalg.eigvalsh(self.compliance_matrix[:2, :2]).max())

    def deflection_mm(self, force_N) -> np.ndarray:
        """Machine deflection δ = C·F (mm) under a machine-XYZ force on the tool F (N), (…, 3): the tool
        is displaced along the force on it (the axes, or the file's compliance matrix, in series with
        the tool)."""
        return np.asarray(force_N, float) @ self.compliance_matrix.T


def _compliance(t: Table) -> tuple[tuple[float, float, float], ...] | None:
    """The file's optional compliance_mm_per_N: a 3×3 matrix (mm/N, machine XYZ), symmetric (to 1e-9
    relative) and positive definite (a stiffness matrix's inverse); None when absent."""
    raw = t.raw("compliance_mm_per_N", None)
    if raw is None:
        return None
    rule = "a 3×3 matrix [[..],[..],[..]] of numbers (mm/N), symmetric and positive definite"
    if not (isinstance(raw, list) and len(raw) == 3 and all(isinstance(r, list) and len(r) == 3 for r in raw)
            and all(is_number(v) for r in raw for v in r)):
        raise t.fail("compliance_mm_per_N", raw, rule)
    c = np.array(raw, float)
    if not np.allclose(c, c.T, rtol=1e-9, atol=0.0):
        raise t.fail("compliance_mm_per_N", raw, rule + ": it is not symmetric")
    if np.linalg.eigvalsh(c).min() <= 0:
        raise t.fail("compliance_mm_per_N", raw, rule + ": it has an eigenvalue <= 0")
    return tuple(tuple(float(v) for v in row) for row in c)


def _axis(t: Table, name: str) -> Axis:
    drive = t.string("drive", choices=DRIVES)
    if drive == "ballscrew":
        lead, radius = t.number("lead_mm", gt=0), 0.0
    else:
        lead, radius = 0.0, t.number("pulley_radius_mm", gt=0)
    kt = t.number("kt_Nm_per_A", gt=0)
    motor = Motor(kt, t.number("resistance_ohm", gt=0), t.number("inductance_H", gt=0),
                  t.number("bus_voltage_V", gt=0), t.number("current_limit_A", gt=0),
                  t.number("rotor_inertia_kgm2", ge=0), t.number("ke_V_s_per_rad", kt, gt=0))
    axis = Axis(name=name, moving_mass_kg=t.number("moving_mass_kg", gt=0), drive=drive, lead_mm=lead,
                pulley_radius_mm=radius, gear_ratio=t.number("gear_ratio", 1.0, gt=0),
                efficiency=t.number("efficiency", gt=0, le=1), motor=motor,
                friction_coulomb_N=t.number("friction_coulomb_N", 0.0, ge=0),
                friction_viscous_N_s_per_mm=t.number("friction_viscous_N_s_per_mm", 0.0, ge=0),
                stiffness_N_per_mm=t.number("stiffness_N_per_mm", gt=0),
                vmax_mm_min=t.number("vmax_mm_min", gt=0), amax_mm_s2=t.number("amax_mm_s2", gt=0))
    t.done()
    return axis
