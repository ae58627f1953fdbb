"""End cutting (plunging, drilling, ramping, pecking): engagement of the tool's end and its thrust and
torque against closed forms and published drilling formulas.

References (the worked examples are those of the drilling literature, recomputed here):
- Kienzle lip model of a twist drill (Paucksch/Tschätsch, *Zerspantechnik*; Tschätsch, *Praxis der
  Zerspantechnik*): per lip h = (f/2)·sin(σ/2), b = (D/2)/sin(σ/2), F_c = b·h·k_c1.1·h^(−m_c), torque
  M = 2·F_c·D/4. Plunging end mill (κ = 90°): M = k_c·f·D²/8; ball nose M = z·k_c1.1·f_z^(1−m_c)·R²/(2 − m_c).
- Machinery's Handbook 31st ed., Machining Power, SI Eqs. (4)–(6), Tables 6–9 (Shaw & Oxford 1957):
  M = 2.5e-5·K_d·f^0.8·D^1.8·A, T = 0.05·K_d·f^0.8·D^0.8·B + 0.007·K_d·D²·J.
- Tungaloy general catalogue 2020–21 p. L068: T = 570·K·D·f^0.85, M = K·D²·(0.630 + 16.84·f)/100.
- ISCAR Rotating Tools 2017 "General – Calculations": M = f·k_c·D²/8·sin κ, F = 0.63·(D/2)·f·k_c·sin κ.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from millpost.errors import SafetyError

from millpost import stock
from millpost.engagement import Engagement, simulate
from millpost.forces.endcut import EndCut, chisel_factor, end_chip_factor, entry_chip_factor, thrust_limit_N, torque_limit_Nm
from millpost.gcode import read_text
from millpost.job import load_job
from millpost.materials import Material
from millpost.optimize import optimize
from millpost.tools import Tool

JOBS = Path(__file__).resolve().parents[2] / "sample_jobs"


def solid_end(n: int = 1, bins: int = 8) -> Engagement:
    """n samples of an end fully in material moving straight down (a drill or plunge in solid stock)."""
    e = Engagement.uniform(np.zeros(n), np.zeros(n), 1.0, 1.0)
    return replace(e, end_engaged=np.ones((n, bins)), descent=np.ones(n))


def model(name: str) -> EndCut:
    return EndCut.from_material(Material.load(name))


def kienzle_lip_torque(kc11, mc, D, f_rev, sigma_deg):
    """Twist drill, Kienzle per lip: M = 2·F_c·D/4 (N·m)."""
    s = math.sin(math.radians(sigma_deg / 2))
    h = f_rev / 2 * s
    b = D / 2 / s
    return 2 * b * h * kc11 * h ** (-mc) * D / 4 / 1000


def mh_drilling(Kd, D, f, A, B, J):
    """Machinery's Handbook / Shaw–Oxford (sharp tool, W = 1): (torque N·m, thrust N)."""
    return 2.5e-5 * Kd * f ** 0.8 * D ** 1.8 * A, 0.05 * Kd * f ** 0.8 * D ** 0.8 * B + 0.007 * Kd * D * D * J


