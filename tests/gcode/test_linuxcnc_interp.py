"""LinuxCNC's interpreter test cases (../shared/data/linuxcnc/tests/interp and tests/ccomp, cutter
compensation): each case's `expected` file is the canonical trace LinuxCNC printed, with the case's
tool table `test.tbl` when it has one (read in inches, as the standalone interpreter does). For every
case within scope (millpost does not refuse it as an out-of-scope feature: lathe cycles, rotation,
lathe tool orientations, ...), the moves must match the expected STRAIGHT_TRAVERSE / STRAIGHT_FEED /
ARC_FEED sequence within 1e-4 in program units.
The counts are printed (run with -s) and asserted against the measured coverage."""

from __future__ import annotations

from pathlib import Path

import pytest

import rs274_oracle
from conftest import SHARED_DATA
from millpost.errors import ParseError
from millpost.gcode import ReaderOptions, read_program
from millpost.gcode.tool_table import read_tool_table

TESTS = SHARED_DATA / "linuxcnc" / "tests"
ROOT = TESTS / "interp"
# LinuxCNC 2.9 feeds G84 along the wrong axis in G18/G19; its `expected` traces record the bug.
LINUXCNC_BUGS = ("g84/g18", "g84/g19")


def cases() -> list[tuple[Path, Path]]:
    out = []
    for expected in sorted(ROOT.rglob("expected")) + sorted((TESTS / "ccomp").rglob("expected")):
        programs = sorted(expected.parent.glob("*.ngc"))
        if len(programs) == 1 and not (expected.parent / "test.ini").exists():
            out.append((programs[0], expected))
    return out


@pytest.mark.skipif(not ROOT.exists(), reason=f"{ROOT} is absent (third-party corpus, not in the repo)")
def test_interp_cases_match_expected_traces() -> None:
    in_scope, matched, refused, failures = 0, 0, [], []
    for program_path, expected in cases():
        name = str(program_path.relative_to(TESTS))
        trace = rs274_oracle.parse(expected.read_text(errors="replace"))
        options = ReaderOptions.linuxcnc()
        table = program_path.parent / "test.tbl"
        if table.exists():
            if any(q not in (0, 9) for q in read_tool_table(table, units="inch").orientation.values()):
                refused.append(f"{name}: lathe tool orientations (compensation of a lathe tool's nose)")
                continue
            options.use_tool_table(table, units="inch")
        try:
            program = read_program(program_path, options)
        except ParseError as err:
            if "not supported" in err.reason or "unknown G code" in err.reason:
                refused.append(f"{name}: {err.reason}")
                continue
            in_scope += 1
            if trace.error is None and trace.moves:
                failures.append(f"{name}: refused what LinuxCNC ran: {err}")
            else:
                matched += 1  # both refuse
            continue
        if any(bug in name for bug in LINUXCNC_BUGS):
            refused.append(f"{name}: LinuxCNC bug recorded in expected")
            continue
        in_scope += 1
        diff = rs274_oracle.mismatches(program, trace, prefix=trace.error is not None)
        if diff:
            failures.append(f"{name}: {diff[:2]}")
        else:
            matched += 1
    print(f"\nLinuxCNC interp cases: {in_scope} in scope, {matched} match; {len(refused)} out of scope:")
    print("\n".join("  " + r for r in refused))
    assert not failures, "\n".join(failures)
    assert in_scope >= 15
    assert not any("ccomp" in r or "cam-nisley" in r for r in refused if "lathe" not in r)
