"""Machine drives against PHYSICS.md §5.5 oracles and hand calculations; machine files validated."""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from millpost.config import builtin_names, resolve
from millpost.errors import ConfigError
from millpost.machine import Axis, Machine, Motor


def axis(drive="ballscrew", *, lead=5.0, radius=0.0, eta=0.9, mass=50.0, kt=0.5, R=1.0, L=2.5e-3, ke=0.05,
         V=24.0, imax=5.0, J=0.0, fc=0.0, cv=0.0) -> Axis:
    return Axis("x", mass, drive, lead, radius, 1.0, eta, Motor(kt, R, L, V, imax, J, ke), fc, cv, 1000.0,
                5000.0, 1000.0)


def test_ball_screw_oracle_E1():
    ax = axis()
    rho = 0.005 / (2 * math.pi)  # m/rad
    # at rest, an axial force F needs the motor torque F ρ / η
    assert ax.demand(0.0, 0.0, cut_force_N=500.0).torque_Nm == pytest.approx(0.44210, abs=1e-5)
    assert ax.demand(0.0, 0.0, cut_force_N=500.0).current_A == pytest.approx(0.8842, abs=1e-4)
    # 5 A pushes K_t i η / ρ = 2827.4 N
    assert ax.demand(0.0, 0.0, cut_force_N=2827.4).current_A == pytest.approx(5.0, rel=4e-5)
    # the moving mass seen at the motor shaft, m ρ²: the torque per motor acceleration (1 m/s² = 1/ρ rad/s²)
    # times η
    assert ax.demand(0.0, 1000.0).torque_Nm * 0.9 * rho == pytest.approx(3.1663e-5, rel=1e-4)


def test_belt_oracle():
    ax = axis("belt", radius=40 / math.pi / 2, eta=1.0, mass=1.0)
    rho = 40 / math.pi / 2 / 1000  # m/rad
    assert ax.demand(0.0, 0.0, cut_force_N=100.0).torque_Nm == pytest.approx(0.6365, rel=1e-3)
    assert ax.demand(0.0, 1000.0).torque_Nm * rho == pytest.approx(4.0513e-5, rel=1e-3)


def test_current_rise_limit_oracle():
    """The fastest current rise the bus allows, (V_bus − R i − K_e ω) / L, takes the drive's voltage to the
    bus exactly: at 2 A and ω = 0, 100, 200, 300 rad/s, 8800, 6800, 4800, 2800 A/s."""
    ax = axis(R=1.0, L=2.5e-3, ke=0.05, V=24.0)
    rho = 0.005 / (2 * math.pi)
    per_amp = 0.5 * 0.9 / rho  # N of axial force per A (K_t η / ρ)
    for omega, rise in zip([0, 100, 200, 300], [8800, 6800, 4800, 2800]):
        d = ax.demand(omega * rho * 1000, 0.0, cut_force_N=2.0 * per_amp, cut_force_rate_N_s=rise * per_amp)
        assert d.current_A == pytest.approx(2.0, rel=1e-12) and d.di_dt_A_s == pytest.approx(rise, rel=1e-12)
        assert d.voltage_V == pytest.approx(24.0, rel=1e-12)
        assert bool(d.within_voltage)
        faster = ax.demand(omega * rho * 1000, 0.0, cut_force_N=2.0 * per_amp,
                           cut_force_rate_N_s=(rise + 1.0) * per_amp)
        assert not bool(faster.within_voltage)
    # speed where the back-EMF eats the bus at 2 A: (24 − 2)/0.05 = 440 rad/s, where no rise is left
    assert ax.demand(440.0 * rho * 1000, 0.0, cut_force_N=2.0 * per_amp).voltage_V == pytest.approx(24.0, rel=1e-12)


def test_drive_demand_matches_hand_calculation():
    # ball screw 5 mm, η 0.9, 20 kg, K_t 0.5, R 1 Ω, L 2.5 mH, K_e 0.05, rotor 1e-4 kg·m², Coulomb 30 N,
    # viscous 0.02 N·s/mm; sample at v 50 mm/s, a 2000 mm/s², jerk 1e5 mm/s³, cut 300 N rising 1000 N/s.
    ax = axis(mass=20.0, J=1e-4, fc=30.0, cv=0.02)
    d = ax.demand(50.0, 2000.0, cut_force_N=300.0, jerk_mm_s3=1e5, cut_force_rate_N_s=1000.0)
    rho = 0.005 / (2 * math.pi)                       # m/rad
    f_axis = 20 * 2.0 + 30 + 20.0 * 0.05 + 300        # m a + F_c + c v + F_cut = 371 N
    torque = 1e-4 * 2.0 / rho + f_axis * rho / 0.9
    assert d.torque_Nm == pytest.approx(torque, rel=1e-12)
    assert d.current_A == pytest.approx(torque / 0.5, rel=1e-12)
    dtorque = 1e-4 * 100.0 / rho + (20 * 100.0 + 20.0 * 2.0 + 1000.0) * rho / 0.9
    assert d.di_dt_A_s == pytest.approx(dtorque / 0.5, rel=1e-12)
    omega = 0.05 / rho
    assert d.omega_rad_s == pytest.approx(omega, rel=1e-12)
    assert d.voltage_V == pytest.approx(1.0 * torque / 0.5 + 2.5e-3 * dtorque / 0.5 + 0.05 * omega, rel=1e-12)
    assert bool(d.within_current) == (torque / 0.5 <= 5.0)


