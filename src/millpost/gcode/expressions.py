"""RS274/NGC parameters and expressions (LinuxCNC dialect): ``#1``, ``#<name>``, ``#[expr]``,
``[1 + 2 * #3]``, functions (ABS ACOS ASIN ATAN COS EXP FIX FUP ROUND LN SIN SQRT TAN EXISTS) and
operators (``**``; ``* / MOD``; ``+ -``; ``EQ NE GT GE LT LE``; ``AND OR XOR``). Angles in degrees.

`scan_line` reads a whole line that uses them: words with evaluated values, plus the parameter
assignments, which take effect after the line (as in LinuxCNC: a line reads the old values).
Every value is finite: a result that overflows or is undefined (``[1/0]``, ``[-8 ** 0.5]``,
``[#1 * #1]`` beyond 1.8e308) is refused where it arises, as is nesting deeper than `MAX_DEPTH`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable

from ..errors import ParseError

_FUNCS: dict[str, Callable[[float], float]] = {
    "ABS": abs, "ACOS": lambda v: math.degrees(math.acos(v)), "ASIN": lambda v: math.degrees(math.asin(v)),
    "COS": lambda v: math.cos(math.radians(v)), "EXP": math.exp, "FIX": math.floor, "FUP": math.ceil,
    "ROUND": lambda v: float(math.floor(v + 0.5)), "LN": math.log, "SIN": lambda v: math.sin(math.radians(v)),
    "SQRT": math.sqrt, "TAN": lambda v: math.tan(math.radians(v)),
}


def _power(a: float, b: float) -> float:
    if a < 0 and b != int(b):  # (Python would return a complex number)
        raise ValueError("a negative number to a fractional power")
    return a ** b


_BINOPS: list[dict[str, Callable[[float, float], float]]] = [  # lowest precedence first
    {"AND": lambda a, b: float(bool(a) and bool(b)), "OR": lambda a, b: float(bool(a) or bool(b)),
     "XOR": lambda a, b: float(bool(a) != bool(b))},
    {"EQ": lambda a, b: float(a == b), "NE": lambda a, b: float(a != b), "GT": lambda a, b: float(a > b),
     "GE": lambda a, b: float(a >= b), "LT": lambda a, b: float(a < b), "LE": lambda a, b: float(a <= b)},
    {"+": lambda a, b: a + b, "-": lambda a, b: a - b},
    {"*": lambda a, b: a * b, "/": lambda a, b: a / b, "MOD": lambda a, b: math.fmod(a, b) if a * b >= 0 else a % b},
    {"**": _power},
]
_LEVEL = {op: level for level, ops in enumerate(_BINOPS) for op in ops}  # precedence of each operator
_WORD_OPERATORS = sorted((op for op in _LEVEL if op.isalpha()), key=len, reverse=True)
_NUM = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)")
MAX_DEPTH = 50  # brackets, unary signs and functions nested in one value


class _Scanner:
    """Cursor over one line with whitespace skipped; errors carry the column."""

    def __init__(self, text: str, line: int, file: str, params: dict) -> None:
        self.text, self.line, self.file, self.params = text, line, file, params
        self.pos = 0
        self.depth = 0
        self.upper = text.upper()

    def error(self, message: str, expected: str, at: int | None = None) -> ParseError:
        at = self.pos if at is None else at
        word = self.text[at:at + 12].strip() or "end of line"
        return ParseError(message, file=self.file, line=self.line, column=at + 1, word=word, expected=expected)

    def skip(self) -> None:
        while self.pos < len(self.text) and self.text[self.pos] in " \t":
            self.pos += 1

    def operator(self) -> str | None:
        """The binary operator at the cursor, if any (``**`` before ``*``)."""
        self.skip()
        ch = self.text[self.pos:self.pos + 1]
        if ch == "*":
            return "**" if self.text.startswith("**", self.pos) else "*"
        if ch in ("+", "-", "/"):
            return ch
        if ch.isalpha():
            for op in _WORD_OPERATORS:
                if self.upper.startswith(op, self.pos):
                    return op
        return None

    def expect(self, ch: str) -> None:
        self.skip()
        if self.text[self.pos:self.pos + 1] != ch:
            raise self.error(f"expected {ch!r}", f"{ch!r}")
        self.pos += 1

    # --- grammar ---------------------------------------------------------------------------
    def value(self) -> float:
        """A real value: number, parameter, [expression], unary function, or signed value."""
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise self.error(f"expression nested more than {MAX_DEPTH} deep", "a simpler expression")
        try:
            return self._value()
        finally:
            self.depth -= 1

    def _value(self) -> float:
        self.skip()
        ch = self.text[self.pos:self.pos + 1]
        if ch in "+-" and ch:
            self.pos += 1
            v = self.value()
            return -v if ch == "-" else v
        if ch == "[":
            self.pos += 1
            v = self.expression()
            self.expect("]")
            return v
        if ch == "#":
            return self.params_get(self.parameter_ref())
        m = _NUM.match(self.text, self.pos)
        if m and ch not in "+-":
            v = float(m.group(0))
            if not math.isfinite(v):
                raise self.error("number too large", "a number below 1.8e308")
            self.pos = m.end()
            return v
        start = self.pos
        name = re.match(r"[A-Za-z]+", self.text[self.pos:])
        if name:
            fn = name.group(0).upper()
            self.pos += len(fn)
            if fn == "ATAN":
                self.expect("[")
                a = self.expression()
                self.expect("]")
                self.expect("/")
                self.expect("[")
                b = self.expression()
                self.expect("]")
                return math.degrees(math.atan2(a, b))
            if fn == "EXISTS":
                self.expect("[")
                self.skip()
                try:
                    key = self.parameter_ref()
                except ParseError:  # a number out of range cannot exist
                    key = None
                    end = self.text.find("]", self.pos)
                    if end < 0:
                        raise self.error("unclosed EXISTS[", "EXISTS[#<name>]") from None
                    self.pos = end
                self.expect("]")
                return float(isinstance(key, int) or (key is not None and key in self.params))
            if fn in _FUNCS:
                self.expect("[")
                a = self.expression()
                self.expect("]")
                try:
                    v = float(_FUNCS[fn](a))
                except (ValueError, OverflowError) as exc:
                    raise self.error(f"{fn} of {a:g} is undefined ({exc})", "an argument in the function's domain",
                                     start) from None
                if not math.isfinite(v):
                    raise self.error(f"{fn} of {a:g} overflows", "an argument in the function's domain", start)
                return v
            self.pos = start
        raise self.error("expected a number, parameter or expression", "a value such as 1.5, #3, #<name> or [1+2]")

    def parameter_ref(self) -> int | str:
        """After '#': a number, #<name>, or #[expr] / ##n (indirect). Returns the key."""
        self.expect("#")
        self.skip()
        if self.text[self.pos:self.pos + 1] == "<":
            end = self.text.find(">", self.pos)
            if end < 0:
                raise self.error("unterminated parameter name", "#<name>")
            key = "".join(self.text[self.pos + 1:end].split()).lower()
            self.pos = end + 1
            return key
        v = self.value()
        if v != int(v) or not 0 <= v <= 5601:
            raise self.error(f"parameter number {v:g} is out of range", "an integer parameter 0..5601")
        return int(v)

    def params_get(self, key: int | str) -> float:
        try:
            return self.params[key]
        except KeyError:
            pass
        if isinstance(key, int):
            return 0.0
        raise self.error(f"parameter #<{key}> is used before it is set", "a named parameter assigned earlier")

    def expression(self, level: int = 0) -> float:
        """Operators of precedence `level` and above, left to right (precedence climbing)."""
        left = self.value()
        while True:
            op = self.operator()
            if op is None or _LEVEL[op] < level:
                return left
            at = self.pos
            self.pos += len(op)
            right = self.expression(_LEVEL[op] + 1)
            try:
                left = float(_BINOPS[_LEVEL[op]][op](left, right))
            except (ZeroDivisionError, OverflowError, ValueError) as exc:
                if getattr(self.params, "values_unknown", False):  # locating words only: any value will do
                    left = 0.0
                    continue
                raise self.error(f"{op} is undefined here ({exc})", "a defined arithmetic result", at) from None
            if not math.isfinite(left):
                raise self.error(f"{op} overflows (the result is beyond 1.8e308)", "a finite arithmetic result", at)


