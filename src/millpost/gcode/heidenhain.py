"""HEIDENHAIN Klartext (TNC 640/530 conversational) programs, read through a translation to RS-274/NGC;
ISO programs (``%NAME G71 *``) go to `heidenhain_iso`, and `convert` writes Klartext with
`heidenhain_write`.

Section numbers cite the HEIDENHAIN TNC 640 user's manual "Klartext programming" (ID 892903):
§ 3.2 program structure (BEGIN PGM / BLK FORM / END PGM), § 6 tools (TOOL CALL, TOOL DEF),
§ 7 contours with Cartesian (L, CC, C, CR, CT, RND, CHF; C and CR in the ZX and YZ planes after
a CC X.. Z.. or CC Y.. Z..) and polar (LP, CP) coordinates, and DEP LT ("Approaching and departing
a contour"), § 8 subprograms and repeats (LBL, CALL LBL REP), § 9 Q parameters (FN, formulas); the cycles
manual for CYCL DEF 7 (datum shift), 9 (dwell), 32 (tolerance), 200/203/205 (drilling).

The translation is line for line (`Dialect.translate`): NGC line k runs what Klartext block k does.
Positions the Klartext semantics need (the last programmed point for incremental ``IX``, the circle
centre ``CC``/pole, the direction of the last contour element for ``CT``, the datum shift) are kept
in named parameters the translation assigns on the same line (``#<_hh_x>``, ``#<_hh_ccx>``,
``#<_hh_tx>``, ``#<_hh_dx>`` ...), so they stay right inside repeats and subprograms. Q parameter
``Qn`` is ``#<_qn>``. Lengths are in the program's units (``BEGIN PGM name MM|INCH``), angles in
degrees, feeds in units per minute, dwells in seconds.

Refused, with file:line:column and why: tilted working planes (PLANE, CYCL DEF 19), TCPM (M128,
FUNCTION TCPM), SL contour cycles (CYCL DEF 20–25), FK free contour programming, APPR/DEP approach
and departure other than DEP LT, feed per tooth or revolution (FZ, FU), tool axes other than Z,
CT/LP/CP after a CC outside XY, arcs outside XY with RL/RR, FN functions other than arithmetic
(FN 9 jumps, FN 18 system data ...), and any block this reader does not know.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from ..errors import MillpostError, ParseError
from .dialects import Dialect
from . import heidenhain_iso as iso
from .heidenhain_write import write as _write
from .tool_names import tool_note, tool_number

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)"
_BLOCK_NUMBER = re.compile(r"[ \t]*\d+(?=[ \t]|$)[ \t]*")
_TOKEN = re.compile(r"\S+")
# coordinate words: axis (incremental with I), value a signed number or a signed Q parameter
_COORD = re.compile(rf"(I?)(X|Y|Z)({_NUMBER}|[-+]?Q[LR]?\d+)$")
_POLAR = re.compile(rf"(I?)(PA|PR)({_NUMBER}|[-+]?Q[LR]?\d+)$")
_FEED = re.compile(rf"F({_NUMBER}|MAX|AUTO|Q[LR]?\d+)$")
_M = re.compile(r"M(\d+)$")
_PASSED_M = {0, 1, 2, 3, 4, 5, 8, 9, 30}
_NOOP_M = {126: "shortest rotary path", 127: "rotary path as programmed", 129: "TCPM off"}
_REFUSED_M = {128: "TCPM (tool centre point management) is not supported",
              140: "M140 (retract along the tool axis) on a block that moves", 118: "M118 (handwheel "
              "superimposition) is not supported"}
_NO_TILT = re.compile(r"PLANE\s+RESET\s+STAY|FUNCTION\s+RESET\s+TCPM")
_REFUSED = [
    (re.compile(r"PLANE\b"), "tilted working planes (PLANE) are not supported", "a 3-axis program"),
    (re.compile(r"FUNCTION\s+TCPM\b"), "TCPM is not supported", "a 3-axis program"),
    (re.compile(r"CYCL\s+DEF\s+19\b"), "tilted working planes (CYCL DEF 19) are not supported", "a 3-axis program"),
    (re.compile(r"CYCL\s+DEF\s+2[0-5]\b"), "SL contour cycles (CYCL DEF 20-25) are not supported",
     "the contour as L/C blocks"),
    (re.compile(r"F(?:L|LT|C|CT|POL|SELECT|PL|LN)\b"), "FK free contour programming is not supported",
     "the contour as L/C/CR/CT blocks"),
    (re.compile(r"(?:APPR|DEP(?![ \t]+LT\b))\b(?:[ \t]+P?[A-Z]+\b)?"), "approach and departure functions (APPR LT, LN, CT, LCT; DEP LN, CT, LCT) "
     "are not supported", "the approach and departure as L/C/CT blocks (DEP LT is read)"),
]


@dataclass
class _State:
    """What the translation carries from block to block (in text order)."""

    file: str
    inch: bool = False
    comp: str = "R0"
    tool_f: str | None = None  # the TOOL CALL F (for FAUTO)
    ended: bool = False
    unknown: set[str] = field(default_factory=lambda: set("XYZ"))  # axes with no programmed position yet
    labels: dict[int, str] = field(default_factory=dict)  # line → the NGC control line of a LBL/CALL LBL
    lines: list[str] = field(default_factory=list)  # the program's lines (RND/CHF look ahead)
    corner: int = 0  # the line of the RND/CHF whose points the last L block computed
    cycle: int = 0  # the drilling cycle defined (200, 203, 205; 0: none)
    cycle_q: dict[int, float | str | None] = field(default_factory=dict)  # its parameters as written
    cycle_at: dict[int, tuple[int, int]] = field(default_factory=dict)  # their lines and columns
    tools: dict[str, int] = field(default_factory=dict)  # tools called by name → their numbers (`tool_names`)
    cc_plane: tuple[str, str, str] = ("X", "Y", "G17")  # the plane of the last CC (`_PLANES`)
    other_planes: bool = False  # the program has a CC outside XY: every arc and cycle names its plane


def _error(st: _State, line: int, column: int, word: str, message: str, expected: str) -> ParseError:
    return ParseError(message, file=st.file, line=line, column=column, word=word, expected=expected)


@dataclass
class _Tokens:
    """A block's words after its keyword: text and 1-based column."""

    words: list[tuple[str, int]]
    line: int
    column: int = 1  # the block keyword's (for an arc's refusals)

    def take(self, pattern: re.Pattern) -> list[tuple[re.Match, int]]:
        """The words matching `pattern` (removed from the block)."""
        found, rest = [], []
        for text, col in self.words:
            m = pattern.match(text)
            (found if m else rest).append((m, col) if m else (text, col))
        self.words = rest
        return found


_LONE_AXIS = re.compile(r"I?(?:X|Y|Z|PA|PR)$")
_NUMBER_TOKEN = re.compile(rf"{_NUMBER}$")


def _split(code: str, start: int, offset: int, line: int) -> _Tokens:
    """The whitespace-separated words of `code` from index `start` (columns offset by `offset`); an
    axis letter apart from its number (``Z 25.000``) and ``F MAX``, as some posts write, are one word."""
    words: list[tuple[str, int]] = []
    for m in _TOKEN.finditer(code, start):
        text = m.group()
        if words and ((_NUMBER_TOKEN.match(text) and _LONE_AXIS.match(words[-1][0]))
                      or (words[-1][0] == "F" and text in ("MAX", "AUTO"))):  # "F MAX", as some posts write
            words[-1] = (words[-1][0] + text, words[-1][1])
        else:
            words.append((text, m.start() + 1 + offset))
    return _Tokens(words, line)


def _value(text: str) -> str:
    """An NGC value from a Klartext number or Q parameter (``+5`` → ``5``, ``-Q3`` → ``[-#<_q3>]``)."""
    sign, body = (text[0], text[1:]) if text[0] in "+-" else ("", text)
    if body.startswith("Q"):
        return f"[{'-' if sign == '-' else ''}{_param(body)}]"
    return f"-{body}" if sign == "-" else body


def _div(a: str, b: str) -> str:
    """a / b in NGC."""
    return f"[{a}/{b}]"


def _comment(text: str) -> str:
    """An NGC comment holding `text` (its parentheses as brackets)."""
    clean = text.strip().replace("(", "[").replace(")", "]")
    return f"({clean})" if clean else ""


def translate(text: str, file: str) -> str:
    """The Klartext program `text` as RS-274/NGC, line for line (see the module docstring)."""
    st = _State(file)
    lines = text.split("\n")
    if iso.is_iso(lines):
        return iso.translate(lines, file)
    lines = _comment_continuations(lines)
    st.labels, st.lines = _label_plan(st, lines), lines
    st.other_planes = any(_OTHER_PLANE.match(raw) for raw in lines)
    first = _next_block(st, 0)
    if first is None or not first[1][first[2]:].upper().startswith("BEGIN PGM"):
        n, code, start = first or (1, "", 0)
        raise _error(st, n, start + 1, code[start:].strip()[:20], "a Klartext program starts with BEGIN PGM",
                     "BEGIN PGM <name> MM|INCH")
    return "\n".join(_line(st, raw.rstrip("\r"), n) for n, raw in enumerate(lines, 1))


