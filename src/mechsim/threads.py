"""The BLAS threads of a run.

A run factors and multiplies small matrices (tens to a few hundred rows) thousands of times.
A multithreaded BLAS wakes its threads for each of them, which costs more than the
arithmetic, and on a busy machine its threads compete with the run's own for the cores.
So a run holds the BLAS libraries numpy and scipy loaded to one thread while it works
(threadpoolctl, restored after), unless the user chose a count in the environment
(`USER_VARIABLES`): that choice is left alone. docs/benchmarks.md has the measurements.
"""

from __future__ import annotations

import contextlib
import functools
import os

# Setting any of these says the user chose the BLAS threads: a run then leaves them as set.
USER_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                  "BLIS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")


def chosen_by_user() -> bool:
    """Whether the environment sets a BLAS thread count (`USER_VARIABLES`)."""
    return any(os.environ.get(name, "").strip() for name in USER_VARIABLES)


# How many `run_threads` blocks the running code is inside (one thread's): an inner block
# (each run of a sequence of runs) finds the limit set already.
_DEPTH = 0


@contextlib.contextmanager
def run_threads():
    """Within the block, BLAS runs on one thread (threadpoolctl), unless the user chose a
    count (`chosen_by_user`); the previous limits come back when it ends, also on an
    exception. Blocks nest: only the outermost sets and restores the limit."""
    global _DEPTH
    if chosen_by_user() or _DEPTH:
        yield
        return
    _DEPTH += 1
    try:
        with _controller().limit(limits=1, user_api="blas"):
            yield
    finally:
        _DEPTH -= 1


@functools.lru_cache(maxsize=1)
def _controller():
    """The process's BLAS libraries, found once (threadpoolctl's scan of the loaded
    libraries takes milliseconds, as long as a small run): scipy's linear algebra is
    imported first, so that its BLAS is among them."""
    import scipy.linalg  # noqa: F401
    from threadpoolctl import ThreadpoolController
    return ThreadpoolController()


def in_run_threads(function):
    """`function` called within `run_threads` (a decorator for the analyses that are runs:
    kinematics, equilibrium, periodic orbits)."""
    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        with run_threads():
            return function(*args, **kwargs)
    return wrapper
