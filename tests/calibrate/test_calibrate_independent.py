"""`calibrate fit --log` on logs millpost did not make (tests/independent_log.py: its own G-code reader,
exact-stop trapezoid motion with its own acceleration and rapid rate, swept-stock engagement, per-tooth
force integration, its own clock), with positions logged: the coefficients within 3 % (K_tc, K_rc) and
5 % (K_ac) of the generator's, whatever the log's clock, holds, override, lost rows or coverage; a log
whose positions do not fit the program is refused naming its rows; one pass of a multi-pass program
aligns to that pass."""

from __future__ import annotations

import json

import numpy as np
import pytest

from independent_log import Mill, generate, read_moves
from millpost import signals
from millpost.cli import main
from millpost.measure import Log, align, write_log
from millpost.measure.alignment import MisalignedLog

TRUTH = (700.0, 190.0, 220.0, 16.0, 15.0, 2.0)   # not the prior's (al6061: 631, 99, 273, 13, 10, 2.8)
BOX = ((0.0, 0.0, -20.0), (80.0, 100.0, 0.0))


@pytest.fixture(scope="module")
def plan(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cal") / "cal"
    assert main(["calibrate", "plan", "--diameter", "6", "--flutes", "3", "--helix", "35", "--material", "al6061",
                 "--machine", "vmc-small", "--stock-box", ",".join(str(v) for v in BOX[0] + BOX[1]), "--rpm", "8000",
                 "--fz", "0.02,0.04,0.06,0.08", "--ap", "1.5,3", "--idle-rpm", "3000,8000", "-o", str(folder)]) == 0
    return folder


def _slot_moves(text: str) -> list[int]:
    return [k for k, m in enumerate(read_moves(text)) if m.kind == "feed" and m.start[2] < 0
            and abs(m.end[0] - m.start[0]) > 50]


CASES = {
    "own clock, all rows": dict(rate_hz=250.0, epoch_s=5321.7),
    "feeding only, holds, 90 % override, 5 % rows lost": dict(rate_hz=200.0, feeding_only=True, drop=0.05,
                                                              override=0.9, holds=((0, 0.4, 2.5), (3, 0.7, 1.0))),
    "part of the program (slots only), slow accelerations": dict(rate_hz=100.0, accel_mm_s2=150.0, slots_only=True),
}


@pytest.mark.parametrize("case", list(CASES))
def test_log_fit_recovers_the_generators_coefficients(plan, tmp_path, case):
    kw = dict(CASES[case])
    text = (plan / "calibration.nc").read_text()
    slots = _slot_moves(text)
    mill = Mill(K=TRUTH, override=kw.pop("override", 1.0), accel_mm_s2=kw.pop("accel_mm_s2", 450.0))
    holds = {slots[i]: (f, s) for i, f, s in kw.pop("holds", ())}
    if kw.pop("slots_only", False):
        moves = read_moves(text)
        kw["lines"] = (moves[slots[0]].line - 2, moves[slots[-1]].line)
    g = generate(text, BOX, mill, holds=holds, seed=len(case), **kw)
    write_log(tmp_path / "log.npz", Log(g.columns, path="gen"))
    assert main(["calibrate", "fit", "--log", str(tmp_path / "log.npz"), "--plan", str(plan), "--json",
                 str(tmp_path / "fit.json")]) == 0
    got = json.loads((tmp_path / "fit.json").read_text())
    assert got["alignment"]["method"] == "position" and got["alignment"]["position_max_mm"] < 0.05
    err = {k: got["mechanistic"][k]["value"] / t - 1 for k, t in zip(("Ktc", "Krc", "Kac"), TRUTH)}
    print(case, {k: f"{100 * v:+.2f} %" for k, v in err.items()})
    assert abs(err["Ktc"]) < 0.03 and abs(err["Krc"]) < 0.03 and abs(err["Kac"]) < 0.05, err
    assert {"Ktc", "Krc", "Kac"} <= set(got["mechanistic_identifiability"]["identified"])


def test_log_off_the_program_is_refused_naming_rows(plan, tmp_path, capsys):
    """The same log with the work offset 1.5 mm off in Y: exit 2, the rows named, nothing written."""
    g = generate((plan / "calibration.nc").read_text(), BOX, Mill(K=TRUTH), feeding_only=True, seed=5)
    g.columns["y_mm"] = g.columns["y_mm"] + 1.5
    write_log(tmp_path / "off.npz", Log(g.columns, path="gen"))
    assert main(["calibrate", "fit", "--log", str(tmp_path / "off.npz"), "--plan", str(plan), "-o",
                 str(tmp_path / "m.toml")]) == 2
    err = capsys.readouterr().err
    assert "do not lie on the program's path" in err and "Worst rows: row " in err and "mm from the path" in err
    assert not (tmp_path / "m.toml").exists()


def test_one_pass_of_a_multi_pass_program_aligns_to_that_pass(tmp_path):
    """Three passes deepening one slot (3, 6, 12 mm) retrace the same XY; a log of the second pass alone
    matches the second pass (all three coordinates), row by row."""
    from test_signals import make_job
    lines = ["G21 G90 G94 G17", "T1 M6", "S8000 M3"]
    for depth in (3, 6, 12):
        lines += ["G0 X-5 Y20 Z5", f"G1 Z{-depth} F300", "G1 X45 F900", "G0 Z5"]
    text = "\n".join(lines + ["M5", "M30"]) + "\n"
    job = make_job(tmp_path, text)
    sig = signals.simulate(job)
    second = [m.line for m in read_moves(text) if m.end[2] == -6 or m.start[2] == -6]
    g = generate(text, ((0.0, 0.0, -20.0), (40.0, 40.0, 0.0)), Mill(diameter_mm=job.tools[1].diameter_mm),
                 lines=(min(second), max(second)), seed=2, epoch_s=-35.0)
    log = Log(g.columns, path="pass2")
    a = align(log, sig)
    matched = sig.line[a.samples(sig)]
    assert a.on_path.all() and np.mean(matched == g.truth["line"]) > 0.97
    assert set(np.unique(matched)) <= set(second) | {min(second) - 1}   # the rapid ending where pass 2 starts
    # the same log 1.5 mm deeper than any pass (a tool length off): refused, not matched to another pass
    log.columns["z_mm"] = log.columns["z_mm"] - 1.5
    with pytest.raises(MisalignedLog):
        align(log, sig)
