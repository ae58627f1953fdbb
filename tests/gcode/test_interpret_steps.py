"""The interpreter's block steps (`Interpreter.STEPS`): in LinuxCNC's order of execution, woken by the
codes they read (running every step on every block reads the same programs), and each one run on its own
against a block."""

from __future__ import annotations

import pytest

from conftest import SHARED_DATA
from millpost.errors import ParseError
from millpost.gcode import FeedMode, ReaderOptions, dialects, read_program, read_text
from millpost.gcode.interpret import _MODAL_GROUPS, INCH, Interpreter
from millpost.gcode.lexer import lex_line

# LinuxCNC G-code overview, "order of execution": the item each step belongs to (1 O words and 2 comments
# are `Interpreter.run`'s; 7 HAL pin I/O is where M codes that move nothing are passed through)
ORDER = {"set_feed_mode": 3, "set_feed_rate": 4, "set_spindle_speed": 5, "select_tool": 6, "other_m_codes": 7,
         "change_tool": 8, "switch_spindle": 9, "switch_coolant": 11, "dwell": 14, "set_plane": 15, "set_units": 16,
         "radius_compensation": 17, "length_compensation": 18, "select_coordinate_system": 19, "set_path_mode": 20,
         "set_distance_modes": 21, "set_retract_mode": 22, "read_axis_words": 23, "offsets_and_homes": 23,
         "set_motion_mode": 24, "move": 24, "stop": 25}
# the step that reads each G-code modal group
GROUP_STEP = {"motion": "set_motion_mode", "plane": "set_plane", "units": "set_units", "distance": "set_distance_modes",
              "arc distance": "set_distance_modes", "feed mode": "set_feed_mode", "tool length": "length_compensation",
              "retract": "set_retract_mode", "coordinate system": "select_coordinate_system", "path": "set_path_mode"}
# programs that wake every step (the last five are refused: a word nothing uses, two
# motion codes, G93 without F, G98 and M48 with compensation on)
PROGRAMS = [
    "G21 G90 G17 T1 M6 S8000 M3 M8\nG0 X0 Y0 Z5\nG1 Z-1 F300\nG2 X10 Y0 I5 J0\nG4 P0.5\nS9000\nG91 G1 X1\nG90 M9 M5\nM30\n",
    "G20 G94 F10\nG93 G1 X1 F5\nG95 S1000 M4 G1 Y1 F0.002\nG94 G18 G3 X0 Z0 I-0.5 K0 F10\nG17 G61\nG64 P0.01 Q0.01\nM2\n",
    "G21 G55 G0 X0 Y0 Z10\nG10 L2 P2 X5\nG92 X0 Y0\nG28 Z5\nG92.2\nG92.3\nG52 X1\nG30\nM10\nG92.1 G54\nM1\nM0\nM30\n",
    "G21 G99 G0 X0 Y0 Z10\nG81 X1 Y1 Z-2 R1 F100\nX2\nG98 G83 X3 Z-4 Q1 R1\nG80\nG43 H1 G0 Z5\nG49\nM60\nM2\n",
    "G21 G17 T2 M6 G0 X-10 Y-10\nG41 D2 G1 X0 Y0 F300\nY10\nG40 G1 X-10\nG90.1 G2 X-10 Y-30 I-10 J-10\nG91.1\nM2\n",
    "G21 T2\nG0 X1\nT3\nM6\nG1 X2 F100\nM2\n",
    "G21 G0 X0 Y0\nG1 X1 Q3 F100\nM2\n",
    "G21 G1 G2 X1\n",
    "G21 G93 G1 X1 F5\nG1 X2\nM2\n",
    "G21 T1 M6 G0 X-10 Y-10\nG41 D1 G1 X0 Y0 F300\nG98\nM2\n",
    "G21 T1 M6 G0 X-10 Y-10\nG41 D1 G1 X0 Y0 F300\nM48\nM2\n",
]
DIAMETERS_MM = {n: 3.0 for n in range(1, 100)}


def interpreter(dialect: str = "linuxcnc") -> Interpreter:
    return Interpreter(ReaderOptions(), "t.nc", dialects.get(dialect))


def run_step(interp: Interpreter, name: str, text: str):
    codes = interp.block_codes(lex_line(text, 1, "t.nc", {}))
    getattr(Interpreter, name)(interp, codes)
    return codes


def test_steps_follow_linuxcnc_order_of_execution():
    names = [step.__name__ for step in Interpreter.STEPS]
    assert sorted(names) == sorted(ORDER)
    items = [ORDER[n] for n in names]
    assert items == sorted(items)


def test_feed_rate_on_a_units_line_in_the_units_before_it():
    interp = interpreter()
    run_step(interp, "set_feed_rate", "G20 F10")
    run_step(interp, "set_units", "G20 F10")
    assert interp.f == 10.0 and interp.scale == INCH  # LinuxCNC: F before G20, so 10 mm/min
    assert "shares its line with the change to inch" in interp.notes[0]
    grbl = interpreter("grbl")
    run_step(grbl, "set_feed_rate", "G20 F10")
    assert grbl.f == pytest.approx(254.0) and not grbl.notes


