"""The report's stability lobes: each curve is the zero-order limit (`zero_order_limit_mm` called here on
its own, with the tool's FRF and the material's mechanistic coefficients) at the immersions the tool cuts,
the points marked over their limit are the summary's chatter lines, and the page has the figure from
optimize and from a saved trace with its job, a note without the job, nothing without an FRF.

Job: `sample_jobs/chatter_slot` (full slots at S18600, 1.5 mm deep, where the slot's limit is ~0.6 mm)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from millpost.cli import main
from millpost.forces.mechanistic import Mechanistic
from millpost.job import load_job
from millpost.report import collect, figures, read_trace, render
from millpost.report.lobes import tool_lobes
from millpost.stability.frf import ToolTipFRF
from millpost.stability.lobes import zero_order_limit_mm

JOB = Path(__file__).resolve().parents[2] / "sample_jobs" / "chatter_slot"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """optimize --report --trace --json on the job, once: (folder, summary, trace)."""
    d = tmp_path_factory.mktemp("lobes")
    assert main(["optimize", str(JOB), "-o", str(d / "o.nc"), "--report", str(d / "a.html"), "--trace",
                 str(d / "t.csv"), "--json", str(d / "s.json")]) == 0
    return d, json.loads((d / "s.json").read_text()), read_trace(d / "t.csv")


def test_curves_are_the_zero_order_limit_at_the_cut_immersions(run):
    _, _, trace = run
    job = load_job(JOB)
    (lobes,) = tool_lobes(trace, job)
    ktc, krc = Mechanistic.from_material(job.material).coef_[:2]
    main_curve = lobes.curves[0]
    assert main_curve.phi_st_deg == 0.0 and main_curve.phi_ex_deg == pytest.approx(180.0, abs=0.2)  # the slots: most samples
    sp = job.machine.spindle
    assert main_curve.rpm[-1] == sp.rpm_max and main_curve.rpm[0] == max(sp.rpm_min, 0.05 * sp.rpm_max)
    for c in lobes.curves:
        frf = ToolTipFRF(job.frf[1].y, job.frf[1].x) if c.along_y else job.frf[1]
        at = np.linspace(0, len(c.rpm) - 1, 9).astype(int)
        expected = zero_order_limit_mm(frf, kt_N_per_mm2=float(ktc), kr=float(krc / ktc), flutes=3,
                                       phi_st_rad=math.radians(c.phi_st_deg), phi_ex_rad=math.radians(c.phi_ex_deg),
                                       rpm=c.rpm[at])
        assert np.allclose(c.a_lim_mm[at], expected, rtol=1e-9)
    # the pockets are the curve's interior maxima; the fastest near 22000 rpm (the job file's comment)
    fastest = main_curve.pockets[0]
    assert 21000 < fastest.rpm < 23000 and fastest.depth_mm == pytest.approx(main_curve.a_lim_mm.max(), rel=1e-9)


def test_points_over_are_the_summarys_chatter_lines(run, monkeypatch):
    _, summary, trace = run
    (lobes,) = tool_lobes(trace, load_job(JOB))
    rows = summary["chatter"]["lines"]
    assert len(rows) == 6 and set(lobes.lines_over) == {r["line"] for r in rows}
    over = set(zip(lobes.points_rpm[lobes.points_over].round(1), lobes.points_ap_mm[lobes.points_over].round(3)))
    assert over == {(r["rpm"], r["ap_mm"]) for r in rows} == {(18600.0, 1.5)}
    # drawn: the curve as computed, the over points as crosses
    drawn = {}
    monkeypatch.setattr(figures, "svg", lambda fig, name: drawn.setdefault(name, fig) and "")
    figures.stability_lobes(lobes)
    ax = drawn["lobes-T1"].axes[0]
    by_gid = {line.get_gid(): line.get_xydata() for line in ax.lines if line.get_gid()}
    assert np.array_equal(by_gid["lobe-0"][:, 1], lobes.curves[0].a_lim_mm)
    assert np.array_equal(by_gid["cuts-above"], [[18600.0, 1.5]]) and "cuts-stable" not in by_gid


def test_page_has_the_lobes_from_optimize_and_from_the_trace(run):
    d, _, _ = run
    assert 'data-figure="lobes-T1"' in (d / "a.html").read_text()
    assert main(["report", str(d / "t.csv"), "--summary", str(d / "s.json"), "--job", str(JOB), "-o",
                 str(d / "b.html")]) == 0
    assert 'data-figure="lobes-T1"' in (d / "b.html").read_text()
    assert main(["report", str(d / "t.csv"), "-o", str(d / "c.html")]) == 0  # the trace alone: a note
    c = (d / "c.html").read_text()
    assert "lobes-T1" not in c and "give --job" in c and c.count("<svg data-figure=") == 4


def test_no_frf_no_lobes(run):
    """A trace without the chatter columns (a job without an FRF) and no job: the page has no lobes section."""
    _, summary, trace = run
    plain = {k: v for k, v in trace.items() if k not in ("rpm", "a_lim_mm", "phi_st_deg", "phi_ex_deg",
                                                         "feed_along_y", "chatter_over")}
    data = collect({k: v for k, v in summary.items() if k != "chatter"}, plain)
    assert data.lobes == [] and data.lobes_note == "" and "stability lobes" not in render(data)
