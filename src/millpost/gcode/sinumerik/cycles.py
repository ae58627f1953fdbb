"""Sinumerik drilling cycles CYCLE81-86 as RS-274 canned cycles (G81, G82, G83/G73, G84/G74, G85/G89, G86).

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

CYCLE84 (Cycles manual, "CYCLE84 - Tapping without compensating chuck"): RTP, RFP, SDIS, DP, DPR, DTB,
SDAC (spindle after the cycle: 3), MPIT (thread size M3-M48: its ISO coarse pitch) or PIT (pitch in
the program's unit per revolution; negative: left-hand), POSS (oriented start: no path effect), SST
(tapping speed; else the S in force), SST1 (retract speed: 0, or SST) → G84 (G74 left-hand) with the
feed |pitch|·speed written for the cycle (`FEED_PARAMETER` then restores the programmed F). Pecking
(_VARI 1/2), a pitch unit other than the program's (_PTAB 2, 3: inch/TPI) and the later parameters
are refused.
CYCLE85 ("CYCLE85 - Boring 1"): RTP, RFP, SDIS, DP, DPR, DTB, FFR (feed in), RFF (feed out: the same)
→ G85, or G89 with DTB's dwell, at FFR (then the programmed F restored).
CYCLE86 ("CYCLE86 - Boring 2"): RTP, RFP, SDIS, DP, DPR, DTB, SDIR (3: restarted clockwise), RPA, RPO,
RPAP (lift-off: 0), POSS (the oriented stop: no path effect) → G86 (feed in, dwell, spindle stop, rapid
out, spindle on) at the F in force; a lift-off is refused (G86 has none).
"""

from __future__ import annotations

from collections.abc import Callable

from .syntax import Line, Token, skip

CYCLES = {"CYCLE81": 81, "CYCLE82": 82, "CYCLE83": 83, "CYCLE84": 84, "CYCLE85": 85, "CYCLE86": 86}
FEED_PARAMETER = "#<_sin_f>"  # the programmed F, kept where a program has CYCLE84/85 (their own feed)
_NAMES = {81: ("RTP", "RFP", "SDIS", "DP", "DPR"), 82: ("RTP", "RFP", "SDIS", "DP", "DPR", "DTB"),
          83: ("RTP", "RFP", "SDIS", "DP", "DPR", "FDEP", "FDPR", "DAM", "DTB", "DTS", "FRF", "VARI", "_AXN",
               "_MDEP", "_VRT", "_DTD", "_DIS1"),
          84: ("RTP", "RFP", "SDIS", "DP", "DPR", "DTB", "SDAC", "MPIT", "PIT", "POSS", "SST", "SST1", "_AXN",
               "_PTAB", "_TECHNO", "_VARI", "_DAM", "_VRT"),
          85: ("RTP", "RFP", "SDIS", "DP", "DPR", "DTB", "FFR", "RFF"),
          86: ("RTP", "RFP", "SDIS", "DP", "DPR", "DTB", "SDIR", "RPA", "RPO", "RPAP", "POSS")}
# ISO metric coarse pitches of the thread sizes MPIT names (Cycles manual, CYCLE84 "MPIT")
_COARSE = {3: 0.5, 4: 0.7, 5: 0.8, 6: 1.0, 8: 1.25, 10: 1.5, 12: 1.75, 14: 2.0, 16: 2.0, 18: 2.5, 20: 2.5,
           22: 2.5, 24: 3.0, 27: 3.0, 30: 3.5, 33: 3.5, 36: 4.0, 39: 4.0, 42: 4.5, 45: 4.5, 48: 5.0}
# parameters that must be left out or neutral (what the RS-274 cycle cannot make)
_NEUTRAL = {83: (("DAM", "0"), ("FRF", "1"), ("DTS", "0"), ("DTB", "0"), ("_DTD", "0")),
            84: (("SDAC", "3"), ("_PTAB", "0"), ("_TECHNO", "0"), ("_VARI", "0"), ("_DAM", "0"), ("_VRT", "0")),
            86: (("SDIR", "3"), ("RPA", "0"), ("RPO", "0"), ("RPAP", "0"))}


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


