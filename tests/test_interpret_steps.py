"""The interpreter's block steps (`Interpreter.STEPS`): in LinuxCNC's order of execution, and each one
run on its own against a block."""

from __future__ import annotations

import pytest

from millpost.errors import ParseError
from millpost.gcode import FeedMode, ReaderOptions, dialects
from millpost.gcode.interpret import _MODAL_GROUPS, INCH, Interpreter
from millpost.gcode.lexer import lex_line

# LinuxCNC G-code overview, "order of execution": the item each step belongs to (1 O words and 2 comments
# are `Interpreter.run`'s; 7 HAL pin I/O is where M codes that move nothing are passed through)
ORDER = {"set_feed_mode": 3, "set_feed_rate": 4, "set_spindle_speed": 5, "select_tool": 6, "other_m_codes": 7,
         "change_tool": 8, "switch_spindle": 9, "switch_coolant": 11, "dwell": 14, "set_plane": 15, "set_units": 16,
         "radius_compensation": 17, "length_compensation": 18, "select_coordinate_system": 19, "set_path_mode": 20,
         "set_distance_modes": 21, "set_retract_mode": 22, "read_axis_words": 23, "offsets_and_homes": 23,
         "set_motion_mode": 24, "move": 24, "stop": 25}


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