def test_drill_steel_ex1_against_kienzle_and_published_envelope():
    """Ø6.8 HSS drill, 118°, standard point, steel 1045, f = 0.12 mm/rev."""
    tool = Tool(6.8, 2, shape="drill", tip_angle_deg=118, material="hss")
    thrust, torque = model("steel1045").predict(solid_end(), 0.06, tool)
    assert torque[0] == pytest.approx(kienzle_lip_torque(1500, 0.22, 6.8, 0.12, 118), rel=1e-3)
    assert torque[0] == pytest.approx(2.00, abs=0.01)                       # the lip model's 588 N per lip
    # the published methods for this drill: MH/Shaw–Oxford, Tungaloy (K = 2.22), ISCAR (k_c = 2100)
    M_mh, T_mh = mh_drilling(24000, 6.8, 0.12, 1.085, 1.355, 0.030)
    M_tu, T_tu = 2.22 * 6.8 ** 2 * (0.630 + 16.84 * 0.12) / 100, 570 * 2.22 * 6.8 * 0.12 ** 0.85
    s = math.sin(math.radians(59))
    M_is, T_is = 0.12 * 2100 / 1000 * 6.8 ** 2 / 8 * s, 0.63 * 3.4 * 0.12 * 2100 * s
    assert (M_mh, T_mh) == pytest.approx((3.76, 1615), rel=0.01)           # the handbook's worked numbers
    assert min(M_mh, M_tu, M_is) <= torque[0] <= max(M_mh, M_tu, M_is)
    assert min(T_mh, T_tu, T_is) <= thrust[0] <= max(T_mh, T_tu, T_is)
    # lips: ISCAR's 0.63·sin κ × the lips' cutting force (2 × 588 N); chisel (feed independent):
    # Shaw–Oxford's second term 0.007·K_d·D²·J
    chisel = model("steel1045").predict(solid_end(), 0.0, tool)[0][0]
    assert chisel == pytest.approx(0.007 * 24000 * 6.8 ** 2 * 0.030, rel=1e-9)
    assert thrust[0] - chisel == pytest.approx(0.63 * s * 2 * 588.0, rel=0.005)


def test_drill_aluminium_ex2_split_point():
    """Ø10 carbide drill, 140°, split point (c/d = 0.03), Al 6061-T6, f = 0.25 mm/rev."""
    tool = Tool(10, 2, shape="drill", tip_angle_deg=140, chisel_ratio=0.03)
    thrust, torque = model("al6061").predict(solid_end(), 0.125, tool)
    assert torque[0] == pytest.approx(kienzle_lip_torque(800, 0.25, 10, 0.25, 140), rel=1e-3)
    assert torque[0] == pytest.approx(4.27, abs=0.02)
    M_mh, T_mh = mh_drilling(7000, 10, 0.25, 1.0, 1.1, 0.001)
    M_tu, T_tu = 1.01 * 100 * (0.630 + 16.84 * 0.25) / 100, 570 * 1.01 * 10 * 0.25 ** 0.85
    s = math.sin(math.radians(70))
    M_is, T_is = 0.25 * 800 / 1000 * 100 / 8 * s, 0.63 * 5 * 0.25 * 800 * s
    assert (M_mh, T_mh) == pytest.approx((3.64, 806), rel=0.01)
    assert min(M_mh, M_tu, M_is) <= torque[0] <= max(M_mh, M_tu, M_is)
    assert min(T_mh, T_tu, T_is) <= thrust[0] <= max(T_mh, T_tu, T_is)
    assert chisel_factor(0.03) == 0.001 and chisel_factor(0.18) == 0.030 and chisel_factor(0.35) == 0.120


def test_ball_nose_plunge_closed_form():
    """Fully sunk ball nose: M = z·k_c1.1·f_z^(1−m_c)·R²/(2 − m_c), 2/(2 − m_c) ≈ 1.14 × the flat end's."""
    ball, flat = Tool(6, 3, shape="ball"), Tool(6, 3)
    _, m_ball = model("al6061").predict(solid_end(), 0.05, ball)
    _, m_flat = model("al6061").predict(solid_end(), 0.05, flat)
    assert m_ball[0] == pytest.approx(3 * 800 * 0.05 ** 0.75 * 9 / 1.75 / 1000, rel=0.01)
    assert m_ball[0] == pytest.approx(1.31, abs=0.01)
    assert m_ball[0] / m_flat[0] == pytest.approx(2 / 1.75, rel=0.01)


