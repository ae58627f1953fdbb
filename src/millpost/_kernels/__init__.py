"""Compiled (numba) inner loops. Each module is an implementation detail of a public module:
`raster` of `millpost.stock.mesh`, `engage` of `millpost.engagement`.

The time-domain force kernel runs its samples on several threads (`set_threads`, from `--jobs`);
its samples are independent, so the result does not depend on the count.

Every kernel is compiled with `cache=True`: the first run after an install (or an edit of a kernel)
compiles them, about a minute on a small machine, and later runs load them from `__pycache__`.
`compiling` wraps a kernel's call and reports the stage "compile kernels" to `millpost.progress.current()`
(a progress bar on a terminal) while the kernel is not yet compiled in this process; nothing is printed.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from ..progress import current


@contextmanager
def compiling(*kernels) -> Iterator[None]:
    """Around a call of numba dispatchers: the stage "compile kernels" started and finished when one of
    them has no compiled copy in this process yet (numba compiles it, or loads it from the disk cache)."""
    if all(k.signatures for k in kernels):
        yield
        return
    report = current()
    report("compile kernels", 0.0, 0.0)
    yield
    report("compile kernels", 1.0, 1.0)


def set_threads(n: int) -> None:
    """Threads of the parallel kernels in this thread of the process: n, at most numba's maximum."""
    import numba

    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))
