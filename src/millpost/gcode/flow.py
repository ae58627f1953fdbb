"""O-word control flow as LinuxCNC runs it, and Fanuc-style subprograms (``M98 P<n> L<repeats>`` runs
the lines after ``O<n>`` up to ``M99``, sharing the caller's parameters; ``M99`` in the main program
ends it): ``oN sub``/``endsub``/``return``/``call`` with up to 30
positional arguments (#1–#30, local to the call, as are named parameters without a leading ``_``),
``if``/``elseif``/``else``/``endif``, ``while``/``endwhile``, ``do``/``while``, ``repeat``/``endrepeat``,
``break`` and ``continue``; ``endsub``/``return`` may carry a value, stored in ``#<_value>``.

`Source` walks a program's text one line at a time and can return to a line it has passed (it keeps
8 bytes per line, and counts the lines read more than once: at most `MAX_REPEATED_LINES`); the interpreter reads straight-line programs without it and starts one at the
first control statement. `Flow` holds the call and loop stacks and moves the source where a statement sends it.
Subroutines must be in the same file (LinuxCNC's search of other files is not modelled: such a call
is an error that says so).
"""

from __future__ import annotations

import re
from array import array
from dataclasses import dataclass, field

from ..errors import ParseError
from .expressions import evaluate_all

# a control line: optional block delete and N number, then o<label>, oNNN or o#<param> (a call's
# target from a parameter), then a keyword (spaces inside it ignored, as everywhere in RS-274)
_LABEL = re.compile(r"[ \t]*(?:/[ \t]*)?(?:[Nn][ \t]*\d+(?:\.\d*)?[ \t]*)?[Oo][ \t]*"
                    r"(\d+|<[^>]*>|#[ \t]*(?:<[^>]*>|\d+))")
_COMMENT = re.compile(r"\([^()]*\)")
_PROGRAM = re.compile(r"[ \t]*[Oo][ \t]*(\d+)[ \t]*(?:\([^()]*\)[ \t]*)*(?:;.*)?$")  # a Fanuc subprogram's O line
KEYWORDS = {"sub", "endsub", "return", "call", "if", "elseif", "else", "endif", "while", "endwhile", "do",
            "repeat", "endrepeat", "break", "continue"}
# Lines read again (loops, calls, M98 repeats, skips over a body) beyond the first reading of each:
# a loop that never ends, or one that expands a program past what a post-processed file holds, is
# refused (LinuxCNC has no such limit; at ~30 us a line this bounds the reading to a few seconds).
MAX_REPEATED_LINES = 100_000


def control_of(raw: str) -> tuple[str, str, int] | None:
    """(label, keyword, offset just past the keyword) when the line is an O-word control statement.
    Labels: a number as its integer text, <name> lower case without spaces, #… as written."""
    if "o" not in raw and "O" not in raw:
        return None
    m = _LABEL.match(raw)
    if m is None:
        return None
    i, letters = m.end(), []
    while i < len(raw) and (raw[i].isalpha() or raw[i] in " \t"):
        if raw[i].isalpha():
            letters.append(raw[i].lower())
        i += 1
    keyword = "".join(letters)
    if keyword not in KEYWORDS:
        return None
    label = "".join(m.group(1).split())
    if label.startswith("<"):
        label = label[1:-1].lower()
    elif label.isdigit():
        label = str(int(label))
    return label, keyword, i


class Source:
    """Lines of a text by number (1-based), read forward and revisited by `seek`."""

    def __init__(self, text: str, line: int = 0, pos: int = 0) -> None:
        """Positioned after `line` (its next line starting at offset `pos`)."""
        self.text = text
        self.pos = pos
        self.line = line
        self.repeats = 0  # lines read again after their first reading
        self.starts = array("q", [0])  # offset of every line seen so far, and of the one after
        while len(self.starts) < line:
            self.starts.append(text.find("\n", self.starts[-1]) + 1)
        if line:
            self.starts.append(pos)

    def next(self) -> str | None:
        if self.pos >= len(self.text):
            return None
        end = self.text.find("\n", self.pos)
        end = len(self.text) if end < 0 else end
        raw = self.text[self.pos:end].rstrip("\r")
        self.pos = end + 1
        self.line += 1
        if self.line == len(self.starts):
            self.starts.append(self.pos)
        else:
            self.repeats += 1
        return raw

    def seek(self, line: int) -> None:
        """Make `line` (seen, or the one after the last seen) the next line returned."""
        self.line = line - 1
        self.pos = self.starts[line - 1]


@dataclass
class _Frame:
    label: str
    return_line: int
    saved: dict  # the caller's local parameters (none for M98: Fanuc subprograms share them)
    loops: int  # depth of the loop stack at the call
    start: int = 0  # M98: the subprogram's O line, and the runs still to go
    repeats: int = 0


