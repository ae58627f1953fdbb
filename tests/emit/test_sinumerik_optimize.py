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


MAIN = """N10 G90 G94 G17 G710
N20 T1 M6
N30 S9000 M3
N40 G0 Z10
N50 G0 X-5 Y8
N60 G0 Z2
N70 G1 Z-1.5 F300
N80 G1 X65 F700
N90 G0 Z2
N100 G0 X-5 Y20
N110 SLOT P2
N120 G0 X-5 Y32
N130 G1 Z-3 F300
N140 G1 X65 F700
N150 G0 Z10
N160 M30
"""
SLOT = """PROC SLOT
N10 G1 Z-1.5 F300
N20 G1 X65 F700
N30 G0 Z2
N40 X-5
N50 M17
"""


def test_a_program_calling_a_subprogram_optimizes_with_only_its_own_f_words_changed(tmp_path):
    """FB "Subprogram technique": SLOT P2 runs SLOT.SPF twice; optimize rewrites F words of the main
    program only (the subprogram's file is not written: its moves keep their programmed feeds), and the
    output, read with the subprogram beside it, is the same path within 1e-4 mm."""
    folder = _job(tmp_path / "job", "main.mpf", MAIN)
    (folder / "SLOT.SPF").write_text(SLOT)
    assert main(["optimize", str(folder), "-o", str(folder / "out.mpf"), "-q", "--jobs", "1"]) == 0
    before, after = MAIN.splitlines(), (folder / "out.mpf").read_text().splitlines()
    assert len(before) == len(after) and (folder / "SLOT.SPF").read_text() == SLOT
    changed = [(a, b) for a, b in zip(before, after) if a != b]
    assert changed and all(_F.sub("", a) == _F.sub("", b) for a, b in changed)
    opts = ReaderOptions(dialect="sinumerik")
    original, optimized = read_program(folder / "main.mpf", opts), read_program(folder / "out.mpf", opts)
    assert same_path(original, optimized) == []
    in_sub = optimized.toolpath.line > len(before)
    assert in_sub.sum() == 8
    assert np.array_equal(optimized.toolpath.feed_mm_min[in_sub], original.toolpath.feed_mm_min[in_sub],
                          equal_nan=True)
    shutil.rmtree(tmp_path, ignore_errors=True)