def cycle_words(src: Line, t: Token, expr: Callable[[int], tuple[str, int]], frame_z: str | None,
                spindle: str | None = None) -> list[str]:
    """The canned-cycle words (G98 G8x R.. Z.. P.. Q.. [F..]) of a CYCLE8x call; `expr(offset)`
    translates the expression at that offset of the line; `frame_z`: the programmable Z offset's
    parameter, added to the planes (None: no offset); `spindle`: the S in force (CYCLE84's speed)."""
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
    if code in _NEUTRAL:
        _neutral(src, t, args, values)
    if code in (82, 84, 86, 85) and "DTB" in values:
        words.append(_word("P", values["DTB"]))
    if code == 84:
        words.insert(0, "G74" if values.get("PIT", values.get("MPIT", "")).startswith("-") else "G84")
        words.append(_tap_feed(src, t, args, values, spindle))
    elif code == 85:
        words.insert(0, "G89" if "DTB" in values else "G85")
        words.append(_bore_feed(src, t, args, values))
    elif code == 83:
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


def _neutral(src: Line, t: Token, args: list[tuple[str, int]], values: dict[str, str]) -> None:
    """A parameter the RS-274 cycle cannot make, given other than its neutral value, is refused."""
    code = CYCLES[t.name]
    for name, neutral in _NEUTRAL[code]:
        if values.get(name, neutral) not in (neutral, f"{neutral}.", f"{neutral}.0"):
            at = args[_NAMES[code].index(name)][1]
            raise src.error(f"{t.name} with {name}={values[name]}: G{code} cannot make it", at, values[name],
                            f"{name}={neutral} (or left out)")


def _tap_feed(src: Line, t: Token, args: list[tuple[str, int]], values: dict[str, str], spindle: str | None) -> str:
    """CYCLE84's feed: |pitch| (PIT, or MPIT's coarse pitch) times the tapping speed (SST, else the S
    in force); a retract speed SST1 other than 0 or SST is refused (G84 retracts at the same speed)."""
    if "PIT" in values:
        pitch = f"ABS[{values['PIT']}]"
    elif "MPIT" in values:
        size = values["MPIT"].lstrip("+-")
        size = str(int(float(size))) if size.replace(".", "", 1).isdigit() and float(size).is_integer() else ""
        if not size or int(size) not in _COARSE:
            at = args[_NAMES[84].index("MPIT")][1]
            raise src.error(f"CYCLE84 MPIT={values['MPIT']}: not an ISO thread size", at, values["MPIT"],
                            "MPIT 3 ... 48 (M3 ... M48), or PIT=<pitch>")
        pitch = str(_COARSE[int(size)])
    else:
        raise src.error("CYCLE84 without a pitch", t.start, t.name, "PIT (pitch) or MPIT (thread size)")
    speed = values.get("SST") or spindle
    if speed is None:
        raise src.error("CYCLE84 without a speed", t.start, t.name, "SST, or an S word before the cycle")
    if values.get("SST1", "0") not in ("0", "0.", "0.0", values.get("SST")):
        at = args[_NAMES[84].index("SST1")][1]
        raise src.error("CYCLE84 with a retract speed SST1 other than SST: G84 retracts at the tapping speed", at,
                        values["SST1"], "SST1=0 (or left out)")
    return f"F[{pitch}*ABS[{speed}]]"


def _bore_feed(src: Line, t: Token, args: list[tuple[str, int]], values: dict[str, str]) -> str:
    """CYCLE85's feed: FFR in and RFF out, the same (G85 feeds out as in)."""
    if "FFR" not in values:
        raise src.error("CYCLE85 without its feed FFR", t.start, t.name, "FFR (feed in) given")
    if values.get("RFF", values["FFR"]) != values["FFR"]:
        at = args[_NAMES[85].index("RFF")][1]
        raise src.error("CYCLE85 with a feed out RFF other than FFR: G85 feeds out as in", at, values["RFF"],
                        f"RFF={values['FFR']} (or left out)")
    return _word("F", values["FFR"])


def _peck_code(src: Line, t: Token, args: list[tuple[str, int]], values: dict[str, str]) -> str:
    """G83 (VARI=1, chip removal) or G73 (VARI=0, chip breaking); what G83 cannot make is refused."""
    vari = values.get("VARI", "0")
    if vari not in ("0", "1"):
        at = args[_NAMES[83].index("VARI")][1]
        raise src.error(f"CYCLE83 VARI={vari}", at, vari, "VARI=0 (chip breaking) or 1 (chip removal)")
    return "G83" if vari == "1" else "G73"
