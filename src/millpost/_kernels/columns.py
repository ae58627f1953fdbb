"""Multi columns of `millpost.stock.Stock` (numba): where a column's gaps are and how much material
they take out of a z range.

A multi column's material is [z_floor, top] less its gaps (empty z ranges below its original top,
top-down, disjoint). The multi columns are marked in a bitset of 64-column words (bit c & 63 of word
c >> 6); `rank[w]` counts the multi columns before word w, so column c is multi column number
rank[c >> 6] + popcount(word & bits below c): its gaps are lo/hi[ptr[m]:ptr[m + 1]].
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def _popcount(typingctx, x):
    """Set bits of an int64 (LLVM's ctpop: one instruction where the CPU has it)."""
    if not isinstance(x, types.Integer) or x.bitwidth != 64:
        return None

    def codegen(context, builder, signature, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.IntType(64), [ir.IntType(64)]),
                                            "llvm.ctpop.i64")
        return builder.call(fn, args)

    return types.int64(x), codegen


@njit(cache=True, inline="always")
def is_multi(c, bits):
    """Whether column c is a multi column."""
    return (bits[c >> 6] >> (c & 63)) & 1 != 0


@njit(cache=True, inline="always")
def multi_index(c, bits, rank):
    """Number m of multi column c (its gaps are lo/hi[ptr[m]:ptr[m + 1]])."""
    w = c >> 6
    below = bits[w] & ((np.int64(1) << (c & 63)) - np.int64(1))
    return np.int64(rank[w]) + _popcount(below)


@njit(cache=True, inline="always", error_model="numpy")
def gap_overlap(m, za, zb, ptr, lo, hi):
    """Length of multi column m's gaps inside [za, zb] (mm)."""
    s = 0.0
    for k in range(ptr[m], ptr[m + 1]):
        s += max(min(np.float64(hi[k]), zb) - max(np.float64(lo[k]), za), 0.0)
    return s


@njit(cache=True)
def ranks(bits, rank):
    """rank[w] = multi columns in the words before w; returns their total."""
    n = np.int64(0)
    for w in range(bits.shape[0]):
        rank[w] = n
        n += _popcount(bits[w])
    return n


@njit(cache=True, error_model="numpy")
def gaps_length(top, zf, bits, rank, ptr, lo, hi):
    """Sum over the multi columns of their gaps' length below their top (mm)."""
    s = 0.0
    m = 0  # the multi columns in order: their index counts up
    for w in range(bits.shape[0]):
        word = bits[w]
        if word == 0:
            continue
        for b in range(64):
            if (word >> b) & 1:
                s += gap_overlap(m, zf, np.float64(top[w * 64 + b]), ptr, lo, hi)
                m += 1
    return s