def test_trapezoid_profile_currents():
    # accelerate at 1000 mm/s², cruise, brake: current steps follow m a ρ/η/K_t plus friction
    ax = axis(mass=10.0, fc=0.0, cv=0.0, J=0.0)
    v = np.array([10.0, 50.0, 50.0, 10.0])
    a = np.array([1000.0, 0.0, 0.0, -1000.0])
    d = ax.demand(v, a)
    rho = 0.005 / (2 * math.pi)
    np.testing.assert_allclose(d.current_A, [10 * 1.0 * rho / 0.9 / 0.5, 0, 0, -10 * 1.0 * rho / 0.9 / 0.5])


def test_max_thrust_voltage_limited_at_speed():
    ax = axis(kt=0.5, R=1.0, ke=0.5, V=24.0, imax=5.0)
    rho = 0.005 / (2 * math.pi)
    assert ax.max_thrust_N(0.0) == pytest.approx(0.5 * 5 * 0.9 / rho)            # current limited
    v_mm_s = 40 * rho * 1000                                                    # motor at 40 rad/s
    assert ax.max_thrust_N(v_mm_s) == pytest.approx(0.5 * (24 - 0.5 * 40) / 1.0 * 0.9 / rho)


def test_spindle_curves():
    router = Machine.load("hobby-router").spindle
    # 2.2 kW at 400 Hz (24000 rpm), constant torque: 2200 / (2π·400) = 0.8754 N·m (PHYSICS.md §5.3)
    assert router.torque_Nm(24000) == pytest.approx(0.8754, abs=1e-4)
    assert router.torque_Nm(12000) == pytest.approx(0.8754, abs=1e-4)
    assert router.power_available_W(12000) == pytest.approx(1100, rel=1e-9)
    assert router.torque_Nm(30000) == 0
    vmc = Machine.load("vmc-small").spindle
    assert vmc.power_available_W(6000) == pytest.approx(5500)                 # constant power above base
    assert vmc.torque_Nm(1000) == pytest.approx(5500 / (2 * math.pi * 1500 / 60))


def test_builtin_machines_load():
    assert builtin_names("machines") == ["benchtop-belt", "hobby-router", "vmc-small"]
    belt = Machine.load("benchtop-belt")
    assert belt.axes["x"].drive == "belt"
    assert belt.axes["x"].motor.inductance_H == pytest.approx(3e-3)             # "3 mH" converted
    assert belt.axes["x"].motor.rotor_inertia_kgm2 == pytest.approx(6.8e-6)     # "68 g*cm^2"
    assert belt.feed_max_mm_min == 6000
    np.testing.assert_allclose(belt.deflection_mm([400.0, 0.0, 0.0]), [1.0, 0.0, 0.0])


def _data() -> dict:
    with open(resolve("machines", "hobby-router"), "rb") as fh:
        return tomllib.load(fh)


@pytest.mark.parametrize("edit, field, rule", [
    (lambda d: d["axes"]["x"].update(moving_mass_kg=-3), "axes.x.moving_mass_kg", "must be > 0"),
    (lambda d: d["axes"]["x"].update(moving_mass_kg="5 mm"), "axes.x.moving_mass_kg", "not a mass unit"),
    (lambda d: d["axes"]["x"].update(drive="rack"), "axes.x.drive", "must be one of"),
    (lambda d: d["axes"]["y"].pop("lead_mm"), "axes.y.lead_mm", "is required"),
    (lambda d: d["axes"]["z"].update(lead_in=0.2), "axes.z.lead_in", "did you mean 'lead_mm'"),
    (lambda d: d["axes"]["x"].update(efficiency=1.2), "axes.x.efficiency", "must be <= 1"),
    (lambda d: d["spindle"].update(base_rpm=30000), "spindle.base_rpm", "must be <="),
    (lambda d: d.pop("axes"), "axes", "is required"),
    (lambda d: d["controller"].update(kind="haas"), "controller.kind", "must be one of"),
])
def test_bad_machine_files(edit, field, rule):
    data = copy.deepcopy(_data())
    edit(data)
    with pytest.raises(ConfigError) as err:
        Machine.from_dict(data, file="m.toml")
    assert err.value.field == field and rule in err.value.rule, str(err.value)


def test_unknown_machine():
    with pytest.raises(ConfigError, match="unknown machine.*benchtop-belt"):
        Machine.load("cnc-9000")


def test_lateral_compliance_bounds_the_in_plane_deflection():
    """The largest in-plane deflection per newton (optimize's deflection bound, calc's machine deflection)
    is the largest eigenvalue of the compliance's XY block: 1/min(k_x, k_y) for axes in series; with the
    thin-wall sample's coupled matrix [[0.01, 0.003], [0.003, 0.01]] mm/N, 0.013 mm/N along the diagonal,
    and no force direction in the plane deflects it more."""
    m = Machine.load(Path(__file__).resolve().parents[1] / "sample_jobs" / "thin_wall_finish" / "machine.toml")
    c = m.compliance_matrix
    assert m.lateral_compliance_mm_per_N == pytest.approx(c[0, 0] + abs(c[0, 1]), rel=1e-12)
    angles = np.linspace(0.0, np.pi, 721)
    unit = np.column_stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)])
    reach = np.linalg.norm(m.deflection_mm(unit)[:, :2], axis=1)
    assert reach.max() == pytest.approx(m.lateral_compliance_mm_per_N, rel=1e-4)
    assert reach.max() <= m.lateral_compliance_mm_per_N * (1 + 1e-12)
    vmc = Machine.load("vmc-small")
    assert vmc.lateral_compliance_mm_per_N == pytest.approx(
        1.0 / min(vmc.axes["x"].stiffness_N_per_mm, vmc.axes["y"].stiffness_N_per_mm), rel=1e-12)
