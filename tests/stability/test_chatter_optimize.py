"""Chatter in `optimize`: each sample's axial depth against the zero-order limiting depth at its speed.

Oracle (independent of `lobes`' frequency grid): the sample job `chatter_slot` cuts full slots (φ 0…π)
with a symmetric single-mode tool (f_n 2200 Hz, ζ 0.03, k 8000 N/mm), N = 3, in Al 6061 (K_tc 631, K_rc 99
N/mm²). For a slot the directional matrix has the eigenvalues λ = π(−K_r ± i), so Λ = −1/(λ G) in closed
form at every chatter frequency f, a(f) = −2π|Λ|²/(Λ_R N K_t) and ε(f) = π − 2 atan(Λ_I/Λ_R); at a speed n the
limit is the smallest a(f) > 0 over the roots of f·60/(N n) − ε(f)/2π = k, k = 0, 1, 2, …, found here by
bracketing on a fine grid and Brent's method (`slot_limit_mm`).
"""

from __future__ import annotations

import math
import re
import shutil

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from chatter_jobs import SLOT as JOB, job_with, mode_csv
from millpost.engagement import Engagement
from millpost.job import load_job
from millpost.optimize import optimize
from millpost.stability import check
from millpost.stability.check import CutImmersion, limiting_depth_mm, margin
from millpost.stability.frf import DirectionFRF, Mode, ToolTipFRF
from millpost.stability.lobes import semi_discretisation_limit_mm, zero_order_limit_mm
from millpost.toolpath import FEED

FN, ZETA, K, N, KT, KR = 2200.0, 0.03, 8000.0, 3, 631.0, 99.0 / 631.0
SLOT_LINES = [9, 13, 19, 23, 29, 33]  # the G1 X65 passes, 1.5 mm deep each


def slot_limit_mm(rpm: float) -> float:
    """The zero-order limit of a full slot at `rpm` for the job's tool, from the closed-form eigenvalues."""
    T = 60.0 / (N * rpm)
    f = np.linspace(1.0, 3 * FN, 400_001)
    best = math.inf
    for sign in (1.0, -1.0):
        def parts(f):
            G = 1 / (K * (1 - (f / FN) ** 2 + 2j * ZETA * f / FN))
            lam = -1 / (math.pi * (-KR + sign * 1j) * G)
            a = -2 * math.pi * abs(lam) ** 2 / (lam.real * N * KT) if np.ndim(f) == 0 else \
                -2 * np.pi * np.abs(lam) ** 2 / (lam.real * N * KT)
            return a, f * T - (math.pi - 2 * np.arctan(lam.imag / lam.real)) / (2 * math.pi)
        a, theta = parts(f)
        for k in range(int(np.nanmax(theta)) + 1):
            h = theta - k
            for i in np.flatnonzero((np.sign(h[:-1]) != np.sign(h[1:])) & (a[:-1] > 0) & (a[1:] > 0)
                                    & (np.abs(h[1:] - h[:-1]) < 0.5)):
                root = brentq(lambda x: parts(x)[1] - k, f[i], f[i + 1], xtol=1e-10)
                best = min(best, parts(root)[0])
    return best


@pytest.fixture(scope="module")
def programmed():
    return optimize(load_job(JOB), progress=False).summary


@pytest.fixture(scope="module")
def at_optimized_speed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("chatter_slot")
    for name in ("program.nc", "job.toml"):
        shutil.copy(JOB / name, folder / name)
    with (folder / "job.toml").open("a") as fh:
        fh.write('\n[limits]\nrpm = "optimize"\n')
    result = optimize(load_job(folder), progress=False)
    return result.summary, result.text


def test_the_oracle_is_the_lobes_own_value():
    """The closed-form slot limit and `zero_order_limit_mm` agree at the programmed and pocket speeds."""
    frf = ToolTipFRF.symmetric(Mode(FN, ZETA, K))
    for rpm in (18600.0, 21659.0, 22000.0):
        lobes = zero_order_limit_mm(frf, kt_N_per_mm2=KT, kr=KR, flutes=N, phi_st_rad=0.0, phi_ex_rad=math.pi,
                                    rpm=[rpm])[0]
        assert lobes == pytest.approx(slot_limit_mm(rpm), rel=2e-3)