def test_bull_nose_plunge_closed_form():
    """Bull nose (corner radius r_ε): flat part h = f_z for r ≤ a = R − r_ε; on the torus h = f_z·cos ψ,
    r = a + r_ε·sin ψ, db = r_ε·dψ, so M = z·k_c1.1·f^p·[a²/2 + r_ε·(a·∫cos^p ψ dψ + r_ε/(p + 1))] with
    ∫₀^{π/2} cos^p ψ dψ = (√π/2)·Γ((p+1)/2)/Γ(p/2 + 1), p = 1 − m_c."""
    from scipy.special import gamma
    tool, p, a, re = Tool(10, 4, shape="bull", corner_radius_mm=1.5), 0.75, 3.5, 1.5
    _, M = model("al6061").predict(solid_end(), 0.04, tool)
    i_cos = math.sqrt(math.pi) / 2 * gamma((p + 1) / 2) / gamma(p / 2 + 1)
    closed = 4 * 800 * 0.04 ** p * (a * a / 2 + re * (a * i_cos + re / (p + 1))) / 1000
    assert M[0] == pytest.approx(closed, rel=0.005)


def box_plunge(tool: Tool, program: str, cell=0.05):
    prog = read_text(program)
    samples = prog.toolpath.resample(0.1)
    eng = simulate(stock.box((-20, -20, -20), (20, 20, 0), cell), tool, samples, progress=False)
    return samples, eng


def test_flat_plunge_ex3_simulated():
    """Ø6 3-flute flat end mill plunging into Al 6061 at f_z = 0.05 (f = 0.15 mm/rev): M = k_c·f·D²/8 =
    1.14 N·m, thrust 0.63·Σ F_c = 480 N, once the end is below the surface; none in the air above it."""
    tool = Tool(6, 3)
    samples, eng = box_plunge(tool, "G21 G90 G0 X0.013 Y-0.021 Z2\nS8000 M3\nG1 Z-4 F1200\n")
    thrust, torque = model("al6061").predict(eng, 0.05, tool)
    z = samples.xyz_mm[:, 2]
    inside = z < -0.15
    kc = 800 * 0.05 ** -0.25
    assert torque[inside] == pytest.approx(kc * 0.15 * 36 / 8 / 1000, rel=1e-3)
    assert torque[inside] == pytest.approx(1.14, abs=0.01)
    assert thrust[inside] == pytest.approx(0.63 * 3 * kc * 3 * 0.05, rel=1e-3)
    assert np.all(thrust[z > 0.05] == 0) and np.all(torque[z > 0.05] == 0)
    # the flank sweeps nothing on a pure plunge: no side engagement
    assert np.all(~np.isfinite(eng.phi_st[inside]))


def test_end_engagement_annulus_over_a_hole():
    """A Ø10 end mill plunging over a Ø4 pre-drilled hole cuts an annulus: Σ w_j·(bin area) = π(R² − r0²),
    and the removed volume per step is that area × the step's drop."""
    tools = {1: Tool(4, 2), 2: Tool(10, 4)}
    prog = read_text("G21 G90 G0 X0.013 Y-0.021 Z2\nS8000 M3\nT1\nG1 Z-6 F300\nG0 Z2\nT2\nG1 Z-3 F300\n")
    samples = prog.toolpath.resample(0.1)
    eng = simulate(stock.box((-20, -20, -20), (20, 20, 0), 0.025), tools, samples, progress=False)
    sel = (samples.tool == 2) & (samples.xyz_mm[:, 2] < -0.2) & eng.descending
    J = eng.end_engaged.shape[1]
    edges = np.linspace(0, 5, J + 1)
    area = eng.end_engaged[sel] @ (np.pi * np.diff(edges ** 2))
    assert area == pytest.approx(np.pi * (25 - 4), rel=0.01)
    drop = -np.diff(samples.xyz_mm[:, 2], prepend=samples.xyz_mm[0, 2])
    assert eng.volume_mm3[sel] == pytest.approx(np.pi * (25 - 4) * drop[sel], rel=0.01)
    assert np.all(eng.end_engaged[sel][:, 0] == 0)    # the hole: nothing under the centre
    # not enclosed: chips fall into the hole; the end's chip is its axial chip f_z·descent·sin κ (flat: 1)
    chip = end_chip_factor(eng, tools[2])
    assert np.all(entry_chip_factor(eng, tools[2], 0.5, chip)[sel] == chip[sel])
    assert np.all(chip[sel] == 1.0)


