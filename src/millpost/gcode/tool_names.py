"""Tools called by name (Sinumerik ``T="MILL_D10"``, Heidenhain ``TOOL CALL "MILL_D10"``): a job
describes tools by number, so each name gets one. The rule, the same in every dialect: a name of
digits alone is that number; any other name gets the next number by first appearance in the
program's text (1, 2, ...; the same name, the same number). The readers say which number each
name got in a note (``tool MILL_D10 = T1``)."""

from __future__ import annotations


def tool_number(name: str, numbers: dict[str, int]) -> int:
    """The number of the tool called `name`; `numbers` holds the names numbered so far (updated)."""
    return int(name) if name.isdigit() else numbers.setdefault(name, len(numbers) + 1)


def tool_note(name: str, number: int) -> str:
    """The note that says which number the tool called `name` got."""
    return f"tool {name} = T{number}"
