"""Mutation fuzzing of the G-code reader at scale (issue 13: >= 100 000 mutants of the real corpus;
the test suite runs 3 000). Each mutant (tests/gcode_mutants.py: 1-3 seeded mutations of a window of
at most 2 000 lines of a program in ../shared/data) is read with a 10 s CPU-time limit, alternately
with the LinuxCNC dialect and with the dialect detected from the text, in worker processes whose
address space is capped (--memory-mb), so memory growing without bound shows as a MemoryError.

Prints one JSON object: mutants, accepted, refused, uncaught (exceptions other than MillpostError),
hangs (over 10 s of CPU), nonfinite (inf/NaN in an accepted program or its summary), examples of each
failure (seed, program, mutation, message), seconds, mutants_per_s, the slowest mutant's CPU and wall
seconds, peak_mb (largest worker), and ratio_vs_unmutated (mean read time of a mutant over that of
the unmutated windows, measured in the same run).

Run: nice python benchmarks/fuzz.py [--mutants 100000] [--processes 2] [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import gcode_mutants  # noqa: E402
from conftest import SHARED_DATA  # noqa: E402

WINDOW = 2000
_programs: list = []


def _init(memory_mb: int) -> None:
    global _programs
    if memory_mb:
        limit = memory_mb * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    _programs = gcode_mutants.corpus(SHARED_DATA)


def _chunk(seeds: range) -> dict:
    counts: dict[str, int] = {}
    examples: dict[str, list] = {}
    slowest = (0.0, 0.0, -1)
    for seed in seeds:
        name, text, done = gcode_mutants.mutant(_programs, seed, window=WINDOW)
        c0, w0 = time.process_time(), time.perf_counter()
        status, detail = gcode_mutants.check(text, name, linuxcnc=seed % 2 == 0, seconds=10.0)
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        if cpu > slowest[0]:
            slowest = (cpu, wall, seed)
        counts[status] = counts.get(status, 0) + 1
        if status not in ("accepted", "refused") and len(examples.setdefault(status, [])) < 10:
            examples[status].append({"seed": seed, "program": name, "mutation": done, "detail": detail})
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {"counts": counts, "examples": examples, "slowest": slowest, "peak_mb": peak}


def _baseline(programs: list) -> float:
    """Mean seconds to read one unmutated window (the first WINDOW lines of each program)."""
    from millpost.errors import MillpostError
    from millpost.gcode import ReaderOptions, read_text

    t0 = time.perf_counter()
    for name, lines in programs:
        try:
            read_text("\n".join(lines[:WINDOW]) + "\n", name, ReaderOptions.linuxcnc())
        except MillpostError:
            pass
    return (time.perf_counter() - t0) / len(programs)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--mutants", type=int, default=100_000)
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--chunk", type=int, default=250)
    ap.add_argument("--memory-mb", type=int, default=3000, help="address-space cap per worker (0: none)")
    args = ap.parse_args()
    if not SHARED_DATA.exists():
        sys.exit(f"{SHARED_DATA} is absent (third-party corpus, not in the repo)")
    programs = gcode_mutants.corpus(SHARED_DATA)
    baseline_s = _baseline(programs)
    stop = args.seed + args.mutants
    chunks = [range(s, min(s + args.chunk, stop)) for s in range(args.seed, stop, args.chunk)]
    totals: dict[str, int] = {}
    examples: dict[str, list] = {}
    slowest, peak = (0.0, 0.0, -1), 0.0
    t0 = time.perf_counter()
    with multiprocessing.Pool(args.processes, _init, (args.memory_mb,)) as pool:
        for res in pool.imap_unordered(_chunk, chunks):
            for k, v in res["counts"].items():
                totals[k] = totals.get(k, 0) + v
            for k, v in res["examples"].items():
                examples.setdefault(k, []).extend(v[:10 - len(examples.get(k, []))])
            slowest = max(slowest, res["slowest"])
            peak = max(peak, res["peak_mb"])
    seconds = time.perf_counter() - t0
    mean_s = seconds * args.processes / args.mutants
    json.dump({
        "mutants": args.mutants, "programs": len(programs), "seed": args.seed,
        "accepted": totals.get("accepted", 0), "refused": totals.get("refused", 0),
        "uncaught": totals.get("uncaught", 0), "hangs": totals.get("hang", 0),
        "nonfinite": totals.get("nonfinite", 0), "examples": examples,
        "seconds": round(seconds, 1), "mutants_per_s": round(args.mutants / seconds, 1),
        "slowest_mutant": {"cpu_s": round(slowest[0], 3), "wall_s": round(slowest[1], 3), "seed": slowest[2]},
        "peak_mb": round(peak, 1), "unmutated_read_s": round(baseline_s, 5),
        "ratio_vs_unmutated": round(mean_s / baseline_s, 2),
    }, sys.stdout)
    print()


if __name__ == "__main__":
    main()