def test_ramp_and_helix_descent_and_whole_end_engaged():
    """Linear ramp at α: the whole end cuts the axial feed f_z·sin α (descent = sin α); helical entry:
    tan α = p / (π·D_path)."""
    tool = Tool(6, 3)
    samples, eng = box_plunge(tool, "G21 G90 G0 X-10 Y0.013 Z0.2\nS8000 M3\nG1 X10 Z-1.5 F600\n")
    alpha = math.atan2(1.7, 20)
    steady = (samples.xyz_mm[:, 0] > -9) & (samples.xyz_mm[:, 0] < 9) & (samples.xyz_mm[:, 2] < -0.2)
    assert eng.descent[steady] == pytest.approx(math.sin(alpha), rel=1e-6)
    assert eng.end_engaged[steady].mean() == pytest.approx(1.0, abs=0.02)
    assert np.all(np.isfinite(eng.phi_st[steady]).any(axis=1))          # and the flank cuts the slot
    # an enclosed end: the axial feed per tooth f_z·sin α over the entry share 0.5
    entry = entry_chip_factor(eng, tool, 0.5, end_chip_factor(eng, tool))
    assert entry[steady] == pytest.approx(math.sin(alpha) / 0.5, rel=1e-6)
    # helix of radius 4 (path Ø8), pitch 1 mm per turn, two turns down from the surface
    samples, eng = box_plunge(tool, "G21 G90 G0 X4 Y0 Z0\nS8000 M3\nG17 G2 X4 Y0 Z-1 I-4 J0 F600\nG2 X4 Y0 Z-2 I-4 J0\n")
    tan_a = 1.0 / (math.pi * 8)
    later = samples.xyz_mm[:, 2] < -1.05
    assert eng.descent[later] == pytest.approx(math.sin(math.atan(tan_a)), rel=2e-3)
    assert eng.end_engaged[later].mean() > 0.95


def test_peck_cycle_loads_per_peck():
    """G83 pecks (Q3 from R2 to Z-9): each peck re-enters its own bottom and picks up the load where the
    previous peck left it (the engagement is the drilled shape, not a fresh face); once the point is
    formed (depth ≥ L_p = R/tan(σ/2) = 1.50 mm) that is the full drilling load at the programmed feed;
    the 0.254 mm clearance above the last depth is fed in air (no load)."""
    tool = Tool(5, 2, shape="drill")
    samples, eng = box_plunge(tool, "G21 G90 G0 X0.013 Y-0.021 Z10\nS3000 M3\nG98 G83 X0.013 Y-0.021 Z-9 R2 Q3 F150\nG80\n")
    thrust, torque = model("al6061").predict(eng, 150 / (2 * 3000), tool)
    full_M = kienzle_lip_torque(800, 0.25, 5, 0.05, 118)
    cutting = torque > 1e-9
    starts = np.flatnonzero(np.diff(cutting.astype(int)) == 1) + 1
    ends = np.flatnonzero(np.diff(cutting.astype(int)) == -1)
    assert len(starts) == 4                                             # pecks to Z-1, -4, -7 and -9
    z = samples.xyz_mm[:, 2]
    L_p = 2.5 / math.tan(math.radians(59))
    assert torque[starts[0]] < 0.1 * full_M                             # first entry into the flat face
    assert torque[ends[0]] == pytest.approx(full_M * (1.0 / L_p) ** 2, rel=0.1)   # M ∝ (r_e/R)² in the point
    for start, last in zip(starts[1:], ends):
        assert z[start - 1] > z[last] and z[start] < z[last] + 0.1    # the air re-entry carries no load
        assert torque[start] <= torque[last] * 1.001                    # the step that crosses the bottom
        assert torque[start + 1] == pytest.approx(torque[last + 0], rel=0.05, abs=0.02 * full_M) or \
            torque[start + 1] >= torque[last]                           # continues the point's transient
    for start in starts[2:]:
        assert torque[start + 1] == pytest.approx(full_M, rel=0.01)
    assert np.max(torque) == pytest.approx(full_M, rel=0.01)


