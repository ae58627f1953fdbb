"""The air clearance: a feed move that cuts nothing keeps its programmed feed in the shell of width
`air_clearance_mm` around the stock as loaded (the tool grown by c, radius R + c and tip c lower, meets
it and its tip disc is not inside it); farther away, and inside what the program cut, it is raised.
The per-sample flag (`Engagement.near_stock`) is checked against the closed-form distance of a
cylinder to a box, and end to end on a job whose approaches, far moves and pocket moves are known.
Air in space the tool swept before is known (`Engagement.swept_air`): checked on a disc of loops beside
the box (closed form) and against a brute-force union of the tool's earlier bodies."""

from __future__ import annotations

import numpy as np
import pytest

from millpost.engagement import simulate
from millpost.errors import ConfigError
from millpost.gcode import read_program, read_text
from millpost.job import load_job
from millpost.optimize import optimize
from millpost.replay import feed_at_samples
from millpost.stock import box
from millpost.toolpath import RAPID
from millpost.tools import Tool

import rs274_oracle

CLEAR = 3.0  # mm, the default
TOOL = Tool(diameter_mm=6.0, flutes=3, flute_length_mm=16.0, stickout_mm=24.0, number=1)
STOCK = ((0.0, 0.0, -10.0), (60.0, 40.0, 0.0))


def _box_distance_xy(xy: np.ndarray) -> np.ndarray:
    """Horizontal distance (mm) of points from the stock's rectangle (0 inside)."""
    (x0, y0, _), (x1, y1, _) = STOCK
    dx = np.maximum.reduce([x0 - xy[:, 0], np.zeros(len(xy)), xy[:, 0] - x1])
    dy = np.maximum.reduce([y0 - xy[:, 1], np.zeros(len(xy)), xy[:, 1] - y1])
    return np.hypot(dx, dy)


def test_near_stock_is_the_grown_tool_meeting_the_box():
    """Random air moves around an uncut box: near exactly where the closed form says the cylinder of
    radius R + c with its tip c lower meets the box (away from a cell of the boundary)."""
    rng = np.random.default_rng(7)
    lines = ["G21 G90 G94", "T1 M6", "S9000 M3"]
    R = TOOL.radius_mm
    while len(lines) < 600:
        x, y, z = rng.uniform(-15, 75), rng.uniform(-15, 55), rng.uniform(-6, 8)
        # only moves that cannot touch the box: tip above its top, or the tool beside it
        if z < 0.05 and _box_distance_xy(np.array([[x, y]]))[0] < R + 0.6:
            continue
        lines += ["G0 Z10", f"G0 X{x:.3f} Y{y:.3f}", f"G0 Z{z:.3f}", f"G1 X{x + 0.3:.3f} F500"]
    program = read_text("\n".join(lines) + "\nM30\n", "air.nc")
    samples = program.toolpath.resample(0.1)
    stock = box(*STOCK, cell_mm=0.05)
    eng = simulate(stock, {1: TOOL}, samples, clearance_mm=CLEAR, progress=False)
    feed = (samples.kind != RAPID) & (eng.ap_mm <= 1e-9)
    d = _box_distance_xy(samples.xyz_mm[:, :2])
    tip = samples.xyz_mm[:, 2] - CLEAR  # the grown tool's tip
    expect = (d <= R + CLEAR) & (tip < 0.0)
    clear_of_boundary = (np.abs(d - (R + CLEAR)) > 0.1) & (np.abs(tip) > 1e-3)
    sel = feed & clear_of_boundary
    assert sel.sum() > 300 and expect[sel].any() and (~expect[sel]).any()
    np.testing.assert_array_equal(eng.near_stock[sel], expect[sel])
    assert not eng.near_stock[samples.kind == RAPID].any()  # rapids: not asked


