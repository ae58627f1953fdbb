"""A CAM-style pocket (`cam_pocket`: slowed inside corner arcs, level changes through the pocket already
cut, plunges from the feed height within the air clearance) through `optimize`, read as a machinist reads
the output (`machinist`): the edge of the cutter on the slowed inside arcs runs no faster than the
straights' chip-load feed, every descent below the stock's top stays within 2 × its programmed feed (a
restart from an operation's start, a skipped level or a broken tool makes it a plunge into solid metal),
approaches within the clearance keep their programmed feed, no F word is above the axis rates of its
move's direction; and a spindle too weak for the cuts is refused, nothing written."""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pytest

import machinist
from cam_pocket import write_job
from millpost.cli import main
from millpost.gcode import read_program, read_text
from millpost.job import load_job
from millpost.machine import Machine
from millpost.optimize import optimize
from millpost.toolpath import ARC_CW, RAPID

CASES = {"vmc-small al6061": ("vmc-small", "al6061", None), "router mdf on linuxcnc": ("hobby-router", "mdf", "linuxcnc")}


@pytest.fixture(scope="module", params=sorted(CASES))
def pocket(request, tmp_path_factory):
    machine, material, kind = CASES[request.param]
    folder = write_job(tmp_path_factory.mktemp("pocket"), material=material, machine=machine,
                       rpm=9000 if material == "al6061" else 18000)
    job = load_job(folder)
    if kind:
        job = replace(job, machine=replace(job.machine, controller=replace(job.machine.controller, kind=kind)))
    result = optimize(job, progress=False, trace=True)
    assert result.summary["status"] == "solved", result.summary["message"]
    original = read_program(job.program).toolpath
    emitted = read_text(result.text, "out.nc").toolpath
    return job, result, original, emitted


def test_edge_feed_on_slowed_inside_arcs_within_the_straights_chip_load_feed(pocket):
    """The CAM slowed each R1 corner (wall R4, 6 mm tool) to F × 1/4 so that the edge at the wall runs at
    the straights' feed; the optimized corner's edge feed F_arc × (r + R)/r (the arc's F as written) is at
    most the feed at which the straights on either side reach the chip load (their executed feed ×
    chip limit / chip, median over each straight; within one feed step)."""
    job, result, original, emitted = pocket
    R = job.tools[1].radius_mm
    step = job.settings.feed_step
    tr = result.trace
    first = machinist.pieces_of_moves(original, emitted)
    arcs = np.flatnonzero(original.kind >= ARC_CW)
    assert len(arcs) >= 12
    for i in arcs:
        r = float(np.linalg.norm(original.start[i, :2] - original.center[i, :2]))
        edge = emitted.feed_mm_min[first[i]:first[i + 1]].max() * (r + R) / r
        chip_feed = []
        for j in (i - 1, i + 1):
            on = (tr["line"] == original.line[j]) & (tr["chip_mm"] > 0)
            if on.any():  # a straight that cuts (not the retract after the ring)
                chip_feed.append(np.median(tr["feed_executed_mm_min"][on] * tr["chip_limit_mm"][on] / tr["chip_mm"][on]))
        assert edge <= min(chip_feed) * (1 + step), f"line {original.line[i]}: edge {edge:.0f} > {min(chip_feed):.0f}"


def test_descents_approaches_and_axis_rates(pocket):
    job, result, original, emitted = pocket
    top, c = 0.0, job.settings.air_clearance_mm
    box = np.array(job.stock_box)[:, :2] + [[-job.tools[1].radius_mm - c], [job.tools[1].radius_mm + c]]
    assert machinist.descent_excess(original, emitted, top, job.settings.plunge_raise_max) == []
    assert machinist.approach_excess(original, emitted, top, c, box) == []
    vmax = [job.machine.axes[a].vmax_mm_min for a in "xyz"]
    assert machinist.axis_rate_excess(original, emitted, vmax) == []
    # the level changes go down through the pocket already cut: the program's F300 there is raised at most 2x
    level = [k for k in range(len(original)) if original.kind[k] != RAPID and original.end[k, 2] in (-2.0, -4.0)
             and original.start[k, 2] in (-1.0, -3.0)]
    assert level


def test_trusting_the_cut_space_lifts_the_descent_rule(tmp_path):
    """`[limits] trust_cut_space = true`: the program always runs whole, so a descent through space it cut
    before is air and may go at the machine's rate; without it, at most 2 × the programmed F300."""
    folder = write_job(tmp_path)
    job = load_job(folder)
    original = read_program(job.program).toolpath
    through = [k for k in range(len(original)) if original.kind[k] != RAPID and original.start[k, 2] == -1.0
               and original.end[k, 2] == -2.0]  # from 1 mm over the first floor down to it: all in cut space
    assert through
    feeds = {}
    for trust in (False, True):
        job = replace(job, settings=replace(job.settings, trust_cut_space=trust))
        out = read_text(optimize(job, progress=False).text, "out.nc").toolpath
        first = machinist.pieces_of_moves(original, out)
        feeds[trust] = max(out.feed_mm_min[first[k]:first[k + 1]].max() for k in through)
    assert feeds[False] <= 2 * 300 + 0.1
    assert feeds[True] > 10 * 300


def test_a_spindle_too_weak_is_refused_and_nothing_written(tmp_path, capsys):
    """The same pocket on a spindle of 60 W (the cuts ask up to 351 W): within its power the program takes
    several times the programmed time: exit 2, nothing written, per tool the limit and the lines; with
    `--allow slower` it is written with the warning."""
    folder = write_job(tmp_path, machine="weak.toml")
    base = Machine.builtin_path("vmc-small") if hasattr(Machine, "builtin_path") else None
    text = (base.read_text() if base else
            (load_job.__globals__["Path"](__import__("millpost").__file__).parent / "data/machines/vmc-small.toml")
            .read_text())
    (folder / "weak.toml").write_text(re.sub(r"(?m)^power_W = .*$", "power_W = 60", text))
    out = folder / "out.nc"
    assert main(["optimize", str(folder), "-o", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert not out.exists()
    assert "slower_max" in err and "T1 power up to" in err and "--allow slower" in err
    # within its power the cuts are still over it at the lowest feed written (2.04x): refused again
    assert main(["optimize", str(folder), "-o", str(out), "--quiet", "--allow", "slower"]) == 2
    assert "even at the lowest feed" in capsys.readouterr().err and not out.exists()
    assert main(["optimize", str(folder), "-o", str(out), "--quiet", "--allow", "slower", "--allow", "overload"]) == 0
    assert out.exists()
