"""`[limits] rpm = "optimize"`: S chosen per operation within the surface-speed window and the spindle's
range, only where it shortens the cycle under the same limits; only S and F words change; LinuxCNC's
interpreter reads the result and runs the spindle at the new S. Default: no S changes."""

from __future__ import annotations

import dataclasses
import math
import re
import subprocess
from pathlib import Path

import pytest

import rs274_oracle
from millpost.gcode import read_text
from millpost.emit import replace_numbers
from millpost.job import load_job
from millpost.optimize import optimize

ROOT = Path(__file__).resolve().parents[1]
SLOTTING = ROOT / "sample_jobs" / "slotting"
# HSS in 6061: 120–230 m/min (the material file); a 6 mm tool: n = 1000·v_c/(π·6) = 6366–12202 rpm; the
# small VMC's spindle turns at most 10000 rpm
HSS_WINDOW = (120e3 / (math.pi * 6), 10000.0)


def _job(tmp_path: Path, s_word: str, rpm: str | None):
    """The slotting job with an HSS end mill (feeds there bound by its chip load), its S word replaced."""
    program = (SLOTTING / "program.nc").read_text().replace("S9000", s_word)
    (tmp_path / "program.nc").write_text(program)
    toml = (SLOTTING / "job.toml").read_text().replace("stickout_mm = 24", 'stickout_mm = 24\nmaterial = "hss"')
    if rpm is not None:
        toml += f'\n[limits]\nrpm = "{rpm}"\n'
    (tmp_path / "job.toml").write_text(toml)
    return load_job(tmp_path)


def _geometry_lines(text: str) -> list[str]:
    """Each line with its S and F words removed (what must stay as it was)."""
    return [re.sub(r"\s*\b[SsFf][-+]?[\d.]+", "", line).strip() for line in text.splitlines()]


def _only_s_and_f_changed(before: str, after: str) -> None:
    """Every input line is in the output, in order, with only its S and F words changed; lines the output
    adds are straight feed moves (a long move split where its feed changes; written like their line, so
    without G1 where the line had none)."""
    a, b = _geometry_lines(before), _geometry_lines(after)
    i = 0
    for line in b:
        if i < len(a) and line == a[i]:
            i += 1
        else:
            assert re.fullmatch(r"(G1 )?[XYZ][-\d.]+( [XYZ][-\d.]+)*", line), (line, a[i] if i < len(a) else None)
    assert i == len(a)


def _spindle_speeds(path: Path) -> list[float]:
    """The speeds LinuxCNC's interpreter sets running the program (SET_SPINDLE_SPEED calls)."""
    out = subprocess.run([rs274_oracle.RS274, "-g", str(path)], capture_output=True, text=True, timeout=60,
                         stdin=subprocess.DEVNULL).stdout
    return [float(m) for m in re.findall(r"SET_SPINDLE_SPEED\(\d+, ([\d.]+)\)", out)]


def test_a_faster_s_in_the_window_shortens_the_cycle(tmp_path):
    (tmp_path / "fixed").mkdir()
    (tmp_path / "free").mkdir()
    fixed = optimize(_job(tmp_path / "fixed", "S7000", None), progress=False)
    job = _job(tmp_path / "free", "S7000", "optimize")
    free = optimize(job, progress=False)
    (row,) = free.summary["spindle"]["blocks"]
    assert row["changed"] and row["programmed_rpm"] == 7000
    lo, hi = HSS_WINDOW
    assert row["window_rpm"] == [pytest.approx(lo, abs=0.1), pytest.approx(hi, abs=0.1)]
    assert 7000 < row["rpm"] <= hi and row["rpm"] == int(row["rpm"])
    assert "spindle's maximum" in row["reason"] and f"S7000 → S{row['rpm']:g}" in row["reason"]
    assert any(f"S{row['rpm']:g}" in note for note in free.summary["notes"])
    # shorter than the same job at the programmed S, under the same limits, all held on the replay
    assert free.summary["status"] == fixed.summary["status"] == "solved"
    assert free.summary["cycle_time_after_s"] < fixed.summary["cycle_time_after_s"] * 0.99
    assert max(free.summary["limits"].values()) <= 1 + 1e-6
    _only_s_and_f_changed(job.program.read_text(), free.text)
    assert re.findall(r"^S(\d+) M3$", free.text, re.M) == [f"{row['rpm']:g}"]
    # the emitted program read back runs its cuts at the new speed
    tp = read_text(free.text, "free.nc").toolpath
    assert set(tp.rpm[tp.kind != 0].tolist()) == {row["rpm"]}
    if rs274_oracle.RS274 is None:
        pytest.skip("LinuxCNC's rs274 is not installed: the S and F checks above ran")
    out = tmp_path / "free.nc"
    out.write_text(free.text)
    assert rs274_oracle.run(out).error is None
    assert _spindle_speeds(out) == [row["rpm"]]