def _comment_continuations(lines: list[str]) -> list[str]:
    """The lines with a comment continued on the next line (a comment line ending in ``~``, as the
    TNC 640 and Fusion 360 break long comments) marked as comments (``;`` put in front)."""
    out, continued = [], False
    for raw in lines:
        out.append(";" + raw if continued else raw)
        code = raw.partition(";")[0]
        m = _BLOCK_NUMBER.match(code)
        continued = (continued or not code[m.end() if m else 0:].strip()) and raw.rstrip().endswith("~")
    return out


def _line(st: _State, raw: str, n: int) -> str:
    """One Klartext block as one NGC line (a block continued on the next line with ``~``, as the TNC 640
    writes cycle definitions, is read line by line: each of its lines is whole)."""
    code, _, note = raw.partition(";")
    code, note = code.rstrip().removesuffix("~"), note.rstrip().removesuffix("~")
    m = _BLOCK_NUMBER.match(code)
    start = m.end() if m else len(code) - len(code.lstrip())
    body = code[start:].rstrip()
    comment = _comment(note)
    if not body or body.startswith("*"):
        return " ".join(p for p in (_comment(body[1:].lstrip(" -")) if body else "", comment) if p)
    ngc = st.labels[n] if n in st.labels else _block(st, code, start, n)
    return f"{ngc} {comment}".strip()


def _block(st: _State, code: str, start: int, n: int) -> str:
    """The NGC words of the block `code[start:]` (its keyword decides)."""
    body = code[start:].upper()
    if _NO_TILT.fullmatch(body.strip()):  # the untilted plane / no TCPM: the 3-axis state, nothing moves
        return _comment(body.strip())
    for pattern, message, expected in _REFUSED:
        hit = pattern.match(body)
        if hit:
            raise _error(st, n, start + hit.start() + 1, hit.group(), message, expected)
    keyword = body.split()[0]
    handler = _HANDLERS.get(keyword)
    if handler is None:
        for prefix, h in _PREFIXED:
            if body.startswith(prefix):
                return h(st, code, start, n)
        raise _error(st, n, start + 1, keyword, "unknown Klartext block",
                     "L, C, CC, CR, CT, LP, CP, RND, CHF, TOOL CALL/DEF, CYCL DEF/CALL, FN, Q.. =, LBL, CALL LBL, "
                     "STOP, BEGIN/END PGM, BLK FORM, M functions")
    return handler(st, code, start + len(keyword), n)


def _begin(st: _State, code: str, start: int, n: int) -> str:
    """BEGIN PGM name MM|INCH (§ 3.2): the units; absolute, XY plane, no compensation."""
    words = code[start:].split()
    if len(words) != 3 or words[0].upper() != "PGM" or words[2].upper() not in ("MM", "INCH"):
        raise _error(st, n, start + 1, code[start:].strip(), "malformed BEGIN PGM", "BEGIN PGM <name> MM|INCH")
    st.inch = words[2].upper() == "INCH"
    return (f"{'G20' if st.inch else 'G21'} G90 G17 G94 G40 #<_hh_x>=0 #<_hh_y>=0 #<_hh_z>=0 #<_hh_ccx>=0 "
            f"#<_hh_ccy>=0 #<_hh_ccz>=0 #<_hh_tx>=0 #<_hh_ty>=0 #<_hh_dx>=0 #<_hh_dy>=0 #<_hh_dz>=0 ({_comment(words[1])[1:-1]})")


def _end(st: _State, code: str, start: int, n: int) -> str:
    """END PGM name (§ 3.2): the end of the program (M2 unless an M2/M30 ended it before)."""
    return "(END PGM)" if st.ended else "M2"


def _blk_form(st: _State, code: str, start: int, n: int) -> str:
    """BLK FORM 0.1/0.2 (§ 3.2): the blank, as a comment (see `blank`)."""
    _blank_corner(st, code, start, n)
    return _comment(f"BLK FORM {code[start:].strip()}")


def _blank_corner(st: _State, code: str, start: int, n: int) -> tuple[str, dict[str, tuple[bool, float]]]:
    """The corner kind ("0.1" min point, "0.2" max point) and its {axis: (incremental, value)}."""
    tokens = _split(code, start, 0, n)
    if not tokens.words or tokens.words[0][0] not in ("0.1", "0.2"):
        col = tokens.words[0][1] if tokens.words else start + 1
        raise _error(st, n, col, tokens.words[0][0] if tokens.words else "", "malformed BLK FORM",
                     "BLK FORM 0.1 Z X.. Y.. Z.. or BLK FORM 0.2 X.. Y.. Z..")
    kind = tokens.words.pop(0)[0]
    if kind == "0.1" and tokens.words and tokens.words[0][0].upper() in ("X", "Y", "Z"):
        axis, col = tokens.words.pop(0)
        if axis.upper() != "Z":
            raise _error(st, n, col, axis, "tool axis other than Z", "Z")
    corner = {}
    for m, col in tokens.take(_COORD):
        if m.group(2) not in "XYZ" or "Q" in m.group(3):
            raise _error(st, n, col, m.group(), "BLK FORM takes X, Y, Z numbers", "X+.. Y+.. Z+..")
        corner[m.group(2)] = (m.group(1) == "I", float(m.group(3)))
    _no_more(st, tokens, "BLK FORM X.. Y.. Z..")
    return kind, corner


def _no_more(st: _State, tokens: _Tokens, expected: str) -> None:
    if tokens.words:
        text, col = tokens.words[0]
        raise _error(st, tokens.line, col, text, "unexpected word", expected)


def blank(text: str, file: str = "<string>") -> tuple[tuple[float, float, float], tuple[float, float, float]] | None:
    """The blank of a Klartext program (BLK FORM 0.1 min point, 0.2 max point, § 3.2) as
    ((xmin, ymin, zmin), (xmax, ymax, zmax)) in mm; None when the program has no BLK FORM. An
    incremental 0.2 point (IX/IY/IZ) is relative to the 0.1 point."""
    st = _State(file)
    corners: dict[str, dict[str, tuple[bool, float]]] = {}
    for n, raw in enumerate(text.split("\n"), 1):
        code = raw.partition(";")[0].rstrip("\r")
        m = _BLOCK_NUMBER.match(code)
        start = m.end() if m else 0
        upper = code[start:].upper()
        if upper.startswith("BEGIN PGM"):
            st.inch = upper.split()[-1] == "INCH"
        elif upper.startswith("BLK FORM"):
            kind, corner = _blank_corner(st, code, start + len("BLK FORM"), n)
            corners[kind] = corner
    if "0.1" not in corners or "0.2" not in corners:
        return None
    scale = 25.4 if st.inch else 1.0
    lo = tuple(corners["0.1"].get(a, (False, 0.0))[1] for a in "XYZ")
    hi = tuple((lo[i] if inc else 0.0) + v for i, (inc, v) in
               enumerate(corners["0.2"].get(a, (False, lo["XYZ".index(a)])) for a in "XYZ"))
    pairs = [sorted((lo[i] * scale, hi[i] * scale)) for i in range(3)]
    return tuple(p[0] for p in pairs), tuple(p[1] for p in pairs)


_TOOL_NAME = re.compile(r'\s*"([^"]*)("?)')


def _tool_number(st: _State, code: str, start: int, n: int) -> tuple[str | None, str | None, _Tokens]:
    """The tool a TOOL CALL/TOOL DEF names (§ 6.3: by number, or by name in quotes, as hyperMILL and NX
    post), the note saying which number a name got (`tool_names`: the same rule as Sinumerik's
    ``T="name"``), and the block's words after it."""
    named = _TOOL_NAME.match(code, start)
    if named:
        name = named.group(1).strip()
        if not name or not named.group(2):
            raise _error(st, n, named.start(1), named.group().strip(), "a tool name in quotes",
                         'TOOL CALL "<name>" Z S..')
        number = tool_number(name, st.tools)
        return str(number), _comment(tool_note(name, number)), _split(code, named.end(), 0, n)
    tokens = _split(code, start, 0, n)
    if tokens.words and tokens.words[0][0].isdigit():
        return tokens.words.pop(0)[0], None, tokens
    return None, None, tokens


