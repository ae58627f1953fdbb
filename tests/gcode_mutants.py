"""A seeded mutation fuzzer for the G-code reader, over the real corpus in ../shared/data.

`mutant(programs, seed)` takes one corpus program (a window of at most `window` lines of it, the
header kept) and applies 1 to 3 mutations of the kinds that broke readers before: digit runs and huge
numbers (``X`` + 309 nines overflows a float), exponents (``X1e308``), words deleted, duplicated,
swapped or moved, random letters with numbers (``Q0.001`` on a G1), truncation, stray characters,
and control-flow edits (loop bounds, repeat counts ``L``/``repeat [n]``, conditions, ``M98``/``M99``,
dropped ``endwhile``/``endsub``). `check(text)` reads a mutant and classifies it: accepted (and every
number of the result finite), refused (a MillpostError), or a failure: an uncaught exception, a
non-finite value in an accepted program, or (with a time limit) a hang. Used by tests/gcode/test_fuzz.py
(a few thousand mutants) and benchmarks/fuzz.py (>= 100 000).
"""

from __future__ import annotations

import json
import math
import random
import re
import signal
from pathlib import Path

import numpy as np

from millpost.errors import MillpostError
from millpost.gcode import ReaderOptions, read_text
from millpost.gcode.summary import summary
from millpost.toolpath import ARC_CW, RAPID

EXTENSIONS = {".ngc", ".nc", ".gcode", ".tap", ".cnc"}
_NUMBER = re.compile(r"(?<![A-Za-z_<])[-+]?(?:\d+\.?\d*|\.\d+)")
_WORD = re.compile(r"[A-Za-z][ \t]*[-+]?(?:\d+\.?\d*|\.\d+)")
_FLOW = re.compile(r"\b(while|repeat|if|elseif|do|call|sub|endsub|endwhile|endrepeat|return|M98|M99|L\d+)\b",
                   re.IGNORECASE)


def corpus(root: Path) -> list[tuple[str, list[str]]]:
    """(name, lines) of every G-code program under `root`, sorted by path."""
    out = []
    for path in sorted(root.rglob("*")):
        if path.suffix.lower() in EXTENSIONS and path.is_file():
            text = path.read_bytes().decode("utf-8", errors="replace")
            out.append((str(path.relative_to(root)), text.splitlines()))
    return out


def _numbers(line: str) -> list[re.Match]:
    return list(_NUMBER.finditer(line))


def _replace_number(rng: random.Random, line: str, make) -> str:
    found = _numbers(line)
    if not found:
        return line
    m = rng.choice(found)
    return line[:m.start()] + make(m.group(0)) + line[m.end():]


def _huge(rng: random.Random, text: str) -> str:
    digits = rng.choice([10, 11, 16, 20, 40, 308, 309, 310, 400])
    run = rng.choice("19") * digits if rng.random() < 0.5 else "".join(rng.choice("0123456789") for _ in range(digits))
    sign = "-" if rng.random() < 0.3 else ""
    return sign + run.lstrip("0") or "0"


def _exponent(rng: random.Random, text: str) -> str:
    return text + rng.choice(["e308", "E308", "e-5", "e3", "E+2", "e400", "e"])


def _special(rng: random.Random, text: str) -> str:
    return rng.choice(["nan", "inf", "-inf", "1.5.5", ".", "-", "+-1", "0.000000001", "1e6", "99999999999",
                       "-0", "1" + "0" * rng.choice([5, 6, 9, 12]), "0.0001"])


def _tiny_or_big(rng: random.Random, text: str) -> str:
    return rng.choice(["0.001", "0.0000001", "1000000", "100000", "2147483648", "10000000000", "0", "-1"])


def mutate_line(rng: random.Random, line: str, letters: str) -> str:
    """One mutation of one line."""
    kind = rng.randrange(12)
    words = list(_WORD.finditer(line))
    if kind == 0:
        return _replace_number(rng, line, lambda t: _huge(rng, t))
    if kind == 1:
        return _replace_number(rng, line, lambda t: _exponent(rng, t))
    if kind == 2:
        return _replace_number(rng, line, lambda t: _special(rng, t))
    if kind == 3:
        return _replace_number(rng, line, lambda t: _tiny_or_big(rng, t))
    if kind == 4 and words:  # delete a word
        m = rng.choice(words)
        return line[:m.start()] + line[m.end():]
    if kind == 5 and words:  # duplicate a word
        m = rng.choice(words)
        return line[:m.end()] + " " + m.group(0) + line[m.end():]
    if kind == 6 and len(words) >= 2:  # swap two words
        a, b = sorted(rng.sample(words, 2), key=lambda m: m.start())
        return line[:a.start()] + b.group(0) + line[a.end():b.start()] + a.group(0) + line[b.end():]
    if kind == 7:  # a random letter with a number
        word = rng.choice(letters) + rng.choice(["0", "1", "2", "-1", "0.001", "10", "1000000", "3.5", "99"])
        at = rng.randrange(len(line) + 1)
        return line[:at] + " " + word + " " + line[at:]
    if kind == 8 and line:  # truncate the line
        return line[:rng.randrange(len(line))]
    if kind == 9:  # a stray character
        at = rng.randrange(len(line) + 1)
        return line[:at] + rng.choice("#[]()%/;*<>=@^$!\"\\\t.-+eE") + line[at:]
    if kind == 10:  # a G or M code
        word = rng.choice(["G0", "G1", "G2", "G3", "G4", "G10", "G17", "G18", "G19", "G20", "G28", "G43", "G53",
                           "G73", "G80", "G81", "G83", "G87", "G90", "G91", "G91.1", "G92", "G93", "G95", "G98",
                           "G99", "M3", "M5", "M6", "M98", "M99", "M2", "G52", "G4 P1", "G83 R1 Q0.001 Z-10"])
        return word + " " + line if rng.random() < 0.5 else line + " " + word
    if kind == 11 and words:  # change a letter
        m = rng.choice(words)
        return line[:m.start()] + rng.choice(letters) + line[m.start() + 1:]
    return line + " " + rng.choice(letters) + str(rng.randrange(100))


