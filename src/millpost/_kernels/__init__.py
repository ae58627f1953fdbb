"""Compiled (numba) inner loops. Each module is an implementation detail of a public module:
`raster` of `millpost.stock.mesh`, `engage` of `millpost.engagement`.

Every kernel is compiled with `cache=True`: the first run after an install (or an edit of a kernel)
compiles them, about a minute on a small machine, and later runs load them from `__pycache__`.
`announce_compile` says so, once, before that first compile.
"""

from __future__ import annotations

import os
import sys

_announced = False


def announce_compile(*kernels) -> None:
    """One line on stderr, once per process, when one of `kernels` (numba dispatchers) has no
    compiled copy cached on disk yet."""
    global _announced
    if _announced:
        return
    for kernel in kernels:
        if kernel.signatures:  # already compiled in this process
            continue
        index = getattr(getattr(getattr(kernel, "_cache", None), "_cache_file", None), "_index_path", None)
        if index is not None and not os.path.exists(index):
            _announced = True
            print("millpost: compiling the numba kernels once (about a minute; cached on disk for later runs)",
                  file=sys.stderr, flush=True)
            return
