"""`millpost optimize` on a job whose program is HEIDENHAIN Klartext: the program written is the
same Klartext with only F words changed (FMAX blocks untouched), and it reads back to the same path."""

import shutil
from pathlib import Path

import numpy as np
import pytest

from millpost.cli import main
from millpost.errors import ConfigError
from millpost.gcode import ReaderOptions, read_program
from millpost.gcode.convert import same_path
from millpost.job import load_job

from heidenhain_programs import SLOTS

SAMPLE = Path(__file__).resolve().parents[2] / "sample_jobs" / "slotting"
PROGRAM = SLOTS


def _f_free(line: str) -> str:
    return " ".join(w for w in line.split() if not (w.startswith("F") and w[1:2].isdigit()))


DRILLED = PROGRAM.replace("29 L Z+10 FMAX M5", """29 L Z+10 FMAX
  CYCL DEF 200 DRILLING ~
  Q200=+2 ;SET-UP CLEARANCE ~
  Q201=-6 ;DEPTH ~
  Q206=+150 ;FEED RATE FOR PLNGNG ~
  Q202=+3 ;PLUNGING DEPTH ~
  Q210=+0 ;DWELL TIME AT TOP ~
  Q203=+0 ;SURFACE COORDINATE ~
  Q204=+10 ;2ND SET-UP CLEARANCE ~
  Q211=+0 ;DWELL TIME AT DEPTH
  L X+15 Y+30 FMAX M99
  L X+45 Y+30 FMAX M99
  L Z+10 FMAX M5""")


@pytest.mark.parametrize("program", [PROGRAM, DRILLED], ids=["contour", "contour and drilling cycle"])
def test_optimize_a_klartext_program(tmp_path, program):
    """Every F word may change but those of a drilling cycle (its Q206, on the cycle's definition, not on
    the calls: `fixed_feed`), which keeps its programmed feed."""
    job = tmp_path / "job"
    shutil.copytree(SAMPLE, job)
    (job / "program.h").write_text(program)
    toml = (job / "job.toml").read_text().replace('program = "program.nc"', 'program = "program.h"')
    (job / "job.toml").write_text(toml)
    out = tmp_path / "out.h"
    assert main(["optimize", str(job), "-o", str(out), "--quiet", "--jobs", "1"]) == 0
    written = out.read_text()
    assert written != program
    for before, after in zip(program.splitlines(), written.splitlines(), strict=True):
        assert _f_free(before) == _f_free(after)
        assert "FMAX" not in before and "Q206" not in before or before == after
    options = ReaderOptions(dialect="heidenhain")
    a, b = read_program(job / "program.h", options), read_program(out, options)
    assert same_path(a, b) == []
    assert not np.allclose(a.toolpath.feed_mm_min, b.toolpath.feed_mm_min, equal_nan=True)
    drilled = a.cycle != 0
    assert np.array_equal(a.toolpath.feed_mm_min[drilled], b.toolpath.feed_mm_min[drilled], equal_nan=True)


def test_a_job_without_stock_takes_the_programs_blank(tmp_path):
    """BLK FORM 0.1/0.2 is the blank the control shows and simulates (TNC 640 manual, "Defining a
    workpiece blank"): a job with no [stock] takes it as its stock box."""
    job = tmp_path / "job"
    shutil.copytree(SAMPLE, job)
    (job / "program.h").write_text(PROGRAM)
    toml = (job / "job.toml").read_text().replace('program = "program.nc"', 'program = "program.h"')
    lines = toml.splitlines()
    start = lines.index("[stock]")
    end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("[")), len(lines))
    (job / "job.toml").write_text("\n".join(lines[:start] + lines[end:]) + "\n")
    assert load_job(job).stock_box == ((0.0, 0.0, -10.0), (60.0, 40.0, 0.0))
    (job / "program.h").write_text("G21 G90\nG1 X10 F100\nM2\n")
    with pytest.raises(ConfigError, match="no blank"):
        load_job(job)
