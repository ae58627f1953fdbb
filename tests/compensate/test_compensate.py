"""millpost compensate: the deflection vector, the surface error, the compensated program of the
thin-wall sample (its error, what LinuxCNC's interpreter reads of it) and the refusals."""

from __future__ import annotations

import re
import shutil
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from millpost.cli import main
from millpost.compensate import compensate, deflection_vectors
from millpost.compensate.surface import Surfaces
from millpost.errors import ConfigError, MillpostError
from millpost.gcode.lexer import lex_line
from millpost.job import load_job
from millpost.machine import Machine
from millpost.config import load_toml, resolve
from millpost.tools.beam import ToolBeam

ROOT = Path(__file__).resolve().parents[2]
JOB = ROOT / "sample_jobs" / "thin_wall_finish"
sys.path.insert(0, str(ROOT / "tests"))
import rs274_oracle  # noqa: E402


@pytest.fixture(scope="module")
def result():
    return compensate(load_job(JOB))


def _machine(**extra) -> Machine:
    data = load_toml(resolve("machines", "vmc-small"))
    data.update(extra)
    return Machine.from_dict(data, file="m.toml")


def test_compliance_matrix_is_read_and_checked():
    c = [[0.01, 0.003, 0.0], [0.003, 0.01, 0.0], [0.0, 0.0, 0.005]]
    m = _machine(compliance_mm_per_N=c)
    assert np.allclose(m.deflection_mm([10.0, 0.0, 0.0]), [0.1, 0.03, 0.0])  # C·F
    for bad, why in (([[0.01, 0.002, 0], [0.003, 0.01, 0], [0, 0, 0.005]], "not symmetric"),
                     ([[0.01, 0.02, 0], [0.02, 0.01, 0], [0, 0, 0.005]], "eigenvalue"),
                     ([[0.01, 0.0], [0.0, 0.01]], "3×3")):
        with pytest.raises(ConfigError, match=why) as e:
            _machine(compliance_mm_per_N=bad)
        assert "compliance_mm_per_N" in str(e.value) and "m.toml" in str(e.value)
    k = [m2.stiffness_N_per_mm for m2 in _machine().axes.values()]
    assert np.allclose(_machine().deflection_mm([3.0, 4.0, 5.0]), np.array([3.0, 4.0, 5.0]) / k)


def test_straight_wall_constant_force_closed_form():
    """A constant force F across a straight wall: the tool stands off by F·(1/k + C_tool(a_p)) exactly,
    C_tool the cantilever's ∫(a − x)²/EI dx (one segment: a³/3EI), and the wall error is that, signed
    as an undercut when the force pushes the tool away from the wall."""
    job = load_job(JOB)
    tool = job.tools[1]
    beam = ToolBeam.of(tool)
    ap = 12.0
    a = tool.stickout - ap / 2
    ei_flute = beam.E_MPa * np.pi * beam.flute_diameter_mm**4 / 64
    ei_shank = beam.E_MPa * np.pi * beam.shank_diameter_mm**4 / 64
    ls = beam.shank_length_mm
    # two segments: ∫0^ls (a−x)²/EI_s + ∫ls^a (a−x)²/EI_f
    c_tool = (a**3 - (a - ls) ** 3) / (3 * ei_shank) + (a - ls) ** 3 / (3 * ei_flute)
    assert beam.compliance_mm_per_N(ap) == pytest.approx(c_tool, rel=1e-12)
    force = np.array([[0.0, -20.0, 0.0]])  # on the tool, away from a wall at +Y
    sig = SimpleNamespace(force_tool_N=force, tool_deflection_mm=np.array([c_tool * 20.0]),
                          machine_deflection_mm=job.machine.deflection_mm(force))  # as the forward model gives it
    delta = deflection_vectors(job, sig)
    c_machine = np.array(load_toml(JOB / "machine.toml")["compliance_mm_per_N"])
    assert np.allclose(delta[0], c_machine @ force[0] + [0.0, -20.0 * c_tool, 0.0], rtol=1e-12)
    surfaces = Surfaces(np.array([[0.0, 1.0, 0.0]]), np.array([False]))
    wall, _ = surfaces.errors_mm(delta)
    assert wall[0] == pytest.approx(20.0 * (0.010 + c_tool), rel=1e-12)


def test_sample_error_is_removed_along_the_wall(result):
    s = result.summary
    p = result.samples.xyz_mm
    before, _ = result.surfaces.errors_mm(result.before.actual_mm - p)
    after, _ = result.surfaces.errors_mm(result.after.actual_mm - p)
    inner = np.isfinite(before) & (p[:, 0] > 4.0) & (p[:, 0] < 36.0)  # 4 mm from the wall's ends
    assert np.abs(before[inner]).min() > 0.1  # 0.156 mm undercut before: k_c/(k + k_c) of the 0.2 mm allowance
    assert np.abs(after[inner]).max() < 0.005
    assert s["reduction"] >= 0.8 and s["surface_error_before_um"] > 100  # measured: 109.8 → 1.1 µm RMS
    assert s["deflection_iterations"]["before"] < 100 and not s["notes"]


