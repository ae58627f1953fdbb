"""TOML field reading: unit conversion by the unit named in the key, range rules, unknown fields."""

from __future__ import annotations

import math

import pytest

from millpost.config import Table, quantity, resolve
from millpost.errors import ConfigError


def test_quantities_convert_to_the_unit_of_the_key():
    assert quantity("0.5 in", "mm", "f") == pytest.approx(12.7)
    assert quantity("3 mH", "H", "f") == pytest.approx(3e-3)
    assert quantity("1 hp", "W", "f") == pytest.approx(745.69987158)
    assert quantity("1000 SFM", "m_min", "f") == pytest.approx(304.8)
    assert quantity("100 mm/s", "mm_min", "f") == pytest.approx(6000)
    assert quantity("45 °", "deg", "f") == 45 and quantity(f"{math.pi} rad", "deg", "f") == pytest.approx(180)
    assert quantity(7, "mm", "f") == 7.0 and quantity("7", None, "f") == 7.0


@pytest.mark.parametrize("value, suffix, rule", [
    ("5 kg", "mm", "not a length unit"),
    ("5 mm", None, "dimensionless"),
    (True, "mm", "must be a number"),
    ("five", "mm", "'value unit'"),
    (float("nan"), "mm", "finite"),
    ([1, 2], "mm", "must be a number"),
])
def test_bad_quantities(value, suffix, rule):
    with pytest.raises(ConfigError) as err:
        quantity(value, suffix, "axes.x.lead_mm", file="m.toml")
    assert rule in err.value.rule and err.value.field == "axes.x.lead_mm" and err.value.file == "m.toml"


def test_table_rules_and_unknown_fields():
    t = Table({"lead_mm": "0.2 in", "n": 3, "speeds_m_min": [100, "1000 SFM"], "sub": {"a_mm": 1}}, "axis", "f.toml")
    assert t.number("lead_mm", gt=0) == pytest.approx(5.08)
    assert t.integer("n", ge=1, le=5) == 3
    assert t.numbers("speeds_m_min", length=2) == pytest.approx((100, 304.8))
    assert t.number("absent_mm", 2.5) == 2.5
    sub = t.table("sub")
    assert sub.name == "axis.sub" and sub.number("a_mm") == 1
    t.done()
    with pytest.raises(ConfigError, match="must be >= 4 mm"):
        Table({"lead_mm": 3}).number("lead_mm", ge=4)
    with pytest.raises(ConfigError, match="must be in \\[1, 5\\]"):
        Table({"n": 9}).integer("n", ge=1, le=5)
    extra = Table({"lead_mm": 1, "mass_kg": 2})
    extra.number("lead_mm")
    with pytest.raises(ConfigError, match="unknown field.*did you mean 'moving_mass_kg'"):
        extra.done(("moving_mass_kg",))
    with pytest.raises(ConfigError, match="must be a table"):
        Table([1, 2], "axes")


def test_resolve_paths_and_names(tmp_path):
    assert resolve("materials", "al6061").name == "al6061.toml"
    p = tmp_path / "mine.toml"
    p.write_text("")
    assert resolve("materials", p) == p
    with pytest.raises(ConfigError, match="unknown machine"):
        resolve("machines", "nope")
