"""`convert` keeps the machine motion, not just the program-frame path: tool length compensation
(G43 H, G49), G28/G30 homes and G53 moves, checked by LinuxCNC's own interpreter (`rs274`) running
the input and every dialect's output with a tool table of non-zero lengths. What a target cannot
run is refused with file:line:column."""

from __future__ import annotations

import os
import re
import shutil
import subprocess

import pytest

from conftest import SHARED_DATA
from millpost.cli import main
from millpost.errors import MillpostError
from millpost.gcode import dialects, read_program
from millpost.gcode.convert import convert

RS274 = shutil.which("rs274")
needs_rs274 = pytest.mark.skipif(RS274 is None, reason="LinuxCNC's rs274 is not installed")
_CALL = re.compile(r"^\s*\d+\s+N\S*\s+(\w+)\((.*)\)\s*$")

FANUC_STYLE = """%
O1000
G21 G90 G17
T1 M6
S5000 M3
G54
G0 X10 Y10
G43 Z10 H1
G1 Z-1 F300
G1 X20
G0 Z10
G28 G91 Z0.
G90
G0 X30 Y5
G53 G0 Z0.
G49
G0 X0 Y0
M30
%
"""


def machine_moves(path, tmp_path) -> tuple[list[tuple[str, tuple[float, ...]]], str | None]:
    """rs274's moves as machine positions (canonical position + work, G92 and tool length offsets,
    in the program's units), consecutive repeats dropped; and its error message if it stopped."""
    table = tmp_path / "tools.tbl"
    # lengths of 0.1 in · tool number (rs274 reads the table in inches): 2.54 mm for T1
    table.write_text("".join(f"T{i} P{i} Z{0.1 * i:.1f} D0.25 ;\n" for i in range(1, 100)))
    params = tmp_path / "params.var"  # fresh parameters each run (rs274 saves them on exit)
    params.write_text("")
    # rs274 shares its tool table through $HOME/.tool.mmap: a private HOME keeps concurrent runs apart
    proc = subprocess.run([RS274, "-v", str(params), "-t", str(table), "-g", str(path)], capture_output=True,
                          text=True, timeout=60, stdin=subprocess.DEVNULL, cwd=path.parent,
                          env={**os.environ, "HOME": str(tmp_path)})
    g5x = g92 = tlo = (0.0, 0.0, 0.0)
    moves: list[tuple[str, tuple[float, ...]]] = []
    error = None
    for line in (proc.stdout + "\n" + proc.stderr).splitlines():
        m = _CALL.match(line)
        if not m:
            if line.strip() and line.strip() != "executing" and error is None:
                error = line.strip()
            continue
        name = m.group(1)
        if name not in ("SET_G5X_OFFSET", "SET_G92_OFFSET", "USE_TOOL_LENGTH_OFFSET", "STRAIGHT_TRAVERSE",
                        "STRAIGHT_FEED", "ARC_FEED"):
            continue
        args = [float(v) for v in re.split(r"[,\s]+", m.group(2).strip()) if v]
        if name == "SET_G5X_OFFSET":
            g5x = tuple(args[1:4])
        elif name == "SET_G92_OFFSET":
            g92 = tuple(args[:3])
        elif name == "USE_TOOL_LENGTH_OFFSET":
            tlo = tuple(args[:3])
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED"):
            if name == "ARC_FEED":
                continue  # the programs here have no arcs
            pos = tuple(round(args[k] + g5x[k] + g92[k] + tlo[k], 4) for k in range(3))
            kind = "rapid" if name == "STRAIGHT_TRAVERSE" else "feed"
            if not moves or moves[-1][1] != pos:
                moves.append((kind, pos))
    return moves, error


@needs_rs274
@pytest.mark.parametrize("dialect", ["linuxcnc", "fanuc", "mach3"])
def test_tool_length_home_and_g53_keep_the_machine_motion(dialect, tmp_path):
    src = tmp_path / "in.nc"
    src.write_text(FANUC_STYLE)
    out = tmp_path / f"out_{dialect}.nc"
    assert main(["convert", str(src), "--to", dialect, "-o", str(out)]) == 0
    text = out.read_text()
    assert re.search(r"G43 H1\b", text) and "G28" in text and "G53" in text
    want, err_in = machine_moves(src, tmp_path)
    got, err_out = machine_moves(out, tmp_path)
    assert err_in is None and err_out is None
    assert got == want
    # the tip ran at Z-1 with a 2.54 mm tool: the spindle nose at -1 + 2.54; G28 went to machine Z0
    assert ("feed", (20.0, 10.0, 1.54)) in got and any(p[2] == 0.0 for _, p in got)


@needs_rs274
def test_original_g49_bug_is_visible_to_the_oracle(tmp_path):
    """The oracle sees the difference the old conversion made (G43 H1 posted as G49): without the
    tool length the tip runs 2.54 mm lower."""
    src = tmp_path / "in.nc"
    src.write_text(FANUC_STYLE)
    bad = tmp_path / "bad.nc"
    bad.write_text(FANUC_STYLE.replace("G43 Z10 H1", "G49 Z10"))
    want, _ = machine_moves(src, tmp_path)
    got, _ = machine_moves(bad, tmp_path)
    assert got != want and ("feed", (20.0, 10.0, -1.0)) in got