def scan_line(code: str, line: int, file: str, params: dict) -> tuple[list[tuple[str, float, int, int, int]], list]:
    """Words (letter, value, column, start, end) and parameter assignments [(key, value)] of a line
    whose comments were already blanked out."""
    sc = _Scanner(code, line, file, params)
    words: list[tuple[str, float, int, int, int]] = []
    assigns: list[tuple[int | str, float]] = []
    while True:
        sc.skip()
        if sc.pos >= len(code):
            return words, assigns
        start = sc.pos
        ch = code[sc.pos]
        if ch == "#":
            key = sc.parameter_ref()
            sc.expect("=")
            assigns.append((key, sc.value()))
            continue
        if ch.isalpha() or ch in "@^":
            sc.pos += 1
            words.append((ch.upper(), sc.value(), start + 1, start, sc.pos))
            continue
        raise sc.error(f"unexpected character {ch!r}", "words (a letter and a value) or #parameter = value")


def evaluate_all(code: str, start: int, line: int, file: str, params: dict) -> list[float]:
    """Values ([expr], number or parameter) from column `start` to the end of a line whose comments
    were already blanked out: the arguments of an O-word call or the condition of an if/while."""
    sc = _Scanner(code, line, file, params)
    sc.pos = start
    out = []
    while True:
        sc.skip()
        if sc.pos >= len(code):
            return out
        out.append(sc.value())
