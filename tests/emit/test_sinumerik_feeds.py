"""A Sinumerik program optimized is written back in Sinumerik with only F words changed
(`Dialect.set_feed`), and reads back to the same path."""

from __future__ import annotations

import numpy as np
import pytest

from millpost.emit.write import FeedPlan, write_feeds
from millpost.gcode import ReaderOptions, read_text
from millpost.gcode.convert import same_path
from millpost.gcode.sinumerik.write import set_feed

PROGRAM = """%_N_SLOT_MPF
; slot and pocket wall
N10 G90 G94 G17 G710
N20 T="FLAT6" D1
N30 M6
N40 S9000 M3
N50 G0 X-5 Y8 Z2
N60 G1 Z-1.5 F300.
N70 G1 X65 F700. ; slot
N80 G2 X75 Y18 CR=10
N90 G1 Y=AC(30) F=R0+650
N100 G4 F2
N110 X0
N120 M30
"""


@pytest.mark.parametrize("line, f, written", [
    ("N70 G1 X65 F700. ; slot", "612.5", "N70 G1 X65 F612.5 ; slot"),
    ("N80 G2 X75 Y18 CR=10", "700", "N80 G2 X75 Y18 CR=10 F700"),
    ("N80 G2 X75 Y18 CR=10 ; arc", "700", "N80 G2 X75 Y18 CR=10 F700 ; arc"),
    ("N80 G2 X75 Y18 CR=10   ; arc", "700", "N80 G2 X75 Y18 CR=10 F700   ; arc"),
    ("N90 G1 Y=AC(30) F=R0+650", "800", "N90 G1 Y=AC(30) F800"),
    ("N90 G1 F300 X5", None, "N90 G1 X5"),
    ("N90 G1X5F300", "310", "N90 G1X5F310"),
    ('N95 MSG("F100 ; no") G1 X1 F100', "200", 'N95 MSG("F100 ; no") G1 X1 F200'),
])
def test_set_feed_changes_only_the_f_word(line, f, written):
    assert set_feed(line, f) == written


def test_optimized_program_keeps_every_byte_but_f_and_its_path():
    """Feeds changed on two moves (the slot slower, the arc with its own F, in the program's "700." style),
    the rest kept."""
    opts = ReaderOptions(dialect="sinumerik")
    program = read_text(PROGRAM, "slot.mpf", opts)
    tp = program.toolpath
    assert tp.line.tolist() == [7, 8, 9, 10, 11, 13]
    feeds = tp.feed_mm_min.copy()
    feeds[2], feeds[3] = 450.0, 525.0
    out = write_feeds(program, FeedPlan(feeds, {}))
    before, after = PROGRAM.splitlines(), out.splitlines()
    changed = [n for n, (a, b) in enumerate(zip(before, after), 1) if a != b]
    assert len(after) == len(before) and changed == [9, 10]
    assert after[8] == "N70 G1 X65 F450. ; slot" and after[9] == "N80 G2 X75 Y18 CR=10 F525"
    again = read_text(out, "slot.mpf", opts)
    assert same_path(program, again) == []
    assert np.allclose(again.toolpath.feed_mm_min[1:], [300, 450, 525, 650, 650])
    assert write_feeds(program, FeedPlan(tp.feed_mm_min.copy(), {})) == PROGRAM


def test_a_cycle_calls_block_takes_no_feed():
    """FB "Subprogram call": a cycle call stands in a block of its own, so a new feed for an immediate
    CYCLE81 goes into the F line before it when there is one, else is refused (not written as an invalid
    block)."""
    from millpost.errors import MillpostError
    opts = ReaderOptions(dialect="sinumerik")
    program = read_text("N10 G0 X0 Y0 Z10\nN20 F100\nN30 CYCLE81(10, 0, 2, -6)\nN40 M30\n", "c.mpf", opts)
    feeds = program.toolpath.feed_mm_min.copy()
    feeds[program.toolpath.kind != 0] = 80.0
    assert write_feeds(program, FeedPlan(feeds, {})).splitlines()[1] == "N20 F80"  # the F line before takes it
    program = read_text("N10 G0 X0 Y0 Z10\nN20 G1 X1 F100\nN30 CYCLE81(10, 0, 2, -6)\nN40 M30\n", "c.mpf", opts)
    feeds = program.toolpath.feed_mm_min.copy()
    feeds[program.toolpath.line == 3] = 80.0
    with pytest.raises(MillpostError, match="takes a block of its own"):
        write_feeds(program, FeedPlan(feeds, {}))


def test_the_schedule_keeps_a_cycle_calls_programmed_feed():
    """The feed of an immediate CYCLE81 is the F in force, written on another block (`fixed_feed`): the
    emission policy keeps its moves at the programmed feed instead of planning a change it could not
    write; a line with its own F is planned as any other."""
    from millpost.emit import Fragment
    from millpost.emit.write import whole_moves
    from millpost.gcode.sinumerik.write import fixed_feed
    assert fixed_feed("N30 CYCLE81(10, 0, 2, -6) ; drill") and not fixed_feed("N20 G1 X1 F100 ; CYCLE81(")
    program = read_text("N10 G0 X0 Y0 Z10\nN20 G1 X1 F100\nN30 CYCLE81(10, 0, 2, -6)\nN40 M30\n", "c.mpf",
                        ReaderOptions(dialect="sinumerik"))
    tp = program.toolpath
    cutting = [int(i) for i in np.flatnonzero(tp.kind != 0)]
    kept = whole_moves(program, [Fragment(i, 0.0, 1.0, 1.0) for i in cutting])
    feed = {f.move: f.feed_mm_s for f in kept}
    assert all(feed[i] == (tp.feed_mm_s[i] if tp.line[i] == 3 else 1.0) for i in cutting)