def _flags(lines: list[str]):
    """Samples and near flags of a program (header prepended) cut through the uncut box."""
    program = read_text("\n".join(["G21 G90 G94", "T1 M6", "S9000 M3", *lines, "M30"]) + "\n", "air.nc")
    samples = program.toolpath.resample(0.1)
    eng = simulate(box(*STOCK, cell_mm=0.05), {1: TOOL}, samples, clearance_mm=CLEAR, progress=False)
    return samples, eng


# a pocket X15..45 Y10..30 cleared to Z-5 (tool centre X18..42, Y13..27): zigzag, then its contour
POCKET = ["G0 X18 Y13 Z2", "G1 Z-5 F100", "G1 X42 F600", "Y17", "X18", "Y21", "X42", "Y25", "X18", "Y27", "X42",
          "Y13", "X18", "Y27", "X42"]


def test_air_in_a_cut_pocket_is_not_near():
    """The clearance guards the stock model, not the surfaces the program cut: air returns on the floor
    of the pocket, 0.5 mm over it and 0.5 mm from its walls (a trochoid's return), are not near; a
    re-plunge into it from above is near only while its tip is within c above the original top."""
    samples, eng = _flags(POCKET + ["G1 X30 Y20",                              # 19: back along the floor
                                    "G1 Z-4.5", "G1 X41.5 Y13.5",              # 20, 21: to a corner
                                    "G1 Y26.5",                                # 22: 0.5 mm from the wall X45
                                    "G1 X18.5",                                # 23: 0.5 mm from the wall Y30
                                    "G0 Z6", "G0 X30 Y20",
                                    "G1 Z-4 F100"])                            # 26: re-plunge from Z6
    z = samples.xyz_mm[:, 2]
    floor = np.isin(samples.line, (19, 20, 21, 22, 23))
    plunge = samples.line == 26
    assert floor.sum() > 400 and not eng.ap_mm[floor | plunge].any()
    assert not eng.near_stock[floor].any()
    # the grown tool's tip reaches the original top (Z0) below Z3; under Z0 the tip disc is inside it
    above = plunge & (z > 3.0 + 1e-6)
    shell = plunge & (z < 3.0 - 1e-6) & (z > 1e-6)
    below = plunge & (z < -1e-6)
    assert above.sum() > 20 and shell.sum() > 20 and below.sum() > 20
    assert not eng.near_stock[above].any() and eng.near_stock[shell].all() and not eng.near_stock[below].any()


def test_over_a_faced_top_only_the_original_sides_are_near():
    """After facing the top 1 mm down, air 0.5 mm over the faced surface (under the original top) is not
    near over the stock; moving off its side at that height it is near from where the tip disc leaves
    the original stock (the tool's axis R from the side X60) to R + c beyond it, up to a block's error."""
    face = ["G0 X-5 Y0 Z2", "G1 Z-1 F300"]
    for k, y in enumerate(range(0, 44, 4)):
        face += [f"G1 Y{y}", "G1 X65" if k % 2 == 0 else "G1 X-5"]
    samples, eng = _flags(face + ["G0 Z5", "G0 X30 Y20", "G1 Z-0.5 F300", "G1 X35 Y22",
                                  "G1 X30 Y20", "G1 X70 F600"])
    n = len(face) + 3  # the header's three lines, then the first line after the facing is line n + 1
    x, z = samples.xyz_mm[:, 0], samples.xyz_mm[:, 2]
    down = samples.line == n + 3  # from Z5 to Z-0.5: near from Z3 (c over the original top) to Z0
    inner = np.isin(samples.line, (n + 4, n + 5)) | (down & (z < -1e-6))
    off = samples.line == n + 6
    assert not eng.ap_mm[down | inner | off].any()
    assert not eng.near_stock[inner].any() and eng.near_stock[down & (z > 1e-6) & (z < 3.0 - 1e-6)].all()
    R, block = TOOL.radius_mm, 0.5 * np.sqrt(2)  # the snapshot's block: 10 × 10 cells of 0.05 mm
    assert not eng.near_stock[off & (x < 60 - R - block)].any()
    assert eng.near_stock[off & (x > 60 - R + 0.05) & (x < 60 + R + CLEAR - 0.05)].all()
    assert not eng.near_stock[off & (x > 60 + R + CLEAR + block)].any()