def test_only_xyz_of_cutting_lines_change_and_rs274_reads_it(result, tmp_path):
    job = load_job(JOB)
    src = job.program.read_text().splitlines()
    out = result.text.splitlines()
    cutting = {10, 16}  # the two wall passes (G1 X-5 / G1 X45)
    assert sorted(int(l) for l in {int(result.samples.line[result.samples.move == m][0]) for m in result.plan}) == [10, 16]
    # the output is the input with lines 10 and 16 replaced by runs of lines
    i = j = 0
    while i < len(src):
        if i + 1 in cutting:
            head = lex_line(out[j], j + 1, "out")
            orig = lex_line(src[i], i + 1, "in")
            assert [w.text for w in head.words if w.letter not in "XYZ"] == [w.text for w in orig.words if w.letter not in "XYZ"]
            j += 1
            while j < len(out) and re.fullmatch(r"G1( [XYZ]-?[\d.]+)+", out[j]):
                j += 1
        else:
            assert out[j] == src[i]
            j += 1
        i += 1
    assert j == len(out)
    if rs274_oracle.RS274 is None:
        pytest.skip("rs274 (LinuxCNC) is not installed")
    path = tmp_path / "out.nc"
    path.write_text(result.text)
    trace = rs274_oracle.run(path)
    assert trace.error is None
    feeds = [m for m in trace.moves if m[0] == "feed"]
    spacing = 1440 / 60 / job.machine.controller.block_rate_Hz
    starts = [k for k in range(1, len(feeds)) if feeds[k][2] == 1440.0]
    steps = [np.linalg.norm(np.subtract(feeds[k][1], feeds[k - 1][1])) for k in starts]
    assert min(steps) >= spacing - 1e-3  # written points no closer than F·DT (rounded to 1 µm)
    rapids_in = [m[1] for m in rs274_oracle.run(job.program).moves if m[0] == "rapid"]
    assert [m[1] for m in trace.moves if m[0] == "rapid"] == rapids_in


def test_refusals(tmp_path):
    folder = tmp_path / "job"
    shutil.copytree(JOB, folder)
    text = (folder / "program.nc").read_text()
    (folder / "program.nc").write_text(text.replace("G0 X-5 Y4.2", "G92 X0\nG0 X-5 Y4.2"))
    with pytest.raises(MillpostError, match=r"program.nc:13:1: G92"):
        compensate(load_job(folder))
    (folder / "program.nc").write_text(text.replace("G1 X-5 F1440", "G91 G1 X-50 F1440\nG90"))
    with pytest.raises(MillpostError, match=r"program.nc:10: .*incremental"):
        compensate(load_job(folder))
    (folder / "program.nc").write_text(text)
    assert main(["compensate", str(folder), "-o", str(folder / "program.nc"), "-q"]) == 2
    assert main(["compensate", str(folder), "-o", str(tmp_path / "o.nc"), "--tolerance", "0", "-q"]) == 2
    assert not (tmp_path / "o.nc").exists()


def test_surface_errors_read_a_shifted_wall_and_floor():
    """A wall cut 3 cells short (material left) on one half and 2 cells too deep on the other, and a floor
    0.004 mm high: the slice reads +3 h and −2 h at the wall cells, the floor +0.004 mm."""
    from millpost import stock as stocks
    from millpost.compensate.check import surface_errors

    h = 0.01
    original = stocks.box([0, 0, -2], [2, 1, 0], h)
    nominal, actual = original.copy(), original.copy()
    nominal.top[:50, :] = -1.0                      # cut to y = 0.5 (rows 0..49), floor at z = −1
    actual.top[:53, :100] = -0.996                  # x < 1: cut to y = 0.53, 4 µm high
    actual.top[:48, 100:] = -0.996                  # x > 1: cut to y = 0.48
    wall, floor = surface_errors(original, nominal, actual, -0.5)
    assert len(wall) == 200  # one wall cell a column (the grid's edges are not machined)
    cells = np.round(wall / h).astype(int)  # in x order (one row of wall cells)
    assert np.all(cells[3:97] == -3) and np.all(cells[103:] == 2)  # off the step and the grid's edge (not cut)
    assert np.all((cells >= -3) & (cells <= 2))
    assert np.allclose(floor, 0.004, atol=1e-5)