def test_programmed_s_chatters_and_its_lines_are_listed(programmed):
    c = programmed["chatter"]
    assert c["kind"] == "quality" and c["tools"] == [1]
    assert c["kt_N_mm2"] == pytest.approx(KT) and c["kr"] == pytest.approx(KR, abs=1e-4)
    assert [r["line"] for r in c["lines"]] == SLOT_LINES and c["line_count"] == 6
    a_lim = slot_limit_mm(18600.0)  # 0.597 mm
    for row in c["lines"]:
        assert row["tool"] == 1 and row["rpm"] == 18600.0
        assert row["ap_mm"] == pytest.approx(1.5, abs=2e-3)
        assert row["a_lim_mm"] == pytest.approx(a_lim, rel=3e-3)
        assert row["ratio"] == pytest.approx(row["ap_mm"] / a_lim, rel=3e-3)
    warnings = [n for n in programmed["notes"] if n.startswith("warning: chatter")]
    assert len(warnings) == 1 and "T1 at 18600 rpm" in warnings[0] and "9, 13, 19, 23, 29, 33" in warnings[0]
    # a quality limit: no feed is lowered for it (the F words are those of the other limits)
    assert "chatter" not in programmed["binding_limits"] and "chatter" not in programmed["held"]


def test_rpm_optimize_moves_s_into_a_pocket_that_clears(at_optimized_speed):
    s, text = at_optimized_speed
    (block,) = s["spindle"]["blocks"]
    assert block["changed"] and block["programmed_rpm"] == 18600.0
    new = block["rpm"]
    lo, hi = block["window_rpm"]
    assert lo <= new <= hi
    assert f"S{new:g} M3" in text and "S18600" not in text
    assert block["chatter"]["programmed_margin"] == pytest.approx(slot_limit_mm(18600.0) / 1.5, rel=5e-3)
    assert block["chatter"]["clears"] and slot_limit_mm(new) > 1.5
    assert s["chatter"]["lines"] == [] and s["chatter"]["samples_over"] == 0
    assert not [n for n in s["notes"] if n.startswith("warning: chatter")]


def test_without_an_frf_no_chatter_code_runs(tmp_path, monkeypatch):
    """The job without its [tools.1.frf]: nothing is checked (the lobes would raise), the summary has
    no chatter entry, and the program is the same as with the check switched off at its source."""
    (tmp_path / "program.nc").write_text((JOB / "program.nc").read_text())
    toml = (JOB / "job.toml").read_text()
    (tmp_path / "job.toml").write_text(toml[:toml.index("[tools.1.frf]")])
    job = load_job(tmp_path)
    assert job.frf == {}

    def refuse(*args, **kwargs):
        raise AssertionError("a stability limit was computed for a job without an FRF")

    monkeypatch.setattr(check, "zero_order_limit_mm", refuse)
    s = optimize(job, progress=False).summary
    assert "chatter" not in s and not any("chatter" in n for n in s["notes"])


def _job_with_y(tmp_path, y_modes: str):
    """The chatter_slot job with a Y mode of its own (X keeps the job's mode)."""
    (tmp_path / "program.nc").write_text((JOB / "program.nc").read_text())
    toml = (JOB / "job.toml").read_text().replace("x = [{fn_hz = 2200", f"y = [{y_modes}]\nx = [{{fn_hz = 2200")
    (tmp_path / "job.toml").write_text(toml)
    return load_job(tmp_path)


def _cut(job, st_deg, ex_deg, along_y):
    """The CutImmersion of samples 2 mm deep engaging φ st_deg…ex_deg, fed along machine X or Y."""
    n = len(along_y)
    eng = Engagement.uniform(np.radians(np.full(n, st_deg)), np.radians(np.full(n, ex_deg)), 2.0,
                             job.tools[1].radius_mm, slices=4)
    eng.feed_dir[:] = [(0.0, 1.0, 0.0) if y else (1.0, 0.0, 0.0) for y in along_y]
    samples = type("S", (), {"kind": np.full(n, FEED), "tool": np.ones(n, int)})()
    return CutImmersion.of(job, samples, eng)


