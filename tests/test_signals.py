"""The forward model (millpost.signals) against closed forms: Altintas' slot averages rotated to machine
axes, the drive's current balance, the spindle's power, and the controller's time base."""

from __future__ import annotations

import math

import numpy as np
import pytest

from millpost import controller, signals
from millpost.gcode import read_text
from millpost.job import load_job

COEF = dict(Ktc=631.0, Krc=99.0, Kac=273.0, Kte=13.0, Kre=10.0, Kae=2.8)  # al6061.toml's set


def make_job(tmp_path, program: str, *, machine: str = "vmc-small", extra_machine: str = ""):
    (tmp_path / "p.nc").write_text(program)
    machine_ref = f'"{machine}"'
    if extra_machine:
        from millpost.config import resolve
        text = resolve("machines", machine).read_text().replace("[spindle]", "[spindle]\n" + extra_machine, 1)
        (tmp_path / "m.toml").write_text(text)
        machine_ref = '"m.toml"'
    (tmp_path / "job.toml").write_text(f"""program = "p.nc"
material = "al6061"
machine = {machine_ref}
[stock]
box = [[0, 0, -10], [40, 40, 0]]
cell_mm = 0.05
[tools.1]
diameter_mm = 6
flutes = 3
helix_deg = 35
flute_length_mm = 16
stickout_mm = 24
[limits]
ds_mm = 0.2
""")
    return load_job(tmp_path / "job.toml")


SLOT_Y = """G21 G90 G94 G17
T1 M6
S8000 M3
G0 X20 Y-5 Z5
G1 Z-2 F300
G1 Y45 F600
G0 Z5
M5
M30
"""


def slot_means(ap, c, flutes=3, k=COEF):
    """Altintas' slot averages (PHYSICS.md §1.3), feed frame, force on the tool."""
    fx = -flutes * ap * k["Krc"] * c / 4 - flutes * ap * k["Kre"] / math.pi
    fy = flutes * ap * k["Ktc"] * c / 4 + flutes * ap * k["Kte"] / math.pi
    fz = flutes * ap * k["Kac"] * c / math.pi + flutes * ap * k["Kae"] / 2
    return fx, fy, fz


def test_slot_along_y_matches_closed_form_in_machine_axes(tmp_path):
    job = make_job(tmp_path, SLOT_Y, extra_machine="idle_rpm = [3000, 12000]\nidle_power_W = [60, 200]\n"
                                                   "kt_Nm_per_A = 0.5\nidle_current_A = 1.5\n")
    sig = signals.simulate(job, peaks=True)
    steady = (sig.xyz_mm[:, 1] > 15) & (sig.xyz_mm[:, 1] < 25) & (sig.speed_mm_s > 9.99)
    assert steady.sum() > 20
    c = 600.0 / (3 * 8000)
    fx, fy, fz = slot_means(2.0, c)
    # feed +Y: feed-frame x = machine +Y, feed-frame y (left of the feed) = machine −X
    expect_tool = np.array([-fy, fx, fz])
    got = sig.force_tool_N[steady].mean(axis=0)
    np.testing.assert_allclose(got, expect_tool, rtol=0.02)
    np.testing.assert_allclose(sig.force_workpiece_N[steady].mean(0), -expect_tool, rtol=0.02)
    # spindle: P = T ω + idle(8000 rpm) = T ω + 60 + 140·5000/9000
    omega = 2 * math.pi * 8000 / 60
    torque = 3 * 2.0 / (2 * math.pi) * 3.0 * (COEF["Ktc"] * c * 2 + COEF["Kte"] * math.pi) / 1000
    idle = 60 + 140 * 5000 / 9000
    np.testing.assert_allclose(sig.spindle_power_W[steady].mean(), torque * omega + idle, rtol=0.02)
    np.testing.assert_allclose(sig.spindle_current_A[steady].mean(),
                               math.hypot(1.5, (torque + idle / omega) / 0.5), rtol=0.02)
    # Y drive at constant speed: (Coulomb + viscous·v − F_tool,y) ρ/η / K_t
    ay = job.machine.axes["y"]
    f_axis = ay.friction_coulomb_N + ay.friction_viscous_N_s_per_mm * 10.0 - expect_tool[1]
    i_expect = f_axis * ay.rho_m_per_rad / ay.efficiency / ay.motor.kt_Nm_per_A
    np.testing.assert_allclose(sig.axis_current_A[steady, 1].mean(), i_expect, rtol=0.02)
    # deflection: tool beam at mid-depth under |F_xy|, machine per axis F/k
    from millpost.tools.beam import ToolBeam
    comp = ToolBeam.of(job.tools[1]).compliance_mm_per_N(2.0)
    np.testing.assert_allclose(sig.tool_deflection_mm[steady].mean(), comp * math.hypot(fx, fy), rtol=0.02)
    np.testing.assert_allclose(sig.machine_deflection_mm[steady, 0].mean(),
                               -fy / job.machine.axes["x"].stiffness_N_per_mm, rtol=0.02)
    # the peak per revolution: the force model's time-domain run on the same cut
    from millpost.forces import given_cut
    tool = job.tools[1]
    ref = job.material.force_model().predict(given_cut(tool, 6.0, 2.0), c, 8000, tool, peaks=True)
    np.testing.assert_allclose(sig.peak_force_xy_N[steady].mean(), ref.peak_force_xy_N[0], rtol=0.03)
    assert np.all(np.isnan(sig.peak_force_xy_N[sig.ap_mm == 0]))
    cols = sig.log_columns()
    assert set(cols) >= {"t_s", "x_mm", "fx_N", "spindle_power_W", "ix_A"}


def test_time_base_integrates_ds_over_v():
    """time_at from the trapezoids equals ∫ ds / v of the executed speed (fine numerical quadrature)."""
    prog = read_text("G21 G90 G94\nG0 X0 Y0 Z0\nG1 X30 F900\nG1 Y20 F1500\nG2 X40 Y30 I10 J0 F600\nG1 X41 F3000\n"
                     "G4 P1.5\nG1 X60 F2000\nM30\n")
    model = controller.ControllerModel((100.0, 100.0, 50.0), (800.0, 600.0, 400.0), junction_deviation_mm=0.02,
                                       planner=controller.GrblPlanner())
    ex = controller.execute(prog.toolpath, model)
    samples = prog.toolpath.resample(0.002)
    v = ex.speed_at_samples(samples)
    t = ex.time_at_samples(samples)
    assert np.all(np.diff(t) >= -1e-12)
    ds = np.diff(samples.s_mm)
    with np.errstate(divide="ignore"):
        quad = np.concatenate([[0], np.cumsum(np.where(v[1:] + v[:-1] > 0, 2 * ds / (v[1:] + v[:-1]), 0))])
    np.testing.assert_allclose(t, quad, atol=2e-3)
    assert t[-1] == pytest.approx(ex.time_s, abs=1e-6)
    tb = signals.time_base(prog, samples, ex)
    late = samples.move >= [e.move for e in prog.events if e.kind == "dwell"][0]
    np.testing.assert_allclose(tb[late] - t[late], 1.5)