def _tool_call(st: _State, code: str, start: int, n: int) -> str:
    """TOOL CALL n|"name" Z S.. F.. DL+0 DR+0 (§ 6.3): tool change, spindle speed, the feed (modal, and
    FAUTO's); without a tool (TOOL CALL Z S..) only the spindle speed changes."""
    number, note, tokens = _tool_number(st, code, start, n)
    words = [f"T{number} M6 G43"] if number else []
    axis = [w for w in tokens.words if re.fullmatch(r"[XYZ]", w[0])]
    if axis and axis[0][0] != "Z":
        raise _error(st, n, axis[0][1], axis[0][0], "tool axis other than Z is not supported", "Z")
    tokens.words = [w for w in tokens.words if w[0] != "Z"]
    for m, col in tokens.take(re.compile(rf"S({_NUMBER})$")):
        words.append(f"S{_value(m.group(1))}")
    for m, col in tokens.take(re.compile(rf"F({_NUMBER})$")):
        st.tool_f = _value(m.group(1))
        words.append(f"F{st.tool_f}")
    for m, col in tokens.take(re.compile(rf"D(L|R|R2)({_NUMBER})$")):
        if float(m.group(2)) != 0:  # the control would cut DL higher, DR wider than programmed
            raise _error(st, n, col, m.group(), "a length or radius oversize (DL, DR, DR2) moves the cut and is "
                         "not modelled", "DL+0 DR+0, or the tool's size in the job")
    _no_more(st, tokens, "TOOL CALL n Z S.. F.. DL+0 DR+0")
    return " ".join([*words, *([note] if note else [])])


def _tool_def(st: _State, code: str, start: int, n: int) -> str:
    """TOOL DEF n|"name" (L.. R..) (§ 6.3): the next tool, prepared, not changed (its length and radius,
    as older TNCs define them in the program, are the job's tool description's business)."""
    number, note, tokens = _tool_number(st, code, start, n)
    if number is None:
        text, col = tokens.words[0] if tokens.words else ("", start + 1)
        raise _error(st, n, col, text, "malformed TOOL DEF", 'TOOL DEF <number>|"<name>" (L.. R..)')
    tokens.take(re.compile(rf"[LR]{_NUMBER}$"))
    _no_more(st, tokens, "TOOL DEF <number> L.. R..")
    return " ".join([f"T{number}", *([note] if note else [])])


def _cycl_def(st: _State, code: str, start: int, n: int) -> str:
    """CYCL DEF 32 TOLERANCE (and 32.1/32.2): path tolerance, kept as a comment; CYCL DEF 7 DATUM SHIFT."""
    tokens = _split(code, start, 0, n)
    number = tokens.words[0][0] if tokens.words else ""
    if number.split(".")[0] == "32" or number in ("7", "7.0"):
        return _comment(f"CYCL DEF {code[start:].strip()}")
    if number in ("7.1", "7.2", "7.3"):
        return _datum_shift(st, tokens, number)
    if number in ("200", "203", "205"):
        st.cycle, st.cycle_q, st.cycle_at = int(number), {}, {}
        return _comment(f"CYCL DEF {code[start:].strip()}")
    if number in ("9", "9.0"):
        return _comment(f"CYCL DEF {code[start:].strip()}")
    if number == "9.1":
        return _dwell(st, tokens)
    raise _error(st, n, tokens.words[0][1] if tokens.words else start + 1, number,
                 f"CYCL DEF {number} is not supported", "CYCL DEF 32 TOLERANCE")


_CYCLE_DEFAULTS = {200: {210: 0.0, 211: 0.0}, 203: {210: 0.0, 211: 0.0, 212: 0.0, 213: 0.0, 395: 0.0},
                   205: {211: 0.0, 212: 0.0, 257: 0.0, 379: 0.0, 395: 0.0}}
_CYCLE_REFUSED = {210: "a dwell at the top (Q210)", 212: "a plunging depth decrement (Q212)",
                  379: "a deepened starting point (Q379)", 395: "depth measured to the full diameter (Q395=1)"}


def _drill(st: _State, n: int, column: int, xy: list[str]) -> str:
    """The drilling cycle defined (200 DRILLING, 203 UNIVERSAL DRILLING, 205 UNIVERSAL PECKING), called
    here, as one RS-274 drilling cycle: from the set-up clearance R = Q203 + Q200 to the depth
    Z = Q203 + Q201 at F = Q206, in pecks of Q202 (G83, full retracts to R) or in one plunge (G81; G82
    with the dwell at depth Q211), retracting to the set-up clearance (G99), or where the 2nd set-up
    clearance Q204 is higher, to the height the tool came from (G98: the program positions there).
    Chip breaking (Q213, Q257) is run as full retracts: the same cut, other moves in the air."""
    if not st.cycle:
        raise _error(st, n, column, "CYCL CALL", "a cycle call with no cycle defined", "CYCL DEF 200/203/205 before it")
    q = {**_CYCLE_DEFAULTS[st.cycle], **st.cycle_q}
    missing = [k for k in (200, 201, 202, 203, 204) if not isinstance(q.get(k), float)]
    missing += [206] if 206 not in q else []
    if missing:
        line, col = st.cycle_at.get(missing[0], (n, column))
        raise _error(st, line, col, f"Q{missing[0]}", f"cycle {st.cycle} needs Q{missing[0]} as a number",
                     f"Q{missing[0]}=<number> in the CYCL DEF")
    def refuse(k: int, message: str, expected: str) -> ParseError:
        line, col = st.cycle_at.get(k, (n, column))
        return _error(st, line, col, f"Q{k}", message, expected)

    for k, what in _CYCLE_REFUSED.items():
        if k in q and q[k] != 0.0:
            raise refuse(k, f"cycle {st.cycle} with {what} is not supported", f"Q{k}=0")
    if q[201] >= 0:
        raise refuse(201, "a drilling depth Q201 that is not negative", "Q201 < 0")
    peck = 0 < q[202] < -q[201]
    if peck and q[211]:
        raise refuse(211, "a dwell at depth (Q211) with pecking is not supported", "Q211=0")
    code = "G83" if peck else "G82" if q[211] else "G81"
    words = [*_plane(st, _XY, n, column, "CYCL CALL"), f"{'G98' if q[204] > q[200] else 'G99'} {code}", *xy, f"Z{q[203] + q[201]:g}", f"R{q[203] + q[200]:g}"]
    words += [f"Q{q[202]:g}"] if peck else [f"P{q[211]:g}"] if q[211] else []
    retract = "#<_hh_z>" if q[204] > q[200] else f"{q[203] + q[200]:g}"
    feed = f"F{q[206]:g}" if isinstance(q[206], float) else "F#<_q206>"  # Q206=Q2: the parameter's value
    return " ".join([*words, feed, f"#<_hh_z>={retract}"])


def _cycl_call(st: _State, code: str, start: int, n: int) -> str:
    """CYCL CALL (M..): the cycle defined, here (see `_drill`)."""
    tokens = _split(code, start, 0, n)
    if tokens.words and tokens.words[0][0].upper() == "POS":
        raise _error(st, n, tokens.words[0][1], "POS", "CYCL CALL POS is not supported", "L X.. Y.. FMAX M99")
    words, _ = _m_words(st, tokens)
    _no_more(st, tokens, "CYCL CALL M..")
    return " ".join([_drill(st, n, start - 3, []), *words])


def _dwell(st: _State, tokens: _Tokens) -> str:
    """CYCL DEF 9.1 DWELL s (cycle 9, active where defined): a dwell of s seconds."""
    words = tokens.words[1:]
    value = words[-1][0] if words else ""
    if not re.fullmatch(rf"{_NUMBER}|Q[LR]?\d+", value, re.IGNORECASE) or len(words) > 2:
        raise _error(st, tokens.line, words[-1][1] if words else 1, value, "malformed dwell",
                     "CYCL DEF 9.1 DWELL <seconds>")
    return f"G4 P{_value(value)}"


def _datum_shift(st: _State, tokens: _Tokens, number: str) -> str:
    """CYCL DEF 7.1 X.. / 7.2 Y.. / 7.3 Z.. (datum shift, cycle 7): the datum moves to the value
    (incremental IX: by it), as G52; the last programmed position is carried into the new frame."""
    tokens.words.pop(0)
    axis = "XYZ"[int(number[-1]) - 1]
    targets = _targets(st, _Tokens(list(tokens.words), tokens.line), axis) if tokens.words else {}
    if len(tokens.words) != 1 or axis not in targets:
        text, col = tokens.words[0] if tokens.words else ("", 1)
        raise _error(st, tokens.line, col, text, f"CYCL DEF {number} takes one {axis} value", f"{axis}+<shift>")
    shift, pos = f"#<_hh_d{axis.lower()}>", _AXIS_PARAM[axis]
    value = targets[axis].replace(pos, shift)  # IX: incremental to the shift in force
    return f"G52 {axis}{value} {pos}=[{pos}+{shift}-{value}] {shift}={value}"


