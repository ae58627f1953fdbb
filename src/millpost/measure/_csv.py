"""A compiled parser for numeric CSV tables (logs of millions of rows): numbers separated by commas, one
row per line, `#` comment lines and blank lines skipped. Numbers: [+-]digits[.digits][(e|E)[+-]digits],
nan, inf. Decimal to binary by Clinger's fast path (exact when the digits fit 2⁵³ and |exponent| ≤ 22,
as logged values do; within an ulp or two otherwise). Any other text stops the parse; the caller locates
and reports it."""

from __future__ import annotations

import numba
import numpy as np

_POW10 = np.array([10.0 ** k for k in range(23)])


@numba.njit(cache=True)
def _scale(mant: float, exp: int, pow10: np.ndarray) -> float:
    while exp > 22:
        mant *= 1e22
        exp -= 22
    while exp < -22:
        mant /= 1e22
        exp += 22
    return mant * pow10[exp] if exp >= 0 else mant / pow10[-exp]


@numba.njit(cache=True)
def _parse(buf: np.ndarray, start: int, ncols: int, out: np.ndarray, pow10: np.ndarray) -> int:
    """Rows parsed into out (ncols × max_rows: column-major, so that columns are contiguous views);
    the number of rows, or −1 − (byte offset) of the first bad field."""
    max_rows = out.shape[1]
    n = len(buf)
    i, row, col = start, 0, 0
    while i < n:
        c = buf[i]
        if col == 0:
            if c == 10 or c == 13 or c == 32 or c == 9:
                i += 1
                continue
            if c == 35:  # '#': a comment line
                while i < n and buf[i] != 10:
                    i += 1
                continue
        while i < n and (buf[i] == 32 or buf[i] == 9):
            i += 1
        field = i
        neg = False
        if i < n and (buf[i] == 45 or buf[i] == 43):
            neg = buf[i] == 45
            i += 1
        if i + 2 < n and (buf[i] | 32) == 110 and (buf[i + 1] | 32) == 97 and (buf[i + 2] | 32) == 110:
            value = np.nan
            i += 3
        elif i + 2 < n and (buf[i] | 32) == 105 and (buf[i + 1] | 32) == 110 and (buf[i + 2] | 32) == 102:
            value = np.inf
            i += 3
        else:
            mant, exp, digits = 0.0, 0, 0
            while i < n and 48 <= buf[i] <= 57:
                if digits < 18:
                    mant = mant * 10.0 + (buf[i] - 48)
                else:
                    exp += 1
                digits += 1
                i += 1
            if i < n and buf[i] == 46:
                i += 1
                while i < n and 48 <= buf[i] <= 57:
                    if digits < 18:
                        mant = mant * 10.0 + (buf[i] - 48)
                        exp -= 1
                    digits += 1
                    i += 1
            if digits == 0:
                return -1 - field
            if i < n and (buf[i] == 101 or buf[i] == 69):
                i += 1
                eneg = False
                if i < n and (buf[i] == 45 or buf[i] == 43):
                    eneg = buf[i] == 45
                    i += 1
                e, edigits = 0, 0
                while i < n and 48 <= buf[i] <= 57:
                    e = e * 10 + (buf[i] - 48) if e < 100000 else e
                    edigits += 1
                    i += 1
                if edigits == 0:
                    return -1 - field
                exp += -e if eneg else e
            value = _scale(mant, exp, pow10)
        if row >= max_rows:
            return -1 - field
        out[col, row] = -value if neg else value
        while i < n and (buf[i] == 32 or buf[i] == 9):
            i += 1
        if i < n and buf[i] == 44:
            col += 1
            i += 1
            if col >= ncols:
                return -1 - i
        elif i >= n or buf[i] == 10 or buf[i] == 13:
            if col != ncols - 1:
                return -1 - i
            row += 1
            col = 0
        else:
            return -1 - i
    if col != 0:
        return -1 - n
    return row


def parse_numbers(data: bytes, start: int, ncols: int) -> list[np.ndarray] | None:
    """The ncols columns (float arrays) of the table in data[start:], or None when some field is not a
    number or a row has the wrong number of fields (the caller reports where)."""
    buf = np.frombuffer(data, np.uint8)
    max_rows = data.count(b"\n", start) + 1
    out = np.empty((ncols, max_rows))
    rows = _parse(buf, start, ncols, out, _POW10)
    if rows < 0:
        return None
    return [out[c, :rows] for c in range(ncols)]
