"""G-code lexer: one line of text → one `Block` of words with their columns.

Accepts what RS-274 posts write: any letter case, no spaces (``G1X10Y5F300``), comments in
parentheses and after ``;``, ``N`` line numbers, ``O`` program numbers, ``%`` tape marks, block delete
``/`` and ``*`` checksums. LinuxCNC parameters (``#``) and expressions (``[...]``) are evaluated by the
interpreter's expression module when present; the fast path here handles plain numbers.

Every value must be finite and within the range of its letter, in program units (mm or inch, rpm,
degrees): lengths ``X Y Z U V W I J K R Q @`` at most ``LENGTH_LIMIT`` (1 000 000) in magnitude, ``G``
and ``M`` codes below 1000, any other word (``F S P L T H D N A B C ^`` ...) at most ``NUMBER_LIMIT``
(1e9; LinuxCNC's example 3D_Chips.ngc feeds at F2 250 000). A value beyond is a mistake, and the
limits keep every later sum and product finite. Exponents (``1e3``) are not G-code: LinuxCNC reads
the ``e`` as an E word and refuses it; so does millpost, saying why.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from ..errors import ParseError
from .expressions import scan_line

# A word: letter, optional spaces, signed number.
_WORD = re.compile(r"([A-Za-z@^])[ \t]*([-+]?[ \t]*(?:\d+\.?\d*|\.\d+))")
_PLAIN = re.compile(r"(?:[ \t]*[A-Za-z@^][ \t]*[-+]?[ \t]*(?:\d+\.?\d*|\.\d+))*[ \t]*")
_COMMENT = re.compile(r"\([^()]*\)")
_CHECKSUM = re.compile(r"\*[ \t]*\d+[ \t]*$")
LENGTH_LIMIT = 1e6  # program units (1 km in mm)


def source_lines(text: str, keepends: bool = False) -> list[str]:
    """A program's lines as the interpreter numbers them: ended by LF only (a CR alone, as in PyCAM's
    CR CR LF, is not a line break), each without its line end (CRs before the LF included) unless
    `keepends`."""
    parts = text.split("\n")
    tail = parts.pop()  # what follows the last LF (nothing when the text ends with one)
    last = [tail] if tail else []
    if keepends:
        return [part + "\n" for part in parts] + last
    return [part.rstrip("\r") for part in parts + last]
NUMBER_LIMIT = 1e9
_LIMITS = {**dict.fromkeys("XYZUVWIJKRQ@", LENGTH_LIMIT), "G": 999.9, "M": 999.0}


@dataclass(slots=True)
class Word:
    """One word: upper-case letter, value, 1-based column, and [start, end) span in the line."""

    letter: str
    value: float
    column: int
    start: int
    end: int
    text: str


@dataclass(slots=True)
class Block:
    """A lexed line. `words` exclude N, O, comments, checksum; `comments` hold the texts."""

    line: int
    words: list[Word] = field(default_factory=list)
    comments: list[str] = field(default_factory=list)
    block_delete: bool = False
    percent: bool = False
    number: float | None = None  # N word
    program: str | None = None  # O word (program number/name), as written
    code_end: int = 0  # index just past the last word (where new words go)
    assigns: list = field(default_factory=list)  # parameter assignments [(key, value)], applied after the line


def _number(text: str) -> float:
    """A matched number, spaces or tabs between its sign and digits allowed ("- 5")."""
    try:
        return float(text)  # the common case, no spaces inside
    except ValueError:
        return float(text.replace(" ", "").replace("\t", ""))


def lex_line(text: str, line: int, file: str = "<string>", params: dict | None = None) -> Block:
    """Lex one line (without its newline). Raises ParseError naming file:line:column on junk.

    `params` is the interpreter's parameter table, used by lines with ``#`` or ``[`` (LinuxCNC
    parameters and expressions); their assignments are returned in `Block.assigns`."""
    block = Block(line=line)
    code = text
    stripped = code.strip()
    if not stripped:
        return block
    if stripped == "%" or (stripped.startswith("%") and not stripped[1:].strip().startswith(("G", "g"))):
        block.percent = True
        block.comments.append(stripped[1:].strip())
        return block
    # ';' comment to end of line (outside parentheses)
    if ";" in code:
        depth = 0
        for i, ch in enumerate(code):
            if ch == "(":
                depth += 1
            elif ch == ")":
                depth = max(depth - 1, 0)
            elif ch == ";" and depth == 0:
                block.comments.append(code[i + 1:].strip())
                code = code[:i] + " " * (len(code) - i)
                break
    if "(" in code or ")" in code:
        def keep(m: re.Match) -> str:
            block.comments.append(m.group(0)[1:-1].strip())
            return " " * len(m.group(0))
        code = _COMMENT.sub(keep, code)
        for ch in "()":
            pos = code.find(ch)
            if pos >= 0:
                raise ParseError("unbalanced or nested comment parenthesis", file=file, line=line,
                                 column=pos + 1, word=ch, expected="comments as (text) without nesting")
    lead = len(code) - len(code.lstrip())
    if code[lead:lead + 1] == "/":
        block.block_delete = True
        code = code[:lead] + " " + code[lead + 1:]
    if "*" in code:  # checksum: '*' then digits at the end of the block
        m = _CHECKSUM.search(code)
        if m is not None:
            code = code[:m.start()] + " " * (len(code) - m.start())
    if code[lead:].lstrip()[:1] in ("O", "o"):
        # O word: a program number (Fanuc "O1001", LinuxCNC "o<name>"); control statements never get
        # here (the interpreter runs them, see flow.py), so anything after the label is unknown
        body = code[lead:].lstrip()
        col = len(code) - len(code.lstrip()) + 1
        m = re.fullmatch(r"[Oo][ \t]*(\d+|<[^>]*>)[ \t]*(.*)", body.rstrip())
        if m is None:
            raise ParseError("malformed O word", file=file, line=line, column=col, word=body.strip(),
                             expected="a program number such as O1001")
        if m.group(2).strip():
            raise ParseError("unknown O-word statement", file=file, line=line, column=col, word=body.strip(),
                             expected="a program number alone, or oN sub|endsub|return|call|if|elseif|else|endif|"
                                      "while|endwhile|do|repeat|endrepeat|break|continue")
        block.program = m.group(1)
        return block
    if ("#" in code or "[" in code) and params is not None:
        found, block.assigns = scan_line(code, line, file, params)
    else:
        if _PLAIN.fullmatch(code) is None:
            _locate_error(code, line, file)
        found = [(m.group(1).upper(), _number(m.group(2)), m.start() + 1, m.start(), m.end())
                 for m in _WORD.finditer(code)]
    for letter, value, column, start, end in found:
        limit = _LIMITS.get(letter, NUMBER_LIMIT)
        if not -limit <= value <= limit:  # also NaN
            raise ParseError(f"{letter} value out of range", file=file, line=line, column=column,
                             word=text[start:end].strip()[:40], expected=f"|{letter}| <= {limit:g}")
        if letter == "E" and start and code[start - 1] in "0123456789.":
            number = code[block.words[-1].start if block.words else start:end].strip()
            raise ParseError("a number in exponent notation (G-code has none: the 'e' reads as an E word)",
                             file=file, line=line, column=(block.words[-1].column if block.words else column),
                             word=number, expected="the number written out in decimals, e.g. 1000 for 1e3")
        if letter == "N" and not block.words and block.number is None:
            block.number = value
            continue
        block.words.append(Word(letter, value, column, start, end, text[start:end]))
        block.code_end = end
    return block


def _locate_error(code: str, line: int, file: str) -> None:
    """Find the first character that does not start a valid word and raise a ParseError there."""
    pos = 0
    n = len(code)
    while pos < n:
        while pos < n and code[pos] in " \t":
            pos += 1
        if pos >= n:
            break
        m = _WORD.match(code, pos)
        if m:
            pos = m.end()
            continue
        ch = code[pos]
        found = re.match(r"\S+", code[pos:])
        word = found.group(0) if found else repr(ch)
        if ch == "#":
            raise ParseError("parameters (#) are not supported", file=file, line=line, column=pos + 1,
                             word=word, expected="plain numbers as a CAM post writes them")
        if ch == "[":
            raise ParseError("expressions ([...]) are not supported", file=file, line=line, column=pos + 1,
                             word=word, expected="plain numbers as a CAM post writes them")
        if ch.isalpha():
            raise ParseError(f"letter {ch.upper()} is not followed by a number", file=file, line=line,
                             column=pos + 1, word=word, expected="a word: a letter and a number, e.g. X10.5")
        raise ParseError(f"unexpected character {ch!r}", file=file, line=line, column=pos + 1, word=word,
                         expected="words (a letter and a number), comments in ( ) or after ;")
    raise ParseError("cannot read block", file=file, line=line, column=1, word=code.strip(),
                     expected="words (a letter and a number)")
