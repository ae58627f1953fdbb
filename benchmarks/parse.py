"""Parse speed and memory on a 1 M-line program (Fusion-style adaptive clearing: modal G1 lines with
arcs every tenth block). Prints one JSON object: blocks_per_s, seconds, peak_rss_mb, bytes_per_block
(peak memory beyond the text, per block) and ratio_vs_regex_scan (time against the least a reader can
do — one regex scan of every line — measured in the same run).

    python benchmarks/parse.py [--lines N]
"""

from __future__ import annotations

import argparse
import json
import re
import resource
import sys
import time


def program(n: int) -> str:
    out = ["G21 G90 G17", "T1 M6", "S12000 M3", "G0 X0 Y0 Z5", "G1 Z-2 F800"]
    x = y = 0.0
    for i in range(n - 6):
        if i % 10 == 9:
            out.append(f"G3 X{x + 1:.3f} Y{y:.3f} I0.5 J0")
            x += 1
        else:
            x += 0.137 if (i // 200) % 2 == 0 else -0.137
            y += 0.011
            out.append(f"G1 X{x:.3f} Y{y:.3f}" + (" F1500" if i % 50 == 0 else ""))
    out.append("M30")
    return "\n".join(out) + "\n"


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--lines", type=int, default=1_000_000)
    n = ap.parse_args().lines
    text = program(n)
    word = re.compile(r"([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
    t0 = time.perf_counter()
    count = 0
    for line in text.split("\n"):
        count += len(word.findall(line))
    baseline_s = time.perf_counter() - t0
    del count

    from millpost.gcode import read_text

    before = rss_mb()
    t0 = time.perf_counter()
    prog = read_text(text, "bench.nc")
    seconds = time.perf_counter() - t0
    peak = rss_mb()
    blocks = prog.blocks
    json.dump({
        "lines": n, "blocks": blocks, "moves": len(prog.toolpath), "seconds": round(seconds, 3),
        "blocks_per_s": round(blocks / seconds), "peak_rss_mb": round(peak, 1),
        "bytes_per_block": round((peak - before) * 1024 * 1024 / blocks, 1),
        "text_mb": round(len(text) / 1e6, 1), "regex_scan_s": round(baseline_s, 3),
        "ratio_vs_regex_scan": round(seconds / baseline_s, 2),
    }, sys.stdout)
    print()


if __name__ == "__main__":
    main()
