"""`millpost optimize` end to end on a Sinumerik program: the slotting sample job's program re-posted
for Sinumerik (`convert`), optimized; the output differs from the input only in F words, reads back to
the same path within 1e-4 mm, and takes the feeds the same job optimized in RS-274 takes."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np

from millpost.cli import main
from millpost.gcode import ReaderOptions, dialects, read_program
from millpost.gcode.convert import convert, same_path

JOB = Path(__file__).resolve().parents[2] / "sample_jobs" / "slotting"
_F = re.compile(r"\s*\bF[-+]?(?:\d+\.?\d*|\.\d+)")


def _job(folder: Path, program: str, text: str) -> Path:
    folder.mkdir()
    toml = (JOB / "job.toml").read_text().replace('program = "program.nc"', f'program = "{program}"')
    (folder / "job.toml").write_text(toml.replace("cell_mm = 0.05", "cell_mm = 0.2"))
    (folder / program).write_text(text)
    return folder


def test_optimized_sinumerik_program_changes_only_f_words(tmp_path):
    ngc = (JOB / "program.nc").read_text()
    mpf = convert(read_program(JOB / "program.nc"), dialects.get("sinumerik"))
    plain, sin = _job(tmp_path / "ngc", "program.nc", ngc), _job(tmp_path / "sin", "program.mpf", mpf)
    for folder, name in ((plain, "out.nc"), (sin, "out.mpf")):
        assert main(["optimize", str(folder), "-o", str(folder / name), "-q", "--jobs", "1"]) == 0
    before, after = mpf.splitlines(), (sin / "out.mpf").read_text().splitlines()
    assert len(before) == len(after)
    changed = [(a, b) for a, b in zip(before, after) if a != b]
    assert changed and all(_F.sub("", a) == _F.sub("", b) for a, b in changed)
    original = read_program(sin / "program.mpf")
    optimized = read_program(sin / "out.mpf", ReaderOptions(dialect="sinumerik"))
    assert optimized.dialect == "sinumerik" and same_path(original, optimized) == []
    reference = read_program(plain / "out.nc")
    cut = optimized.toolpath.kind != 0
    assert np.allclose(optimized.toolpath.feed_mm_min[cut], reference.toolpath.feed_mm_min[reference.toolpath.kind != 0],
                       rtol=1e-3)
    shutil.rmtree(tmp_path, ignore_errors=True)