def test_the_feed_direction_against_the_one_mode_closed_form(tmp_path):
    """X flexible (the job's mode), Y all but rigid (k 1e7 N/mm): with G_yy ≈ 0 the zero-order equation
    has the single root Λ = −1/(α G) of the feed direction's factor α (α_xx fed along X; fed along Y the
    flexible direction is the feed frame's y, α_yy), so a(f) = 2π/(N K_t α Re G(f)) and its smallest positive
    value over all speeds is 2π/(N K_t α Re G_ext), Re G_ext = −1/(4kζ(1+ζ)) for α < 0 and 1/(4kζ(1−ζ)) for
    α > 0 (Altintas, "Manufacturing Automation" 2nd ed. §3.4 and §3.10). α is integrated here from the
    force model: α_xx = ∫ 2·∂F_x/∂Δx = ∫ −(sin 2φ + 2K_r sin²φ) dφ, α_yy = ∫ (sin 2φ − 2K_r cos²φ) dφ."""
    job = _job_with_y(tmp_path, "{fn_hz = 5000, zeta = 0.05, k_N_per_mm = 1e7}")
    st, ex = math.radians(20.5), math.radians(131.0)
    a_xx = quad(lambda p: -(math.sin(2 * p) + 2 * KR * math.sin(p) ** 2), st, ex)[0]   # −0.879
    a_yy = quad(lambda p: math.sin(2 * p) - 2 * KR * math.cos(p) ** 2, st, ex)[0]      # +0.274
    cut = _cut(job, 20.5, 131.0, [False, True])
    rpm = np.linspace(12000.0, 30000.0, 4001)
    for i, alpha in ((0, a_xx), (1, a_yy)):
        re_g = -1 / (4 * K * ZETA * (1 + ZETA)) if alpha < 0 else 1 / (4 * K * ZETA * (1 - ZETA))
        a_crit = 2 * math.pi / (N * KT * alpha * re_g)
        # the checked arc is at most 1 % wider than 20.5…131°: within 3 % (test_an_arc_s_limit_is_within...)
        got = margin(job, cut, np.array([i]), rpm).min() * 2.0
        assert got == pytest.approx(a_crit, rel=0.03)
    # and the grouping: each sample gets the limit of its own direction, the margin of both the smaller
    both = limiting_depth_mm(job, cut, np.array([18000.0, 18000.0]))
    assert both[0] != pytest.approx(both[1], rel=0.1)
    assert margin(job, cut, np.arange(2), np.array([18000.0]))[0] == pytest.approx(min(both) / 2.0, rel=1e-9)


def test_an_arc_s_limit_is_within_3_percent_of_the_engaged_arc_s():
    """The arc checked (`binned_arc`) contains the engaged one and is less than 1 % wider; the limit it
    gives is within 3 % of the engaged arc's (6000–30000 rpm) for a 5.1° and a 20.5° finishing arc (down
    milling: the 5° bins this replaced gave 1.78× and 1.60× too low) and the arcs of straight flank cuts,
    down and up milling, 0.5…180° wide."""
    frf = ToolTipFRF.symmetric(Mode(FN, ZETA, K))
    rpm = np.geomspace(6000.0, 30000.0, 40)
    widths = np.geomspace(0.5, 180.0, 40) * 0.999
    arcs = [(180.0 - 5.1, 180.0), (180.0 - 20.5, 180.0)] + [(180.0 - w, 180.0) for w in widths] + [(0.0, w) for w in widths]
    for st_deg, ex_deg in arcs:
        st, ex = math.radians(st_deg), math.radians(ex_deg)
        lo, hi = check.binned_arc(st, ex)
        assert lo <= st and hi >= ex and (hi - lo) < 1.01 * (ex - st) + 1e-12
        kw = dict(kt_N_per_mm2=KT, kr=KR, flutes=N, rpm=rpm)
        exact = zero_order_limit_mm(frf, phi_st_rad=st, phi_ex_rad=ex, **kw)
        binned = zero_order_limit_mm(frf, phi_st_rad=float(lo), phi_ex_rad=float(hi), **kw)
        assert np.all(np.isfinite(exact) == np.isfinite(binned))
        np.testing.assert_allclose(binned[np.isfinite(exact)], exact[np.isfinite(exact)], rtol=0.03)


def test_a_measured_frf_gives_the_modes_limit(tmp_path):
    """The FRF as a measured table (the mode sampled finely) gives the limit of the mode itself."""
    f = np.linspace(100.0, 6600.0, 13001)
    mode_csv(tmp_path / "frf.csv", f)  # the mode (FN, ZETA, K) sampled
    measured = job_with(tmp_path, 'csv = "frf.csv"').frf[1]
    assert isinstance(measured.x, DirectionFRF) and measured.x.f_hz is not None
    a = zero_order_limit_mm(measured, kt_N_per_mm2=KT, kr=KR, flutes=N, phi_st_rad=0.0, phi_ex_rad=math.pi,
                            rpm=[18600.0])[0]
    assert a == pytest.approx(slot_limit_mm(18600.0), rel=5e-3)


