"""Material library: built-ins load and carry their cited values; bridges and guidance match PHYSICS.md;
bad files give errors that name field, value and rule."""

from __future__ import annotations

import copy
import tomllib

import numpy as np
import pytest

from millpost.config import builtin_names, resolve
from millpost.engagement import Engagement
from millpost.errors import ConfigError
from millpost.materials import Material
from millpost.tools.cutter import Tool

NAMES = ["al6061", "al7075", "brass", "mdf", "plywood", "pom", "ss304", "steel1045", "ti6al4v"]


def test_builtin_library_is_complete_and_sourced():
    assert builtin_names("materials") == NAMES
    for name in NAMES:
        m = Material.load(name)
        assert m.name == name
        assert m.kienzle.source and m.speed_source and m.chip_source and m.min_chip_source
        lo, hi = m.chip_load_mm(10)
        assert 0 < lo <= hi


def test_iscar_values_are_those_of_physics_table():
    # PHYSICS.md §2.2 rows 22, 2, 14, 37 (2017), 27
    expect = {"al7075": (800, 0.25), "steel1045": (1500, 0.22), "ss304": (2150, 0.20), "ti6al4v": (2110, 0.22),
              "brass": (700, 0.27)}
    for name, (kc, mc) in expect.items():
        k = Material.load(name).kienzle
        assert (k.kc11_N_mm2, k.mc) == (kc, mc)


def test_wood_cutting_force_is_ettelts_law():
    """Wood and MDF cut by Ettelt's law F_c = k·b·√h (Zerspanung von Holz und Holzwerkstoffen, 2nd ed. 2023,
    p. 120): MDF k = 20–25, beech 26–40 and oak 22–44 N/mm^1.5 (crosscut, the toughest direction). A slot
    with a 1.4 mm 2-flute bit, 1 mm deep at 0.1 mm a tooth (Fusion's ledfloor program, which its author
    ran in plywood) then takes a mean tangential force of k·b·∫√(f_z sin φ)dφ/2π·z ≈ 10 N: well
    under the ~39 N the beam model allows that bit, as the program's survival says."""
    for name, (lo, hi) in {"mdf": (20, 25), "plywood": (22, 44)}.items():
        k = Material.load(name).kienzle
        assert k.mc == 0.5 and lo <= k.kc11_N_mm2 <= hi
        assert k.kc11_N_mm2 * 0.1 ** (1 - k.mc) == pytest.approx(k.kc11_N_mm2 * np.sqrt(0.1))
    model = Material.load("plywood").force_model("kienzle")
    eng = Engagement.uniform([0.0], [np.pi], 1.0, 0.7)
    torque_Nm = model.predict(eng, 0.1, 5000, Tool(diameter_mm=1.4, flutes=2)).torque_Nm[0]
    # ∫₀^π √(sin φ) dφ = 2.3963 (Γ(3/4)/Γ(5/4)·√π); mean F_t = 2 flutes·42·1·√0.1·2.3963/(2π)
    assert torque_Nm / 0.7e-3 == pytest.approx(2 * 42 * np.sqrt(0.1) * 2.396280 / (2 * np.pi), rel=2e-3)
    assert torque_Nm / 0.7e-3 < 15


def test_al7075_mechanistic_set_reproduces_slot_oracle():
    model = Material.load("al7075").force_model("mechanistic")
    eng = Engagement.uniform([0.0], [np.pi], 5.0, 19.05 / 2)
    loads = model.predict(eng, 0.1, 6000, Tool(diameter_mm=19.05, flutes=4))
    np.testing.assert_allclose(loads.force_feed_N[0], [-253.741, 559.849, 148.330], atol=1e-3)


def test_kienzle_tangent_bridge_oracle():
    # PHYSICS.md §2.3: tangent at h0 = 0.05 mm of 1500/0.22 → K_tc 2261.58 N/mm², K_te 31.894 N/mm
    steel = Material.load("steel1045")
    assert steel.mechanistic is None
    k = steel.force_model("mechanistic", h0_mm=0.05).coef_
    assert k[0] == pytest.approx(2261.58, abs=0.01)
    assert k[3] == pytest.approx(31.894, abs=1e-3)
    assert k[1] == pytest.approx(0.30 * k[0]) and k[5] == pytest.approx(0.29 * k[3])


