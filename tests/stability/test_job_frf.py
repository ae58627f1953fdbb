"""`[tools.N.frf]` in a job file: modes per direction (y = x when absent) or a measured CSV; refusals name
the file, the field or the line and column."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from chatter_jobs import HEADER, job_with, mode_csv
from millpost.errors import ConfigError, ParseError



def test_modes_and_y_defaulting_to_x(tmp_path):
    frf = job_with(tmp_path, "x = [{fn_hz = 2200, zeta = 0.03, k_N_per_mm = 8000}, "
                             "{fn_hz = 900, zeta = 0.05, k_N_per_mm = 3e4}]").frf[1]
    assert frf.y is frf.x and len(frf.x.modes) == 2
    # at its own natural frequency a mode's receptance is −i/(2kζ) (closed form), the other adds its own
    g = frf.x.receptance_mm_per_N(2200.0)
    other = 1 / (3e4 * (1 - (2200 / 900) ** 2 + 2j * 0.05 * 2200 / 900))
    assert g == pytest.approx(-1j / (2 * 8000 * 0.03) + other, rel=1e-12)


def test_different_directions(tmp_path):
    frf = job_with(tmp_path, "x = [{fn_hz = 2200, zeta = 0.03, k_N_per_mm = 8000}]\n"
                             "y = [{fn_hz = 2500, zeta = 0.02, k_N_per_mm = 9000}]").frf[1]
    assert frf.x.modes[0].fn_hz == 2200 and frf.y.modes[0].fn_hz == 2500 and frf.y.modes[0].k_N_per_mm == 9000


def test_measured_csv(tmp_path):
    (tmp_path / "frf.csv").write_text("# hammer test, T1 in its collet\n" + HEADER
                                      + "100, 1e-5, -2e-6, 2e-5, -1e-6\n\n300, 3e-5, -4e-6, 1e-5, -3e-6\n")
    job = job_with(tmp_path, 'csv = "frf.csv"')
    frf = job.frf[1]
    assert frf.x.receptance_mm_per_N(200.0) == pytest.approx(2e-5 - 3e-6j)   # halfway, linear
    assert frf.y.receptance_mm_per_N(300.0) == pytest.approx(1e-5 - 3e-6j)
    assert tmp_path / "frf.csv" in job.inputs  # an output may not replace it


def test_columns_in_any_order(tmp_path):
    (tmp_path / "frf.csv").write_text("im_y_mm_per_N,re_y_mm_per_N,f_hz,im_x_mm_per_N,re_x_mm_per_N\n"
                                      "-1,2,10,-3,4\n-1,2,20,-3,4\n")
    frf = job_with(tmp_path, 'csv = "frf.csv"').frf[1]
    assert np.allclose(frf.x.f_hz, [10, 20]) and frf.x.receptance_mm_per_N(15.0) == pytest.approx(4 - 3j)
    assert frf.y.receptance_mm_per_N(15.0) == pytest.approx(2 - 1j)


@pytest.mark.parametrize("body, where", [
    ("100,1e-5,-2e-6,2e-5,-1e-6\n200,1e-5,abc,2e-5,-1e-6\n", (3, 10, "abc")),
    ("100,1e-5,-2e-6,2e-5,-1e-6\n 90,1e-5,-2e-6,2e-5,-1e-6\n", (3, 2, "90")),
    ("100,1e-5,-2e-6,2e-5,-1e-6\n200,1e-5,-2e-6,2e-5\n", (3, 1, "")),
    ("100,1e-5,-2e-6,2e-5,-1e-6\n-5,1e-5,-2e-6,2e-5,-1e-6\n", (3, 1, "-5")),
    ("100,1e-5,-2e-6,2e-5,nan\n200,1e-5,-2e-6,2e-5,-1e-6\n", (2, 21, "nan")),
])
def test_csv_refusals_name_line_and_column(tmp_path, body, where):
    (tmp_path / "frf.csv").write_text(HEADER + body)
    with pytest.raises(ParseError) as err:
        job_with(tmp_path, 'csv = "frf.csv"')
    e = err.value
    assert (Path(e.file).name, e.line, e.column, e.word) == ("frf.csv", *where)


def test_csv_header_and_length(tmp_path):
    (tmp_path / "frf.csv").write_text("f_hz,re_x,im_x_mm_per_N,re_y_mm_per_N,im_y_mm_per_N\n1,1,1,1,1\n2,1,1,1,1\n")
    with pytest.raises(ParseError, match="missing re_x_mm_per_N") as err:
        job_with(tmp_path, 'csv = "frf.csv"')
    assert err.value.line == 1 and err.value.word == "re_x"
    (tmp_path / "frf.csv").write_text(HEADER + "1,1,1,1,1\n")
    with pytest.raises(ParseError, match="at least two"):
        job_with(tmp_path, 'csv = "frf.csv"')


@pytest.mark.parametrize("body, field, rule", [
    ("x = [{fn_hz = 2200, zeta = 1.2, k_N_per_mm = 8000}]", "tools.1.frf.x[0].zeta", "must be < 1"),
    ("x = [{fn_hz = 2200, zeta = 0.03, k_N_per_mm = -5}]", "tools.1.frf.x[0].k_N_per_mm", "must be > 0"),
    ("x = [{fn_hz = 2200, zeta = 0.03, k_N_per_mm = 8000}]\ny = [{fn_hz = 2e6, zeta = 0.03, k_N_per_mm = 8000}]",
     "tools.1.frf.y[0].fn_hz", "must be <= 50000"),
    ("x = [{fn_hz = 2200, zeta = 0.03, k_N_per_mm = 8000, fn_Hz = 3}]", "tools.1.frf.x[0].fn_Hz", "did you mean 'fn_hz'"),
    ("x = []", "tools.1.frf.x", "non-empty list of tables"),
    ("y = [{fn_hz = 2200, zeta = 0.03, k_N_per_mm = 8000}]", "tools.1.frf.x", "is required"),
    ('csv = "frf.csv"\nx = [{fn_hz = 2200, zeta = 0.03, k_N_per_mm = 8000}]', "tools.1.frf.csv", "not both"),
    ('csv = "nothere.csv"', "tools.1.frf.csv", "file not found"),
    ("x = [{fn_hz = 2200, zeta = 0.03, k_N_per_mm = 8000}]\nz = 1", "tools.1.frf.z", "unknown field"),
    # a misspelt field is named (it was "zeta = None: is required")
    ("x = [{fn_hz = 2200, damping = 0.03, k_N_per_mm = 8000}]", "tools.1.frf.x[0].damping", "unknown field"),
    ("X = [{fn_hz = 2200, zeta = 0.03, k_N_per_mm = 8000}]", "tools.1.frf.X", "unknown field (known: csv, x, y)"),
])
def test_table_refusals_name_the_field_and_file(tmp_path, body, field, rule):
    with pytest.raises(ConfigError) as err:
        job_with(tmp_path, body)
    assert err.value.field == field and rule in err.value.rule and err.value.file.endswith("job.toml")


def test_csv_with_positive_imaginary_part_at_the_peak_is_refused(tmp_path):
    """Im G_x > 0 where |G_x| is largest (2200 Hz, the 11th row: line 12): not a driving-point receptance."""
    mode_csv(tmp_path / "frf.csv", np.linspace(200.0, 4200.0, 21), sign=-1.0)
    with pytest.raises(ParseError, match="Im G_x > 0 where .G_x. is largest .2200 Hz.") as err:
        job_with(tmp_path, 'csv = "frf.csv"')
    e = err.value
    cells = (tmp_path / "frf.csv").read_text().splitlines()[11].split(",")
    assert (Path(e.file).name, e.line, e.column, e.word) == ("frf.csv", 12, len(cells[0]) + len(cells[1]) + 3, cells[2])
    assert float(e.word) > 0


def test_measured_table_doubts(tmp_path):
    """A band that stops below the resonance, and a table in m/N (1000× too small), are doubted; the mode
    sampled across its resonance in mm/N is not."""
    f = np.linspace(200.0, 4200.0, 41)
    mode_csv(tmp_path / "frf.csv", f)
    assert job_with(tmp_path, 'csv = "frf.csv"').frf[1].x.doubts == []
    mode_csv(tmp_path / "frf.csv", f[f < 1500.0])
    (doubt,) = job_with(tmp_path, 'csv = "frf.csv"').frf[1].x.doubts
    assert "is at the end of its band, 1400 Hz" in doubt
    mode_csv(tmp_path / "frf.csv", f, scale=1e-3 * 1e-3)     # m/N, and a mode 1000× stiffer
    (doubt,) = job_with(tmp_path, 'csv = "frf.csv"').frf[1].y.doubts
    assert doubt.startswith("|G| ≤ 2.08e-09 mm/N everywhere") and "m/N?" in doubt