# a disc of radius 7 about C = (-7.5, 20) swept at Z-2 beside the box's -X face (air): a plunge, then
# circles of radius 1.5 and 4 about C (a tool of radius 3 sweeps the annuli 0..4.5 and 1..7)
LOOPS = ["G0 X-6 Y20 Z2", "G1 Z-2 F300", "G3 X-6 Y20 I-1.5 J0", "G1 X-3.5", "G3 X-3.5 Y20 I-4 J0"]


def test_air_the_tool_swept_beside_the_stock_is_known():
    """Returns whose tool lies inside the disc the loops swept are known air although they pass within c
    of the stock: the tool at |p - C| <= 3.35 (0.55 mm inside the disc, more than a cell's diagonal and
    half a step) and a re-plunge into it down to the swept level; one whose tool pokes 0.1 mm out of the
    disc (|p - C| >= 4.1), or that runs 0.1 mm under the swept level, is not known and stays near."""
    C = np.array([-7.5, 20.0])
    samples, eng = _flags(LOOPS + ["G1 X-4.5",                                  # 9: in to |p - C| = 3
                                   "G1 Y21.5", "G1 Y18.5",                      # 10, 11: returns inside
                                   "G1 X-3.4", "G1 Y21.5",                      # 12, 13: 0.1 mm out
                                   "G1 X-3.9493 Y22.05",                        # 14: to |p - C| = 4.1
                                   "G3 X-11.0507 Y22.05 I-3.5507 J-2.05",       # 15: 30° to 150° at 4.1
                                   "G0 Z5", "G0 X-4.5 Y20", "G1 Z-2.1",         # 18: re-plunge, 0.1 mm too low
                                   "G1 Y21"])                                   # 19: 0.1 mm under the level
    d = np.linalg.norm(samples.xyz_mm[:, :2] - C, axis=1)
    z = samples.xyz_mm[:, 2]
    line = samples.line
    assert not eng.ap_mm.any()  # all air beside the box, within c of its -X face
    inside = np.isin(line, (10, 11))
    outside = np.isin(line, (13, 15)) | ((line == 12) & (d >= 4.1))
    assert inside.sum() > 40 and outside.sum() > 60 and (d[outside] >= 4.1 - 1e-4).all()
    outside &= eng.near_stock  # the arc leaves the shell (|x - 0| > R + c) beyond 68°
    assert eng.near_stock[inside].all() and eng.near_stock[line == 13].all() and outside.sum() > 50
    assert eng.swept_air[inside].all() and not eng.swept_air[outside].any()
    plunge = line == 18
    shell = plunge & (z < 3.0 - 1e-6)  # near: the grown tool's tip below the box's top
    assert eng.near_stock[shell].all()
    assert eng.swept_air[shell & (z >= -1.9)].all() and not eng.swept_air[plunge & (z < -2.0 + 1e-9)].any()
    assert eng.near_stock[line == 19].all() and not eng.swept_air[line == 19].any()
    assert not eng.swept_air[~eng.near_stock].any()


def _covered(tool: Tool, p: np.ndarray, earlier: np.ndarray, spacing: float = 0.2) -> bool:
    """Brute force: whether the body of `tool` with its tip at p (everything over its cutting surface
    within its radius) lies in the union of its bodies at the tips `earlier`, on a grid of points of
    its disc: each point has an earlier tip within R whose surface there is no higher."""
    R = tool.radius_mm
    g = np.arange(-R, R + 1e-9, spacing)
    dx, dy = (a.ravel() for a in np.meshgrid(g, g))
    keep = np.hypot(dx, dy) <= R
    pts = np.column_stack([dx[keep], dy[keep]]) + p[:2]
    bottom = p[2] + tool.height_at(np.hypot(dx[keep], dy[keep]))
    near = earlier[np.linalg.norm(earlier[:, :2] - p[:2], axis=1) <= 2 * R]
    if not len(near):
        return False
    r = np.linalg.norm(pts[:, None, :] - near[None, :, :2], axis=2)
    surface = near[None, :, 2] + tool.height_at(r)  # inf beyond R
    return bool((surface.min(axis=1) <= bottom + 1e-9).all())


