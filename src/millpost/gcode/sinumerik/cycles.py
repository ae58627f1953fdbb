"""Sinumerik drilling cycles CYCLE81, CYCLE82, CYCLE83 as RS-274 canned cycles (G81, G82, G83/G73).

Parameters (SINUMERIK 840D sl/828D "Cycles" programming manual, "Drilling cycles"): RTP retraction
plane (absolute), RFP reference plane (absolute), SDIS safety distance (above RFP, unsigned), DP final
depth (absolute) or DPR (relative to RFP, unsigned; DPR wins when both are given), DTB dwell at the
bottom (s). CYCLE83: FDEP first depth (absolute) or FDPR (relative to RFP), DAM degression, DTB, DTS,
FRF feed factor of the first infeed, VARI 0 chip breaking (G73) / 1 chip removal (G83), DTB/_DTD dwell
at the depth (s). _MDEP, _VRT (chip-breaking retract: G73's own) and _DIS1 are not read.

The cycle approaches RFP+SDIS at rapid (the canned cycle's R), drills to the depth at the feed in force
and retracts at rapid. The retract goes to the level where the cycle started (G98: the Z of the first
hole of a MCALL sequence), which is RTP when the program positioned there before the call, as CAM
posts do (Fusion, NX); a note says so. Pecks (CYCLE83) are counted from R, as G83 does, a peck of
FDPR (RFP - FDEP); a degression (DAM), a first-infeed feed factor other than 1, or a dwell (at the
start or at the depth) are refused: G83 cannot make them.
"""

from __future__ import annotations

from collections.abc import Callable

from .syntax import Line, Token, skip

CYCLES = {"CYCLE81": 81, "CYCLE82": 82, "CYCLE83": 83}
_NAMES = {81: ("RTP", "RFP", "SDIS", "DP", "DPR"), 82: ("RTP", "RFP", "SDIS", "DP", "DPR", "DTB"),
          83: ("RTP", "RFP", "SDIS", "DP", "DPR", "FDEP", "FDPR", "DAM", "DTB", "DTS", "FRF", "VARI", "_AXN",
               "_MDEP", "_VRT", "_DTD", "_DIS1")}


def arguments(src: Line, t: Token) -> list[tuple[str, int]]:
    """A call's arguments as written (stripped; '' when left out) with their offsets in the line."""
    base = t.end - 1 - len(t.value)
    out, depth, start = [], 0, 0
    for k, ch in enumerate(t.value + ","):
        depth += (ch == "(") - (ch == ")")
        if ch == "," and depth == 0:
            text = t.value[start:k]
            lead = len(text) - len(text.lstrip())
            out.append((text.strip(), base + start + lead))
            start = k + 1
    return out


def cycle_words(src: Line, t: Token, expr: Callable[[int], tuple[str, int]], frame_z: str | None) -> list[str]:
    """The canned-cycle words (G98 G8x R.. Z.. P.. Q..) of a CYCLE8x call; `expr(offset)` translates
    the expression at that offset of the line; `frame_z`: the programmable Z offset's parameter, added
    to the planes (None: no offset)."""
    code = CYCLES[t.name]
    names = _NAMES[code]
    args = arguments(src, t)
    if len(args) > len(names):
        raise src.error(f"{t.name} takes at most {len(names)} parameters", t.start, t.name, ", ".join(names))
    values: dict[str, str] = {}
    for name, (text, at) in zip(names, args):
        if text:
            if text.startswith('"'):
                raise src.error(f"{t.name} parameter {name} is a string", at, text, "a number")
            value, end = expr(at)
            if skip(src.text, end) != at + len(text):
                raise src.error(f"unexpected text in {t.name} parameter {name}", end, src.text[end:at + len(text)],
                                "an expression")
            values[name] = value
    for need in ("RFP",):
        if need not in values:
            raise src.error(f"{t.name} without {need}", t.start, t.name, f"{need} given")
    if "DP" not in values and "DPR" not in values:
        raise src.error(f"{t.name} without a depth", t.start, t.name, "DP (absolute) or DPR (relative to RFP)")
    rfp, sdis = values["RFP"], values.get("SDIS", "0")
    if frame_z:
        rfp = f"[{rfp}+{frame_z}]"
        if "DP" in values:
            values["DP"] = f"[{values['DP']}+{frame_z}]"
    depth = f"[{rfp}-ABS[{values['DPR']}]]" if "DPR" in values else values["DP"]
    words = [f"R[{rfp}+ABS[{sdis}]]", _word("Z", depth)]
    if code == 82 and "DTB" in values:
        words.append(_word("P", values["DTB"]))
    if code == 83:
        words.insert(0, _peck_code(src, t, args, values))
        first = f"ABS[{values['FDPR']}]" if "FDPR" in values else f"[{rfp}-[{values['FDEP']}]]" if "FDEP" in values \
            else None
        if first is None:
            raise src.error("CYCLE83 without a first depth", t.start, t.name, "FDEP or FDPR")
        words.append(_word("Q", first))
    else:
        words.insert(0, f"G{code}")
    return ["G98", *words]


def _word(letter: str, value: str) -> str:
    """An NGC word: the value as is when it is a number, a parameter or a bracketed expression."""
    plain = value.startswith(("[", "#")) or value.lstrip("+-").replace(".", "", 1).isdigit()
    return f"{letter}{value}" if plain else f"{letter}[{value}]"


def _peck_code(src: Line, t: Token, args: list[tuple[str, int]], values: dict[str, str]) -> str:
    """G83 (VARI=1, chip removal) or G73 (VARI=0, chip breaking); what G83 cannot make is refused."""
    for name, neutral in (("DAM", "0"), ("FRF", "1"), ("DTS", "0"), ("DTB", "0"), ("_DTD", "0")):
        if values.get(name, neutral) not in (neutral, f"{neutral}.", f"{neutral}.0"):
            at = args[_NAMES[83].index(name)][1]
            raise src.error(f"CYCLE83 with {name}={values[name]}: G83 cannot make it", at, values[name],
                            f"{name}={neutral} (or left out)")
    vari = values.get("VARI", "0")
    if vari not in ("0", "1"):
        at = args[_NAMES[83].index("VARI")][1]
        raise src.error(f"CYCLE83 VARI={vari}", at, vari, "VARI=0 (chip breaking) or 1 (chip removal)")
    return "G83" if vari == "1" else "G73"