def test_s_at_its_best_stays(tmp_path):
    best = "S10000"  # the top of the window: the chip load allows the most feed there
    (tmp_path / "fixed").mkdir()
    (tmp_path / "free").mkdir()
    fixed = optimize(_job(tmp_path / "fixed", best, None), progress=False)
    free = optimize(_job(tmp_path / "free", best, "optimize"), progress=False)
    (row,) = free.summary["spindle"]["blocks"]
    assert not row["changed"] and row["rpm"] == row["programmed_rpm"] == float(best[1:])
    assert "kept" in row["reason"]
    assert free.text == fixed.text  # the same program as without the option


def test_default_changes_no_s(tmp_path):
    job = load_job(SLOTTING)
    assert job.settings.rpm == "programmed"
    result = optimize(job, progress=False)
    assert "spindle" not in result.summary
    s_words = re.compile(r"^.*[Ss]\s*\d.*$", re.M)
    assert s_words.findall(result.text) == s_words.findall(job.program.read_text())


def test_blocks_that_cannot_change_say_why(tmp_path):
    """Feed per revolution (G95): the feed would change with S, so S stays and the summary says why."""
    program = (SLOTTING / "program.nc").read_text().replace("S9000 M3", "S9000 M3\nG95").replace(" F700", " F0.1")
    program = program.replace(" F300", " F0.03").replace(" F900", " F0.1")
    job = load_job(SLOTTING)
    (tmp_path / "program.nc").write_text(program)
    job = dataclasses.replace(job, program=tmp_path / "program.nc", output=tmp_path / "out.nc",
                              settings=dataclasses.replace(job.settings, rpm="optimize"))
    result = optimize(job, progress=False)
    (row,) = result.summary["spindle"]["blocks"]
    assert not row["changed"] and "G95" in row["reason"]
    assert re.findall(r"^S\d+", result.text, re.M) == ["S9000"]


def test_s_words_keep_their_style():
    text = "G21 G90\ns9000. m3\nG1 X10 F100\nN20 S 12000 M3 (spindle)\nG1 X20\nM30\n"
    program = read_text(text, "style.nc")
    out = replace_numbers(program, {2: {"S": 10000.0}, 4: {"S": 8000.0}})
    assert out == "G21 G90\ns10000. m3\nG1 X10 F100\nN20 S8000 M3 (spindle)\nG1 X20\nM30\n"


def test_a_failed_schedule_keeps_the_programmed_s(tmp_path, monkeypatch):
    """Never new speeds with the programmed feeds: when the final schedule fails, S stays as programmed."""
    import millpost.optimize as opt_module
    from millpost.schedule import Status

    real = opt_module.schedule_samples

    def failing(samples, limits, options=None):
        sch = real(samples, limits, options)
        for _, _, seg in sch.segments:
            seg.status, seg.message = Status.NUMERICAL_ERROR, "forced failure"
        return sch

    monkeypatch.setattr(opt_module, "schedule_samples", failing)  # the choice's own runs still solve
    job = _job(tmp_path, "S7000", "optimize")
    result = optimize(job, progress=False)
    assert result.summary["status"] == "fallback_programmed_feeds"
    assert "S kept as programmed" in " ".join(result.summary["notes"])
    assert result.text == job.program.read_text()  # programmed feeds and the programmed S
