"""Controller dialects: what differs per controller when reading and writing G-code.

A `Dialect` says how numbers are written, whether canned cycles and R-format arcs exist, how
programs start and end, and how dwell P is read. `detect` scores the text against each dialect.
Built-ins are registered as entry points (group ``millpost.dialects``) like any plugin.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..errors import MillpostError
from ..registry import plugins


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
    tool_length_codes: the tool length compensation codes the controller runs (G43 H from its tool
    table, G43.1 dynamic, G43.2 additional, G49 cancel); `convert` refuses the others.
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
    tool_length_codes: frozenset[str] = frozenset({"G43", "G43.1", "G43.2", "G49"})

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

    def score(self, text: str) -> int:
        """How strongly the text looks like this dialect's (markers found in the first 200 lines)."""
        head = "\n".join(text.splitlines()[:200])
        return sum(len(re.findall(m, head, flags=re.IGNORECASE | re.MULTILINE)) for m in self.markers)


GRBL = Dialect("grbl", canned_cycles=False, end_code="M30", tool_length_codes=frozenset({"G43.1", "G49"}),
               markers=(r"^\s*\$[A-Z0-9]", r"grbl", r"^G90 G94$", r"^\(When using Fusion 360 for Personal Use"))
LINUXCNC = Dialect("linuxcnc", markers=(r"#<", r"^\s*o<?\w+>?\s+(sub|call|if|while|repeat)", r"G64\s*P",
                                        r"linuxcnc", r"emc2?\b", r"G90\.1|G91\.1", r"^M2\s*$", r"\bG61\b"))
FANUC = Dialect("fanuc", trailing_point=True, line_numbers=5, dwell_ms=True,
                percent=True, end_code="M30", tool_length_codes=frozenset({"G43", "G49"}),
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