def test_tool_allowances():
    """Buckling F_cr = π²·E·I/(2L)² with I of 0.67·D (a drill) over the safety factor; torsion
    τ = 16 M/(π d³) up to 0.577 × strength / SF with d = 0.5·D."""
    drill = Tool(6.8, 2, shape="drill", material="hss", flute_length_mm=60, stickout_mm=70)
    I = math.pi * (0.2 ** 0.25 * 6.8) ** 4 / 64
    assert thrust_limit_N(drill, 1.0) == pytest.approx(math.pi ** 2 * 200e3 * I / 140 ** 2, rel=1e-9)
    assert 1.9e3 < thrust_limit_N(drill, 1.0) < 2.4e3                  # ≈ 2.3 kN of the worked example
    assert torque_limit_Nm(drill, 1.0) == pytest.approx(0.577 * 2000 * math.pi * 3.4 ** 3 / 16 / 1000, rel=1e-9)


def plunge_job(tmp_path, limits: str = "", shape: str = 'shape = "flat"') -> Path:
    (tmp_path / "p.nc").write_text("%\nG21 G90 G17\nT1 M6\nS9000 M3\nG0 X20 Y20 Z2\nG1 Z-4 F300\n"
                                   "G1 X30 F900\nG0 Z10\nM30\n%\n")
    (tmp_path / "job.toml").write_text(
        'program = "p.nc"\nmaterial = "al6061"\nmachine = "vmc-small"\n[stock]\nbox = [[0, 0, -15], [40, 40, 0]]\n'
        f'cell_mm = 0.05\n[tools.1]\ndiameter_mm = 6\nflutes = 3\n{shape}\nflute_length_mm = 16\n'
        f'stickout_mm = 24\n[limits]\n{limits}')
    return tmp_path / "job.toml"


def plunge_feed(text: str) -> float:
    """The highest feed (mm/min) of the emitted moves going down in material (below Z-1)."""
    tp = read_text(text).toolpath
    down = (tp.kind != 0) & (tp.end[:, 2] < tp.start[:, 2]) & (tp.end[:, 2] <= -1)
    return float(tp.feed_mm_min[down].max())


def test_issue_plunge_not_raised_beyond_end_cutting_bound(tmp_path):
    """`G1 Z-4 F300`, Ø6 3-flute flat end mill into Al 6061 at 9000 rpm (was raised to F2430 with the
    end unmodelled, then to F1215 at half the chip load). Bound asserted: a straight plunge's axial chip
    f_z takes a quarter of the material's chip load (FANAR: entries at 25–50 % of the table feed, the
    lower end for the harshest entry): F ≤ 0.25·h_max(6 mm)·z·n with h_max(6 mm) = 0.09·6/7 (the 7 mm
    row scaled by diameter) = 0.25·0.0771·3·9000 = 520.7 mm/min, under twice the programmed F300 (a
    machinist's plunge, not 4–8×); the chip-load limit binds
    there, so the feed reaches it; and at the emitted feed the end's torque (k_c·f·D²/8) and power stay
    under the spindle's."""
    job = load_job(plunge_job(tmp_path))
    assert job.material.strategies.plunge_fz_ratio == 0.25
    result = optimize(job, progress=False)
    f = plunge_feed(result.text)
    bound = 0.25 * 0.09 * 6 / 7 * 3 * 9000
    assert bound * 0.95 <= f <= bound + 0.1
    fz = f / (3 * 9000)
    M = 800 * fz ** -0.25 * fz * 3 * 36 / 8 / 1000
    assert M < job.machine.spindle.torque_Nm(9000) and M * 2 * math.pi * 150 < job.machine.spindle.power_W
    assert result.summary["limits"]["thrust"] < 1 and result.summary["limits"]["tool_torque"] < 1
    capped = optimize(load_job(plunge_job(tmp_path, "plunge_feed_max_mm_min = 500\n")), progress=False)
    assert plunge_feed(capped.text) <= 500


@pytest.mark.parametrize("shape", ['shape = "ball"', 'shape = "chamfer"\ntip_angle_deg = 28',
                                   'shape = "chamfer"\ntip_angle_deg = 90'])