@dataclass
class _Loop:
    label: str
    kind: str  # while, do, repeat
    line: int  # the loop's opening line
    remaining: int = 0


@dataclass
class Flow:
    """Call and loop stacks of a running program; `statement` executes one control line."""

    source: Source
    file: str
    params: dict
    subs: dict = field(default_factory=dict)  # label → line of its `sub`
    programs: dict = field(default_factory=dict)  # M98 subprogram number → line of its O word
    frames: list = field(default_factory=list)
    loops: list = field(default_factory=list)

    def error(self, line: int, raw: str, message: str, expected: str) -> ParseError:
        return ParseError(message, file=self.file, line=line, column=len(raw) - len(raw.lstrip()) + 1,
                          word=raw.strip()[:40], expected=expected)

    def _values(self, raw: str, at: int, line: int) -> list[float]:
        """The values after the keyword ([expr] [expr] ...), comments blanked."""
        code = _COMMENT.sub(lambda m: " " * len(m.group(0)), raw)
        code = code.split(";", 1)[0]
        return evaluate_all(code, at, line, self.file, self.params)

    def _condition(self, raw: str, at: int, line: int) -> bool:
        values = self._values(raw, at, line)
        if len(values) != 1:
            raise self.error(line, raw, "a condition needs one [expression]", "[expression] after the keyword")
        return values[0] != 0.0

    def statement(self, raw: str, label: str, keyword: str, at: int) -> None:
        """Execute the control line just read (raw, with its parsed label and keyword)."""
        line = self.source.line
        if keyword == "sub":
            self.subs[label] = line
            self._skip_to(label, ("endsub",), line, raw)
        elif keyword == "call":
            self._call(label, raw, at, line)
        elif keyword in ("endsub", "return"):
            self._return(label, raw, at, line)
        elif keyword == "if":
            if not self._condition(raw, at, line):
                self._next_branch(label, line, raw)
        elif keyword in ("elseif", "else"):  # reached at the end of a branch that ran
            self._skip_to(label, ("endif",), line, raw)
        elif keyword == "endif":
            pass
        elif keyword == "do":
            self.loops.append(_Loop(label, "do", line))
        elif keyword == "while":
            self._while(label, raw, at, line)
        elif keyword == "endwhile":
            loop = self._loop(label, line, raw, ("while",))
            self.source.seek(loop.line)
        elif keyword == "repeat":
            top = self.loops[-1] if self.loops else None
            if top is None or top.label != label or top.line != line:
                count = self._values(raw, at, line)
                if len(count) != 1:
                    raise self.error(line, raw, "repeat needs one [count]", "oN repeat [count]")
                top = _Loop(label, "repeat", line, int(count[0]))
                self.loops.append(top)
            if top.remaining <= 0:
                self.loops.pop()
                self._skip_to(label, ("endrepeat",), line, raw)
        elif keyword == "endrepeat":
            loop = self._loop(label, line, raw, ("repeat",))
            loop.remaining -= 1
            self.source.seek(loop.line)
        elif keyword in ("break", "continue"):
            loop = next((lp for lp in reversed(self.loops) if lp.label == label), None)
            if loop is None:
                raise self.error(line, raw, f"{keyword} outside the loop o{label}", f"{keyword} inside its loop")
            while self.loops[-1] is not loop:
                self.loops.pop()
            if keyword == "continue":
                self._continue(loop, line, raw)
            else:
                self.loops.pop()
                end = {"while": ("endwhile",), "repeat": ("endrepeat",), "do": ("while",)}[loop.kind]
                self._skip_to(label, end, line, raw)

    # --- pieces ------------------------------------------------------------------------------
    def _while(self, label: str, raw: str, at: int, line: int) -> None:
        top = self.loops[-1] if self.loops else None
        if top is not None and top.label == label and top.kind == "do":  # the end of do ... while
            if self._condition(raw, at, line):
                self.source.seek(top.line + 1)
            else:
                self.loops.pop()
            return
        if top is None or top.label != label or top.line != line:
            top = _Loop(label, "while", line)
            self.loops.append(top)
        if not self._condition(raw, at, line):
            self.loops.pop()
            self._skip_to(label, ("endwhile",), line, raw)

    def _continue(self, loop: _Loop, line: int, raw: str) -> None:
        if loop.kind == "while":
            self.source.seek(loop.line)
        elif loop.kind == "repeat":
            self._skip_to(loop.label, ("endrepeat",), line, raw)
            loop.remaining -= 1
            self.source.seek(loop.line)
        else:  # do: LinuxCNC 2.9 jumps to the `while` line and reads it as the start of a while loop
            self.loops.pop()
            self._skip_to(loop.label, ("while",), line, raw)
            self.source.seek(self.source.line)

    def _loop(self, label: str, line: int, raw: str, kinds: tuple[str, ...]) -> _Loop:
        if not self.loops or self.loops[-1].label != label or self.loops[-1].kind not in kinds:
            raise self.error(line, raw, f"end of a loop o{label} that is not open", f"o{label} {kinds[0]} before")
        return self.loops[-1]

    def _call(self, label: str, raw: str, at: int, line: int) -> None:
        if label.startswith("#"):  # o#<name> call: the subroutine number from a parameter
            number = evaluate_all(label, 0, line, self.file, self.params)[0]
            label = str(int(number)) if number == int(number) else label
        args = self._values(raw, at, line)
        if len(args) > 30:
            raise self.error(line, raw, "more than 30 subroutine arguments", "at most 30 [arguments]")
        if label not in self.subs:  # defined further on: find it
            self._skip_to(label, ("sub",), line, raw, missing=f"subroutine o{label} is not in this file, and "
                                                               "subroutine files are not supported")
        if len(self.frames) >= 100:
            raise self.error(line, raw, "subroutine calls nested more than 100 deep", "recursion that ends")
        saved = {k: v for k, v in self.params.items() if (isinstance(k, int) and 1 <= k <= 30)
                 or (isinstance(k, str) and not k.startswith("_"))}
        for k in saved:
            del self.params[k]
        for i, v in enumerate(args, start=1):
            self.params[i] = v
        self.frames.append(_Frame(label, line + 1, saved, len(self.loops)))
        self.source.seek(self.subs[label] + 1)

    def _return(self, label: str, raw: str, at: int, line: int) -> None:
        if not self.frames:  # (a return may carry the label of an if around it, as LinuxCNC allows)
            raise self.error(line, raw, f"o{label} endsub/return outside a subroutine call", "a matching call")
        values = self._values(raw, at, line)
        self.params["_value"] = values[0] if values else 0.0
        self.params["_value_returned"] = 1.0 if values else 0.0
        frame = self.frames.pop()
        for k in [k for k in self.params if (isinstance(k, int) and 1 <= k <= 30)
                  or (isinstance(k, str) and not k.startswith("_"))]:
            del self.params[k]
        self.params.update(frame.saved)
        del self.loops[frame.loops:]  # loops a return leaves
        self.source.seek(frame.return_line)

    def call_subprogram(self, label: str, repeats: int, raw: str) -> None:
        """M98 P<label> L<repeats>: run the lines after `O<label>` up to its M99, `repeats` times."""
        line = self.source.line
        if repeats <= 0:
            return
        if label not in self.programs:
            self._find_program(label, line, raw)
        if len(self.frames) >= 100:
            raise self.error(line, raw, "subprogram calls nested more than 100 deep", "recursion that ends")
        self.frames.append(_Frame("", line + 1, {}, len(self.loops), self.programs[label], repeats))
        self.source.seek(self.programs[label] + 1)

    def return_subprogram(self) -> bool:
        """M99: the next run of the subprogram, or back to the line after its M98. False in the
        main program (no call to return from)."""
        if not self.frames or not self.frames[-1].start:
            return False
        frame = self.frames[-1]
        frame.repeats -= 1
        del self.loops[frame.loops:]
        if frame.repeats > 0:
            self.source.seek(frame.start + 1)
        else:
            self.frames.pop()
            self.source.seek(frame.return_line)
        return True

    def _find_program(self, label: str, line: int, raw: str) -> None:
        """Record the line `O<label>` (a number alone, perhaps with a comment): after the call, else
        before it."""
        for first in (line + 1, 1):
            self.source.seek(first)
            while (text := self.source.next()) is not None:
                m = _PROGRAM.match(text)
                if m is not None and str(int(m.group(1))) == label:
                    self.programs[label] = self.source.line
                    self.source.seek(line + 1)
                    return
                if first == 1 and self.source.line >= line:
                    break
        raise self.error(line, raw, f"subprogram O{label} is not in this file", f"a line O{label} with its M99")

    def _next_branch(self, label: str, line: int, raw: str) -> None:
        """After a false if/elseif: run the next elseif whose condition holds, an else, or go past endif."""
        while True:
            got = self._skip_to(label, ("elseif", "else", "endif"), line, raw)
            keyword, text, at = got
            if keyword != "elseif" or self._condition(text, at, self.source.line):
                return

    def _skip_to(self, label: str, keywords: tuple[str, ...], line: int, raw: str,
                 missing: str | None = None) -> tuple[str, str, int]:
        """Read on, without executing, to the line `o<label> <keyword>`; the next line read follows it."""
        while True:
            text = self.source.next()
            if text is None:
                raise self.error(line, raw, missing or f"o{label} {keywords[-1]} not found before the end of the file",
                                 f"o{label} {keywords[-1]}" if missing is None else "the subroutine in this file")
            c = control_of(text)
            if c is not None:
                if c[1] == "sub" and c[0] not in self.subs:
                    self.subs[c[0]] = self.source.line
                if c[0] == label and c[1] in keywords:
                    return c[1], text, c[2]
