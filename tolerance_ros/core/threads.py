"""Caps the threads of the numerical libraries (BLAS, OpenMP) wherever the suite solves, so that a solve
never oversubscribes the cores of a loaded robot computer and runs as fast under load as on one core.

``cap_environment()`` sets the libraries' thread variables (only where the user has not set them);
it takes effect only before numpy is first imported, so entry points call it first thing.
``limited()`` caps the thread pools at run time with threadpoolctl where it is installed (a pip
dependency; ROS users without it rely on ``cap_environment``). Imports nothing numeric.
"""
from __future__ import annotations

import contextlib
import os
import threading

ENV_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
            "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")


def cap_environment(threads: int = 1) -> None:
    """Set each library's thread-count variable to ``threads`` unless it is already set."""
    for name in ENV_VARS:
        os.environ.setdefault(name, str(int(threads)))


# Held while a thread loads shared libraries (imports of numba and scipy, compiled kernels) beside others: the
# scan of the loaded libraries by threadpoolctl (glibc's dl_iterate_phdr, calling back into Python) must not run
# meanwhile, or it waits for the interpreter that the loading thread holds while that thread waits for the
# loader's lock the scan holds (seen as a command hung for good, Python 3.12 with threadpoolctl 3.1).
LOADING = threading.Lock()


def limited(threads: int = 1):
    """Context manager capping the BLAS/OpenMP pools to ``threads`` (threadpoolctl), or doing nothing
    when threadpoolctl is not installed. The libraries are scanned under ``LOADING``."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return contextlib.nullcontext()
    with LOADING:
        return threadpool_limits(limits=int(threads))