def _al_data() -> dict:
    with open(resolve("materials", "al6061"), "rb") as fh:
        return tomllib.load(fh)


def test_rpm_window_and_chip_interpolation():
    data = _al_data()
    data["surface_speed"]["carbide_m_min"] = [300, 300]
    m = Material.from_dict(data)
    assert m.rpm_window(10)[0] == pytest.approx(9549.3, abs=0.1)          # PHYSICS.md §3.2
    assert m.chip_load_mm(9) == pytest.approx((0.075, 0.105))             # midway 7 → 11 mm
    assert m.chip_load_mm(3) == pytest.approx((0.06 * 3 / 7, 0.09 * 3 / 7))  # below 7 mm: ∝ D
    assert m.chip_load_mm(30) == pytest.approx((0.12, 0.15))              # above 18 mm: the last row
    assert m.min_chip_mm(0.006, 10.0) == pytest.approx(0.0018)


def test_min_chip_of_a_material_that_burns_follows_the_chip_load_table():
    """Wood scorches below the chart's smallest chip load: its minimum chip is the larger of the
    ploughing rule (ratio × edge radius) and the share of the table's minimum at the tool's diameter."""
    m = Material.load("mdf")
    lo = m.chip_load_mm(3.175)[0]  # 1/8 in bit: 0.102 mm
    assert lo == pytest.approx(0.102)
    assert m.min_chip_mm(0.005, 3.175) == pytest.approx(m.min_chip_fz_ratio * lo)
    assert m.min_chip_mm(0.005, 1.5875) == pytest.approx(m.min_chip_fz_ratio * lo / 2)  # ∝ D below 1/8 in
    assert Material.load("al6061").min_chip_mm(0.005, 3.175) == pytest.approx(0.3 * 0.005)  # metals: ploughing


@pytest.mark.parametrize("edit, field, rule", [
    (lambda d: d["kienzle"].update(kc11_N_mm2=-800), "kienzle.kc11_N_mm2", "must be >"),
    (lambda d: d["kienzle"].update(kc11_N_mm2="800 kg"), "kienzle.kc11_N_mm2", "not a specific cutting force"),
    (lambda d: d["kienzle"].update(mc=1.5), "kienzle.mc", "must be <"),
    (lambda d: d["kienzle"].pop("source"), "kienzle.source", "required"),
    (lambda d: d["mechanistic"].update(Ktc_N_m2=600), "mechanistic.Ktc_N_m2", "did you mean 'Ktc_N_mm2'"),
    (lambda d: d["chip_load"].update(fz_min_mm=[0.2, 0.2, 0.2]), "chip_load.fz_max_mm", "must be >="),
    (lambda d: d["surface_speed"].update(carbide_m_min=[900, 300]), "surface_speed.carbide_m_min", "[low, high]"),
])
def test_bad_material_descriptions(edit, field, rule):
    data = copy.deepcopy(_al_data())
    edit(data)
    with pytest.raises(ConfigError) as err:
        Material.from_dict(data, file="mine.toml")
    assert err.value.field == field and rule in err.value.rule
    assert str(err.value).startswith("mine.toml: ")


def test_units_in_strings_are_converted():
    data = _al_data()
    data["kienzle"]["kc11_N_mm2"] = "0.8 GPa"
    assert Material.from_dict(data).kienzle.kc11_N_mm2 == pytest.approx(800)


def test_unknown_material_and_bad_toml(tmp_path):
    with pytest.raises(ConfigError, match="unknown material.*al7075"):
        Material.load("unobtainium")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = \n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        Material.load(bad)
    with pytest.raises(ConfigError, match="file not found"):
        Material.load(tmp_path / "missing.toml")
