"""Siemens SINUMERIK 840D sl / 828D programs: read through their RS-274/NGC translation (`translate`),
written back with only F words changed (`set_feed`), written from other dialects by `convert`."""

from __future__ import annotations

from ..dialects import Dialect
from .read import translate
from .write import fixed_feed, set_feed, write

SINUMERIK = Dialect(
    "sinumerik", comment="semicolon", end_code="M30", line_numbers=10, canned_cycles=False,
    translate=translate, set_feed=set_feed, fixed_feed=fixed_feed, write=write,
    tool_length_codes=frozenset({"G43", "G49"}), g43_without_h=True,
    # codes no RS-274 dialect reads (what the text's parenthesised parts leave of them: `dialects.score`)
    decisive=(r"\bG7[01]0\b", r"\bCYCLE8\d\d?\b", r"\bMSG\b", r'\bT\s*=\s*"', r"\bCYCLE832\b", r"_N_\w+_(MPF|SPF)",
              r"\b[XYZIJK]\s*=\s*(AC|IC)\b", r"\b(CR|AR)\s*="),
    markers=(r"^\s*N\d+\b[^;(]*;", r"^\s*(N\d+\s+)?R\d+\s*=", r"\bSUPA\b", r"\bG64[1-5]\b",
             r"^\s*(N\d+\s+)?(SOFT|BRISK|FFWON)\b", r"\bWORKPIECE\s*\(",
             r"^\s*(N\d+\s+)?A?TRANS\b", r"\bGOTO[FB]\b", r"\bG4\s*F", r"\bTURN\s*=", r"\bG50[05]\b",
             r"sinumerik|siemens|\b8[24]0D\b"),
)

__all__ = ["SINUMERIK"]
