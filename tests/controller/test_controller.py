"""Controller model against closed forms: trapezoids, junction deviation, lookahead, block rate."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from toolpaths import make_toolpath

from millpost.controller import ControllerModel, GrblPlanner, LinuxCNCPlanner, Planner, execute, to_blocks
from millpost.errors import ConfigError
from millpost.machine import CONTROLLERS, Machine

A, F = 500.0, 50.0  # mm/s², mm/s


def trap(L, vin, vout, vmax, a):
    """Closed-form time of an accelerate–cruise–decelerate move (independent of the module)."""
    vp = min(math.sqrt((2 * a * L + vin**2 + vout**2) / 2), vmax)
    cruise = L - (vp**2 - vin**2) / (2 * a) - (vp**2 - vout**2) / (2 * a)
    return (vp - vin) / a + (vp - vout) / a + cruise / vp


def model(**kw):
    base = dict(max_rate_mm_s=(200.0, 200.0, 100.0), accel_mm_s2=(A, A, A), planner=GrblPlanner())
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
        ControllerModel((1.0, 1.0), (1.0, 1.0, 1.0), planner=GrblPlanner())
    with pytest.raises(ConfigError):
        model(lookahead_blocks=0)
    with pytest.raises(ConfigError):
        model(planner="linuxcnc")  # a planner object, not its name
    with pytest.raises(ConfigError):
        model(naive_cam_mm=0.05)  # grbl's planner merges nothing
    with pytest.raises(ConfigError):
        Planner.of_kind("haas")  # no planner runs that kind


@pytest.mark.parametrize("kind", CONTROLLERS)
def test_machine_kind_picks_the_planner(kind):
    """Every `[controller] kind` has a planner: grbl's for grbl, LinuxCNC's for the others."""
    router = Machine.load("hobby-router")
    machine = dataclasses.replace(router, controller=dataclasses.replace(router.controller, kind=kind,
                                                                         blend_tolerance_mm=0.02))
    ctl = ControllerModel.from_machine(machine)
    grbl = kind == "grbl"
    assert isinstance(ctl.planner, GrblPlanner if grbl else LinuxCNCPlanner)
    assert ctl.lookahead_blocks == (16 if grbl else 50)
    assert ctl.planner.runs_arcs_whole == ctl.planner.blends_corners == (not grbl)
    # only LinuxCNC's canon merges naive-CAM feeds: its startup G64 P sets the tolerance
    assert ctl.planner.merges_naive_cam == (kind == "linuxcnc")
    assert ctl.naive_cam_mm == (0.02 if kind == "linuxcnc" else 0.0)


# --- LinuxCNC's planner ---------------------------------------------------------------------------
# Cycle times LinuxCNC 2.9 itself gave for these two-line programs (the harness in ../shared/tools/lcnc at
# speed-up 1, axes of vmc-small: X/Y/Z 400/400/333.3 mm/s, 3000/2500/2500 mm/s²); the closed forms below
# reproduce them without LinuxCNC.
VMC = dict(max_rate_mm_s=(400.0, 400.0, 1000.0 / 3.0), accel_mm_s2=(3000.0, 2500.0, 2500.0), planner=LinuxCNCPlanner(),
           lookahead_blocks=50)
MEASURED = {"G0 X100": 0.517, "G0 X50 Y0 / G2 X50 Y0 I-50 J0 F12000": 2.150, "square 20 mm F6000 twice": 1.505,
            "100 rapid/feed stops": 3.716, "G0 X10 / M6 / G0 X20": 0.655, "sine relief F6000": 1.365,
            # `steps` programs (at speed-up 5): 2000 feeds of 0.5 µm along X at F60; 2000 zigzag feeds
            # of 5 µm in X and ±5 µm in Y at F300, merged (Q 10 µm) or not (Q 2 µm)
            "collinear Q0.01": 1.001, "zigzag Q0.01": 2.004, "zigzag Q0.002": 4.020,
            # `slot_into_ramp` (speed-up 5): a 5 mm slot of 0.05 mm feeds at F3000, a 4 mm ramp down 0.7 mm
            # of such feeds at F300 or F600, 4 mm more at the bottom at F3000, all under G64 P0.05 Q0.05
            "slot into ramp F300": 0.689, "slot into ramp F600": 0.477,
            # G61 (exact path) and G61.1 (exact stop), speed-up 5: "G1 X20 F6000 / Y20", and `right_angles`
            "G61 X20 Y20 F6000": 0.482, "G61.1 X20 Y20 F6000": 0.474,
            "G61 right angles F1500": 18.332, "G61 right angles F8000": 11.623, "G61.1 right angles F8000": 11.020}


def right_angles(mode: str, feed_mm_min: float, n: int = 200) -> str:
    """A staircase of n feeds of 2 mm, along X then Y in turn (every corner 90°), in the path mode `mode`."""
    lines = [f"G21 G90 G17 {mode}", "G0 X0 Y0 Z1", f"G1 Z0 F{feed_mm_min:g}"]
    lines += [f"G1 X{2.0 * ((k + 2) // 2):.4f} Y{2.0 * ((k + 1) // 2):.4f}" for k in range(n)]
    return "\n".join(lines + ["G0 Z1", "M2"]) + "\n"


def steps(mode: str, n: int, step_mm: float, feed_mm_min: float, zig_mm: float = 0.0) -> str:
    """A program of n straight feeds of step_mm along X, Y going to zig_mm on the odd ones and back to 0
    on the even ones (a zigzag), after a rapid to the origin, in the path mode `mode`."""
    lines = [f"G21 G90 G17 {mode}", "G0 X0 Y0 Z0"]
    lines += [f"G1 X{i * step_mm:.4f} Y{zig_mm if i % 2 else 0.0:.4f} F{feed_mm_min:g}" for i in range(1, n + 1)]
    return "\n".join(lines + ["M2"]) + "\n"


def lcnc(**kw):
    return ControllerModel(**{**VMC, **kw})


def slot_into_ramp(slow_mm_min: float) -> str:
    """100 feeds of 0.05 mm along X (Y zigzagging by 1 µm) at F3000, 80 such feeds ramping down 0.7 mm
    (10°) at the slow feed, 80 more at the bottom at F3000, under G64 P0.05 Q0.05 (naive CAM's output)."""
    lines = ["G21 G90 G17 G64 P0.05 Q0.05", "G0 X0 Y0 Z0", "G1 X0.05 F3000"]
    lines += [f"X{0.05 + 0.05 * k:.4f} Y{0.001 * (k % 2):.4f}" for k in range(1, 100)]
    lines += [f"X{5 + 0.05 * k:.4f} Z{-0.7 * k / 80:.4f}" + (f" F{slow_mm_min:g}" if k == 1 else "")
              for k in range(1, 81)]
    lines += [f"X{9 + 0.05 * k:.4f} Y{0.001 * (k % 2):.4f} Z-0.7000" + (" F3000" if k == 1 else "")
              for k in range(1, 81)]
    return "\n".join(lines + ["M2"]) + "\n"


def test_linuxcnc_single_segment_runs_at_half_acceleration():
    # the last segment of the queue keeps its parabolic end: half the acceleration on all of it
    tp = make_toolpath((0, 0, 0), [("rapid", (100, 0, 0))])
    a = 1500.0
    t = 2 * math.sqrt(100 / a) + 0.0005  # triangle (400 mm/s not reached) + half a servo period at the stop
    assert execute(tp, lcnc()).time_s == pytest.approx(t, rel=1e-9)
    assert t == pytest.approx(MEASURED["G0 X100"], abs=0.002)


def test_linuxcnc_arc_at_half_tangential_acceleration():
    tp = make_toolpath((0, 0, 0), [("rapid", (50, 0, 0)), ("arc", (50, 0, 0), (0, 0, 0), False)])
    tp.feed_mm_min[:] = 12000.0
    # rapid to the arc: a stop (rapid -> feed), full 3000 mm/s²; the circle: plane acceleration 2500,
    # halved (last segment), half of it along the path; 200 mm/s under √(0.87·1250·50)
    t_rapid = 2 * math.sqrt(50 / 3000) + 0.0005
    a, v, L = 2500 * 0.5 * 0.5, 200.0, 2 * math.pi * 50
    t_arc = L / v + v / a + 0.0005
    assert math.sqrt(0.866 * 1250 * 50) > v
    assert execute(tp, lcnc()).time_s == pytest.approx(t_rapid + t_arc, rel=1e-9)
    assert t_rapid + t_arc == pytest.approx(MEASURED["G0 X50 Y0 / G2 X50 Y0 I-50 J0 F12000"], abs=0.002)


def test_linuxcnc_blend_arcs_and_stops_match_linuxcnc():
    sq = [("line", p) for p in [(20, 0, 0), (20, 20, 0), (0, 20, 0), (0, 0, 0)] * 2]
    assert execute(feed_tp(sq, 6000), lcnc()).time_s == pytest.approx(MEASURED["square 20 mm F6000 twice"], abs=0.003)
    moves = []
    for k in range(50):
        moves += [("rapid", (2 * k + 1, 0, 0)), ("line", (2 * k + 2, 0, 0))]
    tp = make_toolpath((0, 0, 0), moves)
    tp.feed_mm_min[:] = 6000.0
    assert execute(tp, lcnc()).time_s == pytest.approx(MEASURED["100 rapid/feed stops"], abs=0.005)


def test_linuxcnc_blend_speed_is_the_arc_within_tolerance():
    # a right-angle corner between long lines: the blend arc deviates at most P from the corner, so its
    # radius is P·tan45°/(1/sin45° − 1)·… (blendComputeParameters) and its speed √(0.87·a·R)
    tp = feed_tp([("line", (100, 0, 0)), ("line", (100, 100, 0))], 3000 * 60)
    tol = 0.05
    ex = execute(tp, lcnc(blend_tolerance_mm=tol))
    theta = math.pi / 4
    d = math.cos(theta) * tol / (1 - math.sin(theta))
    r = math.tan(theta) * d
    v = math.sqrt(math.sqrt(0.75) * 2500 * r)  # a in the XY plane: the weaker of X and Y
    assert ex.vnom[1] == pytest.approx(v, rel=1e-9)
    assert ex.length[1] + ex.length[2] == pytest.approx(r * math.pi / 2, rel=1e-9)  # its halves on each line


def test_linuxcnc_short_rests_run_as_the_blend_arcs_lead_in():
    # a 3-D raster row as CAM writes it: 0.32 mm X steps, Z on a 0.008 mm grid following a relief (sine,
    # 3 mm amplitude, 0.6·2π mm period) at F6000. Between the blend arcs most lines keep rests of
    # 0.01-0.3 mm, shorter than 4 servo periods at the arcs' 25-95 mm/s: LinuxCNC drops them from the
    # queue and runs them as the next arc's straight lead-in, at the arc's speed and acceleration (with
    # the lines' own acceleration and speed the model was 5 % fast here)
    x, moves = 2.0, [("line", (2.0, 0, 0))]
    for _ in range(60):
        x += 0.32
        moves.append(("line", (x, 0, round(3.0 * math.sin(x / 0.6) / 0.008) * 0.008)))
    moves.append(("line", (x + 2, 0, moves[-1][1][2])))
    ex = execute(feed_tp(moves, 6000), lcnc())
    assert ex.time_s == pytest.approx(MEASURED["sine relief F6000"], abs=0.003)
    # every move a block of its own and each of the 61 arcs two halves, less the rests that joined an arc
    consumed = 3 * len(moves) - 2 - len(ex.length)
    assert consumed > len(moves) / 2


def test_pauses_add_their_time_and_stop_the_motion():
    from millpost.controller import pauses_s, program_time
    from millpost.gcode import read_text

    prog = read_text("G21 G90\nG0 X10\nT2 M6\nG0 X20\nG4 P1.5\nM8\nG0 X30\nM2\n")
    m = lcnc(tool_change_s=0.33, coolant_s=0.01)
    p = pauses_s(prog, m)
    assert np.nansum(p) == pytest.approx(0.33 + 1.5 + 0.01)
    one = 2 * math.sqrt(10 / 1500) + 0.0005  # each 10 mm rapid alone, at half acceleration
    assert program_time(prog, m) == pytest.approx(3 * one + 0.33 + 1.5 + 0.01, rel=1e-9)
    assert program_time(read_text("G21 G90\nG0 X10\nT2 M6\nG0 X20\nM2\n"), lcnc(tool_change_s=0.33)) == \
        pytest.approx(MEASURED["G0 X10 / M6 / G0 X20"], abs=0.02)


def test_exact_path_stops_at_corners():
    """G61 stops at every corner that is not tangent, and LinuxCNC's kink check (tcSetKinkProperties)
    has taken 10 % of both segments' acceleration there all the same; G61.1 stops without it. Neither
    halves the last segment's acceleration (that is G64's parabolic end)."""
    from millpost.controller import program_time
    from millpost.gcode import read_text

    blend = program_time(read_text("G21 G90 G1 X20 F6000\nY20\nM2\n"), lcnc())
    exact = program_time(read_text("G21 G90 G61 G1 X20 F6000\nY20\nM2\n"), lcnc())
    stop = program_time(read_text("G21 G90 G61.1 G1 X20 F6000\nY20\nM2\n"), lcnc())
    # two moves from rest to rest at 100 mm/s, each ending half a servo period late
    t_stop = 20 / 100 + 100 / 3000 + 0.0005 + 20 / 100 + 100 / 2500 + 0.0005
    t_exact = 20 / 100 + 100 / 2700 + 0.0005 + 20 / 100 + 100 / 2250 + 0.0005
    assert stop == pytest.approx(t_stop, rel=1e-9)
    assert exact == pytest.approx(t_exact, rel=1e-9)
    assert t_stop == pytest.approx(MEASURED["G61.1 X20 Y20 F6000"], abs=0.001)
    assert t_exact == pytest.approx(MEASURED["G61 X20 Y20 F6000"], abs=0.001)
    assert blend < stop


@pytest.mark.parametrize("mode, feed", [("G61", 1500), ("G61", 8000), ("G61.1", 8000)])
def test_right_angles_in_exact_modes_match_linuxcnc(mode, feed):
    """200 corners of 90° at a stop each: G61's kink share costs LinuxCNC 0.6 s at F8000 over G61.1
    (the model without it was 4.9 % short of LinuxCNC there, 3 % short on CAMotics' tiny_cat optimized)."""
    from millpost.controller import program_time
    from millpost.gcode import read_text

    t = program_time(read_text(right_angles(mode, feed)), lcnc())
    assert t == pytest.approx(MEASURED[f"{mode} right angles F{feed}"], rel=0.005)


def test_canned_cycle_moves_run_in_exact_path():
    from millpost.controller import EXACT_PATH, path_modes, program_time
    from millpost.gcode import read_text

    # LinuxCNC's convert_cycle sets G61 for a cycle's moves after the climb to R and restores the mode:
    # the rapid from one hole to the next and the rapid down to R stop between them
    prog = read_text("G21 G90 G64 P0.1\nG0 X0 Y0 Z10\nG98 G81 X10 Y0 Z-2 R2 F600\nX20\nG80\nG1 X30 F600\nY10\nM2\n")
    modes = path_modes(prog, lcnc())
    cycle = (prog.toolpath.line == 3) | (prog.toolpath.line == 4)
    assert (modes.blend_mm[cycle] == EXACT_PATH).all() and (modes.blend_mm[~cycle] == 0.1).all()
    assert (modes.merge_mm[cycle] == 0.0).all() and (modes.merge_mm[~cycle] == 0.1).all()  # G64 P sets Q
    # the same as the cycle written between G61 and G64 P0.1: every move of a hole from rest to rest
    explicit = read_text("G21 G90 G64 P0.1\nG0 X0 Y0 Z10\nG61\nG98 G81 X10 Y0 Z-2 R2 F600\nX20\nG80\nG64 P0.1\n"
                         "G1 X30 F600\nY10\nM2\n")
    assert program_time(prog, lcnc()) == pytest.approx(program_time(explicit, lcnc()), rel=1e-12)
    blended = read_text("G21 G90 G64 P0.1\nG0 X0 Y0 Z10\nG0 X10 Y0\nZ2\nG1 Z-2 F600\nG0 Z10\nX20\nZ2\nG1 Z-2\n"
                        "G0 Z10\nG1 X30 F600\nY10\nM2\n")  # the same moves outside a cycle: corners blended
    assert program_time(blended, lcnc()) < program_time(prog, lcnc()) - 0.005


def test_blend_zones_bound_the_blend_arc_at_any_feed():
    from millpost.controller import PathModes, blend_zones, execute

    tol = 0.05
    tp = feed_tp([("line", (100, 0, 0)), ("line", (100, 100, 0)), ("rapid", (0, 100, 0))], 3000 * 60)
    ctl = lcnc(blend_tolerance_mm=tol)
    (a, b, v_top), = blend_zones(tp, ctl, PathModes.uniform(len(tp), ctl))  # none at the rapid
    theta = math.pi / 4
    d = math.cos(theta) * tol / (1 - math.sin(theta))  # blendComputeParameters: within P of the corner
    assert a == pytest.approx(100 - d, rel=1e-12) and b == pytest.approx(100 + d, rel=1e-12)
    assert v_top == pytest.approx(math.sqrt(math.sqrt(0.75) * 2500 * math.tan(theta) * d), rel=1e-12)
    for f_in, f_out in [(180000, 60), (60, 180000), (6000, 600)]:  # the arc runs at the faster feed
        tp.feed_mm_min[:2] = f_in, f_out
        ex = execute(tp, ctl)
        arc = ex.move[1:3] == [0, 1]
        assert arc.all() and ex.length[1] <= d + 1e-12 and ex.length[2] <= d + 1e-12
        assert ex.vnom[1] == pytest.approx(min(v_top, max(f_in, f_out) / 60), rel=1e-9)
        # the execution's own arc: within the zone, its top the highest speed the blocks reach there
        (a1, b1, v1), = ex.blends
        assert a - 1e-9 <= a1 < 100 < b1 <= b + 1e-9 and 100 - a1 == pytest.approx(b1 - 100, rel=1e-9)
        assert v1 <= ex.vnom[1] * (1 + 1e-12)
        x = np.linspace(0, 1, 201)
        inside = np.r_[ex.speed_at(np.zeros(201, int), 1 - x * ex.length[1] / 100),
                       ex.speed_at(np.ones(201, int), x * ex.length[2] / 100)]
        assert inside.max() <= v1 * (1 + 1e-9) and inside.max() >= v1 * 0.98
    assert blend_zones(tp, model(), PathModes.uniform(len(tp), model())).shape == (0, 3)  # grbl: never above
    # the slower block's feed
    assert execute(tp, model()).blends.shape == (0, 3)


def test_blend_limit_lowers_both_sides_of_a_fast_corner():
    from millpost.controller import PathModes, blend_zones
    from millpost.emit import blend_excess, blend_limit

    tp = feed_tp([("line", (10, 0, 0)), ("line", (10, 10, 0))], 600)
    smp = tp.resample(0.1)
    ctl = lcnc(blend_tolerance_mm=0.05)
    zones = blend_zones(tp, ctl, PathModes.uniform(len(tp), ctl))
    limit = np.where(smp.move == 0, 100.0, 5.0)  # a heavy cut after the corner, a light one before
    out = blend_limit(smp, limit, zones)
    d = (zones[0][1] - zones[0][0]) / 2
    near = np.abs(smp.s_mm - 10.0) <= d + 0.1 + 1e-9  # the zone and the next sample on each side
    assert (out[near] == 5.0).all() and (out[~near] == limit[~near]).all()
    assert len(blend_excess(smp, limit, zones)) == 1 and len(blend_excess(smp, out, zones)) == 1
    slow = np.r_[zones[0][:2], 4.0]  # an arc no faster than the slow side needs nothing
    assert (blend_limit(smp, limit, [slow]) == limit).all() and len(blend_excess(smp, limit, [slow])) == 0
    # widened by its length on either side: three times as long; checked against another limit
    wide = blend_limit(smp, limit, zones, widen=1.0)
    assert ((np.abs(smp.s_mm - 10.0) <= 3 * d) <= (wide == 5.0)).all()
    assert (blend_limit(smp, limit, zones, within=np.full(len(smp), 7.0)) == np.minimum(limit, np.where(near, 7.0,
                                                                                                       np.inf))).all()


def test_run_limit_lowers_the_whole_run_a_zone_lies_on():
    from millpost.emit import run_limit

    tp = feed_tp([("line", (10, 0, 0)), ("line", (20, 0, 0)), ("line", (30, 0, 0))], 600)
    smp = tp.resample(0.5)
    limit = np.where(smp.move == 1, 20.0, 50.0)
    rest = np.flatnonzero(np.isclose(smp.s_mm, 10.0))[-1]  # a stop at the first corner: two runs
    limit[rest] = 0.0
    within = limit.copy()
    within[smp.s_mm > 25.0] = 8.0  # the limit the arcs keep: lowest near the end
    out = run_limit(smp, limit, [(21.0, 22.0, 40.0)], within)
    second = smp.s_mm > 10.0
    assert (out[second] == 8.0).all() and (out[~second] == limit[~second]).all()


def test_corner_speeds_bound_what_linuxcnc_runs_at_any_feed():
    from millpost.controller import PathModes, blend_zones, corner_speeds, execute

    tp = feed_tp([("line", (50, 0, 0)), ("line", (100, 0, 0)), ("line", (100, 50, 0)), ("line", (99.9, 100, 0)),
                  ("rapid", (0, 100, 0))], 6000)
    ctl = lcnc(blend_tolerance_mm=0.05)
    cap = corner_speeds(tp, ctl)
    zones = blend_zones(tp, ctl, PathModes.uniform(len(tp), ctl))
    assert cap[1] == np.inf and cap[4] == 0.0 and cap[0] == cap[5] == np.inf  # collinear; feed -> rapid stops
    assert cap[2] == pytest.approx(zones[0][2], rel=1e-12)  # the right angle: its blend arc
    # the slight bend (0.11°): the faster of the tangent kink (the velocity jump in one servo period within
    # 10 % of the acceleration) and the blend arc, here the arc
    u0, u1 = np.array([0.0, 1.0, 0.0]), np.array([-0.1, 50.0, 0.0]) / math.hypot(0.1, 50.0)
    kink = 0.1 * 0.001 / np.max(np.abs(u1 - u0) / [3000.0, 2500.0, 2500.0])
    assert cap[3] == pytest.approx(max(kink, zones[1][2]), rel=1e-12) and cap[3] > kink
    # with a naive-CAM tolerance the canon layer merges straight feeds into lines that depend on the feeds
    # written (here the bend, its corner 0.04999 mm off the chord, into one line at 0.05 mm): such a
    # corner is not sure to slow the tool; the right angle (35 mm off any line through its three points)
    # is never merged and keeps its blend arc; the stop before the rapid still is
    merged = corner_speeds(tp, lcnc(blend_tolerance_mm=0.05, naive_cam_mm=0.05))
    assert merged[1] == merged[3] == np.inf and merged[2] == cap[2] and merged[4] == 0.0
    for feed in (600, 6000, 60000):
        tp.feed_mm_min[:4] = feed
        ex = execute(tp, ctl)
        for j in (2, 3):  # the speed where the corner's blocks meet never exceeds the cap
            k = np.flatnonzero(ex.move == j - 1)[-1]
            assert ex.v_entry[k] <= cap[j] * (1 + 1e-9) and ex.v_entry[k + 1] <= cap[j] * (1 + 1e-9)


def chain_sizes(text: str) -> list[int]:
    """The number of feeds in each chain LinuxCNC's canon merges in this program (rapids left out)."""
    from millpost.controller import naive_cam_chains, path_modes
    from millpost.gcode import read_text
    from millpost.toolpath import FEED

    prog = read_text(text)
    first = naive_cam_chains(prog.toolpath, path_modes(prog, lcnc()))[prog.toolpath.kind == FEED]
    return np.unique(first, return_counts=True)[1].tolist()


def test_naive_cam_merges_straight_feeds_within_q():
    # emccanon's linkable: every point of a chain within Q of the line from its start to its newest
    # point, at most 101 points; Q defaults to P, a plain G64 and G61 merge nothing
    assert chain_sizes(steps("G64 P0.01 Q0.01", 250, 0.0005, 60)) == [101, 101, 48]
    assert chain_sizes(steps("G64 P0.01", 250, 0.0005, 60)) == [101, 101, 48]
    for mode in ("G64 P0.01 Q0", "G64", "G61", "G61.1"):
        assert chain_sizes(steps(mode, 250, 0.0005, 60)) == [1] * 250
    # a zigzag of ±5 µm: within Q = 10 µm of the chord, not within 4 µm
    assert chain_sizes(steps("G64 P0.01 Q0.01", 250, 0.005, 300, zig_mm=0.005)) == [101, 101, 48]
    assert chain_sizes(steps("G64 P0.01 Q0.004", 250, 0.005, 300, zig_mm=0.005)) == [1] * 250
    # in a G20 program everything is inches: Q 0.0004 in holds a zigzag of 0.0003 in, not one of 0.0005 in
    assert chain_sizes(steps("G64 P0.0004", 6, 0.0002, 10, zig_mm=0.0003).replace("G21", "G20")) == [6]
    assert chain_sizes(steps("G64 P0.0004", 6, 0.0002, 10, zig_mm=0.0005).replace("G21", "G20")) == [1] * 6


def test_block_lengths_are_the_merged_chains():
    # the planner receives a chain of 101 collinear 0.5 µm feeds as one line of 50.5 µm, so a block rate
    # of 2000 Hz caps it at 101 mm/s, not at the 1 mm/s of one move; a controller that merges nothing,
    # and a G64 with Q0, leave each move its own block
    from millpost.controller import block_lengths, path_modes
    from millpost.gcode import read_text
    from millpost.toolpath import FEED

    def lengths(text: str, model) -> np.ndarray:
        prog = read_text(text)
        return block_lengths(prog.toolpath, path_modes(prog, model))[prog.toolpath.kind == FEED]

    merged = lengths(steps("G64 P0.01 Q0.01", 250, 0.0005, 60), lcnc())
    np.testing.assert_allclose(merged, [101 * 0.0005] * 202 + [48 * 0.0005] * 48, rtol=1e-9)
    unmerging = lcnc(planner=LinuxCNCPlanner(merges_naive_cam=False))
    for text, model in ((steps("G64 P0.01 Q0.01", 250, 0.0005, 60), unmerging),
                        (steps("G64 P0.01 Q0", 250, 0.0005, 60), lcnc())):
        np.testing.assert_allclose(lengths(text, model), 0.0005, rtol=1e-9)
    # a zigzag's chain is its chord: 101 steps of 5 µm along X, ending at Y 5 µm
    zig = lengths(steps("G64 P0.01 Q0.01", 250, 0.005, 300, zig_mm=0.005), lcnc())
    assert zig[0] == pytest.approx(math.hypot(101 * 0.005, 0.005), rel=1e-9)


def test_naive_cam_chain_ends_where_canon_flushes():
    head = "G21 G90 G64 P0.01\nG0 X0 Y0 Z0\nG1 X1 F600\n"
    assert chain_sizes(head + "X2\nX3\nM2\n") == [3]
    assert chain_sizes(head + "X2 F500\nX3\nM2\n") == [1, 2]  # a new feed rate
    assert chain_sizes(head + "X2 F600\nX3\nM2\n") == [3]  # the same feed rate again
    assert chain_sizes(head + "(a note)\nX2\nX3\nM2\n") == [3]
    for command in ("(MSG, hello)", "M8", "G4 P0", "S1000", "G64 P0.01", "G54"):
        assert chain_sizes(head + f"{command}\nX2\nX3\nM2\n") == [1, 2], command
    assert chain_sizes(head + "G2 X3 R1\nG1 X4\nX5\nM2\n") == [1, 2]  # an arc
    assert chain_sizes(head + "X0\nM2\n") == [1, 1]  # back to the chain's start
    assert chain_sizes(head + "X0.5\nM2\n") == [1, 1]  # a reversal: X1 lies beyond the new end


def test_blend_arc_of_merged_lines_carries_the_fast_feed_into_the_slow_one():
    # the canon layer merges the slot and the ramp into lines of up to 101 points: the blend arc between the
    # slot's line and the ramp's (a 10° turn: within P 0.05 mm of the corner it may reach 1.1 mm into each)
    # reaches 1 mm into the ramp at the slot's 50 mm/s; LinuxCNC ran both programs as the model does, over
    # a third faster than blend arcs per programmed move (reaching at most 12 µm) would let it
    from millpost.controller import execute_program
    from millpost.gcode import read_text

    for slow in (300, 600):
        program = read_text(slot_into_ramp(slow))
        ex = execute_program(program, lcnc())
        assert ex.time_s == pytest.approx(MEASURED[f"slot into ramp F{slow}"], rel=0.005)
        a, b, top = ex.blends[0]
        assert a == pytest.approx(5.0 - 1.0, abs=0.01) and b == pytest.approx(5.0 + 1.0, abs=0.01) and top == 50.0
        unmerged = execute_program(program, lcnc(planner=LinuxCNCPlanner(merges_naive_cam=False)))
        assert unmerged.time_s > 1.35 * ex.time_s and (np.diff(unmerged.blends[:, :2], axis=1) < 0.08).all()


def test_naive_cam_chain_runs_as_one_line():
    from millpost.controller import execute_program, program_time
    from millpost.gcode import read_text

    # 2000 feeds of 0.5 µm merged into 20 collinear lines: 1 mm at 1 mm/s from rest to rest (the first
    # line at full X acceleration, the last one's half), each alone would last at least 1.02 servo periods
    merged = read_text(steps("G64 P0.01 Q0.01", 2000, 0.0005, 60))
    t = 1.0 / 1.0 + 0.5 / 3000 + 0.5 / 1500 + 0.0005
    assert program_time(merged, lcnc()) == pytest.approx(t, rel=1e-6)
    assert t == pytest.approx(MEASURED["collinear Q0.01"], abs=0.002)
    assert program_time(read_text(steps("G64 P0.01 Q0", 2000, 0.0005, 60)), lcnc()) > 2000 * 1.02e-3
    # the merged lines are cut where each move ends: the tool passes the end of move 127 (63.5 µm) at
    # 63.5 ms after the acceleration's 1/6000 s lag
    ex = execute_program(merged, lcnc())
    assert ex.time_at(np.array([127]), np.array([1.0]))[0] == pytest.approx(0.0635 + 1 / 6000, rel=1e-9)
    assert ex.speed_at(np.array([127]), np.array([0.5]))[0] == pytest.approx(1.0, rel=1e-12)
    assert ex.time_s == pytest.approx(ex.block_time_s.sum(), rel=1e-12) and (np.diff(ex.move) >= 0).all()
    for text, key in ((steps("G64 P0.01 Q0.01", 2000, 0.005, 300, zig_mm=0.005), "zigzag Q0.01"),
                      (steps("G64 P0.01 Q0.002", 2000, 0.005, 300, zig_mm=0.005), "zigzag Q0.002")):
        assert program_time(read_text(text), lcnc()) == pytest.approx(MEASURED[key], rel=0.005), key


def test_compiled_blend_math_squares_as_python_does():
    """The planner's kernels square with libm's pow(x, 2.0), as Python's x ** 2 does (the queue the
    pure-Python planner built, and so the programs written, stay bit-identical): for this x, pow and
    x·x differ in the last bit, and so does the plane's inscribed rate 100 / √(1 − x²)."""
    from millpost.controller.segments import SQUARE, inscribed

    x = 0.8040251668887082
    python = 100.0 / math.sqrt(1.0 - x**2)
    assert python != 100.0 / math.sqrt(1.0 - x * x)  # the case tells the two apart
    assert inscribed(np.array([x, 0.0, 0.0]), np.array([100.0, 1e9, 1e9]), SQUARE) == python


def test_sample_fractions_by_arc_length_along_each_move():
    from types import SimpleNamespace

    from millpost.controller import Execution

    # move 0: samples at 0, 1, 4 mm; move 1 continues from 4 mm to 6 and 10 mm; move 2 starts a segment
    # of its own at 10 mm (its first sample is its start); move 3 has no length
    s = np.array([0.0, 1.0, 4.0, 6.0, 10.0, 10.0, 12.0, 14.0, 14.0])
    samples = SimpleNamespace(s_mm=s, move=np.array([0, 0, 0, 1, 1, 2, 2, 2, 3]),
                              segment_start=np.array([True, False, False, False, False, True, False, False, False]))
    assert Execution.sample_fractions(samples).tolist() == [0.0, 0.25, 1.0, 2 / 6, 1.0, 0.0, 0.5, 1.0, 1.0]
