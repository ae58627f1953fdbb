"""One error hierarchy for millpost: every refusal says where and why."""

from __future__ import annotations


class MillpostError(Exception):
    """Base class of every error millpost raises on purpose (the CLI exits 2 on these)."""


class ParseError(MillpostError):
    """A program or file that millpost refuses, located at file:line:column.

    `word` is the offending text, `expected` says what would have been accepted.
    """

    def __init__(self, message: str, *, file: str = "<string>", line: int = 0, column: int = 0,
                 word: str = "", expected: str = "") -> None:
        self.file, self.line, self.column = file, line, column
        self.word, self.expected, self.reason = word, expected, message
        where = f"{file}:{line}:{column}"
        text = f"{where}: {message}"
        if word:
            text += f" (word {word!r})"
        if expected:
            text += f"; expected {expected}"
        super().__init__(text)


class ConfigError(MillpostError):
    """An invalid value in a tool, material, machine or job description.

    Names the field, the value and the rule it breaks (and the file when known).
    """

    def __init__(self, field: str, value: object, rule: str, *, file: str | None = None) -> None:
        self.field, self.value, self.rule, self.file = field, value, rule, file
        prefix = f"{file}: " if file else ""
        super().__init__(f"{prefix}{field} = {value!r}: {rule}")


class SolverError(MillpostError):
    """The feed schedule could not be solved; callers keep the programmed feeds."""


class SafetyError(MillpostError):
    """millpost will not write this: the program or the job looks dangerous (a crash, a cut below the
    stock, no material where the stock should be) or an output would replace an input. `gate` names
    the check; when it may be overridden the message says how."""

    def __init__(self, message: str, gate: str = "") -> None:
        self.gate = gate
        super().__init__(message)


class CrashError(SafetyError):
    """A rapid move runs into material at `xyz` (mm, program frame), on source `line` of `file`; the
    message gives the point in the program's units there (inch: 4 decimals)."""

    def __init__(self, line: int, xyz, file: str | None = None, inch: bool = False) -> None:
        self.line, self.xyz, self.file, self.inch = line, tuple(float(v) for v in xyz), file, inch
        x, y, z = (v / 25.4 for v in self.xyz) if inch else self.xyz
        d, unit = (4, "in") if inch else (3, "mm")
        where = f"{file}:{line}" if file else f"line {line}"
        super().__init__(f"{where}: rapid move runs into the stock at X{x:.{d}f} Y{y:.{d}f} Z{z:.{d}f} ({unit}, "
                         "a crash; use a feed move to cut, or correct the stock)", gate="rapid")
