"""Seeded mutation fuzzing of the reader over the real corpus (tests/gcode_mutants.py): every mutant
is either read, with every number of the result finite, or refused with a MillpostError naming
file:line:column; never another exception, never a hang (10 s of CPU). benchmarks/fuzz.py runs the
same at >= 100 000 mutants."""

from __future__ import annotations

import pytest

import gcode_mutants
from conftest import SHARED_DATA

MUTANTS = 3000


@pytest.fixture(scope="module")
def programs():
    if not SHARED_DATA.exists():
        pytest.skip(f"{SHARED_DATA} is absent (third-party corpus, not in the repo)")
    return gcode_mutants.corpus(SHARED_DATA)


def test_mutants_are_read_or_refused_never_crash(programs):
    failures, counts = [], {}
    for seed in range(MUTANTS):
        name, text, done = gcode_mutants.mutant(programs, seed, window=200)
        status, detail = gcode_mutants.check(text, name, linuxcnc=seed % 2 == 0, seconds=10.0)
        counts[status] = counts.get(status, 0) + 1
        if status not in ("accepted", "refused"):
            failures.append(f"seed {seed} ({name}, {done}): {status}: {detail}")
    assert not failures, "\n".join(failures[:20])
    # the mutations do bite: a good share is refused, and many stay valid programs
    assert counts.get("refused", 0) > MUTANTS // 4 and counts.get("accepted", 0) > MUTANTS // 10, counts


def test_refusals_name_file_line_and_column(programs):
    from millpost.errors import ParseError
    from millpost.gcode import ReaderOptions, read_text

    seen = 0
    for seed in range(300):
        name, text, _ = gcode_mutants.mutant(programs, seed, window=200)
        try:
            read_text(text, name, ReaderOptions.linuxcnc())
        except ParseError as err:
            seen += 1
            assert err.file == name and err.line >= 1 and err.column >= 1 and err.expected, str(err)
            assert str(err).startswith(f"{name}:{err.line}:{err.column}: ")
    assert seen > 50
