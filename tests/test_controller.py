"""Controller model against closed forms: trapezoids, junction deviation, lookahead, block rate."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_schedule import make_toolpath

from millpost.controller import ControllerModel, execute, to_blocks
from millpost.errors import ConfigError

A, F = 500.0, 50.0  # mm/s², mm/s


def trap(L, vin, vout, vmax, a):
    """Closed-form time of an accelerate–cruise–decelerate move (independent of the module)."""
    vp = min(math.sqrt((2 * a * L + vin**2 + vout**2) / 2), vmax)
    cruise = L - (vp**2 - vin**2) / (2 * a) - (vp**2 - vout**2) / (2 * a)
    return (vp - vin) / a + (vp - vout) / a + cruise / vp


def model(**kw):
    base = dict(max_rate_mm_s=(200.0, 200.0, 100.0), accel_mm_s2=(A, A, A))
    base.update(kw)
    return ControllerModel(**base)


def feed_tp(moves, feed=F * 60):
    tp = make_toolpath((0, 0, 0), moves)
    tp.feed_mm_min[:] = feed
    return tp


def test_single_line_is_the_trapezoid():
    ex = execute(feed_tp([("line", (100, 0, 0))]), model())
    assert ex.time_s == pytest.approx(100 / F + F / A, rel=1e-12)
    ex = execute(feed_tp([("line", (2, 0, 0))]), model())
    assert ex.time_s == pytest.approx(2 * math.sqrt(2 / A), rel=1e-12)


def test_collinear_split_costs_nothing():
    one = execute(feed_tp([("line", (100, 0, 0))]), model())
    split = execute(feed_tp([("line", (30, 0, 0)), ("line", (70, 0, 0)), ("line", (100, 0, 0))]), model())
    assert split.time_s == pytest.approx(one.time_s, rel=1e-12)


@pytest.mark.parametrize("delta", [0.01, 0.05])
def test_right_angle_junction_deviation(delta):
    tp = feed_tp([("line", (20, 0, 0)), ("line", (20, 20, 0))])
    ex = execute(tp, model(junction_deviation_mm=delta))
    # grbl: the direction change (−1, 1)/√2 allows √2·A; sin(θ/2) = sin 45°
    s = math.sin(math.pi / 4)
    vj = math.sqrt(math.sqrt(2) * A * delta * s / (1 - s))
    assert ex.v_entry[1] == pytest.approx(vj, rel=1e-9)
    assert ex.time_s == pytest.approx(trap(20, 0, vj, F, A) + trap(20, vj, 0, F, A), rel=1e-12)
    stop = execute(tp, model(exact_stop=True))
    assert stop.time_s == pytest.approx(2 * trap(20, 0, 0, F, A), rel=1e-12)


def test_lookahead_depth_limits_speed_on_short_blocks():
    l, n = 0.2, 400
    tp = feed_tp([("line", (l * (k + 1), 0, 0)) for k in range(n)], feed=200 * 60)
    for depth in (4, 16):
        ex = execute(tp, model(lookahead_blocks=depth))
        # in the middle the planner must be able to stop within `depth` blocks
        assert ex.v_entry[n // 2] == pytest.approx(min(200.0, math.sqrt(2 * A * depth * l)), rel=1e-9)


def test_block_rate_caps_speed_and_sample_speeds():
    l, n = 0.1, 300
    tp = feed_tp([("line", (l * (k + 1), 0, 0)) for k in range(n)], feed=200 * 60)
    ex = execute(tp, model(block_rate_hz=500.0, lookahead_blocks=1000))
    smp = tp.resample(0.05)
    v = ex.speed_at_samples(smp)
    mid = (smp.s_mm > 10) & (smp.s_mm < 20)
    np.testing.assert_allclose(v[mid], 50.0, rtol=1e-9)  # 0.1 mm × 500 /s
    # speeds at samples follow √(2 A s) from rest at the start
    early = smp.s_mm < 2.0
    np.testing.assert_allclose(v[early], np.sqrt(2 * A * smp.s_mm[early]), rtol=1e-9)


def test_arc_chords_follow_arc_tolerance():
    r, tol = 10.0, 0.002
    tp = feed_tp([("arc", (-r, 0, 0), (0, 0, 0), True)])
    tp.start[0] = (r, 0, 0)
    m = model(arc_tolerance_mm=tol)
    blk = to_blocks(tp, m)
    chord = 2 * math.sqrt(tol * (2 * r - tol))
    assert len(blk.move) == math.floor(math.pi * r / chord)
    np.testing.assert_allclose(np.linalg.norm(blk.end[:, :2], axis=1), r, rtol=1e-12)


def test_bad_model_is_a_config_error():
    with pytest.raises(ConfigError):
        ControllerModel((1.0, 1.0), (1.0, 1.0, 1.0))
    with pytest.raises(ConfigError):
        model(lookahead_blocks=0)
