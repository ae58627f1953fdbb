"""Seeded mutation fuzzing of the Heidenhain reader: every mutant of the Klartext and ISO programs
of the tests is read, with finite moves, or refused with a MillpostError (a ParseError naming the
file, a line of the program and a column); never another exception. 1 500 mutants here;
benchmarks/fuzz_dialects.py runs 100 000."""

from __future__ import annotations

import os
import random
import re
from pathlib import Path

import numpy as np
import pytest

import gcode_mutants
from millpost.errors import MillpostError, ParseError
from millpost.gcode import ReaderOptions, read_text

from test_heidenhain import CYCLE, ISO, LOOPED, PLANES, SLOTS

SEEDS = [SLOTS, LOOPED, ISO, PLANES, PLANES.replace("TOOL CALL 1", 'TOOL CALL "MILL D10"'), CYCLE.format(peck="+5", second="+19", dwell="+0"),
         "0 BEGIN PGM P MM\n1 FN 0: Q1 = +5\n2 L X+0 Y+0 Z+5 R0 FMAX\n3 CC X+10 Y+10\n4 LP PR+Q1 PA+0 F300\n"
         "5 CP IPA+720 IZ-2 DR+\n6 L X+0 Y+0\n7 RND R2\n8 L Y+20\n9 CHF 1\n10 L X+30\n"
         "11 CYCL DEF 7.0 DATUM SHIFT\n12 CYCL DEF 7.1 IX+5\n13 CR X+40 Y+10 R-12 DR-\n14 CT X+50 Y+0\n"
         "15 Q2 = SQ(Q1) + SIN(30) * PI\n16 L Z+Q2 FMAX\n17 END PGM P MM\n"]
TOKENS = ["L", "C", "CC", "CR", "CT", "RND R1", "CHF 1", "LP PR+3", "CP PA+90 DR+", "FMAX", "F100", "M99", "M30",
          "X+", "IX-", "Q1", "DR-", "R-", "LBL 1", "CALL LBL 1 REP 2", "LBL 0", "CYCL CALL", "FN 4: Q1 = +1 / +0",
          "*", "~", ";", "(", "=", "G02", "I+5", "%X G71 *", "TOOL CALL 2 Z S100", "BLK FORM 0.1 Z", "1e5", "-",
          "+", ".", "Q200=", "END PGM X MM", "PLANE SPATIAL", "\t", "ä", "CC X+0 Z+0", "CC Y+1 Z-1", "Z+",
          'TOOL CALL "T 1"', '"', "DEP LT LEN+5", "LEN"]


def mutant(seed: int) -> str:
    """A seeded mutation (1-3 edits: a character or token inserted, deleted or replaced, a line doubled
    or dropped, a number changed) of one of the programs."""
    rng = random.Random(seed)
    text = SEEDS[seed % len(SEEDS)]
    for _ in range(rng.randint(1, 3)):
        op = rng.randrange(6)
        lines = text.split("\n")
        k = rng.randrange(len(lines))
        if op == 0 and text:
            i = rng.randrange(len(text))
            text = text[:i] + text[i + 1:]
        elif op == 1:
            i = rng.randrange(len(text) + 1)
            text = text[:i] + rng.choice(TOKENS) + text[i:]
        elif op == 2:
            lines.insert(k, lines[rng.randrange(len(lines))])
            text = "\n".join(lines)
        elif op == 3 and len(lines) > 2:
            del lines[k]
            text = "\n".join(lines)
        elif op == 4:
            words = lines[k].split(" ")
            words[rng.randrange(len(words))] = rng.choice(TOKENS)
            lines[k] = " ".join(words)
            text = "\n".join(lines)
        else:
            digits = [i for i, c in enumerate(text) if c.isdigit()]
            if digits:
                i = rng.choice(digits)
                text = text[:i] + str(rng.choice([0, 1, 5, 9, 99999])) + text[i + 1:]
    return text


def _misplaced(detail: str, text: str) -> bool:
    """A refusal naming a file other than the mutant's, or a line it does not have, or no column."""
    where = re.match(r"([^:]*):(\d+):(\d+):", detail)
    if where is None:  # a MillpostError that names no place (a limit of the reader's work)
        return False
    return where[1] != "f.h" or not 1 <= int(where[2]) <= text.count("\n") + 1 or int(where[3]) < 1


def run(count: int, start: int = 0) -> dict[str, int]:
    """Read `count` mutants (`gcode_mutants.check_with`: accepted with finite moves, or refused; never
    an uncaught exception or a hang), each refusal at a line of the mutant."""
    counts: dict[str, int] = {}
    failures = []
    for seed in range(start, start + count):
        text = mutant(seed)
        # 30 s: a section repeated to the reader's cap of 100 000 lines takes ~15 s of CPU to refuse (each
        # translated line carries the tracked point and tangent as expressions)
        status, detail = gcode_mutants.check_with(text, "f.h", ReaderOptions(dialect="heidenhain"), seconds=30.0)
        if status == "refused" and _misplaced(detail, text):
            status = "misplaced refusal"
        counts[status] = counts.get(status, 0) + 1
        if status not in ("accepted", "refused"):
            failures.append(f"seed {seed}: {status}: {detail}")
    assert not failures, "\n".join(failures[:20])
    return counts


def test_mutants_are_read_or_refused_never_crash():
    counts = run(1500)
    assert counts.get("refused", 0) > 200 and counts.get("accepted", 0) > 200, counts


REAL = os.environ.get("MILLPOST_HEIDENHAIN_DIR")


@pytest.mark.skipif(not REAL, reason="set MILLPOST_HEIDENHAIN_DIR to a folder of real Heidenhain programs (.h, .i)")
def test_real_programs_are_read_or_refused_where_they_say():
    """Real programs (not in the repo): each is read with finite moves, or refused at file:line:column;
    a program read is written back with its feeds and re-read to the same path."""
    from millpost.emit.write import FeedPlan, write_feeds
    from millpost.gcode import read_program
    from millpost.gcode.convert import same_path

    files = sorted(p for p in Path(REAL).rglob("*") if p.suffix.lower() in (".h", ".i"))
    assert files, f"no .h or .i files under {REAL}"
    for path in files:
        try:
            program = read_program(path, ReaderOptions(dialect="heidenhain"))
        except ParseError as err:
            assert err.file == str(path) and err.line >= 1 and err.column >= 1, str(err)
            continue
        tp = program.toolpath
        assert np.isfinite(tp.end).all()
        if len(tp):
            try:
                written = write_feeds(program, FeedPlan(tp.feed_mm_min * 0.9, {}))
            except MillpostError as err:  # a drilling cycle's feed: refused, said so
                assert "Q206" in str(err), str(err)
                continue
            again = read_text(written, str(path), ReaderOptions(dialect="heidenhain"))
            assert same_path(program, again) == [], path
