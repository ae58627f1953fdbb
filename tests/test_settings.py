"""`JobSettings`, the typed `[limits]` table: defaults, feed caps in mm/s, and the rules checked on
construction as well as on reading a job file (the job file's refusals are in test_safety.py)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from millpost.errors import ConfigError
from millpost.settings import RANGES, JobSettings


def test_feed_caps_read_in_mm_s_and_numbers_as_floats():
    s = JobSettings.from_table({"feed_max_mm_min": 3000, "air_feed_max_mm_min": 600, "tool_safety_factor": 3}, "j")
    assert (s.feed_max_mm_s, s.air_feed_max_mm_s, s.plunge_feed_max_mm_s) == (50.0, 10.0, None)
    assert isinstance(s.tool_safety_factor, float) and s.ds_mm == 0.1 and s.lower == "hard"


def test_rules_hold_on_construction_too():
    with pytest.raises(ConfigError, match=r"limits.ds_mm = 0: must be a number in \[0.001, 5\]"):
        replace(JobSettings(), ds_mm=0)
    with pytest.raises(ConfigError, match="limits.trust_cut_space"):
        JobSettings(trust_cut_space=None)
    assert RANGES["feed_step"] == (0.0, 1.0)


def test_the_first_bad_key_in_the_file_is_named():
    with pytest.raises(ConfigError, match=r"^j: limits.lower = 'x': hard or all$"):
        JobSettings.from_table({"lower": "x", "ds_mm": 0}, "j")
    with pytest.raises(ConfigError, match="unknown limit; known: deflection_mm, feed_max_mm_min"):
        JobSettings.from_table({"speed": 3}, "j")


@pytest.mark.parametrize("key,value", [("model", ["mechanistic"]), ("lower", {"hard": 1}), ("rpm", ["optimize"])])
def test_a_list_or_table_for_a_named_choice_is_refused_by_name(key, value):
    """A TOML list or table where a name is expected is a ConfigError naming the key, not a TypeError
    (a list is unhashable: testing it for membership in the plugin registry used to crash)."""
    with pytest.raises(ConfigError, match=rf"^j: limits.{key} = "):
        JobSettings.from_table({key: value}, "j")
