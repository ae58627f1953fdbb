"""Calibration that says what the data identify: one test cut (one chip thickness) updates the
cutting-plus-edge sum per direction and leaves the split at the catalogue prior, and still predicts deeper
cuts of the same slot; a channel with the wrong sign is refused. Measured means come from the independent
generator (tests/independent_log.py: its own per-tooth force integration in a box of stock)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from independent_log import Mill, generate
from millpost.cli import main
from millpost.forces import given_cut
from millpost.materials import Material
from millpost.tools.cutter import Tool

# a steel whose force direction is not the catalogue's: F_r/F_t ≈ 0.6 at h ≈ 0.03 mm (edge forces dominate)
TRUTH = (2100.0, 900.0, 500.0, 45.0, 60.0, 12.0)
D, FLUTES, RPM, FZ = 10.0, 4, 2400.0, 0.03
DEPTHS = (3.0, 6.0, 12.0)


@pytest.fixture(scope="module")
def slots():
    """Mean force on the tool (feed frame = machine XYZ, feed +X) of full slots 3, 6 and 12 mm deep, each in
    fresh stock, over their steady middle."""
    feed = FZ * FLUTES * RPM
    lines = ["G21 G90", f"S{RPM:g} M3"]
    for k, ap in enumerate(DEPTHS):
        y = 10 + 15 * k
        lines += [f"G0 X-8 Y{y} Z5", f"G1 Z{-ap} F300", f"G1 X68 F{feed:g}", "G0 Z5"]
    mill = Mill(diameter_mm=D, flutes=FLUTES, helix_deg=30, flute_length_mm=25, K=TRUTH, accel_mm_s2=800,
                rapid_mm_min=8000, slice_mm=0.25)
    g = generate("\n".join(lines) + "\nM5\n", ((0, 0, -30), (60, 60, 0)), mill, rate_hz=200, noise=0.02, seed=3)
    x, y, z = (g.columns[c] for c in ("x_mm", "y_mm", "z_mm"))
    out = []
    for k, ap in enumerate(DEPTHS):
        on = (np.abs(y - (10 + 15 * k)) < 0.05) & (np.abs(z + ap) < 0.05) & (x > 15) & (x < 45)
        out.append(-np.array([g.columns[c][on].mean() for c in ("fx_N", "fy_N", "fz_N")]))
    return np.array(out)


def _table(path, rows) -> None:
    text = "diameter_mm,flutes,helix_deg,ae_mm,ap_mm,fz_mm,rpm,fx_N,fy_N,fz_N\n"
    text += "".join(f"{D},{FLUTES},30,{D},{ap},{FZ},{RPM}," + ",".join(repr(float(v)) for v in f) + "\n"
                    for ap, f in rows)
    path.write_text(text)


def test_generator_slot_means_are_the_closed_form(slots):
    """The generator's per-tooth integration against Altintas' closed-form slot means (its own check)."""
    Ktc, Krc, Kac, Kte, Kre, Kae = TRUTH
    for ap, f in zip(DEPTHS, slots):
        N = FLUTES
        expect = [-N * ap * Krc * FZ / 4 - N * ap * Kre / np.pi, N * ap * Ktc * FZ / 4 + N * ap * Kte / np.pi,
                  N * ap * Kac * FZ / np.pi + N * ap * Kae / 2]
        np.testing.assert_allclose(f, expect, rtol=0.01)


def test_one_test_cut_fits_names_the_prior_and_predicts_deeper_slots(tmp_path, slots, capsys):
    """One row (the 3 mm slot): the fit succeeds, identifies three combinations (one per direction), leaves
    the rest at steel1045's prior without a standard error, and the written material predicts the 6 and
    12 mm slots within 12 % per component (the catalogue alone is off by far more in direction)."""
    _table(tmp_path / "one.csv", [(DEPTHS[0], slots[0])])
    out, mat = tmp_path / "fit.json", tmp_path / "mine.toml"
    assert main(["calibrate", "fit", "--cuts", str(tmp_path / "one.csv"), "--material", "steel1045", "--json",
                 str(out), "-o", str(mat)]) == 0
    got = json.loads(out.read_text())
    ident = got["mechanistic_identifiability"]
    assert ident["rank"] == 3 and len(ident["combinations"]) == 3
    assert ident["at_prior"], ident
    for name in ident["at_prior"]:
        assert got["mechanistic"][name]["stderr"] is None
    assert got["kienzle_identifiability"]["rank"] == 1
    assert "left near the prior" in capsys.readouterr().err
    tool = Tool(diameter_mm=D, flutes=FLUTES, helix_deg=30)
    fitted = Material.load(mat).force_model("mechanistic")
    catalogue = Material.load("steel1045").force_model("mechanistic")
    for ap, measured in zip(DEPTHS[1:], slots[1:]):
        eng = given_cut(tool, D, ap)
        pred = fitted.predict(eng, FZ, RPM, tool, peaks=False).force_N[0]
        cat = catalogue.predict(eng, FZ, RPM, tool, peaks=False).force_N[0]
        big = np.abs(measured) > 0.1 * np.linalg.norm(measured)
        err = np.abs(pred / measured - 1)[big]
        print(f"ap {ap}: fitted error per component {np.round(100 * err, 2)} %, catalogue "
              f"{np.round(100 * np.abs(cat / measured - 1)[big], 1)} %")
        assert err.max() < 0.12, (ap, pred, measured)
        assert np.abs(cat / measured - 1)[big].max() > 0.3   # the prior alone does not


def test_sign_flipped_channel_is_refused(tmp_path, slots, capsys):
    """A table whose y force is the workpiece's (the sign flipped) is a frame error, said so, exit 2."""
    flipped = slots * np.array([1.0, -1.0, 1.0])
    _table(tmp_path / "flip.csv", [(ap, f) for ap, f in zip(DEPTHS, flipped)])
    assert main(["calibrate", "fit", "--cuts", str(tmp_path / "flip.csv"), "--material", "steel1045"]) == 2
    err = capsys.readouterr().err
    assert "measured y forces run against the model" in err and "sign or frame" in err


def test_three_depths_without_a_prior_fit_or_say_what_is_missing(tmp_path, slots, capsys):
    """Three depths at one feed are still one chip thickness: with no prior (--prior-spread inf) the
    data cannot separate cutting from edge coefficients, and the fit says so instead of guessing."""
    _table(tmp_path / "three.csv", [(ap, f) for ap, f in zip(DEPTHS, slots)])
    assert main(["calibrate", "fit", "--cuts", str(tmp_path / "three.csv"), "--material", "steel1045",
                 "--prior-spread", "inf"]) == 2
    assert "do not determine every coefficient" in capsys.readouterr().err