def test_ball_and_v_plunges_take_the_entry_share_of_the_axial_feed(tmp_path, shape):
    """The same plunge with a ball or a V (28°, 90°) end: the centre of a round or pointed end cuts at
    no speed, so an enclosed entry gets the flat end's bound on the axial feed per tooth, F ≤ 0.25·h_max·z·n
    = 520.7 mm/min, with no chip-thinning credit for sin κ < 1 (a 28° V was raised 33×, a ball 14×)."""
    result = optimize(load_job(plunge_job(tmp_path, shape=shape)), progress=False)
    f = plunge_feed(result.text)
    assert 300 <= f <= 0.25 * 0.09 * 6 / 7 * 3 * 9000 + 0.1


def test_plunge_raised_at_most_twice_the_programmed_feed(tmp_path):
    """`G1 Z-4 F100` (the chip-load bound allows F520): at most plunge_raise_max = 2 × F100 by default
    (the programmer may have slowed it on purpose); with plunge_raise_max = 10 the load bound binds."""
    def feed(limits: str = "") -> float:
        job_path = plunge_job(tmp_path, limits)
        job_path.with_name("p.nc").write_text(job_path.with_name("p.nc").read_text().replace("Z-4 F300", "Z-4 F100"))
        return plunge_feed(optimize(load_job(job_path), progress=False).text)
    assert 190 <= feed() <= 200
    assert 0.95 * 520.7 <= feed("plunge_raise_max = 10\n") <= 520.8


def test_plunge_held_without_end_cutting_data(tmp_path):
    """A material without [end_cutting] data: the loads of the end are unknown, the plunge keeps F300."""
    src = Path(__file__).resolve().parents[2] / "src/millpost/data/materials/al6061.toml"
    text = src.read_text()
    (tmp_path / "al.toml").write_text(text[:text.index("[end_cutting]")])
    job_path = plunge_job(tmp_path)
    job_path.write_text(job_path.read_text().replace('"al6061"', '"al.toml"'))
    result = optimize(load_job(job_path), progress=False)
    assert 290 <= plunge_feed(result.text) <= 300   # held (F words are floored to whole mm/min)


def test_drill_and_mill_cycles(tmp_path):
    """The sample's 5 mm drill (3000 rpm): G81 spot (F200, 2 mm) and G83 pecks (F150, 12 mm). Both are
    raised only to the lip chip load (h = f_z·sin 59° ≤ 0.09 mm: F ≤ 0.09/sin 59°·2·3000 = 630), the
    heavier cycle is never faster than the lighter one, and thrust/torque stay under the drill's."""
    job = load_job(JOBS / "drill_and_mill")
    result = optimize(job, progress=False, trace=True)
    feeds = {ln.split()[1]: float(ln.split("F")[1]) for ln in result.text.splitlines() if ln.startswith("G98 G8")}
    bound = 0.09 / math.sin(math.radians(59)) * 2 * 3000
    assert 200 <= feeds["G81"] <= bound + 1 and 150 <= feeds["G83"] <= bound + 1
    assert feeds["G83"] <= feeds["G81"]
    limits = result.summary["limits"]
    assert limits["thrust"] <= 1.005 and limits["tool_torque"] <= 1.005 and limits["torque"] <= 1.005
    drilling = (result.samples.tool == 2) & (result.trace["thrust_N"] > 0)
    assert drilling.sum() > 50 and np.all(result.trace["torque_Nm"][drilling] > 0)


