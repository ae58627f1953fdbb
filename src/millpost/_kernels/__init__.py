"""Compiled (numba) inner loops. Each module is an implementation detail of a public module:
`raster` of `millpost.stock.mesh`, `engage` of `millpost.engagement`.

The time-domain force kernel runs its samples on several threads (`set_threads`, from `--jobs`);
its samples are independent, so the result does not depend on the count.

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


def set_threads(n: int) -> None:
    """Threads of the parallel kernels in this thread of the process: n, at most numba's maximum."""
    import numba

    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))