def test_feed_mode_step_alone():
    interp = interpreter()
    run_step(interp, "set_feed_mode", "G93 G1 X1 F2")
    assert interp.feed_mode is FeedMode.INVERSE_TIME
    run_step(interp, "set_feed_mode", "G1 X2")
    assert interp.feed_mode is FeedMode.INVERSE_TIME  # modal


def test_spindle_steps_events_in_order():
    interp = interpreter()
    for name in ("set_spindle_speed", "select_tool", "change_tool", "switch_spindle", "switch_coolant"):
        run_step(interp, name, "T3 M6 S1200 M3 M8")
    assert [(e.kind, e.value) for e in interp.events] == [
        ("s_word", 1200.0), ("tool_change", 3), ("spindle", ("cw", 1200.0)), ("coolant", "flood")]
    assert interp.tool == 3 and interp.spindle_on


def test_dwell_step_in_the_dialect_units():
    fanuc = interpreter("fanuc")
    run_step(fanuc, "dwell", "G4 P1500")
    assert fanuc.dwell_s == pytest.approx(1.5)  # Fanuc: P in milliseconds
    with pytest.raises(ParseError, match="dwell G4 needs a non-negative P"):
        run_step(fanuc, "dwell", "G4")


def test_motion_steps_alone():
    interp = interpreter()
    interp.f = 100.0
    codes = run_step(interp, "read_axis_words", "G1 X5 Y2")
    assert set(codes.axis_words) == {"X", "Y"}
    Interpreter.set_motion_mode(interp, codes)
    assert interp.motion == 10 and codes.motion_code == 10
    Interpreter.move(interp, codes)
    assert interp.pos.tolist() == [5.0, 2.0, 0.0]
    codes = run_step(interp, "read_axis_words", "G80 X1")
    with pytest.raises(ParseError, match="axis words with G80"):
        Interpreter.set_motion_mode(interp, codes)


def test_stop_step_ends_the_program():
    interp = interpreter()
    run_step(interp, "stop", "M30")
    assert interp.ended and interp.events[-1].kind == "end"


def test_every_non_modal_code_has_its_handler():
    codes = {c for c, group in _MODAL_GROUPS.items() if group == "non-modal"} - {40, 530}  # G4, G53: steps
    assert set(Interpreter.NON_MODAL) == codes


def test_g92_step_alone():
    interp = interpreter()
    interp.pos = interp.pos + [3.0, 0.0, 0.0]
    codes = run_step(interp, "read_axis_words", "G92 X0")
    Interpreter.offsets_and_homes(interp, codes)
    assert codes.consumed_axes and interp.pos.tolist() == [0.0, 0.0, 0.0] and interp.g92.tolist() == [3.0, 0.0, 0.0]


def codes_waking(name: str) -> set[int]:
    bit = 1 << [step.__name__ for step in Interpreter.STEPS].index(name)
    return {code for code, mask in Interpreter.STEPS.g.items() if mask & bit}


def test_each_g_code_wakes_the_step_that_reads_it():
    for group, name in GROUP_STEP.items():
        codes = {c for c, g in _MODAL_GROUPS.items() if g == group}
        assert codes <= codes_waking(name), (group, name)
    assert codes_waking("set_feed_mode") == set(FeedMode)
    assert codes_waking("offsets_and_homes") == set(Interpreter.NON_MODAL)
    assert codes_waking("dwell") == {40}
    assert codes_waking("length_compensation") == {c for c, g in _MODAL_GROUPS.items() if g == "tool length"}


def reading(path_or_text) -> tuple:
    options = ReaderOptions.linuxcnc()
    options.tool_diameters_mm = DIAMETERS_MM
    try:
        if isinstance(path_or_text, str):
            p = read_text(path_or_text, "t.nc", options)
        else:
            p = read_program(path_or_text, options)
    except ParseError as e:
        return ("refused", str(e))
    tp = p.toolpath
    return (tuple(a.tobytes() for a in (tp.kind, tp.start, tp.end, tp.center, tp.feed_mm_min, tp.rpm, tp.tool,
                                        tp.line, p.feed_mode, p.compensated, p.cycle)),
            repr([(e.line, e.kind, e.value, e.move) for e in p.events]), p.notes)


def test_the_steps_a_block_wakes_read_as_every_step(monkeypatch):
    """A step no code or word of the block wakes does nothing: running all of them on every block reads
    the same moves, events, notes and refusals (hand-written programs, and LinuxCNC's own test programs
    when ../shared/data is present)."""
    programs = PROGRAMS + sorted((SHARED_DATA / "linuxcnc").rglob("*.ngc"))
    woken = [reading(p) for p in programs]
    monkeypatch.setattr(Interpreter.STEPS, "woken_by", lambda codes: Interpreter.STEPS.steps)
    assert [reading(p) for p in programs] == woken
    assert [r[0] == "refused" for r in woken[:len(PROGRAMS)]] == [False] * 6 + [True] * 5