def test_independent_check_of_the_compensated_program(result, tmp_path):
    """Re-read the compensated program, cut a 10 µm height field with the tool placed sample after sample
    where it deflects under the force of the cut it meets (no use of compensate's error model), and
    measure walls and floors against the rigid cut of the programmed program."""
    from millpost import stock as stocks
    from millpost.compensate.check import deflected_cut, surface_errors
    from millpost.gcode import read_program

    job = load_job(JOB)
    out = tmp_path / "out.nc"
    out.write_text(result.text)
    programmed = read_program(job.program, job.reader_options())
    nominal = deflected_cut(job, programmed, 0.01, rigid=True).stock
    original = stocks.box(*job.stock_box, 0.01)
    rms = {}
    for name, program in (("before", programmed), ("after", read_program(out, job.reader_options()))):
        cut = deflected_cut(job, program, 0.01)
        assert cut.unsettled == 0
        wall, floor = surface_errors(original, nominal, cut.stock, -6.0)
        rms[name] = [float(np.sqrt(np.mean(e**2))) for e in (wall, floor, np.concatenate([wall, floor]))]
    # before: 0.150 mm left along the wall (the compensator's model: 0.156), 18.4 µm on the floor strip
    assert rms["before"][0] == pytest.approx(0.149, abs=0.01) and rms["before"][1] == pytest.approx(0.0184, abs=0.003)
    # measured: walls 149.1 → 18.5 µm, floor 18.4 → 3.2 µm RMS (the rest: the walls' exit ends, overcut)
    for k in range(3):
        assert rms["after"][k] <= 0.2 * rms["before"][k]


def test_report_page_shows_the_error_per_operation_and_its_map(result):
    from millpost.commands.compensate import report_page

    page = report_page(result)
    s = result.summary
    assert page.count('data-figure="surface-error"') == 1 and "<script" not in page
    assert f"{s['surface_error_before_um']:.1f} → {s['surface_error_after_um']:.1f} µm" in page
    for op in s["operations"]:
        for surf in ("wall", "floor"):
            assert f"<td>{op['before'][surf]['rms_um']:.1f}</td><td>{op['after'][surf]['rms_um']:.1f}</td>" in page
    # the panels' titles: RMS over the samples that finish a surface (wall where both), before and after
    p = result.samples.xyz_mm
    for name, run in (("as programmed", result.before), ("compensated", result.after)):
        wall, floor = result.surfaces.errors_mm(run.actual_mm - p)
        e = np.where(np.isfinite(wall), wall, floor) * 1000.0
        assert f"{name}: RMS {np.sqrt(np.nanmean(e**2)):.1f} µm, largest {np.nanmax(np.abs(e)):.1f} µm" in page


def test_canned_cycles_are_kept_and_the_rest_compensated():
    """drill_and_mill: facing, a pocket, G81/G83 holes. A cycle block's X Y Z R are its hole's, not a move's
    end, and a drill's thrust bends no wall: the cycle lines keep every byte, a note names them, and the
    milled lines are still compensated (the program is not refused for holding cycles)."""
    job = load_job(ROOT / "sample_jobs" / "drill_and_mill")
    out = compensate(job)
    before = job.program.read_text().splitlines()
    after = out.text.splitlines()
    starts = [k for k, line in enumerate(before) if re.search(r"\bG8[1-9]\b", line)]
    assert len(starts) == 2
    for k in starts:  # the cycle's block and its hole lines up to G80, byte for byte and in order
        block = before[k:before.index("G80", k) + 1]
        at = after.index(block[0])
        assert after[at:at + len(block)] == block
    assert any("canned-cycle line(s) kept as programmed" in n for n in out.summary["notes"])
    assert out.summary["points_added"] > 0 and out.summary["surface_error_after_um"] < out.summary["surface_error_before_um"]


def test_no_displacement_is_the_cut_as_stepped():
    """Moving the tool by nothing across the surfaces it makes gives back the stepped engagement slice by
    slice (the wall's arcs were rebuilt from the sample's a_e before, up to 13.5 µm of deflection off at the
    wall's ends), so the surface error before and the first offsets start from one cut."""
    from millpost import engagement
    from millpost.compensate.model import displaced
    from millpost.gcode import read_program

    job = load_job(JOB)
    program = read_program(job.program, job.reader_options())
    samples, eng, _ = engagement.engage(program, job.stock(), dict(job.tools), job.settings.ds_mm, job.allow,
                                        stage="simulate")
    moved = displaced(eng, Surfaces.of(eng), np.zeros((len(samples), 3)))
    for name in ("phi_st", "phi_ex", "dz_mm", "ae_mm", "ap_mm"):
        np.testing.assert_allclose(getattr(moved, name), getattr(eng, name), rtol=0, atol=1e-12, err_msg=name)
    shifted = displaced(eng, Surfaces.of(eng), np.tile([0.0, 0.05, 0.0], (len(samples), 1)))
    assert np.nanmax(np.abs(shifted.phi_st - eng.phi_st)) > 0.01  # and a move does move the arcs
