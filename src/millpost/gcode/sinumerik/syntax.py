"""Sinumerik block syntax: one line's words and its arithmetic, as RS-274/NGC text.

Addresses are a letter and a number (``X10.5``, ``G1``, ``T1``; no space needed: ``G1X10``), or a name,
optionally with an extension, and ``=`` and an expression (``X=R1+5``, ``CR=-20``, ``I1=AC(5)``,
``ADIS=0.05``, ``T="mill 10"``). Names followed by ``(`` are calls (``CYCLE832(0.01,1,1)``,
``MSG("...")``); other names are keywords (``SOFT``, ``TRANS``). (SINUMERIK 840D sl/828D
Fundamentals, "Fundamentals of NC programming": "Block", "Address", "Value assignments".)

Expressions (Fundamentals, "Arithmetic operations" / Job planning, "Arithmetic functions"): ``+ - * /``,
``DIV`` (integer quotient), ``MOD``, ``== <> < > <= >=``, ``NOT AND OR XOR``, functions ``SIN COS TAN
ASIN ACOS ATAN2 SQRT POT ABS TRUNC ROUND LN EXP MINVAL MAXVAL``, R parameters (``R1``, ``R[expr]``) and
``DEF`` variables. They become NGC expressions: R<n> is ``#<1000+n>``, a DEF variable ``#<_v_name>``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ...errors import ParseError

R_BASE = 1000  # R<n> is NGC parameter #<R_BASE + n>
R_COUNT = 1000  # R0 ... R999
_NUMWORD = re.compile(r"([A-Za-z])[ \t]*([-+]?(?:\d+\.?\d*|\.\d+))")
_BLANKS = re.compile(r"[ \t]*")
_NAME = re.compile(r"[A-Za-z_$][A-Za-z0-9_$]*")
_NUMBER = re.compile(r"(?:\d+\.?\d*|\.\d+)(?:EX[-+]?\d+)?", re.IGNORECASE)
_SYMBOLS = ("==", "<>", "<=", ">=", "<", ">", "+", "-", "*", "/")
_WORD_OPS = ("AND", "OR", "XOR", "DIV", "MOD")
_LEVELS = [{"OR": "OR", "XOR": "XOR"}, {"AND": "AND"},
           {"==": "EQ", "<>": "NE", "<": "LT", ">": "GT", "<=": "LE", ">=": "GE"},
           {"+": "+", "-": "-"}, {"*": "*", "/": "/", "DIV": "DIV", "MOD": "MOD"}]
_ONE_ARG = {"SIN": "SIN", "COS": "COS", "TAN": "TAN", "ASIN": "ASIN", "ACOS": "ACOS", "SQRT": "SQRT", "ABS": "ABS",
            "ROUND": "ROUND", "LN": "LN", "EXP": "EXP"}


@dataclass
class Token:
    """One element of a block: kind "word" (name, value text as written, `eq`: written with '='),
    "call" (name, value = the text between the parentheses) or "keyword" (name). [start, end) in the line."""

    kind: str
    name: str
    value: str
    start: int
    end: int
    eq: bool = False


class Line:
    """One source line being read: its text, where it is, and errors that name it."""

    def __init__(self, text: str, line: int, file: str) -> None:
        self.text, self.line, self.file = text, line, file

    def error(self, message: str, at: int, word: str, expected: str) -> ParseError:
        return ParseError(message, file=self.file, line=self.line, column=at + 1, word=word, expected=expected)


def skip(text: str, i: int) -> int:
    """The first index from `i` that is not a space or tab."""
    return _BLANKS.match(text, i).end()


def string_end(src: Line, i: int) -> int:
    """End (just past the closing quote) of the string starting at `i`."""
    end = src.text.find('"', i + 1)
    if end < 0:
        raise src.error("unterminated string", i, src.text[i:i + 20], 'a closing "')
    return end + 1


def closing(src: Line, i: int) -> int:
    """Index of the ')' matching the '(' at `i` (strings skipped)."""
    depth, j = 0, i
    while j < len(src.text):
        ch = src.text[j]
        if ch == '"':
            j = string_end(src, j)
            continue
        depth += (ch == "(") - (ch == ")")
        if depth == 0:
            return j
        j += 1
    raise src.error("unbalanced parenthesis", i, src.text[i:i + 20], "a closing )")


def tokens(src: Line, start: int, end: int) -> list[Token]:
    """The words, calls and keywords of text[start:end]."""
    text, out, i = src.text, [], skip(src.text, start)
    while i < end:
        m = _NUMWORD.match(text, i)
        after = skip(text, m.end()) if m else i
        if m and not (text.startswith("=", after) and not text.startswith("==", after)):
            out.append(Token("word", m.group(1).upper(), m.group(2), i, m.end()))
            i = skip(text, m.end())
            continue
        name = _NAME.match(text, i)
        if name is None:
            raise src.error(f"unexpected {text[i]!r}", i, text[i:i + 20], "an address (X10, X=R1+2, CR=5), a "
                            "command (SOFT) or a call (CYCLE832(...))")
        j = skip(text, name.end())
        upper = name.group(0).upper()
        if text.startswith("=", j) and not text.startswith("==", j):
            v0 = skip(text, j + 1)
            v1 = value_end(src, v0)
            out.append(Token("word", upper, text[v0:v1], i, v1, eq=True))
            i = v1
        elif text.startswith("(", j):
            k = closing(src, j)
            out.append(Token("call", upper, text[j + 1:k], i, k + 1))
            i = k + 1
        else:
            out.append(Token("keyword", upper, "", i, name.end()))
            i = name.end()
        i = skip(text, i)
    return out


class Expr:
    """A Sinumerik expression → NGC expression text. `names` maps DEF variable names (upper case) to
    their NGC parameter."""

    def __init__(self, src: Line, names: dict[str, str]) -> None:
        self.src, self.names = src, names

    def read(self, i: int) -> tuple[str, int]:
        """(NGC text, end) of the expression starting at `i`."""
        return self.level(i, 0)

    def operator(self, i: int, level: int) -> tuple[str, int] | None:
        j = skip(self.src.text, i)
        text = self.src.text
        for op in _LEVELS[level]:
            if text[j:j + len(op)].upper() == op:
                k = j + len(op)
                if op.isalpha() and k < len(text) and (text[k].isalnum() or text[k] == "_"):
                    continue
                if op in ("<", ">") and text[k:k + 1] in ("=", ">"):
                    continue
                return op, k
        return None

    def level(self, i: int, level: int) -> tuple[str, int]:
        if level == len(_LEVELS):
            return self.unary(i)
        left, i = self.level(i, level + 1)
        while (found := self.operator(i, level)) is not None:
            op, j = found
            right, i = self.level(j, level + 1)
            if op == "DIV":
                left = _trunc(f"[{left}/{right}]")
            else:
                left = f"[{left} {_LEVELS[level][op]} {right}]" if op.isalpha() or level < 3 else f"[{left}{op}{right}]"
        return left, i

    def unary(self, i: int) -> tuple[str, int]:
        text = self.src.text
        i = skip(text, i)
        if text[i:i + 1] in ("-", "+"):
            inner, j = self.unary(i + 1)
            return (f"-{inner}" if text[i] == "-" else inner), j
        if text[i:i + 3].upper() == "NOT" and not (text[i + 3:i + 4].isalnum() or text[i + 3:i + 4] == "_"):
            inner, j = self.unary(i + 3)
            return f"[{inner} EQ 0]", j
        return self.primary(i)

    def primary(self, i: int) -> tuple[str, int]:
        text, src = self.src.text, self.src
        if text[i:i + 1] == "(":
            inner, j = self.read(i + 1)
            j = skip(text, j)
            if text[j:j + 1] != ")":
                raise src.error("expected ')'", j, text[j:j + 10], "a closing parenthesis")
            return f"[{inner}]", j + 1
        m = _NUMBER.match(text, i)
        if m:
            number = m.group(0).upper()
            if "EX" in number:
                mant, _, exp = number.partition("EX")
                return f"[{mant}*10**{int(exp)}]", m.end()
            return number, m.end()
        name = _NAME.match(text, i)
        if name is None:
            raise src.error("expected a value", i, text[i:i + 10], "a number, R parameter, variable, function or (...)")
        return self.named(name.group(0).upper(), i, skip(text, name.end()))

    def named(self, name: str, i: int, j: int) -> tuple[str, int]:
        """A variable or function whose name starts at `i`; `j` is just past the name."""
        text, src = self.src.text, self.src
        r = re.fullmatch(r"R(\d+)", name)
        if r:
            n = int(r.group(1))
            if n >= R_COUNT:
                raise src.error(f"R parameter {name} out of range", i, name, f"R0 ... R{R_COUNT - 1}")
            return f"#{R_BASE + n}", i + len(name)
        if name == "R" and text[j:j + 1] == "[":
            k = text.find("]", j)
            if k < 0:
                raise src.error("unterminated R[...]", j, text[j:j + 10], "R[expression]")
            inner, _ = Expr(Line(text[:k], src.line, src.file), self.names).read(j + 1)
            return f"#[{R_BASE}+{inner}]", k + 1
        if text[j:j + 1] == "(":
            return self.function(name, i, j)
        if name == "$PI":
            return "3.141592653589793", i + len(name)
        if name.startswith("$"):
            raise src.error(f"system variable {name} is the controller's state, which millpost does not model", i,
                            name, "numbers, R parameters and DEF variables")
        if name in self.names:
            return self.names[name], i + len(name)
        if name in ("TRUE", "FALSE"):
            return ("1" if name == "TRUE" else "0"), i + len(name)
        raise src.error(f"unknown variable {name}", i, name, "an R parameter, a DEF variable defined earlier, a number")

    def function(self, name: str, i: int, j: int) -> tuple[str, int]:
        src = self.src
        end = closing(src, j)
        args, k = [], j + 1
        while True:
            arg, k = self.read(k)
            args.append(arg)
            k = skip(src.text, k)
            if src.text[k:k + 1] == ",":
                k += 1
                continue
            break
        if k != end:
            raise src.error(f"unexpected text in {name}(...)", k, src.text[k:end], "arguments separated by commas")
        want = 2 if name in ("ATAN2", "MINVAL", "MAXVAL") else 1
        if name not in _ONE_ARG and name not in ("ATAN2", "MINVAL", "MAXVAL", "POT", "TRUNC"):
            raise src.error(f"unknown function {name}", i, name, "SIN COS TAN ASIN ACOS ATAN2 SQRT POT ABS TRUNC "
                            "ROUND LN EXP MINVAL MAXVAL")
        if len(args) != want:
            raise src.error(f"{name} takes {want} argument(s), not {len(args)}", i, name, f"{name}(...)")
        a = args[0]
        if name in _ONE_ARG:
            out = f"{_ONE_ARG[name]}[{a}]"
        elif name == "POT":
            out = f"[[{a}]*[{a}]]"
        elif name == "TRUNC":
            out = _trunc(a)
        elif name == "ATAN2":
            out = f"ATAN[{a}]/[{args[1]}]"
        else:
            b = args[1]
            lo = name == "MINVAL"
            out = f"[[[{a}] {'LE' if lo else 'GE'} [{b}]]*[{a}]+[[{a}] {'GT' if lo else 'LT'} [{b}]]*[{b}]]"
        return out, end + 1


def _trunc(a: str) -> str:
    """TRUNC: toward zero (NGC's FIX is the floor)."""
    return f"[FIX[ABS[{a}]]*[[[{a}] GE 0]*2-1]]"


def value_end(src: Line, i: int) -> int:
    """Where the value written at `i` ends: a string, a call such as AC(...), or an expression."""
    text = src.text
    if text[i:i + 1] == '"':
        return string_end(src, i)
    m = re.compile(r"(AC|IC)[ \t]*\(", re.IGNORECASE).match(text, i)
    if m:
        return closing(src, m.end() - 1) + 1
    return Expr(src, _Any()).read(i)[1]


class _Any(dict):
    """Every name is a variable (used only to find where an expression ends)."""

    def __contains__(self, key: object) -> bool:
        return True

    def __getitem__(self, key: str) -> str:
        return "0"