@pytest.mark.parametrize("tool", [TOOL, Tool(diameter_mm=6.0, flutes=2, shape="ball", flute_length_mm=16.0,
                                             stickout_mm=24.0, number=1),
                                  Tool(diameter_mm=6.0, flutes=2, shape="chamfer", tip_angle_deg=90.0,
                                       tip_diameter_mm=1.0, flute_length_mm=16.0, stickout_mm=24.0, number=1)],
                         ids=["flat", "ball", "chamfer"])
def test_known_air_lies_in_what_the_tool_swept(tool):
    """Sound against brute force: after the loops, a random walk of air moves at random heights beside
    the box; samples flagged `swept_air` next to one that is not (where an error would show) have their
    tool body (and, when the next sample is near, the next one's) inside the union of the bodies at the
    earlier feed samples. And the flag is not rare."""
    rng = np.random.default_rng(3)
    walk = [f"G1 X{x:.3f} Y{y:.3f} Z{z:.3f}" for x, y, z in zip(rng.uniform(-11, -3, 60), rng.uniform(15, 25, 60),
                                                                rng.uniform(-2.6, -1.0, 60))]
    program = read_text("\n".join(["G21 G90 G94", "T1 M6", "S9000 M3", *LOOPS, *walk, "M30"]) + "\n", "air.nc")
    samples = program.toolpath.resample(0.1)
    eng = simulate(box(*STOCK, cell_mm=0.05), {1: tool}, samples, clearance_mm=CLEAR, progress=False)
    assert not eng.ap_mm.any()
    fed = np.flatnonzero(samples.kind != RAPID)
    known = np.flatnonzero(eng.swept_air)
    assert len(known) > 0.1 * eng.near_stock.sum() > 30
    edge = known[~eng.swept_air[known - 1] | ~eng.swept_air[np.minimum(known + 1, len(samples) - 1)]]
    for k in rng.choice(edge, 15, replace=False):
        before = samples.xyz_mm[fed[fed < k]]
        assert _covered(tool, samples.xyz_mm[k], before), k
        if k + 1 < len(samples) and eng.near_stock[k + 1]:
            assert _covered(tool, samples.xyz_mm[k + 1], samples.xyz_mm[fed[fed <= k]]), k


JOB = """program = "program.nc"
material = "al6061"
machine = "vmc-small"
[stock]
box = [[0, 0, -10], [60, 40, 0]]
cell_mm = 0.05
[tools.1]
diameter_mm = 6
flutes = 3
shape = "flat"
helix_deg = 35
flute_length_mm = 16
stickout_mm = 24
"""

