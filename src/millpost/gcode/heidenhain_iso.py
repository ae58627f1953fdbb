"""HEIDENHAIN ISO programs (``%NAME G71 *`` ... ``N10 G01 X+10 Y+5 F200 *``), translated line for
line to RS-274/NGC like Klartext (see `heidenhain`).

What differs from RS-274 (TNC 640 user's manual, ISO programming): every block ends in ``*``;
``%name G71|G70 *`` begins and ends the program (mm or inch); ``G30``/``G31`` give the blank;
``T n G17 S..`` calls a tool; ``I``/``J`` are the circle centre in absolute coordinates and stay in
force (alone in a block they only set it; G02/G03 without I/J or R turn about it). Supported:
G00-G03 (R or the centre), G17, G40-G42, G90/G91, G70/G71, F, S, M, N. Refused with file:line:column:
any other G code (polar, tangential arcs, rounding, cycles, G99 tool definitions), K, and I/J in
incremental mode.
"""

from __future__ import annotations

import re

from ..errors import ParseError

HEADER = re.compile(r"\s*(?:N\s*\d+\s+)?%(\S+)\s+G7([01])\s*\*?\s*$", re.IGNORECASE)
_WORD = re.compile(r"([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_KEPT_G = {0, 1, 2, 3, 17, 40, 41, 42, 90, 91}


def is_iso(lines: list[str]) -> bool:
    """Whether the program's first block is an ISO ``%name G71 *`` header."""
    first = next((ln for ln in lines if ln.strip()), "")
    return bool(HEADER.match(first.partition(";")[0]))


def translate(lines: list[str], file: str) -> str:
    """The ISO program (its lines) as RS-274/NGC, line for line."""
    state = {"motion": 0, "begun": False, "g91": False}
    return "\n".join(_line(raw.rstrip("\r"), n, file, state) for n, raw in enumerate(lines, 1))


def _error(file: str, n: int, column: int, word: str, message: str, expected: str) -> ParseError:
    return ParseError(message, file=file, line=n, column=column, word=word, expected=expected)


def _line(raw: str, n: int, file: str, state: dict) -> str:
    code, _, note = raw.partition(";")
    comment = f"({note.strip().replace('(', '[').replace(')', ']')})" if note.strip() else ""
    header = HEADER.match(code)
    if header:
        if state["begun"]:
            return f"M2 {comment}".strip()
        state["begun"] = True
        units = "G21" if header.group(2) == "1" else "G20"
        return (f"{units} G90 G90.1 G17 G94 G40 #<_hh_ccx>=0 #<_hh_ccy>=0 "
                f"({header.group(1).replace('(', '[').replace(')', ']')}) {comment}").strip()
    body = code.rstrip()
    if body.endswith("*"):
        body = body[:-1]
    words = _words(body, n, file)
    return " ".join(w for w in (_block(words, body, n, file, state), comment) if w)


def _words(body: str, n: int, file: str) -> list[tuple[str, float, str, int]]:
    """(letter, value, text, column) of each word; anything else is refused where it is."""
    out, pos = [], 0
    while pos < len(body):
        if body[pos] in " \t":
            pos += 1
            continue
        m = _WORD.match(body, pos)
        if not m:
            raise _error(file, n, pos + 1, body[pos:].split()[0], "not an ISO word", "a letter and a number")
        out.append((m.group(1).upper(), float(m.group(2)), m.group(), pos + 1))
        pos = m.end()
    return out


def _block(words: list[tuple[str, float, str, int]], body: str, n: int, file: str, state: dict) -> str:
    """One ISO block's NGC words."""
    letters = {w[0] for w in words}
    g_codes = [w for w in words if w[0] == "G"]
    if any(w[1] in (30, 31) for w in g_codes):
        return f"(blank {body.strip()})"
    if "T" in letters:
        return _tool_call(words, n, file)
    for _, value, text, col in g_codes:
        if value in (70, 71):
            continue
        if value not in _KEPT_G:
            raise _error(file, n, col, text, f"G{value:g} is not supported in ISO programs",
                         "G00-G03, G17, G40-G42, G90, G91, G70, G71")
        state["motion"] = int(value) if value <= 3 else state["motion"]
        state["g91"] = {90: False, 91: True}.get(int(value), state["g91"])
    for letter, _, text, col in words:
        if letter not in "NGXYZIJRFSM":
            raise _error(file, n, col, text, f"{letter} is not supported in ISO programs", "N G X Y Z I J R F S M")
    out = [_ngc_word(w) for w in words if w[0] not in "IJ"]
    centre = {w[0]: w for w in words if w[0] in "IJ"}
    if centre and state["g91"]:
        text, col = next(iter(centre.values()))[2:]
        raise _error(file, n, col, text, "a circle centre in incremental mode (G91)", "I/J with G90")
    moves = bool(letters & set("XYZ"))
    arc = state["motion"] in (2, 3) and moves and "R" not in letters
    sets = [f"#<_hh_cc{'x' if k == 'I' else 'y'}>={centre[k][1]:.10g}" for k in centre]
    if arc:
        out += [f"I{centre['I'][1]:.10g}" if "I" in centre else "I#<_hh_ccx>",
                f"J{centre['J'][1]:.10g}" if "J" in centre else "J#<_hh_ccy>"]
    return " ".join(out + sets)


def _ngc_word(word: tuple[str, float, str, int]) -> str:
    letter, value, text, _ = word
    if letter == "G" and value in (70, 71):
        return "G20" if value == 70 else "G21"
    if letter == "F":
        return "F" + text[1:].strip().lstrip("+")
    return text.replace(" ", "")


def _tool_call(words: list[tuple[str, float, str, int]], n: int, file: str) -> str:
    """T n G17 S.. (a tool call, tool axis Z)."""
    out = []
    for letter, value, text, col in words:
        if letter == "T":
            out += [f"T{value:g}", "M6", "G43"]
        elif letter == "G" and value != 17:
            raise _error(file, n, col, text, "a tool axis other than Z (G17)", "T<n> G17 S..")
        elif letter in "SFN":
            out.append(_ngc_word((letter, value, text, col)))
        elif letter != "G":
            raise _error(file, n, col, text, "unexpected word in a tool call", "T<n> G17 S.. F..")
    return " ".join(out)