def _m_words(st: _State, tokens: _Tokens) -> tuple[list[str], bool]:
    """The block's M functions as NGC words, and whether M91/M92 (machine coordinates) is among them."""
    words, machine = [], False
    for m, col in tokens.take(_M):
        code = int(m.group(1))
        if code in _PASSED_M:
            words.append(f"M{code}")
            st.ended = st.ended or code in (2, 30)
        elif code in (13, 14):
            words += [f"M{code - 10}", "M8"]
        elif code in (91, 92):
            machine = True
        elif code == 99:
            words.append("M99")
        elif code in _NOOP_M:
            words.append(f"(M{code}: {_NOOP_M[code]})")
        elif code in _REFUSED_M:
            raise _error(st, tokens.line, col, m.group(), _REFUSED_M[code], "a 3-axis program without it")
        else:
            raise _error(st, tokens.line, col, m.group(), f"M{code} is not supported",
                         "M0 M1 M2 M3 M4 M5 M8 M9 M13 M14 M30 M91 M92 M126 M127 M129")
    return words, machine


def _m_only(st: _State, code: str, start: int, n: int) -> str:
    """A block of M functions alone (e.g. ``M30``, ``M3``)."""
    tokens = _split(code, start, 0, n)
    words, machine = _m_words(st, tokens)
    _no_more(st, tokens, "M functions")
    return " ".join(words)


def _stop(st: _State, code: str, start: int, n: int) -> str:
    """STOP (§ 11): program stop (M0)."""
    tokens = _split(code, start, 0, n)
    words, _ = _m_words(st, tokens)
    _no_more(st, tokens, "STOP M..")
    return " ".join(["M0", *words])


_AXIS_PARAM = {"X": "#<_hh_x>", "Y": "#<_hh_y>", "Z": "#<_hh_z>"}


def _targets(st: _State, tokens: _Tokens, allowed: str) -> dict[str, str]:
    """The block's X/Y/Z words as absolute NGC expressions ({axis: expr}); ``IX`` adds to the last
    programmed position (§ 7.3, incremental coordinates)."""
    out: dict[str, str] = {}
    for m, col in tokens.take(_COORD):
        inc, axis, value = m.groups()
        if axis not in allowed:
            raise _error(st, tokens.line, col, m.group(), f"{axis} is not a word of this block", allowed)
        if axis in out:
            raise _error(st, tokens.line, col, m.group(), f"{axis} twice in one block", f"one {axis} word")
        if inc and axis in st.unknown:
            raise _error(st, tokens.line, col, m.group(), f"incremental {axis} from an unknown position (program "
                         "start or a machine-coordinate move)", f"an absolute {axis} before it")
        out[axis] = f"[{_AXIS_PARAM[axis]}+{_value(value)}]" if inc else _value(value)
    return out


def _contour_words(st: _State, tokens: _Tokens, rapid_ok: bool = True) -> tuple[str | None, list[str], bool]:
    """The radius compensation (G40/G41/G42 when it changes), F (None: FMAX, a rapid for this block
    only, § 7.2), the M words and whether M91/M92 asks for machine coordinates."""
    pre: list[str] = []
    for m, col in tokens.take(re.compile(r"R(0|L|R)$")):
        comp = "R" + m.group(1)
        if comp != st.comp:
            pre += ["G17"] if st.other_planes and comp != "R0" else []  # compensation in the working plane
            pre.append({"R0": "G40", "RL": "G41", "RR": "G42"}[comp])
            st.comp = comp
    feed = ""
    for m, col in tokens.take(re.compile(r"F[ZU]")):
        raise _error(st, tokens.line, col, m.string, "feed per tooth or per revolution (FZ, FU) is not supported",
                     "F<feed in mm/min>, FMAX or FAUTO")
    for m, col in tokens.take(_FEED):
        if m.group(1) == "MAX":
            if not rapid_ok:
                raise _error(st, tokens.line, col, m.group(), "FMAX on an arc", "F<feed>")
            feed = None
        elif m.group(1) == "AUTO":
            if st.tool_f is None:
                raise _error(st, tokens.line, col, m.group(), "FAUTO with no F in the TOOL CALL", "F<feed>")
            feed = f"F{st.tool_f}"
        else:
            feed = f"F{_value(m.group(1))}"
    m_words, machine = _m_words(st, tokens)
    return feed, pre + m_words, machine


def _assigns(targets: dict[str, str]) -> list[str]:
    return [f"{_AXIS_PARAM[a]}={e}" for a, e in targets.items()]


def _retract(st: _State, tokens: _Tokens) -> str | None:
    """L M140 MB MAX|MB <distance> (§ M functions): a rapid up the tool axis, to the top of its travel
    (machine Z0, as G53 Z0) or by the distance; None when the block has no M140."""
    at = next((k for k, (t, _) in enumerate(tokens.words) if t.upper() == "M140"), None)
    if at is None:
        return None
    words = [t.upper() for t, _ in tokens.words]
    taken = 1 if at + 1 < len(words) and words[at + 1].startswith("MB") else 0
    taken += 1 if taken and words[at + 1] == "MB" and at + 2 < len(words) else 0  # "MB MAX" apart
    mb = "".join(words[at + 1:at + 1 + taken])
    others = words[:at] + words[at + 1 + taken:]
    m = re.fullmatch(rf"MB(MAX|{_NUMBER})", mb)
    if not m or any(t not in ("R0", "FMAX") for t in others):
        text, col = tokens.words[at]
        raise _error(st, tokens.line, col, text, "M140 on a block that moves, or without MB",
                     "L M140 MB MAX or L M140 MB <distance>")
    if m.group(1) == "MAX":
        st.unknown.add("Z")
        return "G53 G0 Z0"
    return f"G0 Z[#<_hh_z>+{_value(m.group(1))}] #<_hh_z>=[#<_hh_z>+{_value(m.group(1))}]"


def _l(st: _State, code: str, start: int, n: int) -> str:
    """L X.. Y.. Z.. R0|RL|RR F..|FMAX|FAUTO M.. (§ 7.4): a straight line, or a rapid with FMAX."""
    tokens = _split(code, start, 0, n)
    retract = _retract(st, tokens)
    if retract:
        return retract
    targets = _targets(st, tokens, "XYZ")
    feed, words, machine = _contour_words(st, tokens)
    _no_more(st, tokens, "L X.. Y.. Z.. R0|RL|RR F..|FMAX M..")
    motion = "G0" if feed is None else "G1"
    coords = [f"{a}{e}" for a, e in targets.items()]
    if machine:
        if st.comp != "R0" or any(e.startswith("[#<_hh") for e in targets.values()):
            raise _error(st, n, start + 1, "M91", "M91/M92 with compensation or incremental coordinates",
                         "L Z.. R0 FMAX M91 with absolute machine coordinates")
        st.unknown |= set(targets)  # where the program's frame puts these axes now is not tracked
        return " ".join(["G53", motion, *coords, *words])
    st.unknown -= set(targets)
    if "M99" in words:  # position, then call the cycle (§ cycles: M99 calls it in this block)
        return _l_cycle_call(st, n, start, targets, feed, words)
    if not targets:  # L with only F or M functions: no motion (FMAX alone moves nowhere)
        return " ".join([*_pre(words), *([feed] if feed else []), *_post(words)])
    tangent = []
    if "X" in targets or "Y" in targets:
        tangent = [f"#<_hh_tx>=[{targets.get('X', '#<_hh_x>')}-#<_hh_x>]",
                   f"#<_hh_ty>=[{targets.get('Y', '#<_hh_y>')}-#<_hh_y>]"]
    corner = _corner_after(st, n, targets)
    if corner:
        coords, tangent = [f"X{corner[0]}", f"Y{corner[1]}"], tangent + corner[2]
    return " ".join([*_pre(words), motion, *coords, *([feed] if feed else []), *_post(words),
                     *_assigns(targets), *tangent])


def _l_cycle_call(st: _State, n: int, start: int, targets: dict[str, str], feed: str | None,
                  words: list[str]) -> str:
    """L X.. Y.. FMAX M99: the cycle at that point (the RS-274 cycle makes the rapid to it)."""
    if "Z" in targets or (feed is not None and targets):
        raise _error(st, n, start + 1, "M99", "M99 on a block that moves Z or feeds to the hole",
                     "L X.. Y.. FMAX M99 (the cycle moves Z)")
    rest = [w for w in words if w != "M99"]
    xy = [f"{a}{e}" for a, e in targets.items()]
    return " ".join([*_pre(rest), _drill(st, n, start + 1, xy), *_post(rest), *_assigns(targets)])


def _pre(words: list[str]) -> list[str]:
    return [w for w in words if w.startswith("G")]


def _post(words: list[str]) -> list[str]:
    return [w for w in words if not w.startswith("G")]