def mutate_flow(rng: random.Random, lines: list[str], at: int) -> None:
    """A control-flow mutation of line `at` (an O-word statement, M98/M99 or an L count), in place."""
    line = lines[at]
    choice = rng.randrange(6)
    if choice == 0:  # the bound of a loop or condition, a repeat count, L
        lines[at] = _replace_number(rng, line, lambda t: rng.choice(["1000000000", "99999", "0", "-1", "1e9",
                                                                      "100000", "2147483648", "0.5"]))
    elif choice == 1:  # drop the statement (an endwhile, endsub, M99 that never comes)
        lines[at] = ""
    elif choice == 2:  # a condition that always holds
        lines[at] = re.sub(r"\[.*\]", "[1]", line, count=1)
    elif choice == 3:  # duplicate the statement
        lines.insert(at, line)
    elif choice == 4:  # swap the keyword
        lines[at] = re.sub(r"\b(while|repeat|if|do|endwhile|endrepeat|endif)\b",
                           lambda m: rng.choice(["while", "do", "repeat", "endwhile", "endif", "continue", "break"]),
                           line, count=1, flags=re.IGNORECASE)
    else:  # a call to itself or a repeat without end
        lines.insert(rng.randrange(len(lines) + 1), line)


def mutant(programs: list[tuple[str, list[str]]], seed: int, window: int = 2000) -> tuple[str, str, str]:
    """(program name, mutated text, what was done) for a seed: reproducible."""
    rng = random.Random(seed)
    name, lines = programs[rng.randrange(len(programs))]
    lines = list(lines)
    if len(lines) > window:  # the header, then a window of the body (reading cost stays bounded)
        start = rng.randrange(20, len(lines) - window + 20)
        lines = lines[:20] + lines[start:start + window - 20]
    letters = "ABCDEFGHIJKLMNOPQRSTUVWXYZ" + "DEHIJKLPQR" * 2  # the words most often misplaced, more often
    done = []
    for _ in range(rng.choice([1, 1, 2, 3])):
        if not lines:
            break
        flow = [i for i, ln in enumerate(lines) if _FLOW.search(ln)]
        if flow and rng.random() < 0.3:
            i = rng.choice(flow)
            mutate_flow(rng, lines, i)
            done.append(f"flow@{i + 1}")
        elif rng.random() < 0.05:  # truncate the program
            cut = rng.randrange(len(lines))
            lines = lines[:cut]
            done.append(f"truncate@{cut}")
        elif rng.random() < 0.05:  # delete, duplicate or swap lines
            i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
            op = rng.randrange(3)
            if op == 0:
                del lines[i]
            elif op == 1:
                lines.insert(j, lines[i])
            else:
                lines[i], lines[j] = lines[j], lines[i]
            done.append(f"lines{op}@{i + 1},{j + 1}")
        else:
            i = rng.randrange(len(lines))
            lines[i] = mutate_line(rng, lines[i], letters)
            done.append(f"line@{i + 1}")
    return name, "\n".join(lines) + "\n", " ".join(done)


def nonfinite(program) -> str | None:
    """What is not finite in an accepted program (None when all is): positions, arc centres, feeds
    of feed moves, spindle speeds, dwell, and the `inspect` summary as strict JSON."""
    tp = program.toolpath
    if not (np.isfinite(tp.start).all() and np.isfinite(tp.end).all()):
        return "move end point"
    arc = tp.kind >= ARC_CW
    if not np.isfinite(tp.center[arc]).all():
        return "arc centre"
    if not np.isfinite(tp.feed_mm_min[tp.kind != RAPID]).all():
        return "feed"
    if not np.isfinite(tp.rpm).all() or not math.isfinite(program.dwell_s):
        return "spindle speed or dwell"
    try:
        json.dumps(summary(program), allow_nan=False)
    except ValueError:
        return "summary (inspect) JSON"
    return None


class Hang(Exception):
    """Raised by the CPU-time alarm of `check`."""


def _alarm(signum, frame):
    raise Hang


def check(text: str, name: str, linuxcnc: bool, seconds: float | None = None) -> tuple[str, str]:
    """Read a mutant: ("accepted" | "refused" | "uncaught" | "nonfinite" | "hang", detail). With
    `seconds`, a read using more CPU time than that is stopped and reported as a hang (Unix only)."""
    return check_with(text, name, ReaderOptions.linuxcnc() if linuxcnc else ReaderOptions(), seconds)


def check_with(text: str, name: str, options: ReaderOptions, seconds: float | None = None) -> tuple[str, str]:
    """`check` with the reader's options given (a dialect forced)."""
    if seconds:
        old = signal.signal(signal.SIGPROF, _alarm)
        signal.setitimer(signal.ITIMER_PROF, seconds)
    try:
        program = read_text(text, name, options)
        bad = nonfinite(program)
    except MillpostError as err:
        return "refused", str(err)[:200]
    except Hang:
        return "hang", f"more than {seconds} s of CPU"
    except Exception as exc:  # noqa: BLE001 - what the fuzzer looks for
        return "uncaught", f"{type(exc).__name__}: {str(exc)[:200]}"
    finally:
        if seconds:
            signal.setitimer(signal.ITIMER_PROF, 0)
            signal.signal(signal.SIGPROF, old)
    return ("nonfinite", bad) if bad else ("accepted", "")
