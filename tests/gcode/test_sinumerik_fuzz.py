"""Seeded mutation fuzzing of the Sinumerik reader: every mutant of Sinumerik programs (posted and
hand-written styles) is read or refused with a ParseError/MillpostError naming the file and line;
never an uncaught exception, a non-finite number or a hang. A few thousand mutants here;
benchmarks/fuzz_dialects.py runs 100 000."""

from __future__ import annotations

import random

import gcode_mutants
from millpost.errors import MillpostError, ParseError
from millpost.gcode import ReaderOptions, read_text

PROGRAMS = [
    """%_N_PART_MPF
;$PATH=/_N_MPF_DIR
N10 G90 G94 G40 G17 G710
N20 T="FLAT10" D1
N30 M6
N40 S6000 M3 M8
N50 G54 CYCLE832(0.01,_SEMIFIN,1)
N60 G0 X-10 Y0 Z15
N70 G1 Z-3 F300.
N80 G1 X50 F1200. ; pass
N90 G2 X60 Y10 I0 J10
N100 G3 X50 Y20 CR=10
N110 G3 X40 Y20 I=AC(45) J=AC(20)
N120 G1 X=IC(-10) Y=AC(30)
N130 G4 F1.5
N140 G0 SUPA Z0 D0
N150 M30
""",
    """N10 G90 G17 G710
N20 T2 D1 M6
N30 S1200 M3
N40 G0 X0 Y0 Z10
N50 F120.
N60 MCALL CYCLE81(10, 0, 2, -6, )
N70 X5 Y5
N80 X15
N90 MCALL
N100 CYCLE82(10, 0, 2, , 4, 0.5)
N110 MCALL CYCLE83(10, 0, 2, -12, , , 3, 0, , 0, 1, 1)
N120 X50
N130 MCALL
N140 M30
""",
    """N10 DEF REAL DEPTH=-2, STEP=0.5
N20 R1=0 R2=R1+2
N30 G0 X0 Y0 Z5 S1000 M3
LOOP1:
N50 G1 X=R1*10 Z=DEPTH+STEP F100
N60 R1=R1+1
N70 IF R1<3 GOTOB LOOP1
N80 IF R1==3 GOTOF SKIP
N90 G1 Y50
SKIP:
N110 WHILE R1>0
N120 G91 G1 X1 Y=AC(5)
N130 R1=R1-1
N140 ENDWHILE
N150 TRANS X10
N160 G2 X20 Y0 AR=90
N170 REPEAT
N180 ATRANS Y1
N190 R2=R2-1
N200 UNTIL R2<=0
N210 IF DEPTH<0
N220 MSG("deep (ok)")
N230 ELSE
N240 G4 S10
N250 ENDIF
N260 M30
""",
    """N10 G90 G17 G710 G0 X0 Y0 Z2
N20 G1 Z-1 F200
N30 G1 X10
N40 CT X20 Y10
N50 X30 Y0
N60 G2 X40 Y10 CR=10
N70 CT X50 Y0
N80 G18 G1 Z5
N90 CT Z10 X55
N100 G17 G0 Z10
N110 M30
""",
]
# frames (ROT, SCALE, MIRROR), tapping/boring cycles and hole patterns: most of their mutants are refused,
# so they are fuzzed apart
FRAME_PROGRAMS = [
    """N10 G90 G17 G710 G0 X0 Y0 Z2
N20 TRANS X10 Y5
N30 AROT RPL=30
N40 G1 Z-1 F200
N50 G1 X10 Y0
N60 G3 X10 Y10 I0 J5
N70 G91 G1 X-5 Y=AC(10)
N80 ASCALE X2 Y2
N90 G90 G2 X0 Y5 CR=3
N100 AMIRROR X0
N110 G1 X5 Y0
N120 G2 X0 Y5 I=AC(0) J=AC(0)
N130 ATRANS X1
N140 ROT Z-15
N150 MCALL CYCLE81(5, 0, 1, -3)
N160 X1 Y1
N170 MCALL
N180 MIRROR
N190 G0 Z10
N200 M30
""",
    """N10 G90 G17 G710 T3 D1 M6
N20 S800 M3
N30 G0 X0 Y0 Z10
N40 F150
N50 CYCLE84(10, 0, 2, -12, , , 3, , 1.25, , 400)
N60 G1 X5
N70 MCALL CYCLE85(10, 0, 2, -8, , 0.5, 120, 120)
N80 HOLES1(10, 20, 30, 5, 10, 3)
N90 MCALL CYCLE86(10, 0, 2, -5, , 1, 3, 0, 0, 0, 90)
N100 HOLES2(0, 0, 15, 0, 0, 5)
N110 X40 Y40
N120 MCALL
N130 CYCLE84(10, 0, 2, , 6, , , 8)
N140 G1 X0 Y0
N150 M30
""",
]
SNIPPETS = ["CR=", "AR=", "X=AC(", "I=AC(", "=IC(", "R1=", "R[", "DEF REAL", "IF", "ENDIF", "ELSE", "GOTOF", "GOTOB",
            "WHILE", "ENDWHILE", "LOOP", "REPEAT", "UNTIL", "MCALL", "CYCLE81(", "CYCLE83(1,0,", "TRANS", "ATRANS",
            "ROT", '"', "(", ")", "=", "==", ",", ":", "MSG(\"", "T=\"", ";", "G4 S", "G4 F", "SUPA", "G700", "G70",
            "TURN=", "ADIS=", "G641", "$PI", "SIN(", "POT(", "DIV", "MOD", "NOT", "AND", "1EX308", "/0", "LBL:"]