def test_absurd_drilling_feed_is_lowered_to_the_drill_strength(tmp_path):
    """FreeCAD's legacy post test drills G83 at F6000 and S1000 (6 mm/rev with a 5 mm drill). The thrust
    bound is the tangent at the chip-load cap, not at the absurd program, so the cycle is lowered below the
    feed where the exact thrust (lips + chisel) reaches the HSS drill's buckling load over its safety
    factor, and no hard limit is held (as a cut too heavy for the tool) at F6000."""
    (tmp_path / "p.nc").write_text("%\nG17 G54 G40 G49 G80 G90 G94\nG21\nM6 T1\nM3 S1000\nG0 X0 Y0 Z20\n"
                                   "G83 Z0 F6000 Q2 R10\nG0 X20\nG83 Z0 Q2 R10\nG80\nM30\n%\n")
    (tmp_path / "job.toml").write_text(
        'program = "p.nc"\nmaterial = "al6061"\nmachine = "vmc-small"\n[stock]\nbox = [[-10, -10, -10], [30, 10, 5]]\n'
        '[tools.1]\ndiameter_mm = 5\nflutes = 2\nshape = "drill"\nmaterial = "hss"\nflute_length_mm = 52\n'
        'stickout_mm = 62\n')
    job = load_job(tmp_path / "job.toml")
    with pytest.raises(SafetyError, match="T1 thrust up to"):  # 4.4x the programmed time: refused by default
        optimize(job, progress=False)
    job = replace(job, allow=frozenset({"slower", "overload"}))
    result = optimize(job, progress=False)
    assert result.summary["status"] == "slower"  # solved, and slower than the program: a hard limit lowered it
    assert not [k for k, v in result.summary["held"].items() if v["kind"] == "hard"]
    feed = float(next(ln for ln in result.text.splitlines() if ln.startswith("G83")).split("F")[1].split()[0])
    tool = job.tools[1]
    thrust = model("al6061").predict(solid_end(), feed / (2 * 1000), tool)[0][0]
    assert thrust <= thrust_limit_N(tool) * 1.001
    assert 50 < feed < 6000 / 10


def test_cycles_are_written_whole_and_taps_and_bores_keep_their_feed(tmp_path):
    """A canned cycle's block holds the hole's X Y Z R, not a move's end: its moves are never split (a split
    would write the cycle word with a split point as the hole bottom and drop R). A tap feeds at its pitch
    times the spindle speed (M8: 1.25 mm × 500 rpm = F625): the optimizer never changes that F, even where
    the schedule would raise or lower it. A boring cycle (G85 in the drilled holes: the schedule sees air)
    never gets a faster F than programmed: its feed sets the finish of the bore."""
    (tmp_path / "p.nc").write_text("G21 G90 G17 G94\nT1 M6\nS3000 M3\nG0 X0 Y0 Z10\n"
                                   "G99 G81 X0 Y0 Z-12 R2 F150\nX20\nG80\nG0 Z10\nT2 M6\nS500 M3\n"
                                   "G99 G84 X0 Y0 Z-10 R2 F625\nX20\nG80\nG0 Z10\nT1 M6\nS3000 M3\n"
                                   "G99 G85 X0 Y0 Z-8 R2 F90\nX20\nG80\nG0 Z10\nM2\n")
    (tmp_path / "job.toml").write_text(
        'program = "p.nc"\nmaterial = "al6061"\nmachine = "vmc-small"\n[stock]\nbox = [[-10, -10, -15], [30, 10, 0]]\n'
        '[tools.1]\ndiameter_mm = 6.8\nflutes = 2\nshape = "drill"\ntip_angle_deg = 118\nflute_length_mm = 40\n'
        'stickout_mm = 50\n[tools.2]\ndiameter_mm = 8\nflutes = 3\nshape = "flat"\nflute_length_mm = 20\n'
        'stickout_mm = 40\n')
    job = load_job(tmp_path / "job.toml")
    result = optimize(job, progress=False, trace=True)
    out = result.text.splitlines()
    assert [ln for ln in out if "G81" in ln][0].startswith("G99 G81 X0 Y0 Z-12 R2 F")
    assert "G99 G84 X0 Y0 Z-10 R2 F625" in out and sum(("G81" in ln) + ("G84" in ln) for ln in out) == 2
    original, emitted = read_text((tmp_path / "p.nc").read_text()), read_text(result.text)
    np.testing.assert_allclose(emitted.toolpath.end, original.toolpath.end, atol=1e-9)
    tap = emitted.cycle == 840
    assert tap.sum() >= 4 and np.all(emitted.toolpath.feed_mm_min[tap & (emitted.toolpath.kind != 0)] == 625)
    bore = emitted.cycle == 850
    assert bore.sum() >= 4 and np.all(emitted.toolpath.feed_mm_min[bore & (emitted.toolpath.kind != 0)] <= 90)
    # the honest baseline keeps them too (a machinist does not retune a tap's feed)
    base, cycle = result.trace["feed_baseline_mm_min"], original.cycle[result.samples.move]
    assert np.all(base[cycle == 840][np.isfinite(base[cycle == 840])] == 625)
    assert np.all(base[cycle == 850][np.isfinite(base[cycle == 850])] <= 90)
    assert result.summary["baseline_feed_mm_min"][2] == {625.0: 625.0}