def test_notes_on_the_frfs(tmp_path):
    """T1's FRF measured and band-limited below its resonance (largest |G| at the band's end) is doubted in
    the notes; T2 has an FRF but the program never uses it: a note, nothing checked for it."""
    f = np.linspace(100.0, 1500.0, 141)
    mode_csv(tmp_path / "frf.csv", f)  # the mode (FN, ZETA, K) sampled
    job = job_with(tmp_path, 'csv = "frf.csv"\n\n[tools.2]\ndiameter_mm = 6\nflutes = 3\n\n'
                                  '[tools.2.frf]\nx = [{fn_hz = 2200, zeta = 0.03, k_N_per_mm = 8000}]')
    s = optimize(job, progress=False).summary
    notes = [n for n in s["notes"] if "tip FRF" in n]
    assert [n[:61] for n in notes] == [
        "warning: T1's tip FRF ([tools.1.frf]) in x: its largest |G| (", "warning: T1's tip FRF ([tools.1.frf]) in y: its largest |G| (",
        "note: T2 has a tip FRF ([tools.2.frf]) but cuts nothing in th"]
    assert "is at the end of its band, 1500 Hz" in notes[0] and s["chatter"]["tools"] == [1, 2]


def test_the_worked_example_quotes_these_runs(programmed, at_optimized_speed):
    """docs/chatter.md's worked example quotes the warning, the new speed, its margins, a_lim there and the
    clearing candidates: each figure is the one these runs give (the page is read, not copied)."""
    page = " ".join((JOB.parents[1] / "docs" / "chatter.md").read_text().split())
    (warning,) = [n for n in programmed["notes"] if n.startswith("warning: chatter")]
    quoted = re.search(r"prints `(warning: chatter: T1 at 18600 rpm [^`]*)`", page).group(1)
    assert quoted == warning.split("; a lighter depth")[0]
    s, _ = at_optimized_speed
    (block,) = s["spindle"]["blocks"]
    c = block["chatter"]
    m = re.search(r"moves S to (\d+) rpm \(`S18600 → S(\d+): a stable pocket, its cuts within the stable depth "
                  r"\(a_lim/ap ≥ ([\d.]+); at S18600 ([\d.]+)\)`\): a_lim there is ([\d.]+) mm", page)
    assert float(m.group(1)) == float(m.group(2)) == block["rpm"]
    assert (float(m.group(3)), float(m.group(4))) == (round(c["margin"], 2), round(c["programmed_margin"], 2))
    assert float(m.group(5)) == round(c["margin"] * 1.5, 2) == pytest.approx(slot_limit_mm(block["rpm"]), abs=0.01)
    clearing = re.search(r"The clearing candidates were (\d+), (\d+) and (\d+) rpm", page).groups()
    assert [float(v) for v in clearing] == c["clearing_rpm"]


def test_where_the_zero_order_check_errs_against_semi_discretisation():
    """The figures docs/chatter.md quotes for the check's method (zero-order) against semi-discretisation
    (the time-varying directional matrix; its own tests compare it with a time-domain simulation), down
    milling at 18600 rpm with chatter_slot's FRF: 1.59× too high at 10°, 0.87× at 30°, 0.96× at 90°."""
    frf = ToolTipFRF.symmetric(Mode(FN, ZETA, K))
    kw = dict(kt_N_per_mm2=KT, kr=KR, flutes=N, phi_ex_rad=math.pi, rpm=[18600.0])
    for arc, zo_mm, sd_mm in ((10.0, 125.3, 78.7), (30.0, 14.66, 16.88), (90.0, 1.576, 1.646)):
        st = math.radians(180.0 - arc)
        zo = zero_order_limit_mm(frf, phi_st_rad=st, **kw)[0]
        sd = semi_discretisation_limit_mm(frf, phi_st_rad=st, **kw)[0]
        assert zo == pytest.approx(zo_mm, rel=2e-3) and sd == pytest.approx(sd_mm, rel=5e-3)