def mutant(seed: int, programs: list[str] = PROGRAMS) -> tuple[str, str]:
    """(mutated text, what was done) for a seed."""
    rng = random.Random(seed)
    lines = programs[rng.randrange(len(programs))].splitlines()
    done = []
    for _ in range(rng.choice([1, 1, 2, 3])):
        i = rng.randrange(len(lines))
        if rng.random() < 0.5:
            at = rng.randrange(len(lines[i]) + 1)
            lines[i] = lines[i][:at] + rng.choice(SNIPPETS) + lines[i][at:]
            done.append(f"snippet@{i + 1}")
        elif rng.random() < 0.9:
            lines[i] = gcode_mutants.mutate_line(rng, lines[i], "ABCDEFGHIJKLMNOPQRSTUVWXYZ")
            done.append(f"line@{i + 1}")
        else:
            j = rng.randrange(len(lines))
            lines[i], lines[j] = lines[j], lines[i]
            done.append(f"swap@{i + 1},{j + 1}")
    return "\n".join(lines) + "\n", " ".join(done)


def run(count: int, programs: list[str] = PROGRAMS, accepted: int = 10) -> dict[str, int]:
    """Mutants of `programs` read or refused with file:line, more than 1/5 refused and 1/`accepted` read."""
    failures, counts = [], {}
    for seed in range(count):
        text, done = mutant(seed, programs)
        status, detail = gcode_mutants.check_with(text, "fuzz.mpf", ReaderOptions(dialect="sinumerik"), seconds=10.0)
        counts[status] = counts.get(status, 0) + 1
        if status not in ("accepted", "refused"):
            failures.append(f"seed {seed} ({done}): {status}: {detail}")
        elif status == "refused" and not detail.startswith("fuzz.mpf:"):
            failures.append(f"seed {seed} ({done}): refusal without file:line: {detail}")
    assert not failures, "\n".join(failures[:20])
    assert counts.get("refused", 0) > count // 5 and counts.get("accepted", 0) > count // accepted, counts
    return counts


def test_the_programs_mutated_are_read():
    for text in PROGRAMS + FRAME_PROGRAMS:
        assert len(read_text(text, "fuzz.mpf", ReaderOptions(dialect="sinumerik")).toolpath) > 3


def test_mutants_are_read_or_refused_never_crash():
    run(3000)


def test_mutants_of_frames_are_read_or_refused_never_crash():
    run(600, FRAME_PROGRAMS, accepted=30)


def test_refusals_name_file_line_and_column():
    seen = 0
    for seed in range(400):
        text, _ = mutant(seed)
        try:
            read_text(text, "fuzz.mpf", ReaderOptions(dialect="sinumerik"))
        except ParseError as err:
            seen += 1
            assert err.file == "fuzz.mpf" and 1 <= err.line <= len(text.splitlines()) and err.column >= 1, str(err)
            assert err.expected, str(err)
        except MillpostError:
            pass
    assert seen > 80