def _subroutine_job(tmp_path, main: str, body: str, x_min: float):
    """Optimize `main` (G21 G90, T1 at S9000, ends G0 Z10 M2) with subroutine o100 = `body` (line 2), a
    6 mm 3-flute flat end mill in an al6061 block from X x_min to x_min + 30, top at Z0, on vmc-small."""
    (tmp_path / "p.ngc").write_text(f"o100 sub\n  {body}\no100 endsub\nG21 G90 G17\nT1 M6\nS9000 M3\n{main}"
                                    "G0 Z10\nM2\n")
    (tmp_path / "job.toml").write_text(
        f'program = "p.ngc"\nmaterial = "al6061"\nmachine = "vmc-small"\n[stock]\n'
        f'box = [[{x_min}, -10, -10], [{x_min + 30}, 10, 0]]\ncell_mm = 0.05\n[tools.1]\ndiameter_mm = 6\n'
        'flutes = 3\nshape = "flat"\nflute_length_mm = 16\nstickout_mm = 24\n')
    return optimize(load_job(tmp_path / "job.toml"), progress=False, trace=True)


def test_subroutine_feed_kept_where_one_f_would_slow_a_run(tmp_path):
    """A subroutine line `G1 F[#1] ...` called at F300 and at F3000 (above the chip-load feed, which the
    default policy does not lower): one constant F for the line would run the F3000 call at the lowest
    feed any run may take. No hard limit needs either run slower, so the line keeps the program's F
    expression, and the optimized program is no slower than the programmed one."""
    result = _subroutine_job(tmp_path, "G0 X0 Y0 Z2\nG1 Z-1 F100\no100 call [300] [10]\no100 call [3000] [20]\n",
                             "G1 F[#1] X[#2]", -10)
    assert "  G1 F[#1] X[#2]" in result.text.splitlines()
    assert result.summary["status"] == "solved"
    assert result.summary["cycle_time_after_s"] <= result.summary["cycle_time_before_s"] * (1 + 1e-3)
    assert any(n.startswith("note: line 2 runs several times") and "keeps the program's F" in n
               for n in result.summary["notes"])


def test_subroutine_line_with_one_f_for_all_runs_is_noted(tmp_path):
    """A subroutine line with no F word of its own, called twice at the modal F300: the first call cuts a
    full 4 mm slot in aluminium, the second runs again in the slot it cut (air). One F word serves both
    runs, so the air run goes no faster than the slot allows: the summary names the line, and the F
    written on it is the slot's (its chip-load feed), not the air's."""
    result = _subroutine_job(tmp_path, "G0 X-10 Y0 Z2\nG1 Z-4 F300\no100 call [20]\nG1 X0\no100 call [20]\n",
                             "G1 X[#1]", -5)
    assert any(n.startswith("note: line 2 runs several times") and "one F serves every run" in n
               for n in result.summary["notes"]), result.summary["notes"]
    trace = result.trace
    line2 = (trace["line"] == 2) & np.isfinite(trace["feed_schedule_mm_min"])
    emitted = read_text(result.text)
    f_line2 = set(emitted.toolpath.feed_mm_min[(emitted.toolpath.line == 2) & (emitted.toolpath.kind != 0)])
    assert len(f_line2) == 1 and f_line2.pop() < np.nanmax(trace["feed_schedule_mm_min"][line2]) / 1.5
