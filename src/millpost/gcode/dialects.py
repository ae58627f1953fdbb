"""Controller dialects: what differs per controller when reading and writing G-code.

A `Dialect` says how numbers are written, whether canned cycles and R-format arcs exist, how
programs start and end, and how dwell P is read. `detect` scores the text against each dialect.
Built-ins are registered as entry points (group ``millpost.dialects``) like any plugin.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from ..errors import MillpostError
from ..registry import plugins

if TYPE_CHECKING:
    from .convert import SourceBlocks
    from .interpret import Program

MARKER_CAP = 3
DECISIVE = 1000  # the score of a text holding a decisive marker: more than any count of plain markers


@dataclass(frozen=True)
class Dialect:
    """How one controller family reads and writes G-code.

    decimals_mm / decimals_inch: digits after the point when writing coordinates (4 and 6: rounding
    stays under 1e-4 mm, finer than any of these controllers resolves).
    trailing_point: write whole numbers as "10." (Fanuc/Haas) instead of "10".
    canned_cycles: the controller runs G73/G8x cycles (else they are expanded into moves).
    line_numbers: N-number step when writing a program from scratch (0: none).
    comment: "paren" or "semicolon". dwell_ms: dwell P in milliseconds (Fanuc).
    percent: wrap programs in % lines (tape format) with an O number.
    markers / decisive: regular expressions that find this dialect in a text (`score`, `detect`);
    a decisive one is code no other dialect reads (G710, BEGIN PGM), so one match settles it.
    tool_length_codes: the tool length compensation codes the controller runs (G43 H from its tool
    table, G43.1 dynamic, G43.2 additional, G49 cancel); `convert` refuses the others.

    What the reader needs to know (LinuxCNC 2.9 is the reference; Fanuc/Haas/Centroid differ):
    starts_g98: canned cycles retract to the old Z until G98/G99 is given (Fanuc starts in G98;
    LinuxCNC in G99, retract to R). g76_lathe: G76 is lathe threading (LinuxCNC; refused by a milling
    reader) rather than fine boring. g80_keeps_motion: after G80 the last G0–G3 stays in effect
    (Fanuc), instead of no motion mode. cycle_k_repeats: K is a canned cycle's repeat count (except
    G87's K, a depth; Fanuc), besides L. zero_repeats_refused: L0 is an error (LinuxCNC) rather than
    "set the cycle up, do not run it". cycle_dwell_any: every canned cycle reads P (dwell), not only
    G82/G86/G88/G89. boring_shift_q: G76/G87 read Q (the shift off the wall). tap_peck_q: G74/G84
    read Q (peck tapping, modelled with a retract to R after each peck). g49_takes_h:
    G49 may carry H (H0, the cancelled offset; Centroid and Haas postambles). off_plane_arc_offset_refused:
    an arc's centre offset along the plane's normal (K in G17, J in G18, I in G19) is an error
    (LinuxCNC: "K word given for arc in xy plane"), not ignored. feed_before_units: F in a block with
    G20/G21 is in the units before the change (LinuxCNC sets the feed rate before the length units;
    grbl converts it with the block's). feed_mode_resets_f: every G93/G94/G95 sets the feed rate to 0
    (LinuxCNC), not only a change of mode. Dwell units: `dwell_s`.
    What the writer needs to know: g43_without_h: G43 with no H takes the loaded tool's length
    (LinuxCNC); path_modes: the controller has G61/G61.1/G64 path control modes (grbl has not).

    A language other than RS-274 (Sinumerik, Heidenhain Klartext) is read through its translation:
    translate(text, file) gives an RS-274/NGC program the interpreter runs, line for line (its line k is the
    translation of source line k, so every move, event and error keeps its source line; lines past the
    source's last may hold subroutines the translation adds: their moves keep their programmed feeds, as
    they are not written back; a translation whose added lines come from other files (Sinumerik subprograms)
    is a str with `origins`, added line → (file, line), and an error the interpreter finds on such a line
    names that file and line). Refusals name the source's file, line and column. set_feed(line, f) writes a
    feed back into one source line: the F word's number text `f` (in the line's units, as the RS-274 writer
    formatted it) in place of the line's F, added where it has none, or the F removed when `f` is None; the
    rest of the line keeps its bytes. fixed_feed(line): the source line's moves run at a feed written
    elsewhere (a Heidenhain cycle call runs at its cycle's Q206): they keep their programmed feed.
    write(program, blocks) writes an interpreted program (and its lexed source blocks) in such a language:
    `convert` uses it in place of its RS-274 writer, from whose text it may start (`convert.write_rs274`).
    blank(text, file): the blank the program states (Heidenhain's BLK FORM) as ((xmin, ymin, zmin),
    (xmax, ymax, zmax)) in mm, or None; a job with no [stock] takes it as its stock.
    """

    name: str
    decimals_mm: int = 4
    decimals_inch: int = 6
    trailing_point: bool = False
    canned_cycles: bool = True
    line_numbers: int = 0
    comment: str = "paren"
    dwell_ms: bool = False
    percent: bool = False
    end_code: str = "M2"
    markers: tuple[str, ...] = ()
    decisive: tuple[str, ...] = ()
    tool_length_codes: frozenset[str] = frozenset({"G43", "G43.1", "G43.2", "G49"})
    starts_g98: bool = True
    g76_lathe: bool = False
    g80_keeps_motion: bool = False
    cycle_k_repeats: bool = False
    zero_repeats_refused: bool = False
    cycle_dwell_any: bool = False
    boring_shift_q: bool = False
    g49_takes_h: bool = False
    tap_peck_q: bool = False
    g43_without_h: bool = False
    path_modes: bool = True
    off_plane_arc_offset_refused: bool = False
    feed_before_units: bool = False
    feed_mode_resets_f: bool = False
    translate: Callable[[str, str], str] | None = field(default=None, compare=False, repr=False)
    set_feed: Callable[[str, str | None], str] | None = field(default=None, compare=False, repr=False)
    fixed_feed: Callable[[str], bool] | None = field(default=None, compare=False, repr=False)
    blank: Callable[[str, str], tuple[tuple[float, float, float], tuple[float, float, float]] | None] | None = field(
        default=None, compare=False, repr=False)
    write: Callable[[Program, SourceBlocks], str] | None = field(default=None, compare=False, repr=False)

    def number(self, value: float, inch: bool, decimals: int | None = None) -> str:
        """Format a coordinate or feed in this dialect's style (no '-0', no exponent)."""
        d = decimals if decimals is not None else (self.decimals_inch if inch else self.decimals_mm)
        text = f"{value:.{d}f}"
        if "." in text:
            text = text.rstrip("0")
            if text.endswith(".") and not self.trailing_point:
                text = text[:-1]
        if text in ("-0", "-0.", "-"):
            text = "0." if self.trailing_point else "0"
        if text == "" or text == ".":
            text = "0"
        return text

    def dwell_s(self, value: float, decimal_point: bool = True, cycle: bool = False) -> float:
        """A dwell P in seconds. With dwell_ms, P counts milliseconds: in a canned cycle always, on G4
        when written without a decimal point (Fanuc: G4 P1500 and G4 P1.5 both wait 1.5 s)."""
        return value / 1000.0 if self.dwell_ms and (cycle or not decimal_point) else value

    def score(self, text: str) -> int:
        """How strongly the text looks like this dialect's: markers found in the first 200 lines, each
        counted at most MARKER_CAP times (a common code written on every line, such as Mach3's G00 that
        Fanuc posts write too, cannot outweigh several distinct markers of another dialect); a decisive
        marker (what no other dialect reads: Sinumerik's G710, Heidenhain's BEGIN PGM) counts DECISIVE."""
        head = "\n".join(text.splitlines()[:200])
        flags = re.IGNORECASE | re.MULTILINE
        code = re.sub(r"\([^()\n]*\)", "", head)  # a decisive marker is code, never in an RS-274 comment
        return (sum(min(MARKER_CAP, len(re.findall(m, head, flags=flags))) for m in self.markers)
                + DECISIVE * sum(re.search(m, code, flags=flags) is not None for m in self.decisive))


GRBL = Dialect("grbl", canned_cycles=False, end_code="M30", tool_length_codes=frozenset({"G43.1", "G49"}),
               path_modes=False,
               markers=(r"^\s*\$[A-Z0-9]", r"grbl", r"^G90 G94$", r"^\(When using Fusion 360 for Personal Use"))
LINUXCNC = Dialect("linuxcnc", starts_g98=False, g76_lathe=True, zero_repeats_refused=True, g43_without_h=True,
                   off_plane_arc_offset_refused=True, feed_before_units=True,
                   feed_mode_resets_f=True,
                   markers=(r"#<", r"^\s*o<?\w+>?\s+(sub|call|if|while|repeat)", r"G64\s*P", r"linuxcnc",
                            r"emc2?\b", r"G90\.1|G91\.1", r"^M2\s*$", r"\bG61\b"))
FANUC = Dialect("fanuc", trailing_point=True, line_numbers=5, dwell_ms=True,
                percent=True, end_code="M30", tool_length_codes=frozenset({"G43", "G49"}), g80_keeps_motion=True,
                cycle_k_repeats=True, cycle_dwell_any=True, boring_shift_q=True, g49_takes_h=True, tap_peck_q=True,
                markers=(r"^%\s*$", r"^O\d{3,5}", r"G28\s*G91", r"G43\s*Z[-\d.]+\s*H\d+", r"\bM29\b", r"\bM30\b",
                         r"haas", r"fanuc", r"G53\s*G0?0\s*Z"))
MACH3 = Dialect("mach3", end_code="M30", tool_length_codes=frozenset({"G43", "G49"}),
                markers=(r"mach\s*3", r"vectric", r"^G00 G2[01] G17 G90 G40 G49 G80", r"^\( VECTRIC", r"\bG00\b"))


def available() -> dict[str, Dialect]:
    """Every dialect: the built-ins and third-party ones, all registered in the ``millpost.dialects``
    entry-point group (millpost's own pyproject declares grbl, linuxcnc, fanuc and mach3)."""
    return {name: d for name, d in plugins("dialects").items() if isinstance(d, Dialect)}


def get(name: str) -> Dialect:
    """A dialect by name (haas is an alias of fanuc)."""
    found = available()
    key = name.lower().replace("haas", "fanuc")
    if key not in found:
        raise MillpostError(f"unknown dialect {name!r}; known: {', '.join(sorted(found))} (haas = fanuc)")
    return found[key]


def names() -> list[str]:
    return sorted(available())


def detect(text: str) -> Dialect:
    """The dialect whose markers the text matches most; LinuxCNC (plain RS-274/NGC) when none match."""
    ranked = sorted(available().values(), key=lambda d: (d.score(text), d.name == "linuxcnc"), reverse=True)
    return ranked[0] if ranked and ranked[0].score(text) > 0 else LINUXCNC