# The planes of CC and the arcs about it (manual, "Circle center CC": the plane of the two coordinates given;
# CC alone: the working plane, XY for tool axis Z): (first axis, second axis, RS-274 plane). DR+ turns the
# first axis towards the second (counter-clockwise looking against the positive normal: Z→X in ZX, as
# G3 in G18, viewed from +Y), so DR+ is G3 and DR- G2 in every plane.
_XY = ("X", "Y", "G17")
_PLANES = {frozenset("XY"): _XY, frozenset("XZ"): ("Z", "X", "G18"), frozenset("YZ"): ("Y", "Z", "G19")}
_OFFSET = {"X": "I", "Y": "J", "Z": "K"}
_OTHER_PLANE = re.compile(r"^[ \t]*\d*[ \t]*CC\b[^;]*\bI?Z", re.IGNORECASE)


def _cc(st: _State, code: str, start: int, n: int) -> str:
    """CC X.. Y.. | CC X.. Z.. | CC Y.. Z.. (§ 7.4, "Circle center CC"): the circle centre (and pole) in
    the plane of the two coordinates; CC alone: the last programmed position in the working plane."""
    tokens = _split(code, start, 0, n)
    targets = _targets(st, tokens, "XYZ")
    _no_more(st, tokens, "CC X.. Y.., CC X.. Z.. or CC Y.. Z..")
    if len(targets) in (1, 3):
        raise _error(st, n, start - 1, "CC", f"CC with {'one coordinate' if len(targets) == 1 else 'X, Y and Z'}",
                     "CC X.. Y.., CC X.. Z.., CC Y.. Z.., or CC alone")
    st.cc_plane = _PLANES[frozenset(targets)] if targets else _XY
    if not targets:
        _known(st, _XY, code, start, n)
        targets = {a: _AXIS_PARAM[a] for a in "XY"}
    return " ".join(f"#<_hh_cc{a.lower()}>={e}" for a, e in targets.items())


def _plane(st: _State, plane: tuple[str, str, str], n: int, column: int, keyword: str) -> list[str]:
    """The plane word of a block that arcs or drills in `plane`: in a program with arcs outside XY every
    such block names its plane (a subprogram may change it); none otherwise. An arc outside XY with
    radius compensation on is refused (the compensation is in the working plane)."""
    if plane != _XY and st.comp != "R0":
        raise _error(st, n, column, keyword, f"an arc in the {plane[0]}{plane[1]} plane with radius compensation "
                     "(RL/RR)", "R0 before it")
    return [plane[2]] if st.other_planes else []


def _direction(st: _State, tokens: _Tokens) -> str:
    """DR+ (counter-clockwise, G3) or DR- (clockwise, G2), § 7.4 (see `_PLANES`)."""
    found = tokens.take(re.compile(r"DR([-+])$"))
    if len(found) != 1:
        raise _error(st, tokens.line, tokens.words[0][1] if tokens.words else 1, "", "an arc needs one direction",
                     "DR+ (counter-clockwise) or DR- (clockwise)")
    return "G3" if found[0][0].group(1) == "+" else "G2"


def _arc_end(st: _State, code: str, start: int, n: int,
             plane: tuple[str, str, str] = _XY) -> tuple[dict[str, str], _Tokens]:
    """The arc's end point and the block's other words; the start point must be known in `plane`."""
    _known(st, plane, code, start, n)
    tokens = _split(code, start, 0, n)
    tokens.column = start - len(code[:start].split()[-1]) + 1
    targets = _targets(st, tokens, "XYZ")
    st.unknown -= set(targets)
    return targets, tokens


def _xy_pole(st: _State, code: str, start: int, n: int) -> None:
    """Refuses LP, CP and CT after a CC outside XY (polar coordinates and tangent arcs are read in the
    working plane XY only)."""
    if st.cc_plane != _XY:
        keyword = code[:start].split()[-1]
        raise _error(st, n, start - len(keyword) + 1, keyword, f"{keyword.upper()} after a CC in the "
                     f"{st.cc_plane[0]}{st.cc_plane[1]} plane is not supported (polar and tangent arcs in XY only)",
                     "CC X.. Y.. before it, or C/CR in that plane")


def _known_xy(st: _State, code: str, start: int, n: int) -> None:
    _known(st, _XY, code, start, n)


def _known(st: _State, plane: tuple[str, str, str], code: str, start: int, n: int) -> None:
    """Refuses an arc or CC from a position unknown in `plane`."""
    if st.unknown & set(plane[:2]):
        keyword = code[:start].split()[-1]
        axes = f"{plane[0]}/{plane[1]}"
        raise _error(st, n, start - len(keyword) + 1, keyword, f"an arc or CC from an unknown {axes} position "
                     "(program start or a machine-coordinate move)",
                     f"an L block to an absolute {plane[0]} and {plane[1]} before it")


def _arc_line(st: _State, tokens: _Tokens, motion: str, targets: dict[str, str], centre: list[str],
              tangent: list[str], expected: str, plane: tuple[str, str, str] = _XY) -> str:
    """An arc's NGC line in `plane` (no end point in the plane: back to the start, a full circle)."""
    feed, words, _ = _contour_words(st, tokens, rapid_ok=False)
    _no_more(st, tokens, expected)
    keyword = expected.split()[0]
    plane_word = [w for w in _plane(st, plane, tokens.line, tokens.column, keyword) if w not in words]
    end = {plane[0]: _AXIS_PARAM[plane[0]], plane[1]: _AXIS_PARAM[plane[1]], **targets}
    coords = [f"{a}{end[a]}" for a in "XYZ" if a in end]
    return " ".join([*plane_word, *_pre(words), motion, *coords, *centre, *([feed] if feed else []),
                     *_post(words), *_assigns(targets), *tangent])


def _end_tangent(motion: str, targets: dict[str, str], cx: str, cy: str,
                 plane: tuple[str, str, str] = _XY) -> list[str]:
    """The direction at an arc's end: perpendicular to the radius, turning with the arc; `cx`, `cy` the
    centre's coordinates along the plane's first and second axis. The XY tangent (for CT) is its
    projection on XY."""
    a, b = plane[:2]
    ea, eb = targets.get(a, _AXIS_PARAM[a]), targets.get(b, _AXIS_PARAM[b])
    sign = "" if motion == "G3" else "-"
    t = {a: f"[{sign}[{cy}-{eb}]]", b: f"[{sign}[{ea}-{cx}]]"}
    return [f"#<_hh_tx>={t.get('X', '0')}", f"#<_hh_ty>={t.get('Y', '0')}"]


def _c(st: _State, code: str, start: int, n: int) -> str:
    """C X.. Y.. DR+|DR- (§ 7.4): an arc about CC to the end point in CC's plane (the third axis too: a
    helix)."""
    plane = st.cc_plane
    targets, tokens = _arc_end(st, code, start, n, plane)
    motion = _direction(st, tokens)
    a, b = (f"#<_hh_cc{x.lower()}>" for x in plane[:2])
    centre = [f"{_OFFSET[x]}[{c}-{_AXIS_PARAM[x]}]" for x, c in zip(plane[:2], (a, b))]
    return _arc_line(st, tokens, motion, targets, centre, _end_tangent(motion, targets, a, b, plane),
                     "C X.. Y.. DR+|DR- F..", plane)


def _cr(st: _State, code: str, start: int, n: int) -> str:
    """CR X.. Y.. R.. DR+|DR- (§ 7.4): an arc of radius R in CC's plane; R negative: the arc over 180°."""
    plane = st.cc_plane
    targets, tokens = _arc_end(st, code, start, n, plane)
    motion = _direction(st, tokens)
    radius = tokens.take(re.compile(rf"R({_NUMBER}|[-+]?Q\d+)$"))
    if len(radius) != 1:
        raise _error(st, n, start + 1, "CR", "CR needs one radius", "CR X.. Y.. R+.. DR+|DR-")
    r = _value(radius[0][0].group(1))
    # the centre, as the interpreter finds it from R: kept for CT after this arc
    sx, sy = (_AXIS_PARAM[x] for x in plane[:2])
    ex, ey = targets.get(plane[0], sx), targets.get(plane[1], sy)
    dx, dy, rr = f"[{ex}-{sx}]", f"[{ey}-{sy}]", f"[{r}]"
    d2 = f"[{dx}*{dx}+{dy}*{dy}]"
    h = f"[SQRT[ABS[{_div(f'{rr}*{rr}', d2)}-0.25]]]"
    side = f"[{'' if motion == 'G3' else '-'}{_div(rr, f'ABS[{rr}]')}]"
    cx, cy = f"[{sx}+{dx}/2-{side}*{h}*{dy}]", f"[{sy}+{dy}/2+{side}*{h}*{dx}]"
    return _arc_line(st, tokens, motion, targets, [f"R{r}"], _end_tangent(motion, targets, cx, cy, plane),
                     "CR X.. Y.. R.. DR+|DR- F..", plane)


