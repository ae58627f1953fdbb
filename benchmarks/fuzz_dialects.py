"""Mutation fuzzing of the Sinumerik and Heidenhain readers at scale (issue 29: 0 crashes on 10^5
mutants of programs in each new dialect; the test suite runs a few thousand). The mutants are those of
tests/gcode/test_sinumerik_fuzz.py and test_heidenhain_fuzz.py (seeded: snippets of the language
inserted, words mutated, lines swapped in posted and hand-written programs); each is read and must be
accepted with finite moves or refused with a ParseError naming the file, a line and a column.

Prints one JSON object per dialect: mutants, counts (accepted, refused), seconds, mutants_per_s,
ratio_vs_unmutated (mean read time of a mutant over that of the unmutated programs, measured in the
same run) and peak_mb (this process's peak resident memory). A failure raises with its seeds.

Run: nice python benchmarks/fuzz_dialects.py [--mutants 100000] [--dialect sinumerik|heidenhain]
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "gcode"))
import test_heidenhain_fuzz  # noqa: E402
import test_sinumerik_fuzz  # noqa: E402

from millpost.gcode import ReaderOptions, read_text  # noqa: E402

FUZZ = {"sinumerik": (test_sinumerik_fuzz, test_sinumerik_fuzz.PROGRAMS),
        "heidenhain": (test_heidenhain_fuzz, test_heidenhain_fuzz.SEEDS)}


def _unmutated_s(dialect: str, programs: list[str], rounds: int = 20) -> float:
    """Mean read time (s) of the programs the mutants come from."""
    t0 = time.perf_counter()
    for _ in range(rounds):
        for text in programs:
            read_text(text, "f", ReaderOptions(dialect=dialect))
    return (time.perf_counter() - t0) / (rounds * len(programs))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mutants", type=int, default=100_000)
    ap.add_argument("--dialect", choices=sorted(FUZZ), action="append")
    args = ap.parse_args()
    for dialect in args.dialect or sorted(FUZZ):
        module, programs = FUZZ[dialect]
        base = _unmutated_s(dialect, programs)
        t0 = time.perf_counter()
        counts = module.run(args.mutants)
        seconds = time.perf_counter() - t0
        print(json.dumps({"dialect": dialect, "mutants": args.mutants, "counts": counts, "crashes": 0,
                          "seconds": round(seconds, 1), "mutants_per_s": round(args.mutants / seconds, 1),
                          "ratio_vs_unmutated": round(seconds / args.mutants / base, 3),
                          "peak_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}))


if __name__ == "__main__":
    main()