def test_grbl_refuses_tool_table_compensation(tmp_path, capsys):
    src = tmp_path / "in.nc"
    src.write_text(FANUC_STYLE)
    out = tmp_path / "out.nc"
    assert main(["convert", str(src), "--to", "grbl", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{src}:8:1: convert: grbl has no G43" in err
    assert not out.exists()


def test_first_move_does_not_invent_an_axis(tmp_path):
    """`G0 X10 Y10` at the start leaves Z where the machine stands: the output must not add the
    reader's assumed Z0 (a dive to the work zero), nor after a home or G53 retract."""
    src = tmp_path / "in.nc"
    src.write_text(FANUC_STYLE)
    text = convert(read_program(src), dialects.get("linuxcnc"))
    moves = [ln for ln in text.splitlines() if ln.startswith("G0 ")]
    assert moves[0] == "G0 X10 Y10"
    assert "G0 X0 Y0" in moves  # after G53 Z0: no Z word


@pytest.mark.parametrize("line,word", [("G92 X0 Y0", "G92"), ("G52 X5", "G52"), ("G10 L2 P1 X5", "G10"),
                                       ("G28.1", "G28.1"), ("G92.1", "G92.1")])
def test_offsets_set_in_the_program_are_refused(line, word, tmp_path):
    src = tmp_path / "in.ngc"
    src.write_text(f"G21 G90\nG0 X1 Y1 Z5\n{line}\nG1 X3 F100\nM2\n")
    with pytest.raises(MillpostError, match=re.escape(f"{src}:3:1: convert: offsets set in the program")) as exc:
        convert(read_program(src), dialects.get("linuxcnc"))
    assert exc.value.word == word


CORPUS = sorted(p for p in SHARED_DATA.rglob("*") if p.suffix.lower() in {".ngc", ".nc", ".tap", ".gcode"}
                and re.search(r"G4[39]|G28|G30|G53", p.read_text(errors="replace"), re.I)
                and "unsupported" not in p.parts) if SHARED_DATA.exists() else []


@needs_rs274
@pytest.mark.skipif(not CORPUS, reason="../shared/data is absent (third-party corpus)")
@pytest.mark.parametrize("path", CORPUS, ids=[str(p.relative_to(SHARED_DATA)) for p in CORPUS])
def test_corpus_machine_motion_survives_every_dialect(path, tmp_path):
    """Every corpus program using G43/G49/G28/G30/G53 that both readers run: each dialect's output
    makes the same machine moves under rs274 with a tool table, or is refused explicitly."""
    try:
        program = read_program(path)
    except MillpostError:
        return  # refused by the reader: covered by the corpus tests
    want, err = machine_moves(path, tmp_path)
    if err is not None or not want:
        pytest.skip(f"rs274 does not run it: {err}")
    for name in ("linuxcnc", "fanuc", "mach3", "grbl"):
        try:
            text = convert(program, dialects.get(name))
        except MillpostError as exc:
            assert re.match(rf"{re.escape(str(path))}:\d+:\d+: convert: ", str(exc)), str(exc)
            continue
        out = tmp_path / f"out_{name}.ngc"
        out.write_text(text)
        got, err_out = machine_moves(out, tmp_path)
        assert err_out is None, (name, err_out)
        assert [k for k, _ in got] == [k for k, _ in want], name
        # the trace prints 4 decimals; the dialects write 4 (mm) or 6 (inch)
        assert max((abs(a - b) for (_, p), (_, q) in zip(got, want) for a, b in zip(p, q)), default=0) <= 2e-4, name


@pytest.mark.parametrize("text", ["%\n%\n", "G43 H1\nM30\n", "(only a comment)\n"])
def test_programs_without_moves_convert_or_refuse_cleanly(text, tmp_path):
    src = tmp_path / "in.nc"
    src.write_text(text)
    program = read_program(src)
    for name in ("linuxcnc", "fanuc", "mach3", "grbl"):
        try:
            out = convert(program, dialects.get(name))
        except MillpostError as exc:
            assert name == "grbl" and f"{src}:1:1: convert: grbl has no G43" in str(exc)
            continue
        assert ("G43 H1" in out) == ("G43" in text)


def test_incremental_move_from_an_unknown_position_is_refused(tmp_path):
    """`G91 G0 Z-5` as the first Z move goes 5 mm down from wherever Z stands: an absolute Z word
    (the reader's assumed start minus 5) would send the tool elsewhere."""
    src = tmp_path / "in.ngc"
    src.write_text("G21 G90\nG0 X10 Y10\nG91 G0 Z-5\nG90 G1 X20 F100\nM2\n")
    with pytest.raises(MillpostError, match=re.escape(f"{src}:3:1: convert: an incremental (G91) move of Z")):
        convert(read_program(src), dialects.get("linuxcnc"))