def _ct(st: _State, code: str, start: int, n: int) -> str:
    """CT X.. Y.. (§ 7.4): the arc tangent to the previous contour element, to the end point (in XY)."""
    _xy_pole(st, code, start, n)
    targets, tokens = _arc_end(st, code, start, n)
    sx, sy = "#<_hh_x>", "#<_hh_y>"
    ex, ey = targets.get("X", sx), targets.get("Y", sy)
    dx, dy = f"[{ex}-{sx}]", f"[{ey}-{sy}]"
    nx, ny = "[-#<_hh_ty>]", "#<_hh_tx>"  # left of the direction of travel
    nd = f"[{nx}*{dx}+{ny}*{dy}]"
    s = _div(f"[{dx}*{dx}+{dy}*{dy}]", f"[2*{nd}]")  # centre = start + s·normal
    motion = f"G[2+[{nd} GT 0]]"
    i, j = f"[{s}*{nx}]", f"[{s}*{ny}]"
    ex_c, ey_c = f"[{sx}+{i}]", f"[{sy}+{j}]"
    ux, uy = f"[{ey_c}-{ey}]", f"[{ex}-{ex_c}]"  # the end direction, counter-clockwise; × sign(nd)
    sign = f"[2*[{nd} GT 0]-1]"
    tangent = [f"#<_hh_tx>=[-{sign}*{ux}]", f"#<_hh_ty>=[-{sign}*{uy}]"]
    return _arc_line(st, tokens, motion, targets, [f"I{i}", f"J{j}"], tangent, "CT X.. Y.. F..")


_LBL = re.compile(r"LBL\s*(\d+|\"[^\"]*\")\s*$", re.IGNORECASE)
_CALL_LBL = re.compile(r"CALL\s+LBL\s*(\d+|\"[^\"]*\")(?:\s+REP\s*(\d+)(?:\s*/\s*\d+)?)?\s*$", re.IGNORECASE)


def _label_name(text: str) -> str:
    """The O-word name of a label (``1`` → ``hh1``, ``"CONTOUR"`` → ``hh_contour``)."""
    if text.startswith('"'):
        return "hh_" + re.sub(r"[^a-z0-9]", "_", text[1:-1].lower())
    return f"hh{int(text)}"


def _label_plan(st: _State, lines: list[str]) -> dict[int, str]:
    """The NGC control line of every LBL and CALL LBL block (§ 8): a section repeat (LBL n before
    ``CALL LBL n REP m``: the section runs m + 1 times) is ``repeat [m+1]``/``endrepeat``; a label
    called without REP is a subprogram (``sub``, up to the next LBL 0 ``endsub``; ``call``). Labels
    nothing calls are comments."""
    blocks: list[tuple[int, str, int]] = []  # (line, block text upper case, column of the block)
    for n, raw in enumerate(lines, 1):
        code = raw.partition(";")[0].rstrip("\r")
        m = _BLOCK_NUMBER.match(code)
        start = m.end() if m else 0
        blocks.append((n, code[start:].strip(), start + 1))
    plan: dict[int, str] = {}
    last_label: dict[str, int] = {}
    subs: dict[str, int] = {}
    for n, body, col in blocks:
        call, label = _CALL_LBL.match(body), _LBL.match(body)
        if label:
            last_label[label.group(1).upper()] = n
            plan[n] = _comment(body)
        elif call and call.group(2) is not None and call.group(1).upper() in last_label:
            at, name = last_label.pop(call.group(1).upper()), _label_name(call.group(1))
            if at in subs.values():
                raise _error(st, n, col, body, "a label both repeated and called as a subprogram", "two labels")
            plan[at], plan[n] = f"o<{name}_{n}> repeat [{int(call.group(2)) + 1}]", f"o<{name}_{n}> endrepeat"
        elif call:
            if call.group(2) is not None:
                raise _error(st, n, col, body, "CALL LBL REP of a label that is not before it (a subprogram "
                             "called several times)", "CALL LBL n REP m after LBL n, or CALL LBL n")
            subs[call.group(1).upper()] = 0
            plan[n] = f"o<{_label_name(call.group(1))}> call"
    _subprograms(st, blocks, plan, subs)
    return plan


def _subprograms(st: _State, blocks: list[tuple[int, str, int]], plan: dict[int, str], subs: dict[str, int]) -> None:
    """The ``sub``/``endsub`` lines of the labels called as subprograms (each ends at the next LBL 0)."""
    open_sub: str | None = None
    for n, body, col in blocks:
        label = _LBL.match(body)
        if not label:
            continue
        key = label.group(1).upper()
        if key == "0":
            if open_sub is not None:
                plan[n] = f"o<{_label_name(open_sub)}> endsub"
                open_sub = None
        elif key in subs:
            if open_sub is not None:
                raise _error(st, n, col, body, f"LBL {open_sub} has no LBL 0 before the next subprogram", "LBL 0")
            if plan.get(n, "(").startswith("o<"):
                raise _error(st, n, col, body, "a label both repeated and called as a subprogram", "two labels")
            plan[n], open_sub, subs[key] = f"o<{_label_name(key)}> sub", key, n
    if open_sub is not None:
        raise _error(st, subs[open_sub], 1, f"LBL {open_sub}", "a subprogram without LBL 0", "LBL 0 after it")
    missing = [k for k, at in subs.items() if not at]
    if missing:
        n = next(n for n, body, _ in blocks if (m := _CALL_LBL.match(body)) and m.group(1).upper() == missing[0])
        raise _error(st, n, 1, f"LBL {missing[0]}", "CALL LBL of a label that is not in the program", "LBL n")


_Q = re.compile(r"Q([LR]?)(\d+)")
_FUNCTIONS = {"SIN": "SIN", "COS": "COS", "TAN": "TAN", "ASIN": "ASIN", "ACOS": "ACOS", "ATAN": "ATAN",
              "SQRT": "SQRT", "ABS": "ABS", "LN": "LN", "EXP": "EXP"}
_FORMULA_TOKEN = re.compile(r"\s*(?:(\d+\.?\d*|\.\d+)|(Q[LR]?\d+)|([A-Z]+)|(\*\*|[-+*/^()]))", re.IGNORECASE)


def _param(text: str) -> str:
    """The NGC name of Q parameter `text` (Qn: #<_qn>; local QLn and remanent QRn: #<_qln>, #<_qrn>)."""
    kind, number = _Q.fullmatch(text.upper()).groups()
    return f"#<_q{kind.lower()}{int(number)}>"


def _formula(st: _State, text: str, at: int, n: int) -> str:
    """A Klartext formula (§ 9.8: + - * / ^, parentheses, SIN COS TAN ASIN ACOS ATAN SQRT SQ ABS LN
    EXP PI, Q parameters) as an NGC expression in brackets; angles in degrees as in NGC. `at`: the
    formula's index in its line (for error columns)."""
    out: list[str] = []
    squares: list[bool] = []  # per open parenthesis: whether it is SQ's (x², written [x]**2)
    pending_sq, pos = False, 0
    while pos < len(text.rstrip()):
        m = _FORMULA_TOKEN.match(text, pos)
        if not m or (pending_sq and m.group(4) != "("):
            word = text[pos:].split()[0]
            raise _error(st, n, at + pos + 1, word, "not a formula term",
                         "numbers, Q parameters, + - * / ^, ( ), SIN COS TAN ASIN ACOS ATAN SQRT SQ ABS LN EXP PI")
        number, q, name, op = m.groups()
        pos = m.end()
        if name:
            name = name.upper()
            if name not in _FUNCTIONS and name not in ("PI", "SQ"):
                raise _error(st, n, at + m.start(3) + 1, name, f"the function {name} is not supported",
                             "SIN COS TAN ASIN ACOS ATAN SQRT SQ ABS LN EXP PI")
            pending_sq = name == "SQ"
            out.append({"PI": "3.141592653589793", "SQ": ""}.get(name, name))
        elif op == "(":
            squares.append(pending_sq)
            out.append("[[" if pending_sq else "[")
            pending_sq = False
        elif op == ")":
            if not squares:
                raise _error(st, n, at + m.start(4) + 1, ")", "unbalanced parenthesis", "( before )")
            out.append("]**2]" if squares.pop() else "]")
        else:
            out.append(number or (_param(q) if q else {"^": "**"}.get(op, op)))
    if squares or pending_sq:
        raise _error(st, n, at + pos + 1, text.strip(), "unbalanced parenthesis", ") for every (")
    return "[" + "".join(out) + "]"


_OPERAND = r"[-+]?\s*(?:\d+\.?\d*|\.\d+|Q[LR]?\d+)"
_FN = re.compile(r"FN\s*(\d+)\s*:\s*", re.IGNORECASE)
_FN_OPS = {0: None, 1: "+", 2: "-", 3: "*", 4: "/"}
_ASSIGN = re.compile(r"(Q[LR]?\d+)\s*=\s*", re.IGNORECASE)