PROGRAM = [
    "G21 G90 G17 G94", "T1 M6", "S9000 M3", "G0 Z10",
    "G0 X-58 Y20", "G0 Z2",
    "G1 Z-1.5 F300",          # 7: plunge with the tool's edge 50 mm beside the stock
    "G1 Y-30 F300",           # 8: and a move 50 mm from it
    "G0 Z2", "G0 X-5 Y36",
    "G1 Z-1.5 F300",          # 11: plunge 2 mm beside the stock
    "G1 X65 F700",            # 12: slot through
    "G0 Z5", "G0 X53 Y5",
    "G1 Z2 F300",             # 15: approach from 5 mm down to 2 mm above the top
    "G0 Z5", "G0 X18 Y13", "G0 Z2",
    "G1 Z-5 F100",            # 19: plunge into the stock, then a pocket X15..45 Y10..30 cleared to Z-5
    "G1 X42 F600", "Y17", "X18", "Y21", "X42", "Y25", "X18", "Y27", "X42",
    "G1 X30 Y20",             # 29: back to the middle of the pocket, on its floor
    "G1 Z-1.5",               # 30: up to 3.5 mm over the floor
    "G1 X31.5 Y18.5",         # 31: air 3.5 mm over the floor, 9 mm from the walls: raised
    "G1 Z-4",                 # 32: down to 1 mm over the floor
    "G1 X29 Y21",             # 33: air 1 mm over the floor: raised (the floor was cut, not guessed)
    "G1 Z1 F300",             # 34: a retract straight up through the top's shell: raised (meets nothing new)
    *LOOPS,                   # 35-39: a disc swept about (-7.5, 20) beside the stock (see above)
    "G1 X-4.5", "G1 Y21.5",   # 40, 41: a return inside it: raised
    "G1 X-3.4", "G1 Y18.5",   # 42, 43: a return 0.1 mm out of it: kept
    "G0 Z10", "M30",
]


@pytest.fixture(scope="module")
def air_job(tmp_path_factory):
    folder = tmp_path_factory.mktemp("air")
    (folder / "job.toml").write_text(JOB)
    (folder / "program.nc").write_text("\n".join(PROGRAM) + "\n")
    job = load_job(folder)
    return job, optimize(job, progress=False)


def _feeds_by_line(job, result) -> dict[int, tuple[float, float]]:
    """Per source line with feed moves: the (lowest, highest) emitted F over its samples (mm/min)."""
    tp = read_program(job.program).toolpath
    emitted = read_text(result.text, "o.nc").toolpath
    f = feed_at_samples(tp, emitted, result.samples)
    fed = result.samples.kind != RAPID
    return {int(n): (float(f[fed & (result.samples.line == n)].min()), float(f[fed & (result.samples.line == n)].max()))
            for n in np.unique(result.samples.line[fed])}


def test_approaches_beside_and_above_keep_their_feed_far_moves_are_raised(air_job):
    job, result = air_job
    assert result.summary["status"] == "solved"
    f = _feeds_by_line(job, result)
    # kept (the schedule's solution lies within 0.1 % under its cap)
    for line in (11, 15):  # the plunge 2 mm beside the stock, the approach down to 2 mm over the top
        assert 0.999 * 300.0 <= f[line][0] <= f[line][1] <= 300.0, (line, f[line])
    # far from the stock: a move raised well beyond the programmed feed (the axes' rates and accelerations
    # cap), a plunge below the stock's top at most 2x its programmed feed wherever it is (a blank larger
    # than modelled, see "Restarts")
    assert f[8][1] > 10 * 300.0
    assert 300.0 < f[7][1] <= 2 * 300.0
    # in the pocket the program cut: over its floor by more and by less than the clearance
    assert f[31][1] > 2 * 600.0 and f[33][1] > 2 * 600.0
    assert f[34][0] > 1.5 * 300.0
    # beside the stock: in the disc the tool swept, and 0.1 mm out of it
    assert f[41][1] > 2 * 300.0 and f[43][1] <= 300.0
    assert result.summary["limits"]["air_clearance"] <= 1.0 + 1e-3
    assert "air_clearance" in result.summary["hard_limits"]


def test_emitted_program_runs_in_rs274(air_job, tmp_path):
    if not rs274_oracle.RS274:
        pytest.skip("LinuxCNC's rs274 is not installed")
    job, result = air_job
    out = tmp_path / "o.ngc"
    out.write_text(result.text)
    trace = rs274_oracle.run(out)
    assert trace.error is None or "%" in trace.error, trace.error


def test_clearance_out_of_range_is_refused(tmp_path):
    (tmp_path / "program.nc").write_text("\n".join(PROGRAM) + "\n")
    (tmp_path / "job.toml").write_text(JOB + "[limits]\nair_clearance_mm = -1\n")
    with pytest.raises(ConfigError, match="air_clearance_mm"):
        load_job(tmp_path)