def _fn(st: _State, code: str, start: int, n: int) -> str:
    """FN 0: Q1 = a (assign), FN 1/2/3/4: Q1 = a +|-|*|/ b (§ 9.3); other FN functions are refused."""
    m = _FN.match(code, start)
    if not m:
        raise _error(st, n, start + 1, code[start:].split()[0], "malformed FN block", "FN <number>: Q<n> = ..")
    number = int(m.group(1))
    if number not in _FN_OPS:
        raise _error(st, n, start + 1, m.group().strip(), f"FN {number} is not supported (only arithmetic: no "
                     "jumps, system data, output or errors)", "FN 0 to FN 4, or a formula Q.. = ..")
    a = _ASSIGN.match(code, m.end())
    if not a:
        raise _error(st, n, m.end() + 1, code[m.end():].strip(), "malformed FN", f"FN {number}: Q<n> = ..")
    rest = code[a.end():].strip()
    op = _FN_OPS[number]
    if op and not re.fullmatch(rf"({_OPERAND})\s*{re.escape(op)}\s*({_OPERAND})", rest, re.IGNORECASE):
        raise _error(st, n, a.end() + 1, rest, f"FN {number} takes two operands", f"a {op} b (numbers or Q)")
    if not op and not re.fullmatch(_OPERAND, rest, re.IGNORECASE):
        raise _error(st, n, a.end() + 1, rest, "FN 0 takes one value", "a number or a Q parameter")
    return f"{_param(a.group(1))}={_formula(st, rest, a.end(), n)}"


def _q_assign(st: _State, code: str, start: int, n: int) -> str:
    """Q1 = formula (§ 9.8)."""
    a = _ASSIGN.match(code, start)
    if not a:
        raise _error(st, n, start + 1, code[start:].split()[0], "a Q parameter block without =", "Q<n> = <formula>")
    value = code[a.end():].strip()
    number = int(re.sub(r"\D", "", a.group(1)))
    if st.cycle and a.group(1).upper().startswith("Q") and a.group(1)[1].isdigit():
        literal = re.fullmatch(_NUMBER, value)
        st.cycle_q[number] = float(value) if literal else value.upper() if value.upper() == "MAX" else None
        st.cycle_at[number] = (n, a.start() + 1)
    if value.upper() == "MAX":  # a cycle's feed at rapid traverse (Q208= MAX)
        return _comment(f"{a.group(1)} = MAX")
    return f"{_param(a.group(1))}={_formula(st, code[a.end():], a.end(), n)}"


def _next_block(st: _State, n: int) -> tuple[int, str, int] | None:
    """The next block after line `n` that is not blank or a comment: (line, its code, start of its body)."""
    for k in range(n + 1, len(st.lines) + 1):
        code = st.lines[k - 1].partition(";")[0].rstrip("\r")
        m = _BLOCK_NUMBER.match(code)
        start = m.end() if m else 0
        if code[start:].strip() and not code[start:].strip().startswith("*"):
            return k, code, start
    return None


_CORNER = re.compile(rf"(RND|CHF)\s+R?({_NUMBER}|[-+]?Q[LR]?\d+)", re.IGNORECASE)


def _corner_after(st: _State, n: int, targets: dict[str, str]) -> tuple[str, str, list[str]] | None:
    """When an RND or CHF block follows this L block (and an L block follows it), the point where
    this line must end (X, Y expressions) and the assignments that hand the corner's points to the
    RND/CHF block: § 7.4, RND R: the arc of radius R tangent to both lines; CHF s: the chamfer
    from s before the corner along the first line to s after it along the second. The last
    programmed position stays the corner (for the next block's incremental coordinates)."""
    after = _next_block(st, n)
    if not after or not _CORNER.match(after[1], after[2]):
        return None
    k, code, start = after
    kind, amount = _CORNER.match(code, start).groups()
    nxt = _next_block(st, k)
    if "Z" in targets or not nxt or not re.match(r"L\s", nxt[1][nxt[2]:] + " "):
        raise _error(st, k, start + 1, kind, f"{kind} between two L blocks in the working plane is supported",
                     "L X.. Y.., RND/CHF, L X.. Y..")
    second = _targets(st, _Tokens([(t, c) for t, c in _split(nxt[1], nxt[2] + 1, 0, nxt[0]).words
                                   if _COORD.match(t)], nxt[0]), "XY")
    x0, y0 = "#<_hh_x>", "#<_hh_y>"
    x1, y1 = targets.get("X", x0), targets.get("Y", y0)
    x2, y2 = (second.get(a, p).replace(p, f"[{c}]") for a, p, c in (("X", x0, x1), ("Y", y0, y1)))
    a1x, a1y, a2x, a2y = f"[{x1}-{x0}]", f"[{y1}-{y0}]", f"[{x2}-{x1}]", f"[{y2}-{y1}]"
    l1, l2 = f"SQRT[{a1x}**2+{a1y}**2]", f"SQRT[{a2x}**2+{a2y}**2]"
    cross, dot = f"[{a1x}*{a2y}-{a1y}*{a2x}]", f"[{a1x}*{a2x}+{a1y}*{a2y}]"
    r = _value(amount)
    d = f"[{r}*{_div(f'ABS[{cross}]', f'[{l1}*{l2}+{dot}]')}]" if kind.upper() == "RND" else r  # to the corner
    u1x, u1y, u2x, u2y = _div(a1x, l1), _div(a1y, l1), _div(a2x, l2), _div(a2y, l2)
    t1x, t1y = f"[{x1}-{d}*{u1x}]", f"[{y1}-{d}*{u1y}]"
    sign = f"[2*[{cross} GT 0]-1]"
    st.corner = k
    return t1x, t1y, [f"#<_hh_r1x>={t1x}", f"#<_hh_r1y>={t1y}", f"#<_hh_r2x>=[{x1}+{d}*{u2x}]",
                      f"#<_hh_r2y>=[{y1}+{d}*{u2y}]", f"#<_hh_rcx>=[{t1x}-{r}*{sign}*{u1y}]",
                      f"#<_hh_rcy>=[{t1y}+{r}*{sign}*{u1x}]", f"#<_hh_rdir>=[2+[{cross} GT 0]]"]


def _rnd_chf(st: _State, code: str, start: int, n: int) -> str:
    """RND R.. / CHF .. (F..) (§ 7.4): the rounding arc or chamfer the L block before computed."""
    keyword = code[:start].split()[-1].upper()
    if st.corner != n:
        raise _error(st, n, start - len(keyword) + 1, keyword, f"{keyword} not after an L block",
                     "L X.. Y.., RND/CHF, L X.. Y..")
    tokens = _split(code, start, 0, n)
    tokens.take(re.compile(rf"R?({_NUMBER}|[-+]?Q[LR]?\d+)$"))
    feed, words, _ = _contour_words(st, tokens, rapid_ok=False)
    _no_more(st, tokens, f"{keyword} <size> F..")
    motion = "G[#<_hh_rdir>]" if keyword == "RND" else "G1"
    if keyword == "RND":
        plane = [w for w in _plane(st, _XY, n, start - len(keyword) + 1, keyword) if w not in words]
        motion = " ".join([*plane, motion])
    centre = ["I[#<_hh_rcx>-#<_hh_r1x>]", "J[#<_hh_rcy>-#<_hh_r1y>]"] if keyword == "RND" else []
    return " ".join([*_pre(words), motion, "X#<_hh_r2x>", "Y#<_hh_r2y>", *centre, *([feed] if feed else []),
                     *_post(words)])


_PR0 = "SQRT[[#<_hh_x>-#<_hh_ccx>]**2+[#<_hh_y>-#<_hh_ccy>]**2]"
_PA0 = "ATAN[#<_hh_y>-#<_hh_ccy>]/[#<_hh_x>-#<_hh_ccx>]"


def _polar(st: _State, code: str, start: int, tokens: _Tokens) -> tuple[dict[str, str], str | None]:
    """The X/Y end point of a polar block (§ 7.5: PR radius, PA angle in degrees from +X about the
    pole CC; IPR/IPA add to the last position's; a missing one keeps the last position's) and the
    incremental angle's expression (None when PA is absolute)."""
    words = {m.group(2): (m.group(1) == "I", _value(m.group(3))) for m, _ in tokens.take(_POLAR)}
    if any(inc or k not in words for k, (inc, _) in {"PA": (False, ""), "PR": (False, ""), **words}.items()):
        _known_xy(st, code, start, tokens.line)
    pr = words.get("PR", (True, "0"))
    pa = words.get("PA", (True, "0"))
    r = f"[{_PR0}+{pr[1]}]" if pr[0] else pr[1]
    a = f"[{_PA0}+{pa[1]}]" if pa[0] else pa[1]
    xy = {"X": f"[#<_hh_ccx>+{r}*COS[{a}]]", "Y": f"[#<_hh_ccy>+{r}*SIN[{a}]]"}
    return xy, (pa[1] if pa[0] and "PA" in words else None)


def _lp(st: _State, code: str, start: int, n: int) -> str:
    """LP PR.. PA.. (Z..) R0|RL|RR F.. M.. (§ 7.5): a straight line to a point in polar coordinates."""
    _xy_pole(st, code, start, n)
    tokens = _split(code, start, 0, n)
    xy, _ = _polar(st, code, start, tokens)
    targets = {**xy, **_targets(st, tokens, "Z")}
    st.unknown -= set(targets)
    feed, words, _ = _contour_words(st, tokens)
    _no_more(st, tokens, "LP PR.. PA.. Z.. R0|RL|RR F..|FMAX M..")
    motion = "G0" if feed is None else "G1"
    tangent = [f"#<_hh_tx>=[{xy['X']}-#<_hh_x>]", f"#<_hh_ty>=[{xy['Y']}-#<_hh_y>]"]
    return " ".join([*_pre(words), motion, *(f"{a}{e}" for a, e in targets.items()), *([feed] if feed else []),
                     *_post(words), *_assigns(targets), *tangent])


def _cp(st: _State, code: str, start: int, n: int) -> str:
    """CP PA.. (IPA..) (Z..) DR+|DR- (§ 7.5): an arc about the pole CC to the polar angle PA (radius:
    the distance from the pole); IPA beyond ±360° adds whole turns (a helix with IZ)."""
    _xy_pole(st, code, start, n)
    _known_xy(st, code, start, n)
    tokens = _split(code, start, 0, n)
    motion = _direction(st, tokens)
    if any(m.group(2) == "PR" for m, _ in ((_POLAR.match(t), c) for t, c in tokens.words) if m):
        raise _error(st, n, start + 1, "CP", "CP takes no PR (the radius is the distance from the pole)", "CP PA..")
    xy, ipa = _polar(st, code, start, tokens)
    targets = {**xy, **_targets(st, tokens, "Z")}
    centre = ["I[#<_hh_ccx>-#<_hh_x>]", "J[#<_hh_ccy>-#<_hh_y>]"]
    if ipa is not None:
        centre.append(f"P[FUP[ABS[{ipa}]/360-0.000000001]+[ABS[{ipa}] LT 0.000000001]]")
    return _arc_line(st, tokens, motion, targets, centre, _end_tangent(motion, targets, "#<_hh_ccx>", "#<_hh_ccy>"),
                     "CP PA.. Z.. DR+|DR- F..")


_LEN = re.compile(rf"LEN({_NUMBER}|[-+]?Q[LR]?\d+)$")


def _dep_lt(st: _State, code: str, start: int, n: int) -> str:
    """DEP LT LEN.. F.. M.. ("Departing on a straight line with tangential connection"): from the last
    contour point PE a straight line LEN long continuing the last contour element's direction, to PN,
    at the block's feed; radius compensation ends there. Refused with compensation in force (where the
    control puts the compensated path's end is not modelled), with a Z (the move to PN, then along
    the tool axis) and after a CC outside XY (the direction is tracked in XY)."""
    _xy_pole(st, code, start, n)
    _known_xy(st, code, start, n)
    tokens = _split(code, code.upper().index("LT", start) + 2, 0, n)
    length = tokens.take(_LEN)
    if st.comp != "R0" or len(length) != 1:
        text, col = tokens.words[0] if tokens.words and len(length) != 1 else ("DEP LT", start - 2)
        raise _error(st, n, col, text, "DEP LT needs one LEN" if len(length) != 1 else "DEP LT with radius "
                     "compensation (RL/RR) in force", "L .. R0 before it, and DEP LT LEN.. F..")
    for m, col in tokens.take(re.compile(r"R[0LR]$")):
        raise _error(st, n, col, m.group(), "DEP takes no radius compensation (it ends it)", "DEP LT LEN.. F..")
    feed, words, _ = _contour_words(st, tokens, rapid_ok=False)
    _no_more(st, tokens, "DEP LT LEN.. F.. M..")
    norm = "SQRT[#<_hh_tx>**2+#<_hh_ty>**2]"
    x, y = (f"[#<_hh_{a}>+{_value(length[0][0].group(1))}*#<_hh_t{a}>/{norm}]" for a in "xy")
    return " ".join([*_pre(words), "G1", f"X{x}", f"Y{y}", *([feed] if feed else []), *_post(words),
                     f"#<_hh_x>={x}", f"#<_hh_y>={y}"])


_HANDLERS = {
    "DEP": _dep_lt, "BEGIN": _begin, "END": _end, "L": _l, "CC": _cc, "C": _c, "CR": _cr, "CT": _ct, "STOP": _stop,
    "LP": _lp, "CP": _cp, "RND": _rnd_chf, "CHF": _rnd_chf,
}
_PREFIXED = [
    ("BLK FORM", lambda st, code, s, n: _blk_form(st, code, s + code[s:].upper().index("FORM") + 4, n)),
    ("TOOL CALL", lambda st, code, s, n: _tool_call(st, code, s + code[s:].upper().index("CALL") + 4, n)),
    ("TOOL DEF", lambda st, code, s, n: _tool_def(st, code, s + code[s:].upper().index("DEF") + 3, n)),
    ("CYCL DEF", lambda st, code, s, n: _cycl_def(st, code, s + code[s:].upper().index("DEF") + 3, n)),
    ("CYCL CALL", lambda st, code, s, n: _cycl_call(st, code, s + code[s:].upper().index("CALL") + 4, n)),
    ("M", _m_only),
    ("FN", lambda st, code, s, n: _fn(st, code, s, n)),
    ("Q", lambda st, code, s, n: _q_assign(st, code, s, n)),
]

_F_WORD = re.compile(rf"(?<![A-Za-z])F\s*(?:{_NUMBER}|Q[LR]?\d+)(?![\d.])")  # FQ2: a feed from Q2 (hyperMILL)
_F_ANY = re.compile(r"(?<![A-Za-z])F\s*(?:MAX|AUTO)\b")
_CYCLE_CALL = re.compile(r"(?<![A-Za-z])M99\b|CYCL\s+CALL", re.IGNORECASE)
_M_WORD = re.compile(r"(?<![A-Za-z])M\d+")


def fixed_feed(line: str) -> bool:
    """A block whose moves run at a feed written elsewhere: a drilling cycle's call (M99, CYCL CALL; its
    feed is the cycle's Q206) and an FAUTO block (the TOOL CALL's F)."""
    code = line.partition(";")[0]
    return bool(_CYCLE_CALL.search(code) or _F_ANY.search(code))


def set_feed(line: str, f: str | None) -> str:
    """The block `line` (Klartext or ISO) with its F word's number `f` (in place; added before the M
    functions, the ISO ``*`` and the comment when the block has none), or without its F when `f` is
    None; a feed from a Q parameter (FQ2) is an F word like any (the number takes its place).
    A block whose feed is written elsewhere (`fixed_feed`) is refused."""
    code, sep, note = line.partition(";")
    if fixed_feed(line):
        raise MillpostError(f"{line.strip()!r}: its feed is written elsewhere (a cycle's Q206, the TOOL CALL's F); "
                            "millpost does not rewrite it (keep the programmed feeds of this block)")
    hit = _F_WORD.search(code)
    if f is None:
        if hit:
            code = code[:hit.start()].rstrip(" \t") + code[hit.end():]
            code = code if code.endswith((" ", "\t")) or not sep else code + " "
        return code + sep + note
    if hit:
        return code[:hit.start()] + f"F{f}" + code[hit.end():] + sep + note
    m = _M_WORD.search(code)
    star = re.search(r"\*\s*$", code)
    at = m.start() if m else star.start() if star else len(code.rstrip(" \t"))
    tail = code[at:]
    rest = " " + tail.lstrip(" \t") if tail.strip() else tail
    return code[:at].rstrip(" \t") + f" F{f}{rest}" + sep + note


# The translation writes G43 without H on TOOL CALL (the control applies the called tool's length) and
# G98/G99 on every drilling cycle; Klartext is written by `heidenhain_write` (the RS-274 fields unused).
HEIDENHAIN = Dialect(
    "heidenhain", comment="semicolon", g43_without_h=True,
    translate=translate, set_feed=set_feed, fixed_feed=fixed_feed, write=_write, blank=blank,
    decisive=(r"BEGIN\s+PGM", r"TOOL\s+CALL", r"BLK\s+FORM", r"^\s*%\w+\s+G7[01]\s*\*"),  # no RS-274 dialect reads them
    markers=(r"^\s*\d+\s+L\s", r"\bFMAX\b", r"END\s+PGM", r"\s\*\s*$"))
